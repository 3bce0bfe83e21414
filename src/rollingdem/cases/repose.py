"""Pile cases: the seed report's angle of repose (case 3) and the PFC repose-angle study.

* :func:`angle_of_repose`: spheres settle in a cylinder on a plate, the cylinder is removed and
  the column collapses. Per model: total kinetic energy over time (log axis, the report's
  Figure 4), the final kinetic energy split into translation, rotation and spin about the
  vertical, and the pile's angle (:func:`rollingdem.analysis.repose_angle`). Without a twisting
  model, spheres left alone on the plate keep spinning about the vertical (LIGGGHTS does this);
  the same case with the Marshall twisting model shows the spin stopped.
* :func:`repose_sweep`: the PFC study: repose angle against mu_r for mu = 0.2 and 0.6, several
  seeds per point, mean with a 95 % Student-t confidence interval, and the iso-value map of the
  angle over the (mu, mu_r) grid.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from ..analysis import ReposeAngle, plot_pile, repose_angle
from ..contact.model import ContactModel
from ..errors import SimulationError
from ..insertion import CylinderRegion
from ..materials import Material
from ..simulation import Simulation
from ..walls import Cylinder, Plane
from .results import CaseResult, Check, pyplot
from .single_sphere import DT, RADIUS, TABLE1

TUBE_RADIUS_PER_1000 = 0.04  # m: the default case's tube, for 1000 spheres of R = 5 mm


@dataclass
class PileRun:
    """One collapse: kinetic energies (J) sampled after the tube is removed, and the final pile."""

    label: str
    t: np.ndarray
    translational: np.ndarray
    rotational: np.ndarray
    spin_vertical: np.ndarray
    positions: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    angle: ReposeAngle | None
    angle_error: str = ""


def pile_run(rolling="epsd", twisting="none", count=1000, friction=TABLE1["friction"],
             rolling_friction=TABLE1["rolling_friction"], seed=1, settle=0.6, collapse=2.0, sample=0.01,
             normal="hertz", label=None) -> PileRun:
    """The report's case 3 at ``count`` spheres (R = 5 mm, Table 1 material, dt = 1e-5 s).

    The tube radius scales with count^(1/2) from the default case's 0.04 m for 1000 spheres, so
    the column keeps its height (about 0.17 m settled) at every size.
    """
    tube = TUBE_RADIUS_PER_1000 * math.sqrt(count / 1000)
    sim = Simulation(contact=ContactModel(normal, rolling=rolling, twisting=twisting), dt=DT)
    sim.add_material(Material("m", **dict(TABLE1, friction=friction, rolling_friction=rolling_friction)))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m", name="plate"))
    wall = sim.add_wall(Cylinder(tube, material="m", name="tube"))
    sim.insert(CylinderRegion(tube, 0.0, 0.6), count, RADIUS, "m", seed=seed)
    sim.run(settle)
    sim.remove_wall(wall)
    n = int(round(collapse / sample))
    ke = np.empty((n, 4))
    inertia = 0.4 * sim.masses * sim.radii ** 2
    for k in range(n):
        sim.run(sample)
        trans, rot = sim.kinetic_energy()
        ke[k] = (sample * (k + 1), trans, rot, 0.5 * float(np.dot(inertia, sim.angular_velocities[:, 2] ** 2)))
    angle, error = None, ""
    try:
        angle = repose_angle(sim.positions, sim.radii, velocities=sim.velocities)
    except (SimulationError, ValueError) as err:  # not settled, or too flat to fit: say so
        error = str(err)
    return PileRun(label or str(rolling), ke[:, 0], ke[:, 1], ke[:, 2], ke[:, 3], sim.positions.copy(),
                   sim.radii.copy(), sim.velocities.copy(), angle, error)


REPOSE_MODELS = {"cdt": ("cdt", "none"), "epsd": ("epsd", "none"), "epsd2": ("epsd2", "none"),
                 "epsd + marshall twisting": ("epsd", "marshall")}


def angle_of_repose(quick=False, outdir=None, progress=None, count=None, models=None) -> CaseResult:
    """Case 3 for CDT, EPSD, EPSD2 and EPSD with twisting resistance.

    Checks (MODELS.md §11.6 and the report's Figure 4): EPSD's final kinetic energy is below 1e-3
    of CDT's (CDT chatters at rest, EPSD comes to rest to numerical accuracy); with a twisting
    model the final spin energy about the vertical is below 1 % of that without.
    """
    tic = time.perf_counter()
    count = count or (500 if quick else 5000)
    collapse = 1.5 if quick else 2.5
    chosen = {k: v for k, v in REPOSE_MODELS.items() if models is None or k in models}
    runs = {}
    for label, (rolling, twisting) in chosen.items():
        runs[label] = pile_run(rolling, twisting, count=count, collapse=collapse, label=label)
        if progress:
            progress()
    rows = []
    for label, r in runs.items():
        rows.append({"model": label, "final KE translational (J)": r.translational[-1],
                     "final KE rotational (J)": r.rotational[-1], "of which spin about z (J)": r.spin_vertical[-1],
                     "repose angle (deg)": r.angle.angle if r.angle else math.nan,
                     "slice mean ± sd (deg)": (f"{r.angle.slice_mean:.2f} ± {r.angle.slice_std:.2f}"
                                               if r.angle else r.angle_error[:80]),
                     "cone fit R²": r.angle.r_squared if r.angle else math.nan})
    checks = []
    if "cdt" in runs and "epsd" in runs:
        ke = {k: runs[k].translational[-1] + runs[k].rotational[-1] for k in ("cdt", "epsd")}
        checks.append(Check("angle-of-repose", "epsd", "final KE / CDT final KE", ke["epsd"] / ke["cdt"], 1e-3, 0.0,
                            bound="upper", source="report Figure 4: CDT keeps chattering, EPSD comes to rest"))
    if "epsd" in runs and "epsd + marshall twisting" in runs:
        ratio = runs["epsd + marshall twisting"].spin_vertical[-1] / max(runs["epsd"].spin_vertical[-1], 1e-300)
        checks.append(Check("angle-of-repose", "epsd + marshall twisting", "final spin energy / without twisting",
                            ratio, 1e-2, 0.0, bound="upper", source="twisting resistance stops the spin"))
    result = CaseResult("angle-of-repose", f"Case 3: angle of repose ({count} spheres)", pd.DataFrame(rows), checks,
                        notes=[f"{count} spheres of R = 5 mm settle 0.6 s in a tube of radius "
                               f"{TUBE_RADIUS_PER_1000 * math.sqrt(count / 1000):.3f} m; the tube is removed and the "
                               f"column collapses for {collapse} s. Spin about z: Σ ½ I ω_z²."])
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(8, 4.5))
        for label, r in runs.items():
            ax.semilogy(r.t, r.translational + r.rotational, label=label)
        ax.set_xlabel("time after the tube is removed (s)")
        ax.set_ylabel("total kinetic energy (J)")
        ax.set_title("Case 3: kinetic energy of the collapsing column (report Figure 4)")
        ax.legend()
        result.add_figure(fig, outdir, "angle_of_repose_ke.png")
        for label, r in runs.items():
            if r.angle is not None:
                path = Path(outdir) / f"pile_{label.replace(' ', '_').replace('+', 'and')}.png"
                fig = plot_pile(r.positions, r.radii, r.angle, path=path)
                result.figures.append(path)
    result.wall_time = time.perf_counter() - tic
    return result


def confidence_interval(values, level=0.95) -> tuple[float, float]:
    """(mean, half-width) of the Student-t confidence interval of the mean; half-width NaN for one value."""
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=float)
    if len(v) == 0:
        return math.nan, math.nan
    if len(v) < 2:
        return float(v.mean()), math.nan
    half = stats.t.ppf(0.5 + level / 2, len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v))
    return float(v.mean()), float(half)


def repose_sweep(quick=False, outdir=None, progress=None, model="rrlinear", frictions=None, rolling_frictions=None,
                 seeds=None, count=None, runner=map) -> CaseResult:
    """The PFC repose-angle study: angle against mu_r for each mu, seeds per point, 95 % intervals.

    ``runner`` maps a function over the grid points (the built-in ``map`` runs them here; a Dask
    client's map runs them on a cluster). Trend checks: the angle grows with mu (at every mu_r)
    and with mu_r (between the smallest and largest mu_r), and for mu = 0.2 it reaches a plateau
    once mu_r > mu (the last two points agree within their intervals plus 1 degree).
    """
    tic = time.perf_counter()
    frictions = frictions or (0.2, 0.6)
    rolling_frictions = rolling_frictions or ((0.05, 0.3, 0.8) if quick else (0.0, 0.05, 0.1, 0.2, 0.4, 0.6, 0.8, 1.0))
    seeds = seeds or ((1, 2) if quick else (1, 2, 3))
    count = count or (400 if quick else 2000)
    points = [(mu, mur, seed) for mu in frictions for mur in rolling_frictions for seed in seeds]
    collapse = 1.5 if quick else 2.5

    def one(point):
        mu, mur, seed = point
        run = pile_run(model, count=count, friction=mu, rolling_friction=mur, seed=seed, collapse=collapse,
                       sample=0.05)
        return run.angle.angle if run.angle else math.nan

    angles = []
    for a in runner(one, points):
        angles.append(a)
        if progress:
            progress()
    raw = pd.DataFrame(points, columns=["mu", "mu_r", "seed"]).assign(angle=angles)
    rows = []
    for (mu, mur), grp in raw.groupby(["mu", "mu_r"]):
        mean, half = confidence_interval(grp["angle"])
        rows.append({"mu": mu, "mu_r": mur, "angle mean (deg)": mean, "95 % CI ± (deg)": half,
                     "seeds": len(grp), "measured": int(grp["angle"].notna().sum())})
    table = pd.DataFrame(rows)
    checks = []
    pivot = table.pivot(index="mu_r", columns="mu", values="angle mean (deg)")
    if len(frictions) >= 2:
        lo, hi = min(frictions), max(frictions)
        checks.append(Check("repose-sweep", model, f"angle(mu={hi}) - angle(mu={lo}), smallest over mu_r (deg)",
                            float((pivot[hi] - pivot[lo]).min()), 0.0, 0.0, bound="lower",
                            source="trend: the angle grows with mu"))
    for mu in frictions:
        checks.append(Check("repose-sweep", model, f"angle(mu_r={pivot.index[-1]}) - angle(mu_r={pivot.index[0]}) "
                            f"at mu={mu} (deg)", float(pivot[mu].iloc[-1] - pivot[mu].iloc[0]), 0.0, 0.0,
                            bound="lower", source="trend: the angle grows with mu_r"))
    mu = min(frictions)
    above = table[(table["mu"] == mu) & (table["mu_r"] > mu)]
    if len(above) >= 2:
        # plateau: beyond mu_r = mu the points agree within their intervals plus 1 degree
        spread = float(above["angle mean (deg)"].max() - above["angle mean (deg)"].min())
        allowed = 1.0 + float(np.nan_to_num(above["95 % CI ± (deg)"]).max())
        checks.append(Check("repose-sweep", model, f"spread of the angle for mu_r > mu = {mu} (deg)", spread,
                            allowed, 0.0, bound="upper", source="PFC: a plateau once mu_r exceeds mu"))
    result = CaseResult("repose-sweep", f"PFC study: repose angle against μr ({count} spheres, {len(seeds)} seeds)",
                        table, checks,
                        notes=[f"Model {model!r}; {len(points)} runs; each point is the mean over seeds with a 95 % "
                               "Student-t confidence interval (scipy.stats.t)."])
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
