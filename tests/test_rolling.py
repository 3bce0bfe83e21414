"""Rolling resistance models against MODELS.md §13 (seed report material, Hertz, dt = 1e-5 s)."""

import numpy as np
import pytest

import rollingdem as rd
from conftest import R, G

MU, MU_R = 0.8, 0.2


def launch_on_flat(rolling, table1, v0=1.0, duration=0.7):
    """T2: settle 0.2 s, launch with v0 and omega0 = 0; returns times, x - x0, v_x."""
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling), dt=1e-5)
    sim.add_material(table1(friction=MU, rolling_friction=MU_R, rolling_damping=0.3))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R]], R, "m")
    sim.run(0.2)
    x0, t0 = sim.positions[0, 0], sim.time
    sim.set_velocities([0], velocity=(v0, 0, 0), angular_velocity=(0, 0, 0))
    ts, xs, vs = [], [], []
    launch_dissipation.clear()
    for _ in range(int(round(duration / 1e-4))):
        sim.run(steps=10)
        ts.append(sim.time - t0)
        xs.append(sim.positions[0, 0] - x0)
        vs.append(sim.velocities[0, 0])
        launch_dissipation.append(sim.dissipated_energy()["rolling"])
    return np.array(ts), np.array(xs), np.array(vs)


launch_dissipation: list[float] = []


def analytic_t2(v0=1.0):
    """Slip phase to t1 = v0 / (g (3.5 mu - 2.5 mu_r)), then rolling deceleration 5/7 mu_r g."""
    t1 = v0 / (G * (3.5 * MU - 2.5 * MU_R))
    v1 = 2.5 * v0 * (MU - MU_R) / (3.5 * MU - 2.5 * MU_R)
    t_stop = t1 + 7 * v1 / (5 * MU_R * G)
    s = v0 * t1 - 0.5 * MU * G * t1 ** 2 + 7 * v1 ** 2 / (10 * MU_R * G)
    return t_stop, s


def test_analytic_reference_values():
    t_stop, s = analytic_t2()
    assert t_stop == pytest.approx(0.50968, abs=1e-5) and s == pytest.approx(0.18836, abs=1e-5)  # MODELS.md §13


SLOW = pytest.mark.slow


@pytest.mark.parametrize("rolling,tol", [("cdt", 0.005), ("epsd", 0.005), ("epsd2", 0.01),
                                         pytest.param("epsd3", 0.01, marks=SLOW),
                                         pytest.param("rrlinear", 0.01, marks=SLOW),
                                         pytest.param({"model": "sds", "rolling_stiffness": 1e4}, 0.01, marks=SLOW),
                                         pytest.param({"model": "displacement_damping", "damping": 0.3}, 0.01,
                                                      marks=SLOW),
                                         pytest.param({"model": "epsd", "damping_ratio": 0.0}, 0.01, marks=SLOW)])
def test_rolling_on_flat_stops_where_theory_says(rolling, table1, tol):
    """CDT and (capped-total) EPSD within 0.5 % of the analytic stop, every spring model within 1 %.
    The stop time is read on a 0.1 ms grid (0.02 % of t_stop)."""
    t_stop, s = analytic_t2()
    ts, xs, vs = launch_on_flat(rolling, table1)
    measured_stop = ts[np.argmax(vs < 1e-3)]  # 1e-3 m/s is 0.7 ms of rolling deceleration before rest
    assert measured_stop == pytest.approx(t_stop, rel=tol)
    assert xs[-1] == pytest.approx(s, rel=tol)


def test_liggghts_parity_epsd_stops_short_by_the_dashpot_spike(table1):
    """MODELS.md §11.5: LIGGGHTS caps only the spring, so at the end of slip the uncapped dashpot
    adds a moment spike and the sphere stops short (LIGGGHTS: 0.18758 m against 0.18836 m). The
    parity preset must stop short of the recommended EPSD by more than 0.1 % and land within 0.3 %
    of LIGGGHTS's distance; 0.3 % because LIGGGHTS's own CDT run already sits 0.13 % short of the
    analytic distance (0.18811 m), an offset common to its models and not from the rolling law."""
    _, xs_default, _ = launch_on_flat("epsd", table1)
    _, xs_parity, _ = launch_on_flat(rd.EPSD(parity="liggghts"), table1)
    assert xs_parity[-1] < (1 - 1e-3) * xs_default[-1]
    assert xs_parity[-1] == pytest.approx(0.18758, rel=3e-3)


def test_epsd_holds_the_sphere_still_after_stopping(table1):
    """The damped spring (eta_r = 0.3) brings the sphere to rest; CDT keeps chattering (§11.6)."""
    ts, xs, vs = launch_on_flat("epsd", table1)
    assert np.abs(vs[ts > 0.6]).max() < 1e-9
    # T6(a): the energy the rolling couple dissipated (work minus stored spring energy) does not fall.
    # Measured: the only dip, 0.1 % of the total, is at the end of slip (t1 = 44 ms), where the spring
    # backed out of the dashpot at the cap (M_k = M - C_r dw_r) hands stored energy back; 0.3 % allowed
    rolled = np.array(launch_dissipation)
    assert np.diff(rolled).min() > -3e-3 * rolled[-1]
    # and at the end it is the kinetic energy lost while rolling: (7/10) m v1^2 of the rolling phase
    # is shared with sliding only before t1, so the rolling share is at least the rolling-phase energy
    m = 1056 * 4 / 3 * np.pi * R ** 3
    v1 = 2.5 * (MU - MU_R) / (3.5 * MU - 2.5 * MU_R)
    assert rolled[-1] > 0.99 * 0.7 * m * v1 ** 2
    ts, xs, vs = launch_on_flat("cdt", table1)
    assert np.abs(vs[ts > 0.6]).max() > 1e-7


def test_unknown_parity_is_refused():
    with pytest.raises(rd.ParameterError, match="epsd parity = 'edem' is not known"):
        rd.EPSD(parity="edem")
    with pytest.raises(rd.ParameterError, match="epsd damping_ratio = -0.1"):
        rd.EPSD(damping_ratio=-0.1)
