"""The Hertz dashpot factor against an independent integration of the impact equation."""

import math

import pytest
from scipy.integrate import solve_ivp

import rollingdem as rd
from rollingdem.physics.contact.normal import hertz_damping_factor


def impact_restitution(c):
    """Restitution of m* d'' = -k d^(3/2) - c sqrt(S_n m*) d', S_n = 3/2 k d^(1/2), k = 4/3 E* sqrt(R*).

    In units d0 = (m* v0^2 / k)^(2/5), t0 = d0 / v0: x'' = -x^(3/2) - sqrt(3/2) c x^(1/4) x',
    x(0) = 0, x'(0) = 1; e = -x' when x is back at 0 (no force clipping, as in LIGGGHTS)."""
    g = math.sqrt(1.5) * c

    def rhs(_t, y):
        x = max(y[0], 0.0)
        return [y[1], -x ** 1.5 - g * x ** 0.25 * y[1]]

    def back_at_zero(_t, y):
        return y[0]

    back_at_zero.terminal = True
    back_at_zero.direction = -1
    sol = solve_ivp(rhs, (0.0, 50.0), [0.0, 1.0], events=back_at_zero, rtol=1e-12, atol=1e-14, method="DOP853")
    return -float(sol.y_events[0][0][1])


@pytest.mark.parametrize("e", [0.1, 0.3, 0.5, 0.7, 0.9, 0.99])
def test_closed_form_factor_gives_the_restitution(e):
    """c = -2 sqrt(5/6) beta(e) returns e from the impact equation to the integrator's accuracy
    (rtol 1e-12 over ~1e3 steps: 1e-9 is a wide margin). A wrong sqrt(5/6) (e.g. sqrt(2/3)) or a
    factor 2 moves e by more than 1 %."""
    assert impact_restitution(hertz_damping_factor(e)) == pytest.approx(e, rel=1e-9)


def test_hertz_has_no_damping_option():
    """The former damping="liggghts" was the same model as the default: it is refused by name."""
    with pytest.raises(rd.ParameterError, match="damping"):
        rd.ContactModel(normal={"model": "hertz", "damping": "liggghts"})
