"""mu(I) and phi(I): the inertial number, the friction law's limits, the fits recovering known
parameters, and the local rheology of a profile across a shear flow."""

import math
import re

import numpy as np
import pytest

from rollingdem.analysis.rheology import fit_mu_of_i, fit_phi_of_i, inertial_number, local_rheology, mu_of_i
from rollingdem.errors import ParameterError

# Jop, Forterre & Pouliquen (2006), glass beads: mu_s = tan 20.9 deg, mu_2 = tan 32.76 deg, I_0 = 0.279
GLASS = (math.tan(math.radians(20.9)), math.tan(math.radians(32.76)), 0.279)


def test_the_inertial_number_of_known_values():
    # 10 /s x 2 mm / sqrt(100 Pa / 2500 kg/m^3) = 0.02 / 0.2 = 0.1
    assert inertial_number(10.0, 100.0, 0.002, 2500.0) == pytest.approx(0.1, rel=1e-14)
    assert inertial_number(-10.0, 400.0, 0.002, 2500.0) == pytest.approx(0.05, rel=1e-14)  # |rate|, sqrt(P)
    assert math.isnan(inertial_number(10.0, 0.0, 0.002, 2500.0))


def test_the_friction_law_runs_from_mu_s_to_mu_2_through_their_mean_at_i_0():
    mu_s, mu_2, i_0 = GLASS
    assert mu_of_i(1e-12, *GLASS) == pytest.approx(mu_s, abs=1e-9)
    assert mu_of_i(1e12, *GLASS) == pytest.approx(mu_2, abs=1e-9)
    assert mu_of_i(i_0, *GLASS) == pytest.approx(0.5 * (mu_s + mu_2), rel=1e-14)


def test_the_fit_recovers_exact_parameters_and_covers_them_under_noise():
    """Eight points from I = 1e-3 to 0.3: exact, the parameters to 1e-6; with Gaussian noise of
    0.005 on mu (seeded), each within three of its stated standard errors of the truth."""
    i = np.logspace(-3, math.log10(0.3), 8)
    exact = fit_mu_of_i(i, mu_of_i(i, *GLASS))
    assert (exact["mu_s"], exact["mu_2"], exact["i_0"]) == pytest.approx(GLASS, rel=1e-6)
    assert exact["rms"] < 1e-9 and exact["points"] == 8
    noisy = fit_mu_of_i(i, mu_of_i(i, *GLASS) + np.random.default_rng(4).normal(0.0, 0.005, len(i)))
    for name, truth in zip(("mu_s", "mu_2", "i_0"), GLASS):
        assert abs(noisy[name] - truth) < 3.0 * noisy[f"{name}_error"], name
    assert 0.001 < noisy["rms"] < 0.01


def test_the_solid_fraction_line():
    i = np.array([0.001, 0.01, 0.05, 0.1, 0.2])
    fit = fit_phi_of_i(i, 0.6 - 0.2 * i)
    assert (fit["phi_max"], fit["a"]) == pytest.approx((0.6, 0.2), rel=1e-12)
    assert fit["phi_max_error"] < 1e-12 and fit["a_error"] < 1e-10


def test_a_uniform_shear_profile_has_one_mu_and_one_i_everywhere():
    """v_x = 5 /s z, normal stresses 200 Pa, sigma_xz = -80 Pa: mu = 80 / 200 = 0.4 and
    I = 5 x 2 mm / sqrt(200 / 2500) at every node (the end nodes by one-sided differences)."""
    z = np.linspace(0.0, 0.02, 11)
    n = len(z)
    profile = {"z (m)": z, "solid_fraction (1)": np.full(n, 0.58), "velocity_x (m/s)": 5.0 * z,
               "stress_xx (Pa)": np.full(n, 200.0), "stress_yy (Pa)": np.full(n, 200.0),
               "stress_zz (Pa)": np.full(n, 200.0), "stress_xz (Pa)": np.full(n, -80.0)}
    local = local_rheology(profile, flow="x", gradient="z", diameter=0.002, density=2500.0)
    np.testing.assert_allclose(local["shear_rate (1/s)"], 5.0, rtol=1e-12)
    np.testing.assert_allclose(local["mu (1)"], 0.4, rtol=1e-14)
    np.testing.assert_allclose(local["inertial_number (1)"], 5.0 * 0.002 / math.sqrt(200.0 / 2500.0), rtol=1e-12)
    np.testing.assert_array_equal(local["solid_fraction (1)"], 0.58)


@pytest.mark.parametrize("call, message", [
    (lambda: fit_mu_of_i([0.01, 0.02, 0.03], [0.4, 0.41, 0.42]), "mu(I) fit of 3 points"),
    (lambda: fit_mu_of_i([0.01, 0.011, 0.012, 0.013], [0.4] * 4), "spanning a factor 3 in I"),
    (lambda: fit_mu_of_i([0.01, 0.1], [0.4]), "2 inertial numbers and 1 values"),
    (lambda: fit_phi_of_i([0.1, 0.1, 0.1], [0.6, 0.6, 0.6]), "at two or more inertial numbers"),
    (lambda: local_rheology({"z (m)": [0.0]}, "z", "z", 0.002, 2500.0), "flow = 'z', gradient = 'z'"),
    (lambda: local_rheology({"y (m)": [0.0]}, "x", "z", 0.002, 2500.0), "no column 'z (m)'"),
    (lambda: inertial_number(1.0, 1.0, -0.002, 2500.0), "diameter = -0.002"),
])
def test_bad_input_is_one_line(call, message):
    with pytest.raises(ParameterError, match=re.escape(message)) as refused:
        call()
    assert "\n" not in str(refused.value)


def test_a_friction_that_does_not_rise_is_fitted_flat_at_its_level():
    """Points that scatter about a level (no rise with I) give mu_s = mu_2 = about their mean: the
    fit keeps mu_2 >= mu_s, so that mu_s cannot run off to its bound with mu_2 below it."""
    i = np.array([0.001, 0.003, 0.01, 0.03, 0.1, 0.3])
    mu = np.array([0.638, 0.567, 0.582, 0.625, 0.528, 0.602])
    fit = fit_mu_of_i(i, mu)
    assert fit["mu_2"] >= fit["mu_s"]
    assert fit["mu_s"] == pytest.approx(mu.mean(), abs=2 * fit["mu_s_error"])
