"""examples/python/synthesis.py: the fit recovers the four-bar the precision points came from
(the independent truth), with the exact Jacobian and with finite differences."""
import importlib.util

import numpy as np
import pytest

from conftest import SOURCE

pytest.importorskip("scipy")


def load_example():
    spec = importlib.util.spec_from_file_location(
        "synthesis", SOURCE / "examples" / "python" / "synthesis.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_synthesis_recovers_the_true_dimensions():
    s = load_example()
    target = s.coupler([s.TRUE[n] for n in s.NAMES])
    x0 = np.array([1.0, 3.5, 2.5, 3.0, 1.5, 1.0])  # examples/four_bar.yaml
    truth = np.array([s.TRUE[n] for n in s.NAMES])
    for exact in (True, False):
        result, _ = s.fit(x0, target, exact)
        assert result.success
        assert np.abs(result.x - truth).max() < 1e-8, (exact, result.x)
        assert np.abs(result.fun).max() < 1e-12


def test_exact_jacobian_matches_finite_differences():
    # The sensitivities against central differences of the whole analysis, at the start point.
    s = load_example()
    x0 = np.array([1.0, 3.5, 2.5, 3.0, 1.5, 1.0])
    _, jac = s.coupler(x0, sensitivity=True)
    h = 1e-6
    for k in range(len(x0)):
        e = np.zeros_like(x0)
        e[k] = h
        fd = (s.coupler(x0 + e) - s.coupler(x0 - e)) / (2 * h)
        # Truncation ~ h^2 |P'''| ~ 1e-12, rounding ~ 1e-16 / h = 1e-10.
        assert np.abs(jac[:, k] - fd).max() < 1e-8, s.NAMES[k]
