"""The checks of multi-fidelity calibration on synthetic targets, each with three seeds of the
procedure (the calibration's run seeds), single and multi-fidelity side by side.

    python benchmarks/multifidelity_checks.py pile  [--work DIR] [--workers 2]
    python benchmarks/multifidelity_checks.py joint [--work DIR] [--workers 2]

- ``pile``: mu_r against one pile angle (repose-rough-base, 1,000 spheres, mu_r in [0, 0.6]), the
  target the mean angle at mu_r = 0.2 of seeds 101-103, its uncertainty their 95 % half-width /
  1.96. Procedure seeds: run seeds 1-3, 4-6 and 7-9. Checks: (1) each multi-fidelity answer lies
  in the single-fidelity 95 % interval of the same seeds; (2) held out: the mean angle of seeds
  201-203 at 10 values of mu_r over the range, at full size, lies within each multi-fidelity
  model's 95 % band (``model.csv``) widened by the held-out mean's own scatter,
  1.96 sqrt(s(x)^2 + sd^2 / 3), sd the seeds' scatter pooled over the calibration's full-size runs,
  in at least 90 % of the 30 comparisons.
- ``joint``: (mu, mu_r) in [0.3, 0.8] x [0.05, 0.35] against a pile angle and a drum angle, the
  targets those of ``benchmarks/time_to_calibration.py joint`` (made at mu = 0.5, mu_r = 0.15 by
  seeds 101-103), 2 seeds a point; procedure seeds 1-2, 3-4 and 5-6. Check: each multi-fidelity
  best point (posterior mean) lies in the single-fidelity 95 % region of the same seeds, and
  mu_r's interval of each holds 0.15.

Prints one JSON line per calibration and per check, writes WORK/checks.json, and exits 1 when a
check fails.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).parent
PILE_FIX = {"count": 1000}
PILE_TRUTH = 0.2
PILE_RANGE = (0.0, 0.6)
HELD_OUT = np.linspace(0.03, 0.57, 10)


def say(row: dict) -> None:
    print(json.dumps(row, default=float), flush=True)


def pile(work: Path, workers: int) -> list[dict]:
    from rollingdem.analysis.intervals import confidence_interval
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.studies.calibration import Execution, Search, calibrate
    from rollingdem.studies.multifidelity import Fidelity
    from rollingdem.studies.sweep import load_sweep, run_sweep

    exe = Execution(workers=workers)
    angles = [EXPERIMENTS["repose-rough-base"].observe({**PILE_FIX, "mur": PILE_TRUTH, "seed": s})["angle"]
              for s in (101, 102, 103)]
    target, half = confidence_interval(angles)
    u = half / 1.96
    say({"target": target, "uncertainty": u, "angles": angles})
    checks, models = [], []
    for k in range(3):
        seeds = [3 * k + 1, 3 * k + 2, 3 * k + 3]
        res = {}
        for kind, search in (("single", Search()), ("multi", Search(fidelity=Fidelity(cheap={"count": 400})))):
            out = work / f"pile-{k + 1}-{kind}"
            r = calibrate("repose-rough-base", target, u, fix=PILE_FIX, free=("mur", PILE_RANGE), seeds=seeds,
                          search=search, out=out, execution=exe, progress=False)
            res[kind] = r
            say({"calibration": f"pile-{kind}", "seeds": seeds, "value": r.value, "low": r.low, "high": r.high,
                 "runs": r.runs, "wall_s": r.wall_time, "truth_inside": r.low <= PILE_TRUTH <= r.high})
        s, m = res["single"], res["multi"]
        checks.append({"check": "multi in single's interval", "seeds": seeds, "multi": m.value,
                       "single": [s.low, s.high], "passed": s.low <= m.value <= s.high})
        say(checks[-1])
        models.append((pd.read_csv(work / f"pile-{k + 1}-multi" / "model.csv"), m.fidelity["full_seed_sd"]))
    spec = load_sweep({"experiment": "repose-rough-base", "fixed": PILE_FIX,
                       "points": [{"mur": float(x)} for x in HELD_OUT], "seeds": [201, 202, 203]})
    with exe.runner() as mapper:
        table = run_sweep(spec, work / "held-out", mapper=mapper, progress=False, summary=False).table
    ok = table[table["status"] == "ok"]
    held = ok.groupby("mur")["angle"].agg(["mean", "count"]).reset_index()
    inside = []
    for model, sd in models:
        m = np.interp(held["mur"], model["mur"], model["angle_mean"])
        s = np.interp(held["mur"], model["mur"], model["angle_std"])
        band = 1.96 * np.sqrt(s ** 2 + sd ** 2 / held["count"])
        inside += list(abs(held["mean"] - m) <= band)
        say({"held_out": held["mur"].round(4).tolist(), "angle": held["mean"].round(3).tolist(),
             "model": np.round(m, 3).tolist(), "band": np.round(band, 3).tolist()})
    share = float(np.mean(inside))
    checks.append({"check": "held-out full-size means within the model's band", "inside": int(sum(inside)),
                   "of": len(inside), "share": share, "passed": share >= 0.9})
    say(checks[-1])
    return checks


def joint(work: Path, workers: int) -> list[dict]:
    sys.path.insert(0, str(HERE))
    from time_to_calibration import DRUM_FIX, PILE_FIX as JOINT_PILE_FIX, TRUTH, joint_arguments

    from rollingdem.experiments import get_experiment
    from rollingdem.studies.calibration import Execution
    from rollingdem.studies.joint_calibration import JointSearch, Target, calibrate_joint
    from rollingdem.studies.multifidelity import JointFidelity, cheap_default

    joint_arguments(work)  # the targets, made once
    made = json.loads((work / "targets.json").read_text())
    targets = [Target(case, "angle", value, u) for case, (value, u) in made.items()]
    fix = {**JOINT_PILE_FIX, **DRUM_FIX}
    free = {"mu": (0.3, 0.8), "mur": (0.05, 0.35)}
    cheap = {case: cheap_default(get_experiment(case, observable=True), fix) for case in made}
    exe = Execution(workers=workers)
    checks = []
    for k in range(3):
        seeds = [2 * k + 1, 2 * k + 2]
        res = {}
        for kind, search, fidelity in (("single", JointSearch(initial=10, rounds=2, per_round=4), None),
                                       ("multi", JointSearch(initial=10, rounds=2, per_round=2),
                                        JointFidelity(cheap=cheap))):
            r = calibrate_joint(targets, free, fix=fix, seeds=seeds, search=search, out=work / f"joint-{k + 1}-{kind}",
                                execution=exe, progress=False, fidelity=fidelity)
            res[kind] = r
            say({"calibration": f"joint-{kind}", "seeds": seeds, "best": r.best, "interval": r.interval,
                 "runs": r.runs, "wall_s": r.wall_time, "truth_in_region": r.in_region(TRUTH)})
        s, m = res["single"], res["multi"]
        lo, hi = m.interval["mur"]
        checks.append({"check": "multi's best in single's region", "seeds": seeds, "multi": m.best,
                       "passed": s.in_region(m.best)})
        say(checks[-1])
        checks.append({"check": "mu_r = 0.15 in multi's interval", "seeds": seeds, "interval": [lo, hi],
                       "passed": lo <= TRUTH["mur"] <= hi})
        say(checks[-1])
    return checks


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("which", choices=("pile", "joint"))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--work", type=Path, default=None)
    a = p.parse_args()
    work = a.work or Path(tempfile.mkdtemp(prefix="rollingdem-mfchecks-"))
    work.mkdir(parents=True, exist_ok=True)
    checks = (pile if a.which == "pile" else joint)(work, a.workers)
    (work / f"checks-{a.which}.json").write_text(json.dumps(checks, indent=2, default=float))
    sys.exit(0 if all(c["passed"] for c in checks) else 1)


if __name__ == "__main__":
    main()
