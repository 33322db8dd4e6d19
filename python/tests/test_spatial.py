"""The Python module on spatial files (space: 3d): analyze, eval, check, generate and view as
the command line gives them (analyze's columns bit for bit, a suspension's travel from its
design position and its motion ratios included), and one error naming the method for what
spatial files do not have yet."""
import json
import re

import numpy as np
import pytest

import kinegen
from conftest import read_csv, run

SPATIAL = ["slider_crank", "double_wishbone", "macpherson"]


def example(source, name):
    return str(source / "examples" / "spatial" / (name + ".yaml"))


def cli_run(path, tmp_path, steps=40):
    out = tmp_path / "cli.csv"
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", str(steps), "-o", str(out))
    assert r.returncode == 0, r.stderr
    return read_csv(out)


def same(a, b):
    # Bit for bit, nan where the other is nan (a motion ratio where the wheel does not move).
    return np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("name", SPATIAL)
def test_analyze_equals_command_line_bit_for_bit(source, tmp_path, name):
    path = example(source, name)
    header, values = cli_run(path, tmp_path)
    m = kinegen.Mechanism(path)
    assert m.nq == 7 * sum(c.endswith(".e0") for c in m.coordinates)
    got = m.analyze(0, 1, 40)
    assert list(got) == header
    for k, column in enumerate(header):
        assert same(got[column], values[:, k]), column


def test_sensitivities_equal_the_command_line_bit_for_bit(source, tmp_path):
    # The suspension's outputs included: their d/d(rack) subtract the design position's.
    path = example(source, "double_wishbone")
    out = tmp_path / "cli.csv"
    r = run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "10", "--sensitivity", "rack",
            "-o", str(out))
    assert r.returncode == 0, r.stderr
    header, values = read_csv(out)
    got = kinegen.Mechanism(path).analyze(0, 1, 10, sensitivity=["rack"])
    assert list(got) == header
    assert "d(toe)/d(rack)" in header
    for k, column in enumerate(header):
        if column.startswith("d("):
            # The sensitivities' design offsets and the points' d s'/dp are evaluated from
            # GiNaC expressions whose term order follows the process's symbol history: equal to
            # rounding (d(wheel_travel)/d(rack), 0 in exact arithmetic, is 1e-17 of noise that
            # differs by 2e-19 between a fresh process and the test suite's).
            assert np.allclose(got[column], values[:, k], rtol=1e-12, atol=1e-15), column
        else:
            assert same(got[column], values[:, k]), column


def test_suspension_columns_are_measured_from_the_design_position(source):
    # design_t = 0.5 in the file: the travel and the track change are 0 there (the grid has
    # t = 0.5 as its row 20), and each is the raw value minus the raw value at design_t.
    path = example(source, "double_wishbone")
    m = kinegen.Mechanism(path)
    got = m.analyze(0, 1, 40)
    assert got["t"][20] == 0.5
    assert got["wheel_travel"][20] == 0 and got["track_change"][20] == 0
    raw_w = got["W.z"] - got["W.z"][20]
    assert np.allclose(got["wheel_travel"], raw_w, rtol=0, atol=1e-15)
    assert np.allclose(got["track_change"], got["contact_y"] - got["contact_y"][20], rtol=0,
                       atol=1e-15)
    # A motion ratio: -(dL/dt) / (d wheel_travel/dt), from the rate columns.
    assert np.allclose(got["spring.motion_ratio"], -got["spring.v"] / got["wheel_travel.v"],
                       rtol=1e-15, atol=0)


def test_eval_and_check_as_the_command_line(source):
    path = example(source, "slider_crank")
    m = kinegen.Mechanism(path)
    q = [0.01 * (k + 1) for k in range(m.nq)]
    qd = [0.02 * (k - 3) for k in range(m.nq)]
    r = run("eval", path, "--t", "0.3", "--q", ",".join(repr(v) for v in q), "--qd",
            ",".join(repr(v) for v in qd))
    assert r.returncode == 0, r.stderr
    cli = json.loads(r.stdout)
    got = m.eval(q, qd, 0.3)
    for key in ("phi", "nu", "gamma", "outputs"):
        assert np.array_equal(got[key], np.array(cli[key])), key
    assert np.array_equal(got["phi_q"], np.array(cli["phi_q"]))
    assert m.nc == m.nq  # the normalization rows counted
    rows = m.check(samples=2)
    assert rows and all(row["ok"] for row in rows)


def test_generate_is_the_command_lines_header(source, tmp_path):
    path = example(source, "slider_crank")
    assert run("generate", path, "-o", str(tmp_path / "cli")).returncode == 0
    written = kinegen.Mechanism(path).generate(str(tmp_path / "py"))
    cli = tmp_path / "cli" / "spatial_slider_crank.hpp"
    assert open(written, "rb").read() == cli.read_bytes()


def viewer(source):
    try:
        kinegen.Mechanism(example(source, "slider_crank")).view(t0=0, t1=1, steps=1)
        return True
    except kinegen.UsageError as e:
        assert "built without the viewer" in str(e)
        return False


def without_source(page):
    # The page names where its run came from ("the analysis (t = ...)" or the CSV's path).
    return re.sub(r'"run":"[^"]*"', '"run":""', page)


def test_view_is_the_command_lines_page_and_its_run_is_analyzes_csv(source, tmp_path):
    if not viewer(source):
        pytest.skip("this build has no viewer (KINEGEN_BUILD_VIEWER=OFF)")
    path = example(source, "double_wishbone")
    cli = tmp_path / "cli.html"
    r = run("view", path, "--t0", "0", "--t1", "1", "--steps", "40", "-o", str(cli))
    assert r.returncode == 0, r.stderr
    page = kinegen.Mechanism(path).view(t0=0, t1=1, steps=40)
    assert page.html.encode() == cli.read_bytes()
    # The page of analyze's CSV holds the same run: travel from the design position and the
    # motion ratios, as analyze writes them.
    csv = tmp_path / "run.csv"
    assert run("analyze", path, "--t0", "0", "--t1", "1", "--steps", "40", "-o",
               str(csv)).returncode == 0
    of_csv = kinegen.Mechanism(path).view(csv=str(csv))
    assert without_source(page.html) == without_source(of_csv.html)


@pytest.mark.parametrize("call, method", [
    (lambda m: m.simulate(1, 10), "simulate"),
    (lambda m: m.dynamics(0, [], []), "dynamics"),
    (lambda m: m.equilibrium(), "equilibrium"),
    (lambda m: m.modes(), "modes"),
    (lambda m: m.linearize(), "linearize"),
    (lambda m: m.analyze(0, 1, 2, forces=True), "analyze(forces=True)"),
    (lambda m: m.view(t0=0, t1=1, steps=2, forces=True), "view(forces=True)"),
    (lambda m: m.view(modes="modes.json"), "view(modes=...)"),
])
def test_what_spatial_files_lack_is_refused_naming_the_method(source, call, method):
    path = example(source, "slider_crank")
    m = kinegen.Mechanism(path)
    with pytest.raises(kinegen.InputError) as e:
        call(m)
    assert str(e.value) == (path + ":4: space: spatial files (space: 3d) are not supported by "
                            "Mechanism." + method + " yet")
    assert m.free == []


def test_free_items_in_a_spatial_file_are_refused_as_on_the_command_line(source, tmp_path):
    text = open(example(source, "slider_crank")).read() + "free:\n  - {body: slider}\n"
    path = tmp_path / "free.yaml"
    path.write_text(text)
    r = run("analyze", str(path), "--t0", "0", "--t1", "1", "--steps", "1")
    assert r.returncode == 2
    with pytest.raises(kinegen.InputError) as e:
        kinegen.Mechanism(str(path))
    assert "error: " + str(e.value) + "\n" == r.stderr
