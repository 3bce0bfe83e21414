"""Rolling resistance models against docs/models.md §13 (seed report material, Hertz, dt = 1e-5 s)."""

import numpy as np
import pytest

import rollingdem as rd
from conftest import R
from rollingdem.experiments.single_sphere import analytic_flat, rolling_flat_run, stop_time

MU, MU_R = 0.8, 0.2


def test_analytic_reference_values():
    _, _, t_stop, s = analytic_flat()
    assert t_stop == pytest.approx(0.50968, abs=1e-5) and s == pytest.approx(0.18836, abs=1e-5)  # docs/models.md §13


SLOW = pytest.mark.slow


@pytest.mark.parametrize("rolling,tol", [("cdt", 0.005), ("epsd", 0.005), ("epsd2", 0.01),
                                         pytest.param("epsd3", 0.01, marks=SLOW),
                                         pytest.param("rrlinear", 0.01, marks=SLOW),
                                         pytest.param({"model": "sds", "rolling_stiffness": 1e4}, 0.01, marks=SLOW),
                                         pytest.param({"model": "displacement_damping", "damping": 0.3}, 0.01,
                                                      marks=SLOW),
                                         pytest.param({"model": "epsd", "damping_ratio": 0.0}, 0.01, marks=SLOW)])
def test_rolling_on_flat_stops_where_theory_says(rolling, tol):
    """CDT and (capped-total) EPSD within 0.5 % of the analytic stop, every spring model within 1 %.
    The stop time is read on a 0.1 ms grid (0.02 % of t_stop)."""
    _, _, t_stop, s = analytic_flat()
    traj = rolling_flat_run(rolling, duration=0.7)
    assert stop_time(traj) == pytest.approx(t_stop, rel=tol)  # v < 1 mm/s: 0.7 ms before rest
    assert traj.x[-1] == pytest.approx(s, rel=tol)


def test_liggghts_parity_epsd_stops_short_by_the_dashpot_spike():
    """docs/models.md §11.5: LIGGGHTS caps only the spring, so at the end of slip the uncapped dashpot
    adds a moment spike and the sphere stops short (LIGGGHTS: 0.18758 m against 0.18836 m). The
    parity preset must stop short of the recommended EPSD by more than 0.1 % and land within 0.3 %
    of LIGGGHTS's distance; 0.3 % because LIGGGHTS's own CDT run already sits 0.13 % short of the
    analytic distance (0.18811 m), an offset common to its models and not from the rolling law."""
    default = rolling_flat_run("epsd", duration=0.7).x[-1]
    parity = rolling_flat_run(rd.EPSD(parity="liggghts"), duration=0.7).x[-1]
    assert parity < (1 - 1e-3) * default
    assert parity == pytest.approx(0.18758, rel=3e-3)


def test_epsd_holds_the_sphere_still_after_stopping():
    """The damped spring (eta_r = 0.3) brings the sphere to rest; CDT keeps chattering (§11.6)."""
    traj = rolling_flat_run("epsd", duration=0.7)
    assert np.abs(traj.v[traj.t > 0.6]).max() < 1e-9
    # T6(a): the energy the rolling couple dissipated (work minus stored spring energy) does not fall.
    # Measured: the only dip, 0.1 % of the total, is at the end of slip (t1 = 44 ms), where the spring
    # backed out of the dashpot at the cap (M_k = M - C_r dw_r) hands stored energy back; 0.3 % allowed
    rolled = traj.rolling_dissipation
    assert np.diff(rolled).min() > -3e-3 * rolled[-1]
    # and at the end it is the kinetic energy lost while rolling: (7/10) m v1^2 of the rolling phase
    # is shared with sliding only before t1, so the rolling share is at least the rolling-phase energy
    m = 1056 * 4 / 3 * np.pi * R ** 3
    v1 = 2.5 * (MU - MU_R) / (3.5 * MU - 2.5 * MU_R)
    assert rolled[-1] > 0.99 * 0.7 * m * v1 ** 2
    traj = rolling_flat_run("cdt", duration=0.7)
    assert np.abs(traj.v[traj.t > 0.6]).max() > 1e-7


def test_unknown_parity_is_refused():
    with pytest.raises(rd.ParameterError, match="epsd parity = 'edem' is not known"):
        rd.EPSD(parity="edem")
    with pytest.raises(rd.ParameterError, match="epsd damping_ratio = -0.1"):
        rd.EPSD(damping_ratio=-0.1)
