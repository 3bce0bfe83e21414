"""T4, the seed report's test case 2: rolling up a 10 deg slope, then rest or creep (MODELS.md §13 T4)."""

import math

import numpy as np
import pytest

import rollingdem as rd
from conftest import R, G

MU, MU_R, THETA = 0.8, 0.2, math.radians(10.0)


def analytic_xmax(v0=1.0):
    """Slip until t1 = v0 / (g [sin + mu cos + 2.5 (mu - mu_r) cos]), then rolling deceleration
    (5/7) g (sin + mu_r cos) to rest."""
    s, c = math.sin(THETA), math.cos(THETA)
    t1 = v0 / (G * (s + MU * c + 2.5 * (MU - MU_R) * c))
    v1 = v0 - G * (s + MU * c) * t1
    a = 5 / 7 * G * (s + MU_R * c)
    return v0 * t1 - 0.5 * G * (s + MU * c) * t1 ** 2 + v1 ** 2 / (2 * a), t1 + v1 / a


def roll_up(rolling, table1, hold=1.2):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling), dt=1e-5)
    sim.add_material(table1(friction=MU, rolling_friction=MU_R, rolling_damping=0.3))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R]], R, "m")
    sim.run(0.2)
    sim.gravity = (-G * math.sin(THETA), 0.0, -G * math.cos(THETA))  # the slope rises towards +x
    sim.set_velocities([0], velocity=(1.0, 0, 0), angular_velocity=(0, 0, 0))
    x0, t0 = sim.positions[0, 0], sim.time
    ts, xs = [], []
    while sim.time - t0 < 0.3:
        sim.run(steps=10)
        ts.append(sim.time - t0)
        xs.append(sim.positions[0, 0] - x0)
    sim.run(hold - 1.0)
    x_start = sim.positions[0, 0]
    sim.run(1.0)
    drift = sim.positions[0, 0] - x_start  # over the last second
    return np.array(ts), np.array(xs), drift


def test_analytic_values():
    x_max, t_max = analytic_xmax()
    assert x_max == pytest.approx(0.104204, abs=2e-6) and t_max == pytest.approx(0.27505, abs=2e-5)


@pytest.mark.parametrize("rolling", ["cdt", "epsd", "epsd2",
                                     pytest.param("epsd3", marks=pytest.mark.slow),
                                     pytest.param("rrlinear", marks=pytest.mark.slow),
                                     pytest.param({"model": "sds", "rolling_stiffness": 2e3}, marks=pytest.mark.slow),
                                     pytest.param({"model": "displacement_damping", "damping": 0.3},
                                                  marks=pytest.mark.slow)])
def test_x_max_and_rest(rolling, table1):
    """x_max within 0.5 % of analytic; EPSD-type springs then hold (drift < 1e-7 m over 1 s)."""
    x_max, t_max = analytic_xmax()
    # Displacement damping's spring is soft: it mobilises at theta_max = 0.035 rad (0.17 mm of
    # rolling), omega_r = sqrt(k_r / I_r) = 88 rad/s, and eta = 0.3 settles it as exp(-26 t): after
    # turning round at the top it still rolls back ~9e-7 m between 0.5 s and 1.5 s. Measured from
    # 1.5 s, the remaining settling is 1e-11 m, so the 1e-7 m bound tests holding, not settling.
    hold = 2.2 if isinstance(rolling, dict) and rolling["model"] == "displacement_damping" else 1.2
    ts, xs, drift = roll_up(rolling, table1, hold=hold)
    assert xs.max() == pytest.approx(x_max, rel=0.005)
    assert ts[np.argmax(xs)] == pytest.approx(t_max, rel=0.01)  # the top is flat: time is less sharp
    if rolling != "cdt":
        assert abs(drift) < 1e-7


def test_cdt_creeps_back_with_or_without_limiter(table1):
    """Without a limiter CDT chatters and creeps down at 4.0e-5 m/s, as LIGGGHTS does (MODELS.md §13 T4;
    10 %: the creep is a chatter average). The STAR-CCM+ limiter |M| <= f I_r |dw_r| / dt turns the
    moment into a viscous clamp at low rates, so it cannot hold a slope either: at steady creep
    f I_r omega / dt = m g R sin(theta) with I_r = 1.4 m R^2, i.e. v = g sin(theta) dt / (1.4 f)
    (2 %), 1.5e-4 m/s for STAR's f = 0.08."""
    _, _, drift = roll_up("cdt", table1)
    assert drift == pytest.approx(-4.0e-5, rel=0.1)
    f = 0.08
    _, _, drift = roll_up(rd.CDT(limiter=f), table1)
    assert drift == pytest.approx(-G * math.sin(THETA) * 1e-5 / (1.4 * f), rel=0.02)
