"""Mechanism.simulate, .dynamics, .equilibrium, .modes and .linearize against the command line
(the same numbers: simulate's CSV bit for bit, the JSON of equilibrium, modes and linearize to
its 17 digits), linearize's A and B against central differences of dynamics, their errors,
and examples/python/lqr.py stabilizing the cart-pole."""
import importlib.util
import json
import subprocess

import numpy as np
import pytest

import kinegen
from conftest import EXE, SOURCE

DYN = SOURCE / "examples" / "dynamics"


def run(*args):
    return subprocess.run([EXE, *args], capture_output=True, text=True)


def test_simulate_equals_command_line_bit_for_bit(tmp_path):
    path = str(DYN / "four_bar_damped.yaml")
    out = tmp_path / "run.csv"
    r = run("simulate", path, "--t1", "0.5", "--steps", "20", "--forces", "-q", "-o", str(out))
    assert r.returncode == 0, r.stderr
    with open(out) as f:
        header = f.readline().rstrip("\n").split(",")
        values = np.array([[float(v) for v in line.split(",")] for line in f])
    got = kinegen.Mechanism(path).simulate(0.5, 20, forces=True)
    assert list(got) == header
    for k, name in enumerate(header):
        assert np.array_equal(got[name], values[:, k]), name


def test_simulate_atol_follows_rtol_and_allow_drift_warns(tmp_path):
    """atol defaults to 1e-2 rtol, as the command line's --atol; allow_drift turns a balance
    past its bound into one warning."""
    m = kinegen.Mechanism(str(DYN / "pendulum.yaml"))
    default = m.simulate(1, 4, rtol=1e-11)
    # 1e-2 * 1e-11 is the double the default computes (1.0000000000000001e-13, not 1e-13).
    given = m.simulate(1, 4, rtol=1e-11, atol=1e-2 * 1e-11)
    assert np.array_equal(default["theta"], given["theta"])
    assert not np.array_equal(m.simulate(1, 4, rtol=1e-11, atol=1e-10)["theta"], given["theta"])
    with pytest.raises(kinegen.UsageError, match="usable range"):
        m.simulate(1, 4, rtol=1e-20)
    spring = tmp_path / "spring.yaml"
    spring.write_text(
        "name: oscillator\nparameters: {m: 1, k: 1e6}\nbodies:\n"
        "  - {name: mass, q0: [0.01, 0, 0], mass: m}\n"
        "joints:\n  - {type: translational, name: guide, i: ground, j: mass, vi: [1, 0]}\n"
        "free:\n  - {type: absolute_x, name: x, body: mass, value0: 0.01, v0: 0}\n"
        "forces:\n  - {type: spring_damper, name: spring, i: ground, j: mass, si: [-1, 0], "
        "sj: [0, 0], stiffness: k, damping: 0, length0: 1}\n")
    s = kinegen.Mechanism(str(spring))
    with pytest.raises(kinegen.AnalysisError, match="energy balance"):
        s.simulate(100, 100, rtol=1e-4)
    with pytest.warns(UserWarning, match="energy balance"):
        rows = s.simulate(100, 100, rtol=1e-4, allow_drift=True)
    assert len(rows["t"]) == 101


@pytest.mark.parametrize("name", ["pendulum", "four_bar_damped", "cart_pole"])
def test_equilibrium_modes_linearize_equal_command_line(name):
    path = str(DYN / (name + ".yaml"))
    m = kinegen.Mechanism(path)
    for command, got in (("equilibrium", m.equilibrium()), ("modes", m.modes()),
                         ("linearize", m.linearize())):
        r = run(command, path, "--format", "json")
        assert r.returncode == 0, r.stderr
        want = json.loads(r.stdout)
        for key, value in want.items():
            if isinstance(value, dict):
                assert got[key] == pytest.approx(value, rel=0, abs=0), (command, key)
            elif isinstance(value, list) and value and isinstance(value[0], str):
                assert list(got[key]) == value, (command, key)
            elif isinstance(value, (list, int, float)):
                assert np.array_equal(np.asarray(got[key], dtype=float).reshape(-1),
                                      np.asarray(value, dtype=float).reshape(-1)), (command, key)
            else:
                assert got[key] == value, (command, key)


def test_equilibrium_start_and_nearest_equal_command_line():
    # The four-bar with a spring released from 0.7 rad (start=, --from) rests at a minimum of
    # its potential (stable); Newton's nearest root from there (nearest=, --nearest) is a
    # maximum (unstable): different points, each the command line's to its 17 digits.
    path = str(DYN / "four_bar_spring.yaml")
    m = kinegen.Mechanism(path)
    found = {}
    for nearest in (False, True):
        got = m.equilibrium(start=[0.7], nearest=nearest)
        args = ["equilibrium", path, "--from", "theta=0.7", "--format", "json"]
        r = run(*args, *(["--nearest"] if nearest else []))
        assert r.returncode == 0, r.stderr
        want = json.loads(r.stdout)
        assert np.array_equal(got["z"], want["z"])
        assert got["stability"] == want["stability"]
        assert got["flow_steps"] == want["flow_steps"]
        found[nearest] = got
    assert found[False]["stability"] == "stable" and found[False]["flow_steps"] > 0
    assert found[True]["stability"] == "unstable" and found[True]["flow_steps"] == 0
    assert abs(found[False]["z"][0] - found[True]["z"][0]) > 1
    with pytest.raises(kinegen.UsageError):
        m.equilibrium(start=[1.0, 2.0])


def test_linearize_is_the_derivative_of_dynamics():
    m = kinegen.Mechanism(str(DYN / "cart_pole.yaml"))
    assert m.free == ["x", "phi"] and m.inputs == ["push_x"]
    x = np.array([0.3, 1.2, -0.7, 2.1])
    u = np.array([3.5])
    lin = m.linearize(t=0.0, z=x[:2], zd=x[2:], u=u)
    f = lambda x, u: np.concatenate([x[2:], m.dynamics(0.0, x[:2], x[2:], u)])
    assert np.array_equal(lin["xdot"], f(x, u))
    h = 1e-6
    a = np.column_stack([(f(x + h * e, u) - f(x - h * e, u)) / (2 * h) for e in np.eye(4)])
    b = (f(x, u + h) - f(x, u - h)) / (2 * h)
    assert np.abs(lin["A"] - a).max() < 1e-7 * np.abs(a).max()
    assert np.abs(lin["B"][:, 0] - b).max() < 1e-7 * np.abs(b).max()


def test_no_inputs_gives_an_empty_b():
    lin = kinegen.Mechanism(str(DYN / "pendulum.yaml")).linearize()
    assert lin["B"].shape == (2, 0) and lin["inputs"] == []


def test_errors_are_the_command_line_ones():
    slider = str(SOURCE / "examples" / "slider_crank.yaml")
    with pytest.raises(kinegen.UsageError, match="needs free coordinates"):
        kinegen.Mechanism(slider).modes()
    m = kinegen.Mechanism(str(DYN / "cart_pole.yaml"))
    with pytest.raises(kinegen.UsageError, match="z expects 2 values"):
        m.linearize(z=[1.0])
    with pytest.raises(kinegen.UsageError, match="u expects 1 value"):
        m.dynamics(0.0, [0, 1.5], [0, 0], [1.0, 2.0])


def load_lqr():
    spec = importlib.util.spec_from_file_location("lqr", SOURCE / "examples" / "python" / "lqr.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_lqr_stabilizes_the_cart_pole(tmp_path):
    pytest.importorskip("scipy")
    pytest.importorskip("matplotlib")
    lqr = load_lqr()
    mech = kinegen.Mechanism(lqr.MECH)
    lin, k = lqr.design(mech)
    assert np.linalg.eigvals(lin["A"]).real.max() > 1  # upright: unstable
    assert np.linalg.eigvals(lin["A"] - lin["B"] @ k).real.max() < 0
    t, y, u = lqr.closed_loop(mech, lin, k)
    assert abs(y[1, -1] - np.pi / 2) < 1e-3 and abs(y[0, -1]) < 1e-2
    assert abs(y[1] - np.pi / 2).max() < 0.5  # it never falls
    out = tmp_path / "lqr.png"
    lqr.plot(t, y, u, out)
    assert out.stat().st_size > 10000


def test_augmented_n_four_bar_40_over_the_benchmarks_20_s(tmp_path):
    """IFToMM A02 at the benchmark's own size (N = 40, nq = 243) through all its flat positions:
    the C++ test of it is hidden from the sanitizer pass (minutes there); here it runs in the
    Release pass. Truths: the parallelogram branch's one-degree-of-freedom model (energy
    1/2 I theta'^2 + G sin(theta), I = (N + 1)/3 + N, G = g (3N + 1)/2; examples/dynamics/
    n_four_bar.py), integrated by scipy, and the energy balance."""
    from scipy.integrate import solve_ivp

    n, out = 40, tmp_path / "n40.csv"
    r = run("simulate", str(DYN / "n_four_bar_40.yaml"), "--t1", "20", "--steps", "400",
            "--method", "augmented", "--rtol", "1e-13", "--atol", "1e-13", "-q", "-o", str(out))
    assert r.returncode == 0, r.stderr
    with open(out) as f:
        header = f.readline().rstrip("\n").split(",")
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    col = {name: rows[:, k] for k, name in enumerate(header)}
    assert rows.shape[0] == 401
    inertia, weight = (n + 1) / 3 + n, 9.81 * (3 * n + 1) / 2
    ref = solve_ivp(lambda t, y: [y[1], -weight * np.cos(y[0]) / inertia], (0, 20),
                    [np.pi / 4, -np.sqrt(2)], t_eval=col["t"], rtol=1e-12, atol=1e-12,
                    method="DOP853")
    theta = col["theta"]
    # Both flat positions (0 and -pi), each passed several times.
    assert theta.min() < -np.pi
    assert np.count_nonzero(np.diff(np.sin(theta) > 0)) >= 12
    # B0 on the reduced model's circle; every crank at theta, every coupler horizontal.
    b0 = np.hypot(col["B0.x"] - np.cos(ref.y[0]), col["B0.y"] - np.sin(ref.y[0]))
    assert b0.max() < 1e-6, b0.max()
    for k in range(n + 1):
        assert np.abs(col[f"crank_{k}.phi"] - theta).max() < 1e-6
    for k in range(n):
        assert np.abs(col[f"coupler_{k}.phi"]).max() < 1e-6
    assert np.abs(col["energy.balance"]).max() < 1e-6


def test_simulate_refuses_an_input_table_short_of_the_run(tmp_path):
    """As the command line: an input table that does not cover [t0, t1] is a UsageError
    before the run, naming the table, its range and the run's (a table is never
    extrapolated)."""
    table = tmp_path / "push_late.csv"
    table.write_text("t,value\n0.1,0\n0.5,0\n0.8,0\n1.2,0\n")
    m = kinegen.Mechanism(str(DYN / "cart_pole.yaml"), inputs={"push_x": str(table)})
    with pytest.raises(kinegen.UsageError) as e:
        m.simulate(1, 10)
    assert "the table covers t = 0.1 to 1.2, the run t = 0 to 1" in str(e.value)
    assert m.simulate(1, 10, t0=0.2)["t"].shape == (11,)
