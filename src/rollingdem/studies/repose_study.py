"""The PFC repose-angle study: the angle-of-repose pile swept over (mu, mu_r) and seeds.

:func:`repose_sweep` runs the pile of :mod:`rollingdem.experiments.repose` through the sweep machinery
(:func:`rollingdem.studies.sweep.run_sweep`, experiment ``angle-of-repose``), reruns piles still creeping, and
reports the angle against mu_r for each mu (mean over seeds with a 95 % Student-t interval) and its
iso-value map; :func:`sweep_checks` holds its trend checks. It sits above :mod:`rollingdem.studies.sweep`:
the experiments below never import the sweep.
"""

from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.experiments.pile import POLYDISPERSITY
from rollingdem.experiments.results import ValidationResult, Check, pyplot
from rollingdem.analysis.intervals import confidence_interval
from rollingdem.studies.sweep import SweepSpec, run_sweep

QUICK_SWEEP, FULL_SWEEP = 2000, 10000  # spheres per run of the PFC study
RETRY_COLLAPSE = 2.0  # a sweep pile not settled by max_collapse runs again to this many times it
SWEEP_LIFT_SPEED = 0.2  # m/s, the tube in the PFC study
SWEEP_YOUNGS_MODULUS = 5e6  # Pa: softer than Table 1, for a 2.5x larger time step (see repose_sweep)
SWEEP_DT = 2.5e-5  # s


def sweep_checks(table: pd.DataFrame, frictions, model: str) -> tuple[list[Check], pd.DataFrame]:
    """The PFC study's trend checks on the per-point table (mu, mu_r, angle mean, 95 % CI): the angle
    grows with mu and with mu_r, and for each mu reaches a plateau once mu_r > mu. Points without an
    angle (a pile that did not settle or was too flat) are left out; a check with nothing to compare
    fails. Returns the checks and the (mu_r x mu) table of mean angles."""
    checks = []
    pivot = table.pivot(index="mu_r", columns="mu", values="angle mean (deg)")
    if len(frictions) >= 2:
        lo, hi = min(frictions), max(frictions)
        # averaged over mu_r (at small mu_r the spheres roll and mu matters less than the seed scatter),
        # over those where both piles have an angle: without rolling resistance a pile may not settle
        # (its spheres roll away); none leaves NaN, a failed check
        diff = (pivot[hi] - pivot[lo]).dropna()
        checks.append(Check("repose-sweep", model, f"angle(mu={hi}) - angle(mu={lo}), mean over the {len(diff)} "
                            "mu_r with both measured (deg)", float(diff.mean()) if len(diff) else math.nan, 0.0, 0.0,
                            bound="lower", source="PFC: the angle grows with mu"))
    for mu in frictions:
        measured = pivot[mu].dropna()
        first, last = (measured.index[0], measured.index[-1]) if len(measured) >= 2 else (math.nan, math.nan)
        checks.append(Check("repose-sweep", model, f"angle(mu_r={last}) - angle(mu_r={first}) at mu={mu}, the "
                            "largest and smallest mu_r with an angle (deg)",
                            float(measured.iloc[-1] - measured.iloc[0]) if len(measured) >= 2 else math.nan, 0.0, 0.0,
                            bound="lower", source="PFC: the angle grows with mu_r"))
    for mu in frictions:
        above = table[(table["mu"] == mu) & (table["mu_r"] > mu)]
        if len(above) >= 2:
            # plateau: beyond mu_r = mu the points agree within their intervals plus 1 degree
            angle = above["angle mean (deg)"]
            spread = float(angle.max(skipna=False) - angle.min(skipna=False))
            allowed = 1.0 + float(np.nan_to_num(above["95 % CI ± (deg)"]).max())
            checks.append(Check("repose-sweep", model, f"spread of the angle for mu_r > mu = {mu} (deg)", spread,
                                allowed, 0.0, bound="upper", source="PFC: a plateau once mu_r exceeds mu"))
    return checks, pivot


def repose_sweep(quick=False, outdir=None, progress=None, model="rrlinear", frictions=None, rolling_frictions=None,
                 seeds=None, count=None, lift_speed=SWEEP_LIFT_SPEED, runner=map) -> ValidationResult:
    """The PFC repose-angle study: angle against mu_r for each mu, seeds per point, 95 % intervals.

    As in the PFC example the tube is lifted (``lift_speed``, m/s). The runs go through
    :func:`rollingdem.studies.sweep.run_sweep` (experiment ``angle-of-repose``) into ``outdir/repose-sweep-runs``,
    so a rerun with the same ``outdir`` skips the runs already finished; ``runner`` maps them (the
    built-in ``map`` here; :func:`rollingdem.studies.parallel.runner` side by side or on a Dask cluster). Trend checks: the angle grows with mu (at every mu_r) and
    with mu_r (between the smallest and largest mu_r), and for the smaller mu it reaches a plateau
    once mu_r > mu (those points agree within their intervals plus 1 degree).
    """
    tic = time.perf_counter()
    frictions = frictions or ((0.4, 0.8) if quick else (0.2, 0.6))
    rolling_frictions = rolling_frictions or ((0.2, 0.8) if quick else (0.0, 0.05, 0.1, 0.2, 0.4, 0.6, 0.8, 1.0))
    seeds = seeds or ((1, 2) if quick else (1, 2, 3))
    count = count or (QUICK_SWEEP if quick else FULL_SWEEP)
    max_collapse = 2.6 if quick else 3.5
    spec = SweepSpec(experiment="angle-of-repose", grid={"mu": list(frictions), "mur": list(rolling_frictions)},
                     seeds=list(seeds), fixed={"model": model, "count": count, "lift_speed": lift_speed,
                                               "youngs_modulus": SWEEP_YOUNGS_MODULUS, "dt": SWEEP_DT,
                                               "max_collapse": max_collapse})
    # the runs table of rollingdem.studies.sweep: rerunning the study with the same outdir skips finished runs
    where = Path(outdir) / "repose-sweep-runs" if outdir is not None else Path(tempfile.mkdtemp(prefix="repose-"))
    swept = run_sweep(spec, where, mapper=runner, progress=False, summary=False, on_run=progress)
    table, retried = swept.table, 0
    # A pile still creeping at max_collapse (high mu and mu_r creep longest) is run again from its
    # start to RETRY_COLLAPSE times that: the same trajectory, continued (a pile that settled stops
    # there, so a longer limit would change no other run). Without rolling resistance the spheres
    # roll away over the plate and never settle: those are not run again.
    creeping = table[(table["status"] == "ok") & table["settled_at"].isna() & (table["mur"] > 0)]
    for (mu, mur), grp in creeping.groupby(["mu", "mur"]):
        again = SweepSpec(experiment=spec.experiment, grid={"mu": [mu], "mur": [mur]}, seeds=sorted(int(x) for x in grp["seed"]),
                          fixed=dict(spec.fixed, max_collapse=RETRY_COLLAPSE * max_collapse))
        redone = run_sweep(again, where, mapper=runner, progress=False, summary=False, on_run=progress).table
        table = pd.concat([table.drop(grp.index), redone], ignore_index=True)
        retried += len(grp)
    raw = table.rename(columns={"mur": "mu_r", "angle": "angle (deg)", "slice_std": "slice sd (deg)",
                                      "r_squared": "cone fit R²", "settled_at": "settled at (s)",
                                      "wall_time_s": "wall time (s)"})
    raw = raw[["mu", "mu_r", "seed", "angle (deg)", "slice sd (deg)", "cone fit R²", "settled at (s)",
               "wall time (s)", "status", "note", "error"]].sort_values(["mu", "mu_r", "seed"])
    points = list(zip(raw["mu"], raw["mu_r"], raw["seed"]))
    rows = []
    for (mu, mur), grp in raw.groupby(["mu", "mu_r"]):
        mean, half = confidence_interval(grp["angle (deg)"])
        rows.append({"mu": mu, "mu_r": mur, "angle mean (deg)": mean, "95 % CI ± (deg)": half,
                     "seeds": len(grp), "measured": int(grp["angle (deg)"].notna().sum())})
    table = pd.DataFrame(rows)
    checks, pivot = sweep_checks(table, frictions, model)
    notes = [f"Model {model!r}, {count} spheres of R = 5 mm ± {POLYDISPERSITY:.0%} per run, {len(points)} runs; "
             "each point is the mean over seeds with a 95 % Student-t confidence interval (scipy.stats.t). "
             f"As in the PFC example the tube is lifted, at {lift_speed} m/s. Table 1 material but E = "
             f"{SWEEP_YOUNGS_MODULUS / 1e6:g} MPa, dt = {SWEEP_DT:g} s: the angle of a pile of non-cohesive "
             "spheres does not depend on their stiffness while overlaps stay small (here below 1 % of d at rest), "
             "and the softer spheres allow a 2.5x larger time step. One row per run: repose_sweep_runs.csv; the sweep "
             "table repose-sweep-runs/runs.csv lets a rerun on the same folder skip the piles already done."]
    compute = float(np.nansum(raw["wall time (s)"]))
    if compute > 0:
        notes.append(f"The {len(raw)} piles of the table took {compute / 3600:.2f} h of compute (the sum of their "
                     "wall times); the study's wall time is that of this invocation, which skips the piles "
                     "already in the table.")
    if retried:
        notes.append(f"{retried} pile(s) with rolling resistance had not settled after {max_collapse:g} s of collapse "
                     f"and were run again to {RETRY_COLLAPSE * max_collapse:g} s (see 'settled at').")
    if quick:
        notes.append(f"Quick: mu = 0.4 and 0.8 instead of the PFC's 0.2 and 0.6 and mu_r = 0.2 and 0.8, two seeds, "
                     f"so no plateau check. A pile of {count} spheres at mu = 0.2 or mu_r < 0.1 spreads to under four "
                     "diameters high, too flat to fit a cone; the full run uses 10,000 spheres and the PFC grid.")
    result = ValidationResult("repose-sweep", f"PFC study: repose angle against μr ({count} spheres, {len(seeds)} seeds)",
                        table, checks, notes=notes)
    if outdir is not None:
        raw.to_csv(Path(outdir) / "repose_sweep_runs.csv", index=False)
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 4.5))
        for mu in frictions:
            sub = table[table["mu"] == mu]
            ax.errorbar(sub["mu_r"], sub["angle mean (deg)"], yerr=sub["95 % CI ± (deg)"].fillna(0), marker="o",
                        capsize=3, label=f"μ = {mu}")
        ax.set_xlabel("rolling friction coefficient μr")
        ax.set_ylabel("repose angle (deg)")
        ax.set_title("Repose angle against μr (95 % Student-t intervals)")
        ax.legend()
        result.add_figure(fig, outdir, "repose_sweep.png")
        if len(frictions) >= 2 and len(rolling_frictions) >= 2:
            fig, ax = plt.subplots(figsize=(6.5, 5))
            grid = pivot.to_numpy()
            cs = ax.contourf(pivot.columns.to_numpy(), pivot.index.to_numpy(), grid, levels=12, cmap="viridis")
            lines = ax.contour(pivot.columns.to_numpy(), pivot.index.to_numpy(), grid, levels=6, colors="k",
                               linewidths=0.6)
            ax.clabel(lines, fmt="%.0f°", fontsize=8)
            fig.colorbar(cs, label="repose angle (deg)")
            ax.set_xlabel("sliding friction μ")
            ax.set_ylabel("rolling friction μr")
            ax.set_title("Iso-value map of the repose angle")
            result.add_figure(fig, outdir, "repose_isomap.png")
    result.wall_time = time.perf_counter() - tic
    return result
