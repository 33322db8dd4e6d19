"""What the module says when a call cannot give a trustworthy answer (issue 35, items 5 and
19): a point whose accelerations are not finite is an error, never a result; a params key that
is not a name, a value that is not a number, times whose span overflows and a name over the
length limit each say what is wrong in Python's terms."""
import math

import numpy as np
import pytest

import kinegen
from conftest import SOURCE

DYN = SOURCE / "examples" / "dynamics"
CART_POLE = str(DYN / "cart_pole.yaml")


def cart_pole_upright_accelerations(force, M=1.0, m=0.2, a=0.3):
    # Lagrange's equations of the cart-pole at rest with the pole upright (phi = pi/2): with
    # J = m (2a)^2 / 12 about the pole's centre,
    #   (M + m) xdd - m a phidd = F,   -m a xdd + (m a^2 + J) phidd = 0.
    j = m * (2 * a) ** 2 / 12
    xdd = force / ((M + m) - (m * a) ** 2 / (m * a * a + j))
    return xdd, m * a * xdd / (m * a * a + j)


def test_dynamics_refuses_accelerations_that_are_not_finite():
    m = kinegen.Mechanism(CART_POLE)
    # A finite point gives the closed form.
    zdd = m.dynamics(0, [0, math.pi / 2], [0, 0], [2.0])
    assert zdd == pytest.approx(cart_pole_upright_accelerations(2.0), rel=1e-12)
    # 1e308 on the cart overflows the forces: [inf, inf] was returned as a success.
    for u in ([1e308], [1.7e308]):
        with pytest.raises(kinegen.AnalysisError) as e:
            m.dynamics(0, [0, 1.5], [0, 0], u)
        assert "not finite" in str(e.value)
    # Values that are not numbers are the caller's mistake, as the command line's --at.
    for z, zd, u in (([math.nan, 1.5], [0, 0], [0]), ([0, 1.5], [math.inf, 0], [0]),
                     ([0, 1.5], [0, 0], [-math.inf])):
        with pytest.raises(kinegen.UsageError) as e:
            m.dynamics(0, z, zd, u)
        assert "not a finite number" in str(e.value)
    with pytest.raises(kinegen.UsageError):
        m.dynamics(math.nan, [0, 1.5], [0, 0], [0])
    # The model is still good after the refusals.
    assert m.dynamics(0, [0, math.pi / 2], [0, 0], [2.0]) == pytest.approx(zdd, rel=0, abs=0)


def test_params_key_that_is_not_a_name():
    with pytest.raises(TypeError) as e:
        kinegen.Mechanism(CART_POLE, params={1: 2})
    text = str(e.value)
    assert "params" in text and "parameter name" in text and "--param" not in text


def test_params_value_that_is_not_a_number():
    with pytest.raises(TypeError) as e:
        kinegen.Mechanism(CART_POLE, params={"m": [1]})
    assert "params['m']" in str(e.value)
    assert "number or an expression string" in str(e.value)
    # Numbers of any Python or numpy kind, and expressions, are accepted.
    for value in (0.3, 1, np.float64(0.3), "0.1 + 0.2"):
        assert kinegen.Mechanism(CART_POLE, params={"m": value}).parameters["m"] == \
            pytest.approx(0.3 if value != 1 else 1.0, rel=1e-15)


def test_inputs_key_that_is_not_a_name():
    with pytest.raises(TypeError) as e:
        kinegen.Mechanism(CART_POLE, inputs={1: "x.csv"})
    assert "inputs" in str(e.value) and "--input" not in str(e.value)


def test_times_whose_span_overflows_are_a_usage_error():
    m = kinegen.Mechanism(str(SOURCE / "examples" / "four_bar.yaml"))
    with pytest.raises(kinegen.UsageError) as e:
        m.analyze(-1e308, 1e308, 4)
    assert "t1 - t0 overflows" in str(e.value)
    assert len(m.analyze(-1, 1, 4)["t"]) == 5
    with pytest.raises(kinegen.UsageError) as e:
        m.view("", t0=-1e308, t1=1e308, steps=4)
    assert "t1 - t0 overflows" in str(e.value)
    p = kinegen.Mechanism(str(DYN / "pendulum.yaml"))
    with pytest.raises(kinegen.UsageError) as e:
        p.simulate(1e308, 4, t0=-1e308)
    assert "t1 - t0 overflows" in str(e.value)


def test_a_name_over_the_limit_says_the_limit(tmp_path):
    text = open(SOURCE / "examples" / "four_bar.yaml").read()
    assert "name: four_bar" in text
    for length, ok in ((64, True), (65, False)):
        path = tmp_path / ("m%d.yaml" % length)
        path.write_text(text.replace("name: four_bar", "name: " + "f" * length, 1))
        if ok:
            assert kinegen.Mechanism(str(path)).name == "f" * 64
        else:
            with pytest.raises(kinegen.InputError) as e:
                kinegen.Mechanism(str(path))
            assert "at most 64" in str(e.value)

