"""The seed report's single-sphere cases 0-2 for every rolling model, with tables, checks and figures.

Each function returns a :class:`~rollingdem.experiments.results.ValidationResult`; with ``outdir`` it also
writes its figures there. ``quick`` trims the grids (fewer angles, coarser bisection). ``runner``
maps the independent runs: the built-in ``map`` one after the other here,
:func:`rollingdem.studies.parallel.runner` side by side in worker processes.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from rollingdem.errors import ParameterError
from rollingdem.experiments.results import ValidationResult, Check, pyplot
from rollingdem.experiments.registry import UNBOUNDED, Experiment, Parameter, common_parameters, resolve_rolling
from rollingdem.experiments.single_sphere import CREEPING, DT, G, NO_THRESHOLD, SLOPE, VISCOUS_TAU, analytic_flat, analytic_flat_curve, analytic_slope, creep_speed, critical_rolling_friction, rolling_flat_run, rolling_slope_run, rolling_threshold_speed, single_thread, speed_down_incline, stop_time, validation_models, viscous_decay_time

ANGLES = (4, 8, 10, 15, 20, 25, 30, 35)
QUICK_ANGLES = (4, 20, 35)  # the angles of a quick run
# The report's Table 2 (LIGGGHTS, EPSD with eta_r = 0): critical mu_r per angle
REPORT_TABLE2 = {
    "cdt": (0.0688, 0.14, 0.17548, 0.26704, 0.36304, 0.46547, 0.576, 0.7),
    "epsd": (0.0688, 0.13948, 0.1752, 0.26688, 0.36288, 0.46521, 0.576, 0.7),
    "epsd2": (0.0688, 0.14, 0.17539, 0.26704, 0.36288, 0.46528, 0.576, 0.69904),
}
# LIGGGHTS 3.8 runs of the seed cases (docs/models.md §13 T2, T4)
LIGGGHTS_FLAT_EPSD = 0.18758
LIGGGHTS_CDT_CREEP = -4.0e-5


def _select(models):
    allm = validation_models()
    if models is None:
        return allm
    unknown = [m for m in models if m not in allm]
    if unknown:
        raise ParameterError(f"models = {unknown} are not known: allowed are {', '.join(allm)}")
    return {m: allm[m] for m in models}


@single_thread
def inclined_wall(models=None, angles=ANGLES, quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """Case 0: critical mu_r by bisection for every model and angle; Table 2 with the ratio to tan b.

    Check: mu_r,crit / tan(beta) within 0.5 % of 1 (the report's LIGGGHTS values are within 1.6 %).
    """
    tic = time.perf_counter()
    chosen = {k: v for k, v in _select(models).items() if k not in NO_THRESHOLD}
    if quick:
        angles = tuple(a for a in angles if a in QUICK_ANGLES) or angles[:1]
    rel_tol = 2e-3 if quick else 1e-3
    rows, checks = [], []
    items = [(beta, label) for beta in angles for label in chosen]

    def one(item):
        return critical_rolling_friction(chosen[item[1]], item[0], rel_tol=rel_tol)

    found = {}
    for item, mu_c in zip(items, runner(one, items)):
        found[item] = mu_c
        if progress:
            progress()
    for beta in angles:
        tan_b = math.tan(math.radians(beta))
        row = {"beta (deg)": beta, "tan(beta)": tan_b}
        for label in chosen:
            mu_c = found[beta, label]
            row[label] = mu_c
            row[f"{label} / tan"] = mu_c / tan_b
            checks.append(Check("inclined-wall", label, f"mu_r,crit / tan(beta) at {beta} deg", mu_c / tan_b, 1.0,
                                0.005, relative=False, source="theory: mu_r,crit = tan(beta)"))
        if beta in ANGLES:
            for label, values in REPORT_TABLE2.items():
                row[f"report {label}"] = values[ANGLES.index(beta)]
        rows.append(row)
    table = pd.DataFrame(rows)
    result = ValidationResult("inclined-wall", "Case 0: inclined wall, critical rolling friction (Table 2)", table, checks,
                        notes=[f"Bisection in tan(beta) x [0.95, 1.05] to a relative width {rel_tol:g}; a sphere "
                               "'rolls' when its mean speed over the last 0.1 s of a 0.3 s hold exceeds half of "
                               "what a sphere rolling from the end of the tilt would reach at that margin. "
                               "The viscous model has no static threshold and is left out."])
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(7, 4))
        for label in chosen:
            ax.plot(table["beta (deg)"], table[f"{label} / tan"], "o-", label=label, ms=4)
        ax.axhspan(0.995, 1.005, color="0.9", label="±0.5 %")
        ax.set_xlabel("wall inclination β (deg)")
        ax.set_ylabel("μr,crit / tan β")
        ax.legend(fontsize=7, ncol=2)
        ax.set_title("Inclined wall: critical rolling friction")
        result.add_figure(fig, outdir, "inclined_wall.png")
    result.wall_time = time.perf_counter() - tic
    return result


@single_thread
def rolling_flat(models=None, quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """Case 1: v0 = 1 m/s, omega0 = 0 on a flat. Checks: stop time and distance against the analytic
    0.50968 s / 0.18836 m within 0.5 % for CDT, the recommended EPSD and Force Proportional (the same
    torque on a still wall), 1 % for the other spring models; the LIGGGHTS-parity EPSD within 0.3 %
    of LIGGGHTS's 0.18758 m (its dashpot spike, docs/models.md §11.5); the viscous model's decay time
    tau = 1.4 R / (c_v g) within 1 % (docs/models.md §13 T5; it never stops)."""
    tic = time.perf_counter()
    t1, v1, t_ref, s_ref = analytic_flat()
    rows, checks, runs = [], [], {}
    chosen = _select(models)
    for label, traj in zip(chosen, runner(lambda m: rolling_flat_run(m, duration=0.8), chosen.values())):
        runs[label] = traj
        t_stop, dist = stop_time(traj), float(traj.x[-1])
        row = {"model": label, "stop time (s)": t_stop, "distance (m)": dist,
               "|v| after 0.7 s (m/s)": float(np.abs(traj.v[traj.t > 0.7]).max())}
        if label == "viscous":
            tau = viscous_decay_time(traj, t1 + 0.05, t1 + 0.5)
            row["decay time (s)"] = tau
            checks.append(Check("rolling-flat", label, "decay time tau (s)", tau, VISCOUS_TAU, 0.01,
                                source="theory: tau = 1.4 R / (c_v g)"))
        elif label == "epsd (liggghts)":
            checks.append(Check("rolling-flat", label, "distance (m)", dist, LIGGGHTS_FLAT_EPSD, 0.003,
                                source="LIGGGHTS 3.8 run (docs/models.md §13 T2)"))
        else:
            tol = 0.005 if label in ("cdt", "cdt (liggghts)", "epsd", "force_proportional") else 0.01
            checks.append(Check("rolling-flat", label, "stop time (s)", t_stop, t_ref, tol, source="analytic"))
            checks.append(Check("rolling-flat", label, "distance (m)", dist, s_ref, tol, source="analytic"))
        rows.append(row)
        if progress:
            progress()
    rows.append({"model": "analytic", "stop time (s)": t_ref, "distance (m)": s_ref})
    result = ValidationResult("rolling-flat", "Case 1: a sphere rolling on a flat (v0 = 1 m/s, ω0 = 0)",
                        pd.DataFrame(rows), checks,
                        notes=[f"Analytic: slip ends at t1 = {t1:.5f} s with v1 = {v1:.5f} m/s, then rolling "
                               f"deceleration (5/7) μr g = {5 / 7 * 0.2 * G:.5f} m/s²; stop at {t_ref:.5f} s after "
                               f"{s_ref:.5f} m. Stop time = first sample (0.1 ms grid) with v < 1 mm/s."])
    if outdir is not None:
        plt = pyplot()
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
        t = np.linspace(0, 0.8, 801)
        ax1.plot(t, analytic_flat_curve(t), "k--", lw=2, label="analytic")
        for label, traj in runs.items():
            ax1.plot(traj.t, traj.x, lw=1, label=label)
            ax2.plot(traj.t, traj.torque, lw=0.8, label=label)
        ax1.set_ylabel("rolling distance x (m)")
        ax1.legend(fontsize=7, ncol=2)
        ax2.set_ylabel("total torque M_y (N m)")
        ax2.set_xlabel("time after launch (s)")
        ax1.set_title("Case 1: rolling on a flat (report Figures 1-2)")
        result.add_figure(fig, outdir, "rolling_flat.png")
    result.wall_time = time.perf_counter() - tic
    return result


@single_thread
def rolling_slope(models=None, quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """Case 2: launched at 1 m/s up a 10 deg slope. Checks: x_max within 0.5 % of the analytic
    0.104204 m (not for the viscous model, which has no such bound); afterwards spring models hold
    (|creep| over the last second < 1e-7 m/s), CDT creeps back at LIGGGHTS's 4.0e-5 m/s (10 %), and
    with the STAR-CCM+ limiter f at g sin(theta) dt / (1.4 f) (2 %: a viscous clamp at low rates)."""
    tic = time.perf_counter()
    x_ref, t_ref = analytic_slope()
    rows, checks, runs = [], [], {}
    chosen = _select(models)
    for label, traj in zip(chosen, runner(lambda m: rolling_slope_run(m, duration=2.2), chosen.values())):
        runs[label] = traj
        k = int(np.argmax(traj.x))
        x_max, back, creep = float(traj.x[k]), float(traj.x[k] - traj.x[-1]), creep_speed(traj)
        rows.append({"model": label, "x_max (m)": x_max, "t at x_max (s)": float(traj.t[k]),
                     "back-roll (m)": back, "creep over last 1 s (m/s)": creep})
        if label != "viscous":
            checks.append(Check("rolling-slope", label, "x_max (m)", x_max, x_ref, 0.005, source="analytic"))
        if label == "cdt (limiter 0.08)":
            checks.append(Check("rolling-slope", label, "creep (m/s)", creep, -G * math.sin(SLOPE) * DT / (1.4 * 0.08),
                                0.02, source="theory: f I_r w / dt = m g R sin(theta)"))
        elif label in ("cdt", "cdt (liggghts)", "force_proportional"):
            checks.append(Check("rolling-slope", label, "creep (m/s)", creep, LIGGGHTS_CDT_CREEP, 0.1,
                                source="LIGGGHTS 3.8 CDT (docs/models.md §13 T4)"))
        elif label not in CREEPING:
            checks.append(Check("rolling-slope", label, "|creep| (m/s)", abs(creep), 1e-7, 0.0, bound="upper",
                                source="a spring holds the sphere"))
        if progress:
            progress()
    rows.append({"model": "analytic", "x_max (m)": x_ref, "t at x_max (s)": t_ref})
    result = ValidationResult("rolling-slope", "Case 2: a sphere rolling up a 10° slope", pd.DataFrame(rows), checks,
                        notes=["Back-roll = x_max - final x; creep = mean velocity over the last second (negative: "
                               "down the slope). The viscous model cannot hold a slope (docs/models.md §12)."])
    if outdir is not None:
        plt = pyplot()
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
        for label, traj in runs.items():
            ax1.plot(traj.t, traj.x, lw=1, label=label)
            sel = traj.t > 0.25
            ax2.plot(traj.t[sel], (traj.x[sel] - x_ref) * 1e3, lw=1, label=label)
        ax1.axhline(x_ref, color="k", ls="-.", lw=1, label="analytic x_max")
        ax1.set_ylim(-0.01, 0.12)  # the viscous model rolls away below
        ax1.set_xlabel("time after launch (s)")
        ax1.set_ylabel("x along the slope (m)")
        ax1.legend(fontsize=7, ncol=2)
        ax2.set_ylim(-1.0, 0.3)
        ax2.set_xlabel("time after launch (s)")
        ax2.set_ylabel("x - analytic x_max (mm)")
        ax2.set_title("zoom: back-roll and creep")
        ax1.set_title("Case 2: rolling up a 10° slope (report Figure 3)")
        result.add_figure(fig, outdir, "rolling_slope.png")
    result.wall_time = time.perf_counter() - tic
    return result


def sphere_material(p: dict) -> dict:
    """The single sphere's contact coefficients of an experiment's parameters."""
    return {"friction": p["mu"], "rolling_friction": p["mur"], "rolling_damping": p["eta_r"], "restitution": p["e"]}


class SingleSphere(Experiment):
    """What the single-sphere experiments share: ``validate`` runs every validation label of the
    rolling models, or those of ``models``."""

    model_keyword = "models"

    def models(self) -> list[str]:
        return list(validation_models())


class InclinedWall(SingleSphere):
    """Case 0 of the seed report: the inclination at which a sphere starts to roll."""

    name = "inclined-wall"
    description = "critical inclination for a given mu_r (report case 0)"
    parameters = (common_parameters(mur_range=(0.05, 0.7), mur_low_open=True)
                  + (Parameter("beta_low", 0.5, "lower end of the bisection bracket", "deg", low=0.0, low_open=True,
                               high=89.0),
                     Parameter("beta_high", 45.0, "upper end of the bisection bracket", "deg", low=0.0, low_open=True,
                               high=89.0),
                     Parameter("rel_tol", 2e-3, "bisection width, relative in tan(beta)", low=1e-5, high=0.1)))
    observables = {"critical_angle": "deg, theory atan(mu_r)"}
    default_observable = "critical_angle"
    targets = {"critical_angle": (0.0, 90.0)}
    sizes = {"quick": {"angles": QUICK_ANGLES, "rel_tol": 2e-3}, "full": {"angles": ANGLES, "rel_tol": 1e-3}}

    def observe(self, params: dict) -> dict:
        """The inclination (deg) at which the sphere starts to roll, by bisection over beta in
        [beta_low, beta_high] to a relative width ``rel_tol`` in tan(beta); NaN when it holds at
        beta_high or rolls at beta_low."""
        p = self.resolve(params)
        if p["beta_low"] >= p["beta_high"]:
            raise ParameterError(f"beta_low = {p['beta_low']} is not allowed: must be below beta_high = {p['beta_high']}")
        model, material = resolve_rolling(p["model"]), sphere_material(p)

        def rolls(beta):
            # the threshold of a quarter of rel_tol above critical keeps the classification bias below the bracket
            return (speed_down_incline(model, p["mur"], beta, material=material)
                    > rolling_threshold_speed(beta, 0.25 * p["rel_tol"]))

        lo, hi = p["beta_low"], p["beta_high"]
        if rolls(lo) or not rolls(hi):
            return {"critical_angle": math.nan}
        while math.tan(math.radians(hi)) - math.tan(math.radians(lo)) > p["rel_tol"] * math.tan(math.radians(lo)):
            mid = 0.5 * (lo + hi)
            if rolls(mid):
                hi = mid
            else:
                lo = mid
        return {"critical_angle": 0.5 * (lo + hi)}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return inclined_wall(models, quick=quick, outdir=outdir, progress=progress, runner=runner)


class RollingFlat(SingleSphere):
    """Case 1 of the seed report: a sphere launched on a flat wall rolls to rest."""

    name = "rolling-flat"
    description = "one Table-1 sphere launched at v0 on a flat (report case 1)"
    parameters = (common_parameters(mur_range=(0.05, 0.6), mur_low_open=True)
                  + (Parameter("v0", 1.0, "launch speed", "m/s", low=0.0, low_open=True, high=10.0),))
    observables = {"distance": "m, from launch to rest", "stop_time": "s, first sample below 1 mm/s"}
    default_observable = "distance"
    targets = {"distance": UNBOUNDED, "stop_time": UNBOUNDED}

    def observe(self, params: dict) -> dict:
        """Case 1 as a function: stop distance (m) and time (s) of a sphere launched at v0."""
        p = self.resolve(params)
        # record until 1.3x the analytic stop (at least 0.3 s after it): the sphere must be seen to stop
        t_stop = analytic_flat(p["v0"], p["mu"], p["mur"])[2]
        traj = rolling_flat_run(resolve_rolling(p["model"]), duration=1.3 * t_stop + 0.3, v0=p["v0"],
                                material=sphere_material(p))
        return {"distance": float(traj.x[-1]), "stop_time": stop_time(traj)}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return rolling_flat(models, quick=quick, outdir=outdir, progress=progress, runner=runner)


class RollingSlope(SingleSphere):
    """Case 2 of the seed report: a sphere launched up a slope stops, and holds or rolls back."""

    name = "rolling-slope"
    description = "one Table-1 sphere launched up a 10 deg slope (report case 2)"

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return rolling_slope(models, quick=quick, outdir=outdir, progress=progress, runner=runner)
