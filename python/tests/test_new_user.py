"""What a new user met in the Python module (issue 26): the file's warnings as Python warnings,
errors that name the call's arguments rather than command-line flags, docstrings, and a clear
message for a string where a list of names belongs."""
import warnings

import pytest

import kinegen


def test_warnings_of_the_file_reach_python(source):
    # The indexer's harmonic rise ends with an acceleration: f'' jumps at t = 1 and at the seam.
    path = str(source / "tests" / "mechanisms" / "indexer.yaml")
    with pytest.warns(UserWarning) as caught:
        m = kinegen.Mechanism(path)
    texts = [str(w.message) for w in caught]
    assert len(texts) == 2, texts
    assert all("f'' jumps" in t and "accelerations jump there" in t for t in texts)
    # The seam's 3-4-5 end has f'' = 0 exactly: printed as 0, not as its 1e-23 of rounding.
    seam = [t for t in texts if "seam t = 4" in t]
    assert len(seam) == 1 and ": 0 before it, " in seam[0], seam
    # The analysis runs (in sub-steps: 8 rows over a period) without more warnings.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = m.analyze(0, 4, 8)
    assert len(run["t"]) == 9


def test_errors_name_the_arguments_not_flags(source):
    path = str(source / "examples" / "four_bar.yaml")
    with pytest.raises(kinegen.InputError) as e:
        kinegen.Mechanism(path, params={"omeg": 1.0})
    assert "params['omeg']" in str(e.value)
    assert "--param" not in str(e.value)
    with pytest.raises(kinegen.UsageError) as e:
        kinegen.Mechanism(path).analyze(0, 1, -1)
    assert "steps must be 0 or more" in str(e.value) and "--" not in str(e.value)
    with pytest.raises(kinegen.UsageError) as e:
        kinegen.Mechanism(path).check(samples=0)
    assert "samples must be at least 1" in str(e.value) and "--" not in str(e.value)
    # An input driver without its table: the message says how to give it from Python.
    drive = str(source / "tests" / "mechanisms" / "pieces_drive.yaml")
    with pytest.raises(kinegen.UsageError) as e:
        kinegen.Mechanism(drive).analyze(0, 1, 2)
    assert "inputs={'stroke': 'FILE.csv'}" in str(e.value), str(e.value)


def test_docstrings():
    assert kinegen.Mechanism.__doc__
    assert "analyze" in kinegen.Mechanism.__doc__ and "params" in kinegen.Mechanism.__doc__
    for name in ("analyze", "eval", "check", "generate", "view", "coordinates", "parameters",
                 "name", "path", "nq", "nc"):
        assert getattr(kinegen.Mechanism, name).__doc__, name


def test_sensitivity_wants_a_list(source):
    m = kinegen.Mechanism(str(source / "examples" / "four_bar.yaml"))
    with pytest.raises(TypeError) as e:
        m.analyze(0, 1, 2, sensitivity="a")
    assert "sensitivity expects a list of parameter names" in str(e.value)
    assert "not the string 'a'" in str(e.value)
    with pytest.raises(TypeError) as e:
        m.analyze(0, 1, 2, sensitivity=["a", 3])
    assert "3 is not a str" in str(e.value)
    # A tuple or a list works.
    a = m.analyze(0, 1, 2, sensitivity=("a",))
    b = m.analyze(0, 1, 2, sensitivity=["a"])
    assert list(a) == list(b) and "d(rocker.phi)/d(a)" in a
