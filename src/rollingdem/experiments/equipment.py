"""The calibration experiments in ``rollingdem validate``: rotating drum, silo discharge, rough-base pile.

Each function runs its case of :mod:`rollingdem.experiments.observables` at several points (and seeds)
through ``runner`` and checks what physics says must hold: the drum's angle grows with mu and mu_r
and keeps at one Froude number when g changes; the silo follows Beverloo's law; the pile on a rough
base forms without rolling resistance and steepens with mu and mu_r. The checks and their
sources: docs/studies.md, "The experiments in rollingdem validate".
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.analysis.intervals import confidence_interval
from rollingdem.experiments.observables import CASES
from rollingdem.experiments.results import CaseResult, Check, pyplot


def _run_all(case: str, points: list[dict], seeds, runner, progress) -> pd.DataFrame:
    """Every point at every seed through ``runner``: one row per run (parameters and observables)."""
    items = [dict(p, seed=s) for p in points for s in seeds]
    run = CASES[case].run
    rows = []
    for params, observables in zip(items, runner(run, items)):
        rows.append({**params, **observables})
        if progress:
            progress()
    return pd.DataFrame(rows)


def _mean_ci(runs: pd.DataFrame, keys: list[str], value: str, within: str | None = None) -> pd.DataFrame:
    """Mean of ``value`` over seeds per point with its 95 % Student-t half-width; with one seed,
    the run's own interval ``within`` (if given)."""
    rows = []
    for point, grp in runs.groupby(keys, sort=True):
        point = point if isinstance(point, tuple) else (point,)
        mean, half = confidence_interval(grp[value])
        if len(grp) == 1 and within is not None:
            half = float(grp[within].iloc[0])
        rows.append({**dict(zip(keys, point)), f"{value} mean": mean, f"{value} 95% CI": half, "runs": len(grp)})
    return pd.DataFrame(rows)


def _rises(case, label, table, key, fixed, value="angle") -> Check:
    """Check that ``value`` grows along ``key`` with the other parameters at ``fixed``: the smallest
    step between successive means must be positive."""
    sel = table
    for k, v in fixed.items():
        sel = sel[np.isclose(sel[k], v)]
    sel = sel.sort_values(key)
    steps = np.diff(sel[f"{value} mean"].to_numpy())
    where = ", ".join(f"{k} = {v:g}" for k, v in fixed.items())
    return Check(case, label, f"smallest rise of the {value} between successive {key} "
                 f"({', '.join(f'{x:g}' for x in sel[key])}) at {where} (deg)",
                 float(steps.min()) if len(steps) else math.nan, 0.0, 0.0, bound="lower",
                 source=f"physics: more {key}, more resistance to flow, a steeper surface")


# --- rotating drum ---------------------------------------------------------------------------------
DRUM_QUICK = {"samples": 12, "spin_up": 60.0, "measure": 60.0}


def rotating_drum(quick=False, outdir=None, progress=None, runner=map, model="epsd") -> CaseResult:
    """The drum at mu_r = 0.05, 0.2, 0.4 (mu = 0.5) and mu = 0.3, 0.5, 0.8 (mu_r = 0.2), and at the
    base point with g four times larger at the same Froude number; 1 seed quick (a shorter run), 3
    full. Checks: the angle rises with mu_r and with mu; at one Froude number the angle does not
    change with g (within the 95 % interval of the difference); below the flowing layer, in the
    middle third of the arc along which the bed touches the wall, the spheres touching the wall
    move at omega r within 2 %."""
    tic = time.perf_counter()
    base = {"model": model, "mu": 0.5, "mur": 0.2, "gravity": 9.81, **(DRUM_QUICK if quick else {})}
    points = [dict(base, mur=m) for m in (0.05, 0.2, 0.4)] + [dict(base, mu=m) for m in (0.3, 0.8)]
    points.append(dict(base, gravity=4 * 9.81))
    seeds = [1] if quick else [1, 2, 3]
    runs = _run_all("rotating-drum", points, seeds, runner, progress)
    keys = ["mu", "mur", "gravity"]
    table = _mean_ci(runs, keys, "angle", within="angle_ci")
    for col in ("com_angle", "torque", "flowing_depth", "passive_speed_ratio", "wall_layer_speed_ratio", "omega"):
        table[col] = runs.groupby(keys, sort=True)[col].mean().to_numpy()
    g0 = table[np.isclose(table["gravity"], 9.81)]
    checks = [_rises("rotating-drum", model, g0, "mur", {"mu": 0.5}),
              _rises("rotating-drum", model, g0, "mu", {"mur": 0.2})]
    at = table[np.isclose(table["mu"], 0.5) & np.isclose(table["mur"], 0.2)].set_index("gravity")
    low, high = at.loc[at.index.min()], at.loc[at.index.max()]
    checks.append(Check("rotating-drum", model, "angle(4 g) - angle(g) at the same Froude number (deg)",
                        high["angle mean"] - low["angle mean"], 0.0,
                        math.hypot(high["angle 95% CI"], low["angle 95% CI"]), relative=False,
                        source="Froude scaling: in the rolling regime the angle depends on g only through Fr; "
                               "tolerance: the 95 % interval of the difference"))
    checks.append(Check("rotating-drum", model, "wall layer's speed / omega r below the flowing layer, middle third "
                        "of the arc", low["wall_layer_speed_ratio"], 1.0, 0.02,
                        source="the passive zone turns with the drum where it touches the wall (off the arc's ends "
                               "and the wall, the thin bed creeps: docs/studies.md)"))
    result = CaseResult("rotating-drum", f"Rotating drum ({model}, {len(seeds)} seed{'s' * (len(seeds) > 1)}"
                        f"{', quick' if quick else ''})", table, checks,
                        notes=[f"A periodic slice of a drum 15 d in radius, 30 % full, at Fr = 5e-3 "
                               f"({int(runs['particles'].iloc[0])} spheres, R = 5 mm ± 20 %, E = 5 MPa); the angle "
                               "is the line fit of the free surface's middle third, its interval over seeds (one "
                               "seed: over blocks of samples). docs/studies.md, \"The rotating drum\"."])
    if outdir is not None:
        plt = pyplot()
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        for ax, key, fixed in ((axes[0], "mur", ("mu", 0.5)), (axes[1], "mu", ("mur", 0.2))):
            ax.set_prop_cycle(color=plt.get_cmap("tab10").colors)
            sel = g0[np.isclose(g0[fixed[0]], fixed[1])].sort_values(key)
            ax.errorbar(sel[key], sel["angle mean"], yerr=sel["angle 95% CI"], fmt="o-", capsize=3, label="surface")
            ax.plot(sel[key], sel["com_angle"], "s--", label="centre of mass")
            ax.set_xlabel(key)
            ax.set_ylabel("dynamic angle of repose (deg)")
            ax.set_title(f"{fixed[0]} = {fixed[1]}")
            ax.legend(fontsize=8)
        result.add_figure(fig, outdir, "rotating_drum.png")
    result.wall_time = time.perf_counter() - tic
    return result


# --- silo discharge --------------------------------------------------------------------------------
#: orifices D0 (d), from 5 d: below about 4.9 d a silo of spheres clogs after avalanches of finite
#: mean size (Zuriguel et al. 2005), so a run may stop before W is measured; the silo's diameter
#: max(2.5 D0, D0 + ``gap``) d; the fill height (d), held; the spheres measured per run. The full
#: sizes keep 30 d of wall gap; the quick silo keeps 2.5 D0 but only 10 d
SILO_QUICK = {"orifices": (5.0, 6.0, 7.0, 8.0), "gap": 10.0, "fill": 12.0, "measured": 1000}
SILO_FULL = {"orifices": (5.0, 6.25, 7.5, 8.75, 10.0), "gap": 30.0, "fill": 20.0, "measured": 2000}
#: the validation's material: a glass-bead-like friction (Beverloo's C and k ranges are for glass
#: beads and sand)
SILO_MATERIAL = {"mu": 0.5, "mur": 0.1}


def silo_discharge(quick=False, outdir=None, progress=None, runner=map, model="epsd") -> CaseResult:
    """The silo at 4 (quick) or 5 orifice sizes from 5 d to 8 or 10 d, one seed each, at a steady
    head; the smallest orifice again at half the fill height. Checks: Beverloo's law with the
    exponent 5/2 fits with k between 1 and 3 and C between 0.45 and 0.75 (the range of measured
    and simulated glass beads and sand); 5/2 lies within the 95 % interval of the exponent fitted
    freely; W at half the fill height equals W at the full within 5 % (or the 95 % interval of
    their ratio, if wider): it does not depend on the fill height."""
    from scipy import stats

    from rollingdem.experiments.silo import BLOCKS, beverloo_exponent_interval, beverloo_fit

    tic = time.perf_counter()
    sizes = SILO_QUICK if quick else SILO_FULL

    def point(d0, fill):
        return {"model": model, **SILO_MATERIAL, "orifice_diameters": d0, "measured": sizes["measured"],
                "silo_diameters": max(2.5 * d0, d0 + sizes["gap"]), "fill_diameters": fill}

    points = [point(d0, sizes["fill"]) for d0 in sizes["orifices"]]
    points.append(point(sizes["orifices"][0], 0.5 * sizes["fill"]))
    runs = _run_all("silo-discharge", points, [1], runner, progress)
    table = runs[["orifice_diameters", "silo_diameters", "fill_diameters", "orifice", "particles", "flow_rate",
                  "flow_rate_ci", "flow_rate_first", "flow_rate_second", "bulk_density", "orifice_density",
                  "clogged"]].copy()
    full = table[np.isclose(table["fill_diameters"], sizes["fill"])]
    ok = full[np.isfinite(full["flow_rate"])]
    d = 2 * CASES["silo-discharge"].by_name["radius"].default
    rho_b = float(ok["bulk_density"].mean()) if len(ok) else math.nan
    checks = []
    # a rate's standard error: its 95 % half-width over the sub-windows / t(0.975, blocks - 1)
    errors = ok["flow_rate_ci"] / stats.t.ppf(0.975, BLOCKS - 1)
    if len(ok) >= 4 and np.all(errors > 0):
        c, k, _ = beverloo_fit(ok["orifice"], ok["flow_rate"], rho_b, d, exponent=2.5, errors=errors)
        _, _, n = beverloo_fit(ok["orifice"], ok["flow_rate"], rho_b, d, errors=errors)
        n_lo, n_hi = beverloo_exponent_interval(ok["orifice"], ok["flow_rate"], errors, rho_b, d)
    else:
        c = k = n = n_lo = n_hi = math.nan
    checks += [Check("silo-discharge", model, "Beverloo k (exponent 5/2)", k, 2.0, 1.0, relative=False,
                     source="Beverloo et al. (1961), Nedderman (1992): k from 1 to 3"),
               Check("silo-discharge", model, "Beverloo C (exponent 5/2)", c, 0.6, 0.15, relative=False,
                     source="Beverloo et al. (1961), Nedderman (1992): C from 0.45 to 0.75"),
               Check("silo-discharge", model, f"exponent of (D0 - k d), fitted freely, 95 % interval "
                     f"[{n_lo:.2f}, {n_hi:.2f}]", n, 2.5, (n - n_lo) if n > 2.5 else (n_hi - n), relative=False,
                     source="Beverloo: W ~ (D0 - k d)^(5/2), dimensional analysis; tolerance: 5/2 within "
                            "the fitted exponent's 95 % interval")]
    at = table[np.isclose(table["orifice_diameters"], sizes["orifices"][0])].set_index("fill_diameters")
    high, low = at.loc[sizes["fill"]], at.loc[0.5 * sizes["fill"]]
    ratio = low["flow_rate"] / high["flow_rate"]
    spread = ratio * math.hypot(low["flow_rate_ci"] / low["flow_rate"], high["flow_rate_ci"] / high["flow_rate"])
    checks.append(Check("silo-discharge", model, f"W(fill {0.5 * sizes['fill']:g} d) / W(fill {sizes['fill']:g} d) "
                        f"at D0 = {sizes['orifices'][0]:g} d", ratio, 1.0,
                        max(0.05, spread) if math.isfinite(spread) else 0.05,
                        source="the flow rate does not depend on the fill height (Janssen); tolerance 5 % or "
                               "the 95 % interval of the ratio, if wider"))
    result = CaseResult("silo-discharge", f"Silo discharge ({model}{', quick' if quick else ''})", table, checks,
                        notes=[f"mu = {SILO_MATERIAL['mu']}, mu_r = {SILO_MATERIAL['mur']}; silos max(2.5 D0, D0 + "
                               f"{sizes['gap']:g} d) wide, filled {sizes['fill']:g} d high and held there (the "
                               f"spheres out are put back on top); W over {sizes['measured']} spheres out. Beverloo "
                               f"fit over {len(ok)} orifices with rho_b = {rho_b:.1f} kg/m^3 (the settled beds'): "
                               f"C = {c:.3f}, k = {k:.2f} (exponent 5/2), weighted by the rates' errors; exponent fitted "
                               f"freely {n:.2f}, 95 % interval [{n_lo:.2f}, {n_hi:.2f}]. "
                               "docs/studies.md, \"Silo discharge\"."])
    if outdir is not None and len(ok):
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.set_prop_cycle(color=plt.get_cmap("tab10").colors)
        ax.errorbar(ok["orifice_diameters"], ok["flow_rate"], yerr=ok["flow_rate_ci"], fmt="o", capsize=3,
                    label="simulated W, 95 % interval")
        x = np.linspace(ok["orifice"].min(), ok["orifice"].max(), 50)
        if math.isfinite(c):
            ax.plot(x / d, c * rho_b * math.sqrt(9.81) * np.maximum(x - k * d, 0) ** 2.5, "-",
                    label=f"Beverloo, C = {c:.2f}, k = {k:.2f}")
        ax.errorbar([low["orifice"] / d], [low["flow_rate"]], yerr=[low["flow_rate_ci"]], fmt="s", capsize=3,
                    label=f"fill {0.5 * sizes['fill']:g} d")
        ax.set_xlabel("orifice diameter D0 / d")
        ax.set_ylabel("mass flow rate W (kg/s)")
        ax.legend(fontsize=8)
        result.add_figure(fig, outdir, "silo_discharge.png")
    result.wall_time = time.perf_counter() - tic
    return result


# --- repose on a rough base ------------------------------------------------------------------------
def repose_rough_base(quick=False, outdir=None, progress=None, runner=map, model="epsd") -> CaseResult:
    """The lifted-cylinder pile on a rough base at mu = 0.2 and 0.6 and mu_r = 0, 0.1, 0.3, over 3
    seeds (1,000 spheres quick, 4,000 full). Checks: a pile forms at mu_r = 0 (on the bare plate
    the spheres roll away); the mean angle rises with mu_r at each mu and with mu at each mu_r.
    With the smooth-plate sweep (``--case repose-sweep``) in the same folder, the figure puts its
    angles beside these."""
    tic = time.perf_counter()
    count = 1000 if quick else 4000
    points = [{"model": model, "mu": mu, "mur": mur, "count": count} for mu in (0.2, 0.6) for mur in (0.0, 0.1, 0.3)]
    runs = _run_all("repose-rough-base", points, [1, 2, 3], runner, progress)
    table = _mean_ci(runs, ["mu", "mur"], "angle")
    table["r_squared mean"] = runs.groupby(["mu", "mur"], sort=True)["r_squared"].mean().to_numpy()
    checks = []
    for mu in (0.2, 0.6):
        zero = runs[np.isclose(runs["mu"], mu) & (runs["mur"] == 0.0)]["angle"]
        checks.append(Check("repose-rough-base", model, f"smallest angle at mu_r = 0, mu = {mu} over 3 seeds (deg)",
                            float(zero.min()) if zero.notna().all() else math.nan, 5.0, 0.0, bound="lower",
                            source="PFC and LIGGGHTS: a rough base holds a pile without rolling resistance"))
        checks.append(_rises("repose-rough-base", model, table, "mur", {"mu": mu}))
    for mur in (0.0, 0.1, 0.3):
        checks.append(_rises("repose-rough-base", model, table, "mu", {"mur": mur}))
    result = CaseResult("repose-rough-base", f"Angle of repose on a rough base ({model}, {count} spheres)", table,
                        checks, notes=["The cylinder (about 6 d in radius for 2,000 spheres) is lifted at 0.1 m/s "
                                       "from a base of fixed spheres (R, spacing 2.2 R, jitter 0.1 R); mean over 3 "
                                       "seeds with the 95 % Student-t interval."])
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        ax.set_prop_cycle(color=plt.get_cmap("tab10").colors)  # distinct neighbours, unlike tab20's pairs
        for mu in (0.2, 0.6):
            sel = table[np.isclose(table["mu"], mu)]
            ax.errorbar(sel["mur"], sel["angle mean"], yerr=sel["angle 95% CI"], fmt="o-", capsize=3,
                        label=f"rough base, mu = {mu}")
        smooth = Path(outdir) / "repose-sweep.csv"
        if smooth.exists():
            s = pd.read_csv(smooth)
            for mu, grp in s.groupby("mu"):
                ax.errorbar(grp["mu_r"], grp["angle mean (deg)"], yerr=grp.get("95 % CI ± (deg)"), fmt="s--",
                            capsize=3, alpha=0.7, label=f"smooth plate (repose-sweep), mu = {mu}")
        ax.set_xlabel("mu_r")
        ax.set_ylabel("angle of repose (deg)")
        ax.legend(fontsize=7)
        result.add_figure(fig, outdir, "repose_rough_base.png")
    result.wall_time = time.perf_counter() - tic
    return result
