"""Time to a calibrated parameter, from empty caches, each calibration as a user runs it.

    python benchmarks/time_to_calibration.py pile [--fidelity single multi] [--share-settling] [--workers 2]
    python benchmarks/time_to_calibration.py joint [--fidelity single multi] [--share-settling] [--workers 2]

- ``pile``: mu_r against one pile angle, the repose-rough-base experiment at its quick size (1,000
  spheres), target 25 +- 0.5 deg, mu_r in [0, 0.6]; single fidelity and multi-fidelity (cheap
  runs of 400 spheres) in turn; with ``--share-settling`` each seed's column settles once.
- ``joint``: (mu, mu_r) in [0.3, 0.8] x [0.05, 0.35] against a pile angle (repose-rough-base, 1,000
  spheres, the cylinder removed at once) and a drum's angle (rotating-drum, 8 samples over 45
  degrees after 45), 2 seeds a point, 10 + 2 x 4 points: the slow test's calibration; multi-fidelity:
  14 cheap points (the pile at 400 spheres, the drum 10 diameters across), then 3 + 2 x 2 full-size
  points. Its targets
  are made at mu = 0.5, mu_r = 0.15, each the mean of 3 seeds the calibration does not use, with
  its 95 % half-width / 1.96 as the uncertainty; made once, before the timing, and kept in
  WORK/targets.json. With ``--share-settling`` each seed's pile column and drum bed settle once.

Each calibration runs ``rollingdem calibrate`` in a fresh process with its own empty engine-module
cache (so the compile counts), into a folder of its own under WORK (default a temporary folder),
and prints its wall time, the runs of each kind and the answer with its 95 % interval.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PILE = ["--experiment", "repose-rough-base", "--target", "25", "--uncertainty", "0.5", "--fix", "count=1000",
        "--free", "mur=0:0.6"]
PILE_FIX = {"count": 1000, "lift_speed": 0.0, "max_collapse": 2.0}
DRUM_FIX = {"samples": 8, "spin_up": 45.0, "measure": 45.0}
TRUTH = {"mu": 0.5, "mur": 0.15}


def joint_arguments(work: Path) -> list[str]:
    """The joint calibration's arguments, its targets made at ``TRUTH`` (once, kept in WORK)."""
    path = work / "targets.json"
    if not path.exists():
        from rollingdem.analysis.intervals import confidence_interval
        from rollingdem.experiments import EXPERIMENTS

        made = {}
        for case, fixed in (("repose-rough-base", PILE_FIX), ("rotating-drum", DRUM_FIX)):
            values = [EXPERIMENTS[case].observe({**fixed, **TRUTH, "seed": s})["angle"] for s in (101, 102, 103)]
            mean, half = confidence_interval(values)
            made[case] = (float(mean), float(half / 1.96))
        path.write_text(json.dumps(made))
    made = json.loads(path.read_text())
    args = []
    for case, (value, u) in made.items():
        args += ["--target", f"{case}.angle={value:.4f}±{u:.4f}"]
    for k, v in {**PILE_FIX, **DRUM_FIX}.items():
        args += ["--fix", f"{k}={v}"]
    return args + ["--free", "mu=0.3:0.8", "--free", "mur=0.05:0.35", "--seeds", "2", "--initial", "10", "--rounds",
                   "2", "--per-round", "4"]


def run(name: str, args: list[str], work: Path, workers: int) -> dict:
    out = work / name
    env = dict(os.environ, ROLLINGDEM_CACHE_DIR=str(work / f"{name}-kernels"))
    tic = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "calibrate", *args, "--out", str(out), "--workers",
                          str(workers), "--no-progress"], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - tic
    if res.returncode != 0:
        print(res.stdout, res.stderr, file=sys.stderr)
        raise SystemExit(f"{name}: rollingdem calibrate failed ({res.returncode})")
    saved = json.loads((out / "calibration.json").read_text())
    row = {"calibration": name, "wall_s": round(wall, 1), "runs": saved.get("runs", saved.get("points"))}
    if "value" in saved:
        row.update(value=saved["value"], low=saved["low"], high=saved["high"])
    else:
        row.update(best=saved["best"], interval=saved["interval"])
    if saved.get("settle_seconds_saved"):
        row.update(settle_seconds_saved=round(saved["settle_seconds_saved"], 1))
    if saved.get("fidelity"):
        f = saved["fidelity"]
        row.update(cheap=f["cheap"], cheap_runs=f["cheap_runs"], full_runs=f["full_runs"],
                   cheap_run_s=round(f["cheap_run_seconds"], 2), full_run_s=round(f["full_run_seconds"], 2))
        if "offset" in f:
            row.update(offset=round(f["offset"], 3))
    print(json.dumps(row), flush=True)
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("which", choices=("pile", "joint"))
    p.add_argument("--fidelity", nargs="+", default=["single", "multi"], choices=("single", "multi"))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--share-settling", action="store_true")
    p.add_argument("--work", type=Path, default=None)
    a = p.parse_args()
    work = a.work or Path(tempfile.mkdtemp(prefix="rollingdem-ttc-"))
    work.mkdir(parents=True, exist_ok=True)
    if a.which == "pile":
        shared = ["--share-settling"] if a.share_settling else []
        for f in a.fidelity:
            run(f"pile-{f}{'-shared' if shared else ''}", PILE + ["--fidelity", f] + shared, work, a.workers)
    else:
        args = joint_arguments(work)
        shared = ["--share-settling"] if a.share_settling else []
        for f in a.fidelity:  # multi: its full-size rounds of 2 points (3 + 2 x 2 full-size points in all)
            run(f"joint-{f}{'-shared' if shared else ''}",
                args + ["--fidelity", f] + (["--per-round", "2"] if f == "multi" else []) + shared, work, a.workers)


if __name__ == "__main__":
    main()
