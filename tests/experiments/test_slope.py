"""T4, the seed report's test case 2: rolling up a 10 deg slope, then rest or creep (docs/models.md §13 T4)."""

import math

import numpy as np
import pytest

import rollingdem as rd
from conftest import G
from rollingdem.experiments.single_sphere import analytic_slope, creep_speed, rolling_slope_run

THETA = math.radians(10.0)


def test_analytic_values():
    x_max, t_max = analytic_slope()
    assert x_max == pytest.approx(0.104204, abs=2e-6) and t_max == pytest.approx(0.27505, abs=2e-5)


@pytest.mark.parametrize("rolling", ["cdt", "epsd", "epsd2",
                                     pytest.param("epsd3", marks=pytest.mark.slow),
                                     pytest.param("rrlinear", marks=pytest.mark.slow),
                                     pytest.param({"model": "sds", "rolling_stiffness": 2e3}, marks=pytest.mark.slow),
                                     pytest.param({"model": "displacement_damping", "damping": 0.3},
                                                  marks=pytest.mark.slow)])
def test_x_max_and_rest(rolling):
    """x_max within 0.5 % of analytic; EPSD-type springs then hold (drift < 1e-7 m over 1 s)."""
    x_max, t_max = analytic_slope()
    # Displacement damping's spring is soft: it mobilises at theta_max = 0.035 rad (0.17 mm of
    # rolling), omega_r = sqrt(k_r / I_r) = 88 rad/s, and eta = 0.3 settles it as exp(-26 t): after
    # turning round at the top it still rolls back ~9e-7 m between 0.5 s and 1.5 s. Measured from
    # 1.5 s, the remaining settling is 1e-11 m, so the 1e-7 m bound tests holding, not settling.
    duration = 2.5 if isinstance(rolling, dict) and rolling["model"] == "displacement_damping" else 1.5
    traj = rolling_slope_run(rolling, duration=duration)
    assert traj.x.max() == pytest.approx(x_max, rel=0.005)
    assert traj.t[np.argmax(traj.x)] == pytest.approx(t_max, rel=0.01)  # the top is flat: time is less sharp
    if rolling != "cdt":
        assert abs(creep_speed(traj)) < 1e-7


def test_cdt_creeps_back_with_or_without_limiter():
    """Without a limiter CDT chatters and creeps down at 4.0e-5 m/s, as LIGGGHTS does (docs/models.md §13 T4;
    10 %: the creep is a chatter average). The STAR-CCM+ limiter |M| <= f I_r |dw_r| / dt turns the
    moment into a viscous clamp at low rates, so it cannot hold a slope either: at steady creep
    f I_r omega / dt = m g R sin(theta) with I_r = 1.4 m R^2, i.e. v = g sin(theta) dt / (1.4 f)
    (2 %), 1.5e-4 m/s for STAR's f = 0.08."""
    drift = creep_speed(rolling_slope_run("cdt", duration=1.5))
    assert drift == pytest.approx(-4.0e-5, rel=0.1)
    f = 0.08
    drift = creep_speed(rolling_slope_run(rd.CDT(limiter=f), duration=1.5))
    assert drift == pytest.approx(-G * math.sin(THETA) * 1e-5 / (1.4 * f), rel=0.02)
