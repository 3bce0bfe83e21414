"""The pile cases of rollingdem validate at their quick sizes (slow: minutes each), and the angle
check of case 3 on stand-in piles (fast).

They assert the cases' own physics checks: EPSD's translational kinetic energy ends two decades
below CDT's chatter floor, a twisting model removes the spin, EPSD2 and EPSD (the same rolling
limit) leave piles of the same angle, and the repose angle grows with mu (the sweep's own check)
and with mu_r by more than the seed-to-seed scatter. The default suite covers the pieces: the angle measurement on
synthetic piles (test_analysis.py), the statistics and the report (test_validate.py).

Seed-to-seed spread of the quick sweep's piles (2000 spheres, 'rrlinear', tube lifted at 0.2 m/s,
E = 5 MPa, dt = 2.5e-5 s; ``repose_sweep(quick=True, seeds=(1, 2, 3, 4))``, about 25 min on a shared
2-core machine):

    mu = 0.4, mu_r = 0.2: 16.46, 18.76, 13.51, 15.85 degrees (mean 16.15)
    mu = 0.4, mu_r = 0.8: 27.48, 25.81, 26.28, 27.12 degrees (mean 26.67)
    mu = 0.8, mu_r = 0.2: 18.18, 19.12, 18.07, 21.36 degrees (mean 19.18)
    mu = 0.8, mu_r = 0.8: 29.69, 29.77, 30.08 degrees (seed 4 still creeping at 2.6 s)

Pooled standard deviation s = 1.44 degree (11 degrees of freedom; t(0.975, 11) = 2.20). The quick
sweep has two seeds a point, so the difference of two points' means has standard deviation s
(variance s^2/2 + s^2/2): the mu_r trend is asserted when larger than t s = 3.2 degrees, and it
is about 10.6 (a sweep in which the angle did not depend on mu_r would pass with a chance of
2.5 %). The mu trend is not asserted beyond the sweep's own check that it is positive: over 4 seeds
mu raises the angle by 3.1 degrees on average, and the quick sweep's statistic (the mean over mu_r
of the mu difference, standard deviation s / sqrt(2) = 1.0) would clear t s / sqrt(2) = 2.2 degrees
only about 4 times in 5 (seeds 1 and 2 give 2.06).
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

from rollingdem.experiments import pile, repose
from rollingdem.experiments.repose import REPOSE_ANGLE_TOLERANCE, angle_of_repose
from rollingdem.studies.repose_study import repose_sweep

QUICK_SWEEP_SPREAD = {(0.4, 0.2): [16.461, 18.758, 13.507, 15.852], (0.4, 0.8): [27.485, 25.807, 26.280, 27.122],
                      (0.8, 0.2): [18.178, 19.119, 18.071, 21.358], (0.8, 0.8): [29.687, 29.769, 30.078]}


def _pooled_sd(groups):
    ss = sum(((np.array(v) - np.mean(v)) ** 2).sum() for v in groups.values())
    dof = sum(len(v) for v in groups.values()) - len(groups)
    return math.sqrt(ss / dof), dof


@pytest.mark.slow
def test_angle_of_repose_quick(tmp_path):
    result = angle_of_repose(quick=True, outdir=tmp_path)
    failed = [c.as_dict() for c in result.checks if not c.passed]
    assert not failed, failed
    assert len(result.checks) == 3
    angle = next(c for c in result.checks if c.model == "epsd2")
    assert angle.reference == 0.0 and angle.tolerance == REPOSE_ANGLE_TOLERANCE and not angle.relative


def test_angle_check_of_case_3_on_stand_in_piles(monkeypatch):
    """The angle check of case 3: EPSD2's angle minus EPSD's, reference 0, absolute tolerance
    REPOSE_ANGLE_TOLERANCE; it passes within, fails beyond, and fails when a pile has no angle."""
    def stand_in(angles):
        def pile_run(rolling, twisting, **kw):
            t = np.linspace(0.01, 1.5, 150)
            e = np.full(t.size, 1e-9)
            a = angles[rolling]
            return SimpleNamespace(label=rolling, t=t, translational=e, rotational=e, spin_vertical=e * 0.1,
                                   angle=None if a is None else SimpleNamespace(angle=a, slice_mean=a, slice_std=1.0,
                                                                                r_squared=0.5),
                                   angle_error="" if a is not None else "too flat", settled_at=1.5, wall_time=1.0)
        return pile_run

    def check(angles):
        monkeypatch.setattr(repose, "pile_run", stand_in(angles))
        result = angle_of_repose(quick=True, models=["epsd", "epsd2"])
        (c,) = [c for c in result.checks if c.model == "epsd2"]
        return c

    tol = REPOSE_ANGLE_TOLERANCE
    assert math.isfinite(tol) and 0 < tol
    c = check({"epsd": 20.0, "epsd2": 20.0 + 0.9 * tol})
    assert c.passed and c.measured == pytest.approx(0.9 * tol)
    assert check({"epsd": 20.0, "epsd2": 20.0 - 0.9 * tol}).passed
    assert not check({"epsd": 20.0, "epsd2": 20.0 + 1.1 * tol}).passed
    assert not check({"epsd": 20.0, "epsd2": None}).passed


@pytest.mark.slow
def test_repose_sweep_quick(tmp_path):
    result = repose_sweep(quick=True, outdir=tmp_path)
    failed = [c.as_dict() for c in result.checks if not c.passed]
    assert not failed, failed
    assert (tmp_path / "repose_sweep_runs.csv").exists()
    # the trends by more than the seed scatter (module docstring)
    s, dof = _pooled_sd(QUICK_SWEEP_SPREAD)
    t = stats.t.ppf(0.975, dof)
    table = result.table.set_index(["mu", "mu_r"])
    assert (table["measured"] == 2).all(), table  # every pile settled and measured
    angle = table["angle mean (deg)"]
    print(f"\n{angle}\nmargin: mu_r {t * s:.2f} deg")
    for mu in (0.4, 0.8):
        assert angle[(mu, 0.8)] - angle[(mu, 0.2)] > t * s


@pytest.mark.slow
def test_a_pile_forms_on_a_rough_base_without_rolling_resistance():
    """mu_r = 0 with the quick sweep's material and pile (2000 spheres, 'rrlinear', mu = 0.4, tube
    lifted at 0.2 m/s): on the bare plate the spheres roll away and no cone can be fitted; on a
    rough base of fixed spheres a pile stands, steeper than 10 degrees (PFC and LIGGGHTS studies
    measure an angle at mu_r = 0 on such bases)."""
    from rollingdem.experiments import EXPERIMENTS

    params = dict(model="rrlinear", mu=0.4, mur=0.0, count=2000, seed=1, lift_speed=0.2, youngs_modulus=5e6,
                  dt=2.5e-5, max_collapse=3.0)
    rough = EXPERIMENTS["angle-of-repose"].observe(dict(params, rough_base=1))
    assert rough["angle"] > 10.0, rough


def test_the_shipped_repose_rough_base_is_what_the_validation_runs_at_its_base_point():
    """``rollingdem experiments show repose-rough-base`` is the pile ``repose-rough-base`` builds at
    its base point (its defaults): every entry of ``pile_case``'s data, as the case file reader
    completes it, equals the shipped file's, numbers to the 6 figures the file writes them with
    (rel. 1e-5). The output aside."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.experiments.pile import pile_case
    from helpers import assert_same_case

    assert_same_case(pile_case(**EXPERIMENTS["repose-rough-base"].pile_arguments({})), "repose-rough-base", 1e-5)


def test_a_pile_stopped_mid_collapse_goes_on_from_its_last_save_bit_for_bit(tmp_path, monkeypatch):
    """``pile_run`` with ``checkpoint``: a pile on a rough base (150 spheres, the tube lifted) saved
    at every sample and stopped during the lift, started again with the same path, ends with the
    positions, velocities and kinetic-energy record of the pile run in one go, bit for bit; so
    does one stopped after the tube left whose newest save was cut short (its JSON written, its
    checkpoint not: the older slot is read). The saves are gone once the pile ends."""
    from rollingdem.experiments.pile import Collapse, PileMaterial, PileSetup, pile_run

    kw = dict(count=150, seed=2, material=PileMaterial(youngs_modulus=5e6), dt=2.5e-5, setup=PileSetup(base="rough"),
              collapse=Collapse(min_time=0.2, max_time=0.25, sample=0.01, lift_speed=0.5))
    whole = pile_run(**kw)
    monkeypatch.setattr(pile, "PILE_CHECKPOINT_SECONDS", 0.0)
    real_save = pile.PileProgress.save

    def stopping(at):
        calls = []

        def save(self, sim, t, ke, wall_time, force=False):
            real_save(self, sim, t, ke, wall_time, force)
            calls.append(t)
            if len(calls) == at:
                raise KeyboardInterrupt  # a kill just after a save
        return save

    for name, at, cut in (("stopped", 6, False), ("cut short", 22, True)):  # the tube leaves at 0.18 s
        path = tmp_path / name
        monkeypatch.setattr(pile.PileProgress, "save", stopping(at))
        with pytest.raises(KeyboardInterrupt):
            pile_run(**kw, checkpoint=path)
        if cut:  # the newest slot's JSON names a step its checkpoint does not hold: the other slot's
            newest, older = sorted(tmp_path.glob(f"{name}.?.npz"), key=lambda f: f.stat().st_mtime_ns)[::-1]
            newest.write_bytes(older.read_bytes())
        monkeypatch.setattr(pile.PileProgress, "save", real_save)
        again = pile_run(**kw, checkpoint=path)
        np.testing.assert_array_equal(again.positions, whole.positions)
        np.testing.assert_array_equal(again.velocities, whole.velocities)
        np.testing.assert_array_equal(again.translational, whole.translational)
        np.testing.assert_array_equal(again.t, whole.t)
        np.testing.assert_equal(again.settled_at, whole.settled_at)
        assert not list(tmp_path.glob(f"{name}.*"))
