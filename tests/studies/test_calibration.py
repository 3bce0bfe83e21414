"""rollingdem calibrate: recover a known parameter from a target observable.

* Stand-in with a known answer: the inclined wall. The sphere starts to roll where
  m g R sin b = mu_r R m g cos b, so the critical angle for mu_r is atan(mu_r) and the mu_r for a
  measured critical angle b is tan(b).
* A small real case: the stop distance of the rolling-flat case against its analytic value
  s(mu_r) = v0 t1 - mu g t1^2 / 2 + 7 v1^2 / (10 mu_r g) (docs/models.md §13 T2).
"""

import json
import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq

import rollingdem as rd
from rollingdem.studies.calibration import Execution, Search, calibrate, monotone_inverse, parse_assignments, parse_free
from rollingdem.experiments.single_sphere import analytic_flat


def test_inclined_wall_gives_back_tan_beta_with_the_interval_of_the_target(tmp_path):
    """beta = 20 deg +- 0.5 deg (one sigma): mu_r = tan 20 deg = 0.36397.

    Tolerance 0.5 %: the bisection brackets tan(beta_crit) to 2e-3 relative (1e-3 from its middle),
    the classification threshold at a quarter of that adds 5e-4, and the linear interpolation of the
    smooth atan between refined points h apart adds at most h^2 |atan''| / 8 < 2e-4 rad for
    h < 0.05 in mu_r (one round of refinement: runs.csv's points, checked below).
    Interval: a deterministic case has no seed spread, so the 95 % interval is the target's:
    mu_r = tan(beta +- 1.96 sigma), half-width 1.96 sigma sec^2(beta) = 0.01937 (+-10 % for the
    bootstrap's percentile estimate and the curvature of tan over the interval).
    """
    res = calibrate("inclined-wall", 20.0, 0.5, fix={"model": "epsd"}, free="mur", out=tmp_path,
                    execution=Execution(workers=2), progress=False, search=Search(rounds=1))
    exact = math.tan(math.radians(20.0))
    assert res.value == pytest.approx(exact, rel=0.005)
    assert res.low < exact < res.high
    half = 0.5 * (res.high - res.low)
    assert half == pytest.approx(1.96 * math.radians(0.5) / math.cos(math.radians(20.0)) ** 2, rel=0.1)
    assert res.direction == "increasing" and res.runs == 5 + 4
    points = np.unique(pd.read_csv(tmp_path / "runs.csv")["mur"])
    k = np.searchsorted(points, res.value)
    assert points[k] - points[k - 1] < 0.05  # the interpolation's h
    saved = json.loads((tmp_path / "calibration.json").read_text())
    assert saved["value"] == pytest.approx(res.value) and (tmp_path / "calibration.png").exists()


def test_rolling_flat_stop_distance_gives_back_the_analytic_mu_r(tmp_path):
    """Target s = 0.25 m at mu = 0.8, v0 = 1 m/s: the analytic mu_r solves s(mu_r) = 0.25. The
    simulated distance is within 0.5 % of the analytic one (validation case 1), and s ~ 1/mu_r
    near there, so mu_r comes back within 0.5 %. The distance falls as mu_r grows."""
    exact = brentq(lambda m: analytic_flat(1.0, 0.8, m)[3] - 0.25, 0.05, 0.6)
    res = calibrate("rolling-flat", 0.25, 0.0, fix={"mu": 0.8, "model": "epsd"}, free="mur", out=tmp_path,
                    execution=Execution(workers=1), progress=False)
    assert res.value == pytest.approx(exact, rel=0.005)
    assert res.direction == "decreasing"
    # rerun with a target uncertainty: the runs already there are reused, the interval widens to
    # the target's, dmu_r = 1.96 u / |ds/dmu_r|
    wider = calibrate("rolling-flat", 0.25, 0.005, fix={"mu": 0.8, "model": "epsd"}, free="mur", out=tmp_path,
                      execution=Execution(workers=1), progress=False, search=Search(rounds=0))
    slope = (analytic_flat(1.0, 0.8, exact * 1.001)[3] - analytic_flat(1.0, 0.8, exact * 0.999)[3]) / (0.002 * exact)
    assert 0.5 * (wider.high - wider.low) == pytest.approx(1.96 * 0.005 / abs(slope), rel=0.1)
    assert wider.value == pytest.approx(exact, rel=0.005)


def test_a_target_out_of_reach_is_refused_with_the_range_found(tmp_path):
    with pytest.raises(rd.ParameterError, match=r"outside what mur in \[0.2, 0.4\] gives"):
        calibrate("rolling-flat", 2.0, fix={"model": "cdt"}, free=("mur", (0.2, 0.4)), search=Search(coarse=3),
                  out=tmp_path, execution=Execution(workers=1), progress=False)
    assert (tmp_path / "runs.csv").exists()  # the runs made are kept


@pytest.mark.parametrize("kwargs, words", [
    ({"free": ("mur", "mu")}, ["one free parameter"]),
    ({"free": "mu_r"}, ["free = 'mu_r' is not known", "mur"]),
    ({"free": "model"}, ["not a real-valued parameter"]),
    ({"free": "seed"}, ["not a real-valued parameter"]),
    ({"uncertainty": -1.0}, ["uncertainty = -1"]),
    ({"search": Search(coarse=2)}, ["coarse = 2"]),
    ({"search": Search(refine=0)}, ["refine = 0", "integer >= 1"]),
    ({"search": Search(bootstrap=0)}, ["bootstrap = 0", "integer >= 1"]),
    ({"search": {"coarse": 3}}, ["search = {'coarse': 3}", "rollingdem.studies.calibration.Search"]),
    ({"execution": Execution(workers=0)}, ["workers = 0", "integer >= 1"]),
    ({"execution": 2}, ["execution = 2", "rollingdem.studies.calibration.Execution"]),
    ({"free": ("mur", (0.4, 0.2))}, ["LOW < HIGH"]),
    ({"free": ("mur", (-0.1, 0.2))}, ["mur = -0.1"]),
    ({"fix": {"mur": 0.2}}, ["both fixed and free"]),
    ({"fix": {"muu": 0.2}}, ["muu", "not known"]),
    ({"observable": "angle"}, ["observable = 'angle'", "distance"]),
    ({"seeds": 0}, ["seeds = 0"]),
    ({"fix": {"model": "epsdx"}}, ["model = 'epsdx'", "allowed"]),
])
def test_bad_calibration_input_is_refused(kwargs, words, tmp_path):
    args = dict(experiment="rolling-flat", target=0.2, out=tmp_path, execution=Execution(workers=1), progress=False)
    args.update(kwargs)
    with pytest.raises(rd.ParameterError) as err:
        calibrate(**args)
    for w in words:
        assert w in str(err.value), str(err.value)
    assert not (tmp_path / "runs.csv").exists()  # refused before any run


def test_monotone_inverse():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    assert monotone_inverse(x, np.array([0.0, 1.0, 1.0, 3.0]), 2.0) == pytest.approx(2.5)
    assert monotone_inverse(x, np.array([0.0, 1.0, 1.0, 3.0]), 1.0) == pytest.approx(1.5)  # flat: the middle
    assert monotone_inverse(x, np.array([3.0, 2.0, 1.0, 0.0]), 2.5) == pytest.approx(0.5)  # decreasing
    assert math.isnan(monotone_inverse(x, np.array([0.0, 1.0, 2.0, 3.0]), 3.5))


def test_command_line_parsing():
    assert parse_assignments(["mu=0.5", "model=epsd", "count=300"], "fix") == {"mu": 0.5, "model": "epsd",
                                                                                "count": 300}
    assert parse_free("mur=0.05:0.6") == ("mur", (0.05, 0.6))
    with pytest.raises(rd.ParameterError, match="NAME=VALUE"):
        parse_assignments(["mu"], "fix")
    with pytest.raises(rd.ParameterError, match="LOW:HIGH"):
        parse_free("mur=0.1")


def test_cli_calibrate(tmp_path):
    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "calibrate", "--case", "rolling-flat", "--target",
                          "0.15", "--fix", "mu=0.8", "--free", "mur=0.2:0.4", "--coarse", "3", "--rounds", "1",
                          "--out", str(tmp_path), "--workers", "1", "--no-progress"],
                         capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    saved = json.loads((tmp_path / "calibration.json").read_text())
    exact = brentq(lambda m: analytic_flat(1.0, 0.8, m)[3] - 0.15, 0.05, 0.6)
    # 3 coarse + 4 refined points over a 0.1 mu_r bracket: linear interpolation of s ~ 1/mu_r over a
    # 0.02 spacing is off by h^2 s'' / 8 / |s'| ~ 2e-4 in mu_r at most (under 0.1 %)
    assert saved["value"] == pytest.approx(exact, rel=0.005)
    assert "mur = " in res.stdout


@pytest.mark.slow
def test_angle_of_repose_calibration_is_reproduced_by_fresh_seeds(tmp_path):
    """The real case: piles of 1000 spheres (mu = 0.6), target 22 deg. Fresh seeds at the
    calibrated mu_r must give a mean angle whose 95 % interval overlaps the target's band
    (+- 1.96 x 1 deg): the calibration and the check are both limited by the seed scatter of a
    small pile (about 1.5 deg per pile)."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.analysis.intervals import confidence_interval

    fix = {"mu": 0.6, "count": 1000, "model": "epsd"}
    res = calibrate("angle-of-repose", 22.0, 1.0, fix=fix, free=("mur", (0.1, 0.8)), seeds=2,
                    search=Search(coarse=4, refine=2, rounds=1), out=tmp_path, progress=False)
    assert res.low < res.value < res.high and res.direction == "increasing"
    angles = [EXPERIMENTS["angle-of-repose"].observe(dict(fix, mur=res.value, seed=s))["angle"] for s in (11, 12, 13)]
    mean, half = confidence_interval(angles)
    assert abs(mean - 22.0) <= half + 1.96 * 1.0, (res, angles)
