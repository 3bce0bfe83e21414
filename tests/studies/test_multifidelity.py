"""Multi-fidelity calibration (rollingdem.studies.multifidelity): the model's parts on inputs with a
known answer, a known parameter given back through cheap runs that are biased, and the refusals."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from rollingdem.errors import ParameterError
from rollingdem.studies.calibration import Execution, Search, calibrate
from rollingdem.studies.multifidelity import Fidelity, cheap_default, corrected_model, posterior_on_grid


def test_the_posterior_of_a_straight_line_is_the_gaussian_of_its_inverse():
    """Model m(x) = 10 + 20 x with std 0.5 everywhere, target 20 (no uncertainty): the likelihood is
    exp(-(20 x - 10)^2 / (2 0.5^2)), a Gaussian in x of mean 0.5 and sd 0.025, so its mode is 0.5
    and its 2.5-97.5 % quantiles 0.5 -+ 1.96 x 0.025 (to the grid's 400 cells on [0, 1]: 0.0025)."""
    from rollingdem.studies.multifidelity import _crossing, _quantiles

    x, w, m = posterior_on_grid(lambda x: (10 + 20 * x, np.full(len(x), 0.5)), 20.0, 0.0, 0.0, 1.0)
    assert _crossing(x, m, 20.0, float(x[np.argmax(w)])) == pytest.approx(0.5, abs=1e-9)
    low, high = _quantiles(x, w, (0.025, 0.975))
    assert low == pytest.approx(0.5 - 1.96 * 0.025, abs=0.0025) and high == pytest.approx(0.5 + 1.96 * 0.025, abs=0.0025)


def test_the_corrected_model_adds_the_full_size_offset_to_the_cheap_curve():
    """Cheap means on the line 10 + 20 x at 7 points, full-size means 2 above it at x = 0.4 and 0.5
    (three seeds each, the same scatter 0.3 in both): near the full-size points the model reads
    the full size's means, and far from them (x = 0 and 1) the cheap line plus the mean offset 2;
    the discrepancy there is 2. Tolerance 0.05: the GP's noise is the means' variance, 0.3^2 / 3,
    so it fits the points to within about a standard error (0.17) and the straight line between
    them nearly exactly."""
    x = np.linspace(0, 1, 7)
    cheap = pd.DataFrame({"x": x, "mean": 10 + 20 * x, "std": 0.3, "count": 3})
    full = pd.DataFrame({"x": [0.4, 0.5], "mean": [20.0, 22.0], "std": 0.3, "count": 3})
    predict, delta = corrected_model(cheap, full, 0.0, 1.0)
    m, s = predict(np.array([0.0, 0.4, 0.5, 1.0]))
    assert m == pytest.approx([12.0, 20.0, 22.0, 32.0], abs=0.2)
    d, _ = delta(np.array([0.0, 1.0]))
    assert d == pytest.approx([2.0, 2.0], abs=0.05)
    assert s[1] < s[0] and s[1] < s[3]  # surer where the full-size runs are


def test_inclined_wall_through_coarse_bisections_gives_back_tan_beta(tmp_path):
    """The inclined wall's critical angle for mu_r is atan(mu_r) (calibration's test); its cheap runs
    bisect to 5 % (rel_tol 0.05) instead of 0.2 %, so they read off by up to 5 % of the angle (at
    the answer 0.17 deg, 0.9 % in mu_r), and two rounds of two full-size points correct them.
    Target beta = 20 deg +- 0.5: the answer is tan 20 deg within 0.2 %: full-size runs lie on both
    sides of it less than 0.05 apart in mu_r (asserted), each bisected to 0.2 % (0.1 % from the
    middle), and the cheap curve's shape between them errs by at most h^2 max|beta''| / 8 =
    0.0025 x 37 deg / 8 = 0.012 deg (0.05 %). The interval holds the answer and is about the
    target's, 1.96 x 0.5 deg / (dbeta/dmu_r) = +-0.019 (0.5-2x: the model's own uncertainty adds
    to it)."""
    exact = math.tan(math.radians(20.0))
    res = calibrate("inclined-wall", 20.0, 0.5, fix={"model": "epsd"}, free=("mur", (0.02, 1.0)), out=tmp_path,
                    execution=Execution(workers=2), progress=False,
                    search=Search(fidelity=Fidelity(cheap={"rel_tol": 0.05}, cheap_points=7, full_points=2, full_rounds=2)))
    assert res.value == pytest.approx(exact, rel=0.002)
    full = np.array(res.fidelity["full_points"])
    below, above = full[full < res.value].max(), full[full > res.value].min()
    assert above - below < 0.05
    assert res.low < exact < res.high
    half = 0.5 * (res.high - res.low)
    target_half = 1.96 * math.radians(0.5) * (1 + exact ** 2)
    assert 0.5 * target_half < half < 2.0 * target_half
    info = res.fidelity
    assert info["cheap_runs"] == 7 and info["full_runs"] == 4 and res.runs == 11
    saved = json.loads((tmp_path / "calibration.json").read_text())
    assert saved["fidelity"]["full_runs"] == 4 and (tmp_path / "calibration.png").exists()
    # the model as written, between the full-size points: atan(mu_r) within its 95 % band plus the
    # full-size runs' bisection tolerance (0.2 % of 20 deg = 0.04 deg)
    model = pd.read_csv(tmp_path / saved["fidelity"]["model_file"])
    near = model[(model["mur"] >= below) & (model["mur"] <= above)]
    assert len(near) >= 5
    exact_there = np.degrees(np.arctan(near["mur"]))
    assert (abs(near["critical_angle_mean"] - exact_there) <= 1.96 * near["critical_angle_std"] + 0.04).all()


def test_multifidelity_refuses_what_it_cannot_do(tmp_path):
    from rollingdem.experiments import get_experiment

    with pytest.raises(ParameterError, match="cheap = mur=0.1 is not allowed: mur is the free parameter"):
        calibrate("inclined-wall", 20.0, 0.5, free=("mur", (0.02, 1.0)), out=tmp_path, progress=False,
                  search=Search(fidelity=Fidelity(cheap={"mur": 0.1})))
    with pytest.raises(ParameterError, match="cheap = {'rel_tol': -1} is not allowed"):
        calibrate("inclined-wall", 20.0, 0.5, free=("mur", (0.02, 1.0)), out=tmp_path, progress=False,
                  search=Search(fidelity=Fidelity(cheap={"rel_tol": -1})))
    with pytest.raises(ParameterError, match="cheap_points = 2 is not allowed: must be an integer >= 3"):
        calibrate("inclined-wall", 20.0, 0.5, free=("mur", (0.02, 1.0)), out=tmp_path, progress=False,
                  search=Search(fidelity=Fidelity(cheap={"rel_tol": 0.05}, cheap_points=2)))
    with pytest.raises(ParameterError, match="has no count to make smaller"):
        cheap_default(get_experiment("inclined-wall", observable=True), {})
    assert cheap_default(get_experiment("repose-rough-base", observable=True), {"count": 1000}) == {"count": 400}
    assert not list(tmp_path.glob("runs.csv"))  # refused before any run


@pytest.mark.parametrize("args, words", [
    (["--fidelity", "multi"], "fidelity = multi is not allowed for 'inclined-wall' without cheap runs"),
    (["--cheap", "rel_tol=0.05"], "--cheap = 'rel_tol=0.05' is not allowed with --fidelity single"),
    (["--fidelity", "several"], "--fidelity = 'several' is not allowed: single or multi"),
    (["--fidelity", "multi", "--cheap", "mur=0.1"], "cheap = mur=0.1 is not allowed: mur is the free parameter"),
])
def test_the_command_refuses_a_fidelity_it_cannot_build_in_one_line(args, words, tmp_path):
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "calibrate", "--experiment", "inclined-wall",
                          "--target", "20", "--free", "mur=0.02:1.0", "--out", str(tmp_path / "cal"), "--no-progress",
                          *args], capture_output=True, text=True)
    assert res.returncode == 2 and words in res.stderr and "Traceback" not in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("case_file", [False, True])
def test_cheap_parcels_wider_than_the_silo_orifice_are_refused_before_any_run(case_file, tmp_path):
    """Parcels of alpha = 6 of spheres 8-12 mm across are up to 72 mm wide; the silo's orifice is 60
    mm (6 d): none could pass, so the cheap runs cannot be built. The built-in silo and its case
    file (which does not write coarse_graining: the short name sets the one material's) are both
    refused in one line, exit 2, before any run (no output folder)."""
    import shutil
    import subprocess
    import sys

    from rollingdem.experiments.case_file import shipped_cases

    if case_file:
        shutil.copy(shipped_cases()["silo"], tmp_path / "silo.yaml")
        where = [str(tmp_path / "silo.yaml"), "--target", "discharge.rate=0.5±0.01"]
        words = "silo: coarse_graining = 6 is not allowed with its opening"
    else:
        where = ["--experiment", "silo-discharge", "--target", "0.5", "--uncertainty", "0.01"]
        words = "orifice_diameters = 6 is not allowed with coarse_graining = 6"
    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "calibrate", *where, "--free", "mur=0:0.5",
                          "--fidelity", "multi", "--cheap", "coarse_graining=6", "--out", str(tmp_path / "cal"),
                          "--no-progress"], capture_output=True, text=True)
    assert res.returncode == 2 and words in res.stderr and "Traceback" not in res.stderr, res.stderr
    assert res.stderr.startswith("error: cheap = {'coarse_graining': 6} is not allowed")
    assert len(res.stderr.strip().splitlines()) == 1 and not (tmp_path / "cal").exists()


@pytest.mark.slow
def test_a_wall_and_a_flat_roll_calibrated_jointly_through_cheap_bisections_give_back_the_true_point(tmp_path):
    """Two targets, two free parameters: the inclined wall's critical angle (atan mu_r, 20 deg +- 0.1)
    and the rolling-flat stop distance at mu = 0.4, mu_r = tan 20 deg (analytic, +- 0.5 %; the
    simulation meets it to 0.1 %). The wall's cheap runs bisect to 5 % (0.17 deg low at the answer,
    0.0034 in mu_r); the flat roll has no cheap runs and runs at full size throughout. The true point
    lies in the 95 % region and in mu_r's interval, which is under 0.02 wide (the target alone gives
    +-1.96 x 0.1 deg / (dbeta / dmu_r) = +-0.0039; the model's uncertainty adds to it), and the
    posterior mean of mu_r is within half of that +-0.0039 of the truth: without the full-size
    correction the cheap runs' bias puts it 0.007 off."""
    from rollingdem.experiments.single_sphere import analytic_flat
    from rollingdem.studies.joint_calibration import JointSearch, Target, calibrate_joint
    from rollingdem.studies.multifidelity import JointFidelity

    mur = math.tan(math.radians(20.0))
    s = analytic_flat(1.0, 0.4, mur)[3]
    targets = [Target("inclined-wall", "critical_angle", 20.0, 0.1), Target("rolling-flat", "distance", s, 0.005 * s)]
    res = calibrate_joint(targets, {"mu": (0.3, 0.5), "mur": (0.3, 0.45)}, fix={"model": "epsd"}, out=tmp_path,
                          search=JointSearch(rounds=1, per_round=2), execution=Execution(workers=2), progress=False,
                          fidelity=JointFidelity(cheap={"inclined-wall": {"rel_tol": 0.05}}, cheap_initial=8,
                                                 full_initial=3))
    assert res.in_region({"mu": 0.4, "mur": mur})
    lo, hi = res.interval["mur"]
    assert lo <= mur <= hi and hi - lo < 0.02
    assert abs(res.best["mur"] - mur) < 0.5 * 1.96 * math.radians(0.1) * (1 + mur ** 2)
    info = res.fidelity
    assert info["cheap_runs"] == 8 and info["full_points"] == 5
    assert info["full_runs"] == 5 + 13  # the wall's full-size points, and every point of the flat roll
    assert res.runs == 8 + 18
    assert json.loads((tmp_path / "calibration.json").read_text())["fidelity"]["cheap_points"] == 8


@pytest.mark.slow
def test_the_readme_multifidelity_command_gives_back_a_known_mu_r(tmp_path):
    """The README's multi-fidelity command on a synthetic target: the mean pile angle at mu_r = 0.2
    (1,000 spheres) of 3 seeds the calibration does not use (101-103), its uncertainty their 95 %
    half-width / 1.96 (docs/studies.md, "Joint calibration", says why). The 95 % interval holds
    0.2; the runs of each kind are those the text names (21 cheap runs of 400 spheres, 12 full).
    About 3 minutes on 2 cores."""
    import subprocess
    import sys
    from pathlib import Path

    from rollingdem.analysis.intervals import confidence_interval
    from rollingdem.experiments import EXPERIMENTS

    readme = (Path(__file__).parents[2] / "README.md").read_text()
    command = ("rollingdem calibrate --experiment repose-rough-base --target 25 --uncertainty 0.5 --fix count=1000 \\\n"
               "                     --free mur=0:0.6 --fidelity multi")
    assert command in readme
    angles = [EXPERIMENTS["repose-rough-base"].observe({"count": 1000, "mur": 0.2, "seed": s})["angle"]
              for s in (101, 102, 103)]
    mean, half = confidence_interval(angles)
    args = command.replace("\\\n", " ").split()[1:]
    args[args.index("25")], args[args.index("0.5")] = f"{mean:.4f}", f"{half / 1.96:.4f}"
    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", *args, "--out", str(tmp_path / "cal"),
                          "--no-progress"], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    saved = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert saved["low"] <= 0.2 <= saved["high"], (saved["value"], saved["low"], saved["high"], angles)
    assert saved["fidelity"]["cheap_runs"] == 21 and saved["fidelity"]["full_runs"] == 12
