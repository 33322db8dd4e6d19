"""Mechanism.view: the page of `kinegen view`, byte for byte (the same library calls), shown
inline in Jupyter (_repr_html_: the page in a sandboxed iframe), with the command line's errors.
The page itself is tested in headless Chromium (viewer/tests/)."""
import html
import re
import subprocess

import pytest

import kinegen
from conftest import EXE

TURN = "6.283185307179586"


def run(*args):
    return subprocess.run([EXE, *args], capture_output=True, text=True)


def viewer_built(source):
    try:
        kinegen.Mechanism(str(source / "examples" / "four_bar.yaml")).view(t0=0, t1=1, steps=1)
        return True
    except kinegen.UsageError as e:
        assert "built without the viewer" in str(e)
        return False


@pytest.fixture
def four_bar(source):
    if not viewer_built(source):
        pytest.skip("this build has no viewer (KINEGEN_BUILD_VIEWER=OFF)")
    return str(source / "examples" / "four_bar.yaml")


def test_view_of_an_analysis_is_the_command_lines_page(four_bar, source, tmp_path):
    for path, extra in [(four_bar, []), (str(source / "examples/forces/press.yaml"), ["--forces"])]:
        cli = tmp_path / "cli.html"
        r = run("view", path, "--t0", "0", "--t1", TURN, "--steps", "120", *extra, "-o", str(cli))
        assert r.returncode == 0, r.stderr
        page = kinegen.Mechanism(path).view(str(tmp_path / "py.html"), t0=0, t1=float(TURN),
                                            steps=120, forces=bool(extra))
        assert page.path == str(tmp_path / "py.html")
        assert (tmp_path / "py.html").read_bytes() == cli.read_bytes()
        assert page.html.encode() == cli.read_bytes()


def test_view_of_a_csv_is_the_command_lines_page(four_bar, tmp_path):
    csv = tmp_path / "run.csv"
    assert run("analyze", four_bar, "--t0", "0", "--t1", TURN, "--steps", "50", "-o",
               str(csv)).returncode == 0
    cli = tmp_path / "cli.html"
    assert run("view", four_bar, "--csv", str(csv), "--max-rows", "20", "-o",
               str(cli)).returncode == 0
    page = kinegen.Mechanism(four_bar).view(csv=str(csv), max_rows=20)
    assert page.path is None  # not written without a path
    assert page.html.encode() == cli.read_bytes()
    assert page.save(str(tmp_path / "saved.html")) == str(tmp_path / "saved.html")
    assert (tmp_path / "saved.html").read_bytes() == cli.read_bytes()
    assert "saved.html" in repr(page)


def test_jupyter_shows_the_page_inline(four_bar):
    page = kinegen.Mechanism(four_bar).view(t0=0, t1=1, steps=10)
    shown = page._repr_html_()
    assert shown.startswith('<iframe sandbox="allow-scripts" ')
    srcdoc = shown.split('srcdoc="', 1)[1].rsplit('"></iframe>', 1)[0]
    assert '"' not in srcdoc and "<" not in srcdoc
    assert html.unescape(srcdoc) == page.html


def test_view_errors_are_the_command_lines(four_bar, source, tmp_path):
    other = tmp_path / "slider.csv"
    assert run("analyze", str(source / "examples/slider_crank.yaml"), "--t0", "0", "--t1", "1",
               "--steps", "3", "-o", str(other)).returncode == 0
    (tmp_path / "empty.csv").write_text("")
    for csv in [other, tmp_path / "empty.csv"]:
        r = run("view", four_bar, "--csv", str(csv), "-o", str(tmp_path / "no.html"))
        assert r.returncode == 2
        with pytest.raises(kinegen.InputError) as e:
            kinegen.Mechanism(four_bar).view(str(tmp_path / "no.html"), csv=str(csv))
        assert "error: " + str(e.value) + "\n" == r.stderr
        assert not (tmp_path / "no.html").exists()
    with pytest.raises(kinegen.UsageError, match="view shows one of"):
        kinegen.Mechanism(four_bar).view(csv=str(other), t0=0)


def test_a_run_that_fails_keeps_its_page(four_bar, tmp_path):
    # The rocker driven past the end of its swing: the step to t = 1.7 fails, and its sub-steps
    # stop near t = 1.69, where the linkage cannot follow.
    text = open(four_bar).read().replace('body: crank\n    f: "omega*t"',
                                         'body: rocker\n    f: "1.3694384060045657 + 0.5*t"')
    path = tmp_path / "rocker_driven.yaml"
    path.write_text(text)
    cli = tmp_path / "cli.html"
    r = run("view", str(path), "--t0", "0", "--t1", "4", "--steps", "80", "-o", str(cli))
    assert r.returncode == 1 and re.search(r"failed at t = 1\.6[89]\d* \(in sub-steps of the step "
                                          r"from t = 1\.649\d* to t = 1\.7,", r.stderr)
    with pytest.raises(kinegen.AnalysisError) as e:
        kinegen.Mechanism(str(path)).view(str(tmp_path / "py.html"), t0=0, t1=4, steps=80)
    assert "error: " + str(e.value) + "\n" == r.stderr.splitlines(keepends=True)[-1]
    assert (tmp_path / "py.html").read_bytes() == cli.read_bytes()
    assert b'"rows":34' in cli.read_bytes()


def test_view_of_an_analysis_refuses_free_coordinates_as_the_command_line(four_bar, source,
                                                                          tmp_path):
    # A mechanism with `free:` has no analysis: its free coordinates move under the forces
    # (simulate). The page of one would draw every free coordinate at 0 and its pins as ground
    # pivots; the command line refuses it, and so does Mechanism.view, with the same error.
    for name in ["pendulum.yaml", "four_bar_spring.yaml", "cart_pole.yaml"]:
        path = str(source / "examples" / "dynamics" / name)
        out = tmp_path / (name + ".html")
        r = run("view", path, "--t0", "0", "--t1", "1", "--steps", "4", "-o", str(out))
        assert r.returncode == 2 and not out.exists()
        assert "free coordinate" in r.stderr
        with pytest.raises(kinegen.UsageError) as e:
            kinegen.Mechanism(path).view(str(out), t0=0, t1=1, steps=4)
        assert "free coordinate" in str(e.value)
        assert not out.exists()
        # analyze refuses it the same way.
        with pytest.raises(kinegen.UsageError) as a:
            kinegen.Mechanism(path).analyze(t0=0, t1=1, steps=4)
        assert str(a.value) == str(e.value)
