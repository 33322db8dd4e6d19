"""The Python module against the command line: the same numbers bit for bit on every example
(the CSV's 17 significant digits round-trip a double exactly), the same column order, and
errors that carry the command line's error: line."""
import json
import math

import numpy as np
import pytest

import kinegen
from conftest import examples, read_csv, run

TURN = "6.283185307179586"


def cli_error(result):
    assert result.stderr.startswith("error: ")
    return result.stderr[len("error: "):].rstrip("\n")


@pytest.mark.parametrize("path", examples())
def test_analyze_equals_command_line_bit_for_bit(path, tmp_path):
    params = [p for p in kinegen.Mechanism(path).parameters]
    out = tmp_path / "out.csv"
    r = run("analyze", path, "--t0", "0", "--t1", TURN, "--steps", "90", "-o", str(out),
            "--sensitivity", ",".join(params))
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    got = kinegen.Mechanism(path).analyze(0, float(TURN), 90, sensitivity=params)
    assert list(got.keys()) == header
    for k, name in enumerate(header):
        assert got[name].dtype == np.float64
        # Exact equality (array_equal): bit for bit, not to a tolerance.
        assert np.array_equal(got[name], values[:, k]), name


def test_params_override_like_param(source, tmp_path):
    path = str(source / "examples" / "slider_crank.yaml")
    out = tmp_path / "out.csv"
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "10", "-o", str(out),
            "--param", "l=2.5")
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    m = kinegen.Mechanism(path, params={"l": 2.5})
    assert m.parameters["l"] == 2.5
    got = m.analyze(0, 1, 10)
    assert list(got) == header
    assert all(np.array_equal(got[h], values[:, k]) for k, h in enumerate(header))
    assert kinegen.Mechanism(path, params={"l": "5/2"}).parameters["l"] == 2.5


@pytest.mark.parametrize("path", examples())
def test_eval_equals_command_line(path):
    m = kinegen.Mechanism(path)
    n = m.nq
    q = [0.1 * (k + 1) for k in range(n)]
    qd = [0.05 * (k - 1) for k in range(n)]
    r = run("eval", path, "--t", "0.25", "--q", ",".join(repr(v) for v in q),
            "--qd", ",".join(repr(v) for v in qd))
    assert r.returncode == 0, r.stderr
    want = json.loads(r.stdout)
    got = m.eval(q, qd, 0.25)
    # Outputs only where the file has them, as on the command line.
    assert list(got) == list(want)
    assert list(got)[:4] == ["phi", "phi_q", "nu", "gamma"]
    for key in want:
        assert np.array_equal(got[key], np.array(want[key], dtype=float)), key
    assert got["phi_q"].shape == (m.nc, m.nq)
    default = m.eval()  # q0, zeros, t = 0
    assert default["phi"].shape == (m.nc,)


def test_properties(source):
    m = kinegen.Mechanism(str(source / "examples" / "four_bar.yaml"))
    assert m.coordinates[:3] == ["crank.x", "crank.y", "crank.phi"]
    assert len(m.coordinates) == m.nq == 9
    assert list(m.parameters) == ["a", "b", "c", "d", "px", "py", "omega"]
    assert m.parameters["b"] == 3.5
    assert m.name == "four_bar"


def test_check_and_generate(source, tmp_path):
    path = str(source / "examples" / "four_bar.yaml")
    m = kinegen.Mechanism(path)
    rows = m.check(samples=3)
    assert {r["block"] for r in rows} == {"phi_q", "nu", "gamma"}
    assert all(r["ok"] for r in rows)
    written = m.generate(str(tmp_path))
    r = run("generate", path, "-o", str(tmp_path / "cli"))
    assert r.returncode == 0, r.stderr
    assert open(written).read() == open(tmp_path / "cli" / "four_bar.hpp").read()


def test_sensitivity_columns_follow_all_others(source):
    m = kinegen.Mechanism(str(source / "examples" / "slider_crank.yaml"))
    got = m.analyze(0, 1, 4, sensitivity=["l"])
    names = list(got)
    first = names.index("d(crank.x)/d(l)")
    assert names[first - 1] == "slider.ay"
    assert names[first:] == ["d(crank.x)/d(l)", "d(crank.y)/d(l)", "d(crank.phi)/d(l)",
                             "d(rod.x)/d(l)", "d(rod.y)/d(l)", "d(rod.phi)/d(l)",
                             "d(tip.x)/d(l)", "d(tip.y)/d(l)",
                             "d(slider.x)/d(l)", "d(slider.y)/d(l)"]
    # slider.x = cos th + sqrt(l^2 - sin^2 th): d/dl = l / sqrt(l^2 - sin^2 th).
    th = got["t"]
    assert np.allclose(got["d(slider.x)/d(l)"], 2 / np.sqrt(4 - np.sin(th) ** 2),
                       rtol=0, atol=1e-12)


def test_errors_carry_the_command_line_message(source, tmp_path):
    path = str(source / "examples" / "slider_crank.yaml")
    # Unknown sensitivity parameter: usage error (exit 2).
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "2", "--sensitivity", "nope")
    assert r.returncode == 2
    with pytest.raises(kinegen.UsageError) as e:
        kinegen.Mechanism(path).analyze(0, 1, 2, sensitivity=["nope"])
    # The same message, naming the call's argument where the command line names its flag.
    assert "--sensitivity" in cli_error(r)
    assert str(e.value) == cli_error(r).replace("--sensitivity", "sensitivity")
    assert isinstance(e.value, ValueError) and isinstance(e.value, kinegen.Error)
    # Unknown --param: input error (exit 2).
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "2", "--param", "zz=1")
    assert r.returncode == 2
    with pytest.raises(kinegen.InputError) as e:
        kinegen.Mechanism(path, params={"zz": 1})
    assert str(e.value) == cli_error(r).replace("--param zz", "params['zz']")
    # A missing file.
    missing = str(tmp_path / "missing.yaml")
    r = run("analyze", missing, "--t0", "0", "--t1", "1", "--steps", "2")
    with pytest.raises(kinegen.InputError) as e:
        kinegen.Mechanism(missing)
    assert str(e.value) == cli_error(r)
    # An analysis that fails (the rod shorter than the crank cannot assemble): exit 1.
    r = run("analyze", path, "--t0", "0", "--t1", "3", "--steps", "6", "--param", "l=0.5")
    assert r.returncode == 1
    with pytest.raises(kinegen.AnalysisError) as e:
        kinegen.Mechanism(path, params={"l": 0.5}).analyze(0, 3, 6)
    assert str(e.value) == cli_error(r)
    assert isinstance(e.value, RuntimeError)
    # Wrong q length in eval.
    with pytest.raises(kinegen.UsageError):
        kinegen.Mechanism(path).eval([1.0, 2.0])


def test_forces_equal_command_line_bit_for_bit(source, tmp_path):
    path = str(source / "examples" / "forces" / "four_bar_balanced.yaml")
    out = tmp_path / "out.csv"
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "36", "--forces",
            "--sensitivity", "k", "-o", str(out))
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    got = kinegen.Mechanism(path).analyze(0, 1, 36, forces=True, sensitivity=["k"])
    assert list(got.keys()) == header
    assert "motor.effort" in header and header.index("motor.effort") < header.index("d(rocker.x)/d(k)")
    assert all(np.array_equal(got[h], values[:, k]) for k, h in enumerate(header))


def test_derived_parameters(tmp_path):
    """A parameter derived from another moves with it; .parameters lists it with its value;
    a sensitivity to a derived one treats it as overridden, bit for bit with the command line."""
    path = tmp_path / "derived.yaml"
    path.write_text("""name: derived
parameters:
  r: 1.0
  l: "2.5*r"
  omega: 1.0
bodies:
  - {name: crank, q0: [0, 0, 0]}
  - {name: rod, q0: [1, 0, 0]}
  - {name: slider, q0: [3.5, 0, 0]}
joints:
  - {type: revolute, i: ground, j: crank}
  - {type: revolute, i: crank, j: rod, si: ["r", 0]}
  - {type: revolute, i: rod, j: slider, si: ["l", 0]}
  - {type: translational, i: ground, j: slider, vi: [1, 0]}
drivers:
  - {type: absolute_angle, body: crank, f: "omega*t"}
""")
    m = kinegen.Mechanism(str(path), params={"r": 2})
    assert list(m.parameters) == ["r", "l", "omega"]
    assert m.parameters["l"] == 5.0
    got = m.analyze(0, 1, 4, sensitivity=["l", "r"])
    out = tmp_path / "out.csv"
    r = run("analyze", str(path), "--param", "r=2", "--t0", "0", "--t1", "1", "--steps", "4",
            "-o", str(out), "--sensitivity", "l,r")
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    assert list(got) == header
    assert all(np.array_equal(got[h], values[:, k]) for k, h in enumerate(header))
    # l held at 5 (its formula dropped): d(slider.x)/d(l) = l / sqrt(l^2 - r^2 sin^2 th) at
    # th = 0 is 1, and r's own sensitivity no longer moves l: d(slider.x)/d(r) = cos th = 1.
    assert got["d(slider.x)/d(l)"][0] == pytest.approx(1.0, abs=1e-12)
    assert got["d(slider.x)/d(r)"][0] == pytest.approx(1.0, abs=1e-12)


def test_eval_outputs_equal_command_line(source):
    path = str(source / "tests" / "mechanisms" / "four_bar_outputs.yaml")
    m = kinegen.Mechanism(path)
    r = run("eval", path, "--t", "0.5")
    assert r.returncode == 0, r.stderr
    want = json.loads(r.stdout)
    got = m.eval(t=0.5)
    assert list(got) == ["phi", "phi_q", "nu", "gamma", "outputs"]
    assert np.array_equal(got["outputs"], np.array(want["outputs"], dtype=float))
    assert got["outputs"].shape == (4,)


def test_velocity_outputs_equal_command_line(source, tmp_path):
    """An output that reads velocities: the same columns as the command line, its .a nan; its
    eval value at the qd given; --sensitivity refused with the command line's message."""
    path = str(source / "tests" / "mechanisms" / "slider_crank_velocity_outputs.yaml")
    out = tmp_path / "out.csv"
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "4", "-o", str(out))
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    got = kinegen.Mechanism(path).analyze(0, 1, 4)
    assert list(got) == header
    for k, name in enumerate(header):
        assert np.array_equal(got[name], values[:, k], equal_nan=True), name
    assert np.isnan(got["slide.a"]).all() and np.isfinite(got["slide.v"]).all()
    assert np.isfinite(got["stroke.a"]).all()
    qd = [0, 0, 1, 0.3, 0, 2]
    r = run("eval", path, "--qd", ",".join(map(str, qd)))
    assert r.returncode == 0, r.stderr
    want = json.loads(r.stdout)["outputs"]
    assert np.array_equal(kinegen.Mechanism(path).eval(qd=qd)["outputs"], np.array(want))
    assert want[0] == 0.3  # slide = xd_rod
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "2", "--sensitivity", "l")
    assert r.returncode == 2
    with pytest.raises(kinegen.InputError) as e:
        kinegen.Mechanism(path).analyze(0, 1, 2, sensitivity=["l"])
    # The same message, naming the call's argument where the command line names its flag.
    assert str(e.value) == cli_error(r).replace("--sensitivity", "sensitivity")


def test_extra_coordinates_are_named_like_the_csv(source):
    """coordinates lists every coordinate, the extra ones after the bodies', with
    the names of the CSV's position columns."""
    path = str(source / "tests" / "mechanisms" / "parabolic_slot.yaml")
    m = kinegen.Mechanism(path)
    assert len(m.coordinates) == m.nq
    got = m.analyze(0, 1, 2)
    for name in m.coordinates:
        assert name in got, name
    assert m.coordinates[-1] == "u"
    assert m.coordinates[:3] == ["plate.x", "plate.y", "plate.phi"]


def test_inputs_like_the_command_line(source, tmp_path):
    """inputs= gives an input driver its table as --input does: the same numbers bit for bit;
    analyze without it is the command line's usage error, while eval takes it as 0."""
    path = str(source / "tests" / "mechanisms" / "pieces_drive.yaml")
    table = str(source / "tests" / "mechanisms" / "pieces_lift.csv")
    out = tmp_path / "out.csv"
    r = run("analyze", path, "--input", "stroke=" + table, "--t0", "0", "--t1", "2",
            "--steps", "8", "-o", str(out))
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    got = kinegen.Mechanism(path, inputs={"stroke": table}).analyze(0, 2, 8)
    assert list(got) == header
    assert all(np.array_equal(got[h], values[:, k]) for k, h in enumerate(header))
    r = run("analyze", path, "--t0", "0", "--t1", "2", "--steps", "8")
    assert r.returncode == 2
    without = kinegen.Mechanism(path)
    with pytest.raises(kinegen.UsageError) as e:
        without.analyze(0, 2, 8)
    # The command line's message, naming the argument where it names --input.
    assert "--input stroke=FILE.csv" in r.stderr
    assert "inputs={'stroke': 'FILE.csv'}" in str(e.value)
    assert without.eval()["phi"].shape == (without.nc,)
    with pytest.raises(kinegen.UsageError):
        kinegen.Mechanism(path, inputs={"nope": table})
