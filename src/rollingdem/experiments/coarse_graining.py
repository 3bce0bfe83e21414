"""``coarse-graining``: parcels against the real particles they stand for (docs/models.md
§18, docs/studies.md "Coarse graining").

The same rig at coarse-graining factors alpha, each scene with the real particles' sizes and counts
and its spheres made parcels alpha times larger (``coarse_graining`` of ``repose-rough-base``,
``rotating-drum`` and ``silo-discharge``), at a time step alpha times the real one:

- the lifted-cylinder pile on a rough base at alpha = 1, 2, 3 and mu_r = 0.1, 0.4, mu_r kept
  dimensionless (the rule), and beside it the other convention, mu_r a length that does not grow
  with the parcel (rolling friction mu_r / alpha on the parcels);
- the rotating drum at alpha = 1, 2, 3 (the same drum at the same Froude number): its dynamic angle,
  and the particles represented per second of wall time;
- the silo at alpha = 1, 2 through an orifice of 6 parcel diameters or more: its mass flow rate,
  beside Beverloo's (D0 - k alpha d)^(5/2), which expects the parcels' empty annulus to slow it;
- one parcel of alpha = 3 on a slope: its critical mu_r against tan(beta) for every rolling model
  with a static threshold (the seed report's Table 2);
- beside each pile of parcels and the drum of alpha = 2, the real particles in the same scene
  alpha times smaller (as many particles as parcels, speeds set by gravity 1/sqrt(alpha) as large,
  Young's modulus 1/alpha): the parcels' scene obeys the same equations as it, made alpha times
  larger.

Each comparison is the difference of the means over seeds with Welch's 95 % interval.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.analysis.intervals import difference_interval
from rollingdem.experiments.drum import RotatingDrum
from rollingdem.experiments.pile import column_size, tube_clearing_time
from rollingdem.experiments.registry import BedExperiment, Parameter, resolve_rolling
from rollingdem.experiments.repose import ReposeRoughBase
from rollingdem.experiments.results import LAWS_REVISION, Check, ValidationResult, kept_run, pyplot
from rollingdem.experiments.silo import SiloDischarge
from rollingdem.experiments.single_sphere import NO_THRESHOLD, critical_rolling_friction, validation_models

CASE = "coarse-graining"
#: deg: the issue's bound on the parcels' pile and drum angles against the real particles'
ANGLE_TOLERANCE = 1.0
#: the issue's bound on the parcels' silo flow rate against the real particles' (relative)
FLOW_TOLERANCE = 0.05
#: Beverloo's k (the empty annulus, in particle diameters) for spheres (Beverloo et al. 1961: 1.4 ± 0.1)
BEVERLOO_K = 1.5
#: deg: the inclined wall's angles at which a parcel's critical mu_r is found (seed report, Table 2)
SLOPE_ANGLES = (10.0, 20.0)
#: s: how long the pile may come to rest once the lifted tube is clear of it
REST = 3.0
#: m and m/s: the pile's mean sphere radius and the tube's lift speed (``repose-rough-base``'s defaults)
PILE_RADIUS, LIFT_SPEED = 0.005, 0.1




def dt_of(alpha: float, dt: float) -> float:
    """The parcels' time step: alpha times the real particles' (every limit of §2 scales so)."""
    return alpha * dt


class CoarseGraining(BedExperiment):
    """The lifted-cylinder pile of parcels against the pile of the real particles."""

    name = "coarse-graining"
    description = ("parcels against the real particles: the pile on a rough base, the rotating drum and the silo at "
                   "coarse-graining factors 1-3 (docs/models.md §18)")
    parameters = (Parameter("model", "epsd", "rolling resistance model", choice="rolling"),
                  Parameter("mu", 0.5, "sliding friction coefficient", low=0.0, low_open=True),
                  Parameter("mur", 0.4, "rolling friction coefficient of the real particles", low=0.0),
                  Parameter("alpha", 1.0, "coarse-graining factor: parcels alpha times the real radius", low=1.0),
                  Parameter("length_convention", 0, "1: mu_r taken as a length that does not grow with the parcel "
                                                    "(the parcels' rolling friction mu_r / alpha); 0: the rule, mu_r "
                                                    "kept", low=0, high=1, integer=True),
                  Parameter("count", 2000, "real particles in the pile (alpha^3 to a parcel)", low=50, integer=True),
                  Parameter("seed", 1, "random seed (insertion, base)", low=0, integer=True),
                  Parameter("dt", 2.5e-5, "the real particles' time step; parcels take alpha times it", "s", low=0.0,
                            low_open=True))
    observables = {"angle": "deg, the pile's angle of repose", "r_squared": "the cone fit's R^2",
                   "parcels": "spheres simulated in the column", "wall_time": "s, the run's wall time"}
    default_observable = "angle"
    targets = {"angle": (0.0, 90.0)}
    sizes = {"quick": {"count": 4000, "alphas": (1.0, 2.0), "murs": (0.4,), "seeds": (1, 2),
                       "drum": {"alphas": (1.0, 2.0), "seeds": (1,), "drum_diameters": 15.0, "spin_up": 60.0,
                                "measure": 60.0, "samples": 12},
                       "silo": {"alphas": (1.0, 2.0), "seeds": (1,), "silo_diameters": 30.0, "fill_diameters": 12.0,
                                "measured": 1000},
                       "slope": {"models": ("epsd",), "angles": (20.0,)}},
             # at least 1,500 parcels at alpha = 3: 40,500 real particles
             "full": {"count": 40500, "alphas": (1.0, 2.0, 3.0), "murs": (0.1, 0.4), "seeds": (1, 2, 3),
                      # a drum 30 d in radius: 15 parcels of alpha 2 across its radius
                      "drum": {"alphas": (1.0, 2.0, 3.0), "seeds": (1, 2, 3), "drum_diameters": 30.0, "spin_up": 90.0,
                               "measure": 180.0, "samples": 30},
                      "silo": {"alphas": (1.0, 2.0), "seeds": (1, 2, 3), "silo_diameters": 30.0, "fill_diameters": 20.0,
                               "measured": 3000},
                      "slope": {"models": None, "angles": SLOPE_ANGLES}}}

    def observe(self, params: dict, checkpoint=None) -> dict:
        """The pile of ``repose-rough-base`` at ``count`` real particles made parcels of ``alpha``;
        resumable with ``checkpoint`` (``pile.pile_run``)."""
        p = self.resolve(params)
        mur = p["mur"] / p["alpha"] if p["length_convention"] else p["mur"]
        res = ReposeRoughBase().observe({"model": p["model"], "mu": p["mu"], "mur": mur, "count": p["count"],
                                         "seed": p["seed"], "coarse_graining": p["alpha"],
                                         "dt": dt_of(p["alpha"], p["dt"]),
                                         "max_collapse": lift_time(p["count"], p["alpha"]) + REST},
                                        checkpoint=checkpoint)
        return {"angle": res["angle"], "r_squared": res["r_squared"],
                "parcels": int(round(p["count"] / p["alpha"] ** 3)), "note": res["note"],
                "wall_time": res["wall_time"]}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        return coarse_graining_study(model, quick=quick, outdir=outdir, progress=progress, runner=runner)


def lift_time(count: int, alpha: float) -> float:
    """s: how long ``repose-rough-base``'s tube takes to rise clear of a column of ``count`` real
    particles on a base of parcels of ``alpha`` (``pile.tube_clearing_time``, clearance one real
    diameter): the pile's collapse may last that long and ``REST`` more."""
    _, height = column_size(count, PILE_RADIUS, 0.2)
    return tube_clearing_time(2.0 * alpha * PILE_RADIUS, height, PILE_RADIUS, 2.0 * PILE_RADIUS, LIFT_SPEED)


def drum_parameters(model: str, alpha: float, seed: int, size: dict) -> dict:
    """``rotating-drum``'s parameters for the study's drum of parcels of ``alpha`` (``size``: its
    ``drum`` entry): mu 0.5, mu_r 0.2, a slice 10 d long, dt alpha x 2.5e-5 s."""
    return {"model": model, "mu": 0.5, "mur": 0.2, "seed": seed, "coarse_graining": alpha, "slice_diameters": 10.0,
            "drum_diameters": size["drum_diameters"], "dt": dt_of(alpha, 2.5e-5), "spin_up": size["spin_up"],
            "measure": size["measure"], "samples": size["samples"]}


def drum_point(model: str, alpha: float, seed: int, size: dict) -> dict:
    """The rotating drum (``drum_diameters`` d in radius, a slice 10 d long: a parcel of alpha = 3 fits
    the periodic length) of parcels of ``alpha``, at the real particles' Froude number: its angle and
    the real particles it moves per second of wall time."""
    tic = time.perf_counter()
    res = RotatingDrum().observe(drum_parameters(model, alpha, seed, size))
    wall = time.perf_counter() - tic
    return {"angle": res["angle"], "angle_ci": res["angle_ci"], "particles": res["particles"],
            "parcels": int(round(res["particles"] / alpha ** 3)), "wall_time": wall}


def scaled_pile_point(model: str, alpha: float, mur: float, seed: int, count: int, checkpoint=None) -> dict:
    """The real particles in the study's pile of parcels of ``alpha`` (``count`` real particles),
    made alpha times smaller: count / alpha^3 of them (the tube, sized by the count, alpha times
    narrower), the tube lifted at LIFT_SPEED / sqrt(alpha) (gravity sets the speeds: the same
    Froude number) and Young's modulus E / alpha (the bed's weight is alpha times smaller: the same
    strain), at the real particles' time step. The parcels' pile obeys the same equations as this
    one made alpha times larger (docs/models.md §18)."""
    experiment = ReposeRoughBase()
    small = int(round(count / alpha ** 3))
    params = {"model": model, "mu": CoarseGraining().resolve({})["mu"], "mur": mur, "count": small, "seed": seed,
              "lift_speed": LIFT_SPEED / math.sqrt(alpha),
              "youngs_modulus": experiment.resolve({})["youngs_modulus"] / alpha, "dt": dt_of(1.0, 2.5e-5),
              "max_collapse": lift_time(count, alpha) / math.sqrt(alpha) + REST}
    res = experiment.observe(params, checkpoint=checkpoint)
    return {"angle": res["angle"], "r_squared": res["r_squared"], "parcels": small, "note": res["note"],
            "wall_time": res["wall_time"]}


def scaled_drum_point(model: str, alpha: float, seed: int, size: dict) -> dict:
    """The real particles in the study's drum of parcels of ``alpha``, made alpha times smaller: a
    drum and a slice alpha times fewer real diameters across (as many particles as parcels), at the
    same Froude number (``rotating-drum`` keeps it), Young's modulus E / alpha, the real particles'
    time step (``scaled_pile_point``)."""
    experiment = RotatingDrum()
    real = drum_parameters(model, 1.0, seed, size)
    params = dict(real, drum_diameters=real["drum_diameters"] / alpha, slice_diameters=real["slice_diameters"] / alpha,
                  youngs_modulus=experiment.resolve({})["youngs_modulus"] / alpha)
    tic = time.perf_counter()
    res = experiment.observe(params)
    return {"angle": res["angle"], "angle_ci": res["angle_ci"], "particles": res["particles"],
            "parcels": res["particles"], "wall_time": time.perf_counter() - tic}


def silo_point(model: str, alpha: float, seed: int, size: dict) -> dict:
    """The silo (orifice 12 d: 6 parcel diameters at alpha = 2) of parcels of ``alpha``: its flow rate."""
    res = SiloDischarge().observe({"model": model, **SiloDischarge.material, "seed": seed, "coarse_graining": alpha,
                                   "orifice_diameters": 12.0, "silo_diameters": size["silo_diameters"],
                                   "fill_diameters": size["fill_diameters"], "measured": size["measured"],
                                   "max_time": 30.0, "dt": dt_of(alpha, 2.5e-5)})
    return {"flow_rate": res["flow_rate"] if not res["clogged"] else math.nan, "flow_rate_ci": res["flow_rate_ci"],
            "particles": res["particles"]}


def slope_point(model: str, alpha: float, beta: float) -> dict:
    """One parcel of ``alpha`` on a wall tilted to ``beta``: the critical mu_r by bisection (seed
    report case 0, ``single_sphere.critical_rolling_friction``), tilted and held alpha times as long
    as the real sphere: its rolling spring's period is alpha times longer, and the tilt must stay as
    slow beside it (docs/models.md §18)."""
    return {"mur_critical": critical_rolling_friction(resolve_rolling(model), beta, rel_tol=1e-3,
                                                      material={"coarse_graining": alpha}, time_scale=alpha)}


def beverloo_ratio(orifice: float, alpha: float, k: float = BEVERLOO_K) -> float:
    """W(parcels) / W(real) by Beverloo's law, W ~ (D0 - k d)^(5/2), at the parcels' d = alpha times
    the real (``orifice`` in real diameters)."""
    return ((orifice - k * alpha) / (orifice - k)) ** 2.5


def coarse_graining_study(model="epsd", quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """Every scene of the size (``CoarseGraining.sizes``) through ``runner``, compared with the
    real particles' (module docstring); with ``outdir``, each run's observables are kept in
    ``outdir/coarse-graining-runs`` as it ends, and a study run again there takes them from it (a
    study stopped goes on where it was; a pile stopped goes on from its last save there,
    ``pile.pile_run``). Checks: each parcels' mean pile angle within 1 deg of the
    real particles' at each mu_r, the drum's angle within 1 deg, the silo's flow rate within 5 %
    (full size: the quick one runs too few seeds to tell, and says so in its notes, with every pile
    forming and every silo draining as its checks); a parcel's critical mu_r within 0.5 % of
    tan(beta) on every slope."""
    tic = time.perf_counter()
    experiment = CoarseGraining()
    key = "quick" if quick else "full"
    size = experiment.sizes[key]
    points = [{"scene": "pile", "alpha": a, "mur": mur, "length_convention": 0, "seed": s}
              for mur in size["murs"] for a in size["alphas"] for s in size["seeds"]]
    points += [{"scene": "pile", "alpha": max(size["alphas"]), "mur": mur, "length_convention": 1, "seed": s}
               for mur in size["murs"] for s in size["seeds"]]
    points += [{"scene": "drum", "alpha": a, "seed": s} for a in size["drum"]["alphas"] for s in size["drum"]["seeds"]]
    points += [{"scene": "silo", "alpha": a, "seed": s} for a in size["silo"]["alphas"] for s in size["silo"]["seeds"]]
    slope_models = size["slope"]["models"] or [m for m in validation_models() if m not in NO_THRESHOLD]
    points += [{"scene": "slope", "alpha": 3.0, "model": m, "beta": b} for m in slope_models
               for b in size["slope"]["angles"]]
    points += [{"scene": "pile-scaled", "alpha": a, "mur": mur, "seed": s} for mur in size["murs"]
               for a in size["alphas"] if a > 1.0 for s in size["seeds"]]
    # the drum checked (alpha 2): at alpha 3 the smaller drum's slice, 3.3 d long, is too thin to fill at random
    points += [{"scene": "drum-scaled", "alpha": 2.0, "seed": s} for s in size["drum"]["seeds"]
               if 2.0 in size["drum"]["alphas"]]
    # the cheap runs first (the real particles' piles last): what a stopped study keeps is most of them
    points.sort(key=lambda p: (-p["alpha"], p["scene"] == "pile"))

    done = None if outdir is None else Path(outdir) / "coarse-graining-runs"

    def one(point):
        """The point's observables; with ``outdir`` kept in a file of their own, so that the study,
        stopped, goes on from the runs it has (a pile from its last save). The run's key: the model,
        the point, the size it belongs to and the laws' revision (a changed size or law runs afresh)."""
        return kept_run(done, [model, size, point, LAWS_REVISION], lambda partial: run_point(point, partial),
                        {"model": model, "point": point})

    def run_point(point, checkpoint=None):
        scene = point["scene"]
        if scene == "pile":
            return experiment.observe({"model": model, "mur": point["mur"], "alpha": point["alpha"],
                                       "length_convention": point["length_convention"], "count": size["count"],
                                       "seed": point["seed"]}, checkpoint=checkpoint)
        if scene == "pile-scaled":
            return scaled_pile_point(model, point["alpha"], point["mur"], point["seed"], size["count"], checkpoint)
        if scene == "drum":
            return drum_point(model, point["alpha"], point["seed"], size["drum"])
        if scene == "drum-scaled":
            return scaled_drum_point(model, point["alpha"], point["seed"], size["drum"])
        if scene == "silo":
            return silo_point(model, point["alpha"], point["seed"], size["silo"])
        return slope_point(point["model"], point["alpha"], point["beta"])

    rows = []
    for point, res in zip(points, runner(one, points)):
        rows.append({**point, **res})
        if progress:
            progress()
    runs = pd.DataFrame(rows)
    result = ValidationResult(CASE, f"Coarse graining: parcels against the real particles ({model})", runs, [])
    pile_checks(result, runs, model, size, quick)
    drum_checks(result, runs, model, quick)
    silo_checks(result, runs, model, quick)
    slope_checks(result, runs)
    similarity_checks(result, runs, model, quick)
    if outdir is not None:
        figure(result, runs, outdir)
    result.wall_time = time.perf_counter() - tic
    return result


def compared(runs: pd.DataFrame, value: str, real: pd.Series, parcels: pd.Series) -> tuple[float, float, float]:
    """(mean of the parcels, mean difference parcels - real, Welch 95 % half-width) of ``value``."""
    diff, half = difference_interval(runs.loc[parcels, value], runs.loc[real, value])
    return float(runs.loc[parcels, value].mean()), diff, half


def pile_checks(result: ValidationResult, runs: pd.DataFrame, model: str, size: dict, quick: bool) -> None:
    piles = runs[runs["scene"] == "pile"]
    for _, r in piles.iterrows():  # a pile forms: mu_r and the rough base hold one
        result.checks.append(Check(CASE, model, f"pile angle, alpha {r['alpha']:g}, mu_r {r['mur']:g}"
                                   f"{', mu_r a length' if r['length_convention'] else ''}, seed {r['seed']:g} (deg)",
                                   r["angle"], 5.0, 0.0, bound="lower", source="a pile forms on the rough base"))
    for mur in size["murs"]:
        at = (runs["scene"] == "pile") & np.isclose(runs["mur"], mur)
        real = at & (runs["alpha"] == 1.0) & (runs["length_convention"] == 0)
        base = runs.loc[real, "angle"].mean()
        for alpha in sorted(set(runs.loc[at, "alpha"])):
            for convention in (0, 1):
                parcels = at & (runs["alpha"] == alpha) & (runs["length_convention"] == convention)
                if alpha == 1.0 or not parcels.any():
                    continue
                mean, diff, half = compared(runs, "angle", real, parcels)
                what = "mu_r as a length (mu_r / alpha on the parcels)" if convention else "mu_r kept (the rule)"
                result.notes.append(f"pile, mu_r = {mur:g}: real particles {base:.2f} deg; parcels of alpha {alpha:g}, "
                                    f"{what}: {mean:.2f} deg, difference {diff:+.2f} +- {half:.2f} deg (95 %, Welch, "
                                    f"{int(parcels.sum())} and {int(real.sum())} seeds)")
                if not quick and not convention:
                    result.checks.append(Check(CASE, model, f"pile angle, alpha {alpha:g} - alpha 1, mu_r {mur:g} (deg)",
                                               diff, 0.0, ANGLE_TOLERANCE, relative=False,
                                               source="the scaling rule keeps the pile angle of the real particles (docs/models.md §18): within 1 deg"))


def drum_checks(result: ValidationResult, runs: pd.DataFrame, model: str, quick: bool) -> None:
    drums = runs[runs["scene"] == "drum"]
    if drums.empty:
        return
    real = (runs["scene"] == "drum") & (runs["alpha"] == 1.0)
    speed = {}
    for alpha in sorted(set(drums["alpha"])):
        at = (runs["scene"] == "drum") & (runs["alpha"] == alpha)
        per_second = (runs.loc[at, "particles"] / runs.loc[at, "wall_time"]).mean()
        speed[alpha] = per_second
        if alpha == 1.0:
            continue
        mean, diff, half = compared(runs, "angle", real, at)
        result.notes.append(f"drum: real particles {runs.loc[real, 'angle'].mean():.2f} deg; parcels of alpha {alpha:g} "
                            f"{mean:.2f} deg, difference {diff:+.2f} +- {half:.2f} deg (95 %, Welch)")
        if not quick and alpha == 2.0:
            result.checks.append(Check(CASE, model, "drum angle, alpha 2 - alpha 1 (deg)", diff, 0.0, ANGLE_TOLERANCE,
                                       relative=False, source="the same drum at the same Froude number turns the same bed (docs/models.md §18)"))
    result.notes.append("drum, particles represented per second of wall time (the whole run, settling included): "
                        + ", ".join(f"alpha {a:g}: {v:.4g} ({v / speed[1.0]:.3g} x alpha 1)" for a, v in speed.items()))
    for _, r in drums.iterrows():
        result.checks.append(Check(CASE, model, f"drum angle, alpha {r['alpha']:g}, seed {r['seed']:g} (deg)", r["angle"],
                                   0.0, 0.0, bound="lower", source="the bed turns and flows: an angle is measured"))


def silo_checks(result: ValidationResult, runs: pd.DataFrame, model: str, quick: bool) -> None:
    silos = runs[runs["scene"] == "silo"]
    if silos.empty:
        return
    real = (runs["scene"] == "silo") & (runs["alpha"] == 1.0)
    for _, r in silos.iterrows():
        result.checks.append(Check(CASE, model, f"silo flow rate, alpha {r['alpha']:g}, seed {r['seed']:g} (kg/s)",
                                   r["flow_rate"], 0.0, 0.0, bound="lower", source="the silo drains (clogged: NaN)"))
    for alpha in sorted(set(silos["alpha"]) - {1.0}):
        at = (runs["scene"] == "silo") & (runs["alpha"] == alpha)
        mean, diff, half = compared(runs, "flow_rate", real, at)
        base = runs.loc[real, "flow_rate"].mean()
        expected = beverloo_ratio(12.0, alpha)
        within = "within" if abs(diff) <= FLOW_TOLERANCE * base else "not within"
        result.notes.append(f"silo, orifice 12 d: real particles {base:.4g} kg/s; parcels of alpha {alpha:g} {mean:.4g} "
                            f"kg/s, {100 * diff / base:+.1f} +- {100 * half / base:.1f} % (95 %, Welch): {within} the "
                            f"{100 * FLOW_TOLERANCE:g} % a flow rate must keep; Beverloo's (D0 - {BEVERLOO_K:g} d)^2.5 at "
                            f"the parcels' d expects {100 * (expected - 1):+.1f} %, and the parcels flow at "
                            f"{mean / base / expected:.3f} of that")
        if not quick:
            result.checks.append(Check(CASE, model, f"silo flow rate, alpha {alpha:g} / alpha 1, over Beverloo's ratio",
                                       mean / base / expected, 1.0, FLOW_TOLERANCE,
                                       source="Beverloo's law at the parcels' diameter: their empty annulus is "
                                              "alpha times wider (docs/models.md §18)"))


def slope_checks(result: ValidationResult, runs: pd.DataFrame) -> None:
    for _, r in runs[runs["scene"] == "slope"].iterrows():
        tan_b = math.tan(math.radians(r["beta"]))
        result.checks.append(Check(CASE, r["model"], f"parcel (alpha {r['alpha']:g}): mu_r,crit / tan(beta) at "
                                   f"{r['beta']:g} deg", r["mur_critical"] / tan_b, 1.0, 0.005, relative=False,
                                   source="theory: mu_r,crit = tan(beta) whatever the size (docs/models.md §18)"))


def similarity_checks(result: ValidationResult, runs: pd.DataFrame, model: str, quick: bool) -> None:
    """Each pile and drum of parcels against the real particles in the same scene alpha times
    smaller (``scaled_pile_point``, ``scaled_drum_point``): the difference of the means with its
    interval; full size: within 1 deg or, where the seeds' scatter is wider, within the 95 %
    interval (no difference resolved)."""
    for scene in ("pile", "drum"):
        small = runs[runs["scene"] == f"{scene}-scaled"]
        for alpha in sorted(set(small["alpha"])):
            for mur in sorted(set(small["mur"])) if scene == "pile" else [None]:
                scaled = (runs["scene"] == f"{scene}-scaled") & (runs["alpha"] == alpha)
                parcels = (runs["scene"] == scene) & (runs["alpha"] == alpha)
                if mur is not None:
                    scaled &= np.isclose(runs["mur"], mur)
                    parcels &= np.isclose(runs["mur"], mur) & (runs["length_convention"] == 0)
                if not parcels.any():
                    continue
                mean, diff, half = compared(runs, "angle", scaled, parcels)
                label = scene if mur is None else f"{scene}, mu_r {mur:g}"
                result.notes.append(f"{label}: parcels of alpha {alpha:g} {mean:.2f} deg; the real particles in the "
                                    f"{scene} {alpha:g} times smaller {runs.loc[scaled, 'angle'].mean():.2f} deg: "
                                    f"parcels {diff:+.2f} +- {half:.2f} deg (95 %, Welch)")
                if not quick:
                    result.checks.append(Check(CASE, model, f"{label} angle, alpha {alpha:g} - the real particles' "
                                                            f"{scene} {alpha:g} times smaller (deg)",
                                               diff, 0.0, half if half > ANGLE_TOLERANCE else ANGLE_TOLERANCE,
                                               relative=False,
                                               source="the rule's similarity: parcels of alpha are the real particles "
                                                      "of a scene alpha times smaller (docs/models.md §18); 1 deg, or "
                                                      "the 95 % interval where wider"))


def figure(result: ValidationResult, runs: pd.DataFrame, outdir) -> None:
    plt = pyplot()
    fig, (ax, ax2, ax3) = plt.subplots(1, 3, figsize=(12, 4))
    piles = runs[runs["scene"] == "pile"]
    for (mur, convention), grp in piles.groupby(["mur", "length_convention"]):
        ax.plot(grp["alpha"], grp["angle"], "s" if convention else "o",
                label=f"μr {mur:g}" + (", μr a length" if convention else ""))
    for mur, grp in runs[runs["scene"] == "pile-scaled"].groupby("mur"):
        ax.plot(grp["alpha"], grp["angle"], "x", label=f"μr {mur:g}, real particles, the pile α times smaller")
    ax.set_xlabel("α")
    ax.set_ylabel("pile angle (deg)")
    ax.legend(fontsize=7)
    drums = runs[runs["scene"] == "drum"]
    ax2.plot(drums["alpha"], drums["angle"], "o", label="parcels of α")
    small = runs[runs["scene"] == "drum-scaled"]
    ax2.plot(small["alpha"], small["angle"], "x", label="real particles, the drum α times smaller")
    ax2.legend(fontsize=7)
    ax2.set_xlabel("α")
    ax2.set_ylabel("drum dynamic angle (deg)")
    silos = runs[runs["scene"] == "silo"]
    ax3.plot(silos["alpha"], silos["flow_rate"], "o", label="measured")
    if not silos.empty and (silos["alpha"] == 1.0).any():
        base = silos.loc[silos["alpha"] == 1.0, "flow_rate"].mean()
        alphas = np.linspace(1.0, silos["alpha"].max(), 20)
        ax3.plot(alphas, [base * beverloo_ratio(12.0, a) for a in alphas], "-", label="Beverloo, d = α d_real")
    ax3.set_xlabel("α")
    ax3.set_ylabel("silo flow rate (kg/s)")
    ax3.legend(fontsize=7)
    fig.suptitle("Coarse graining: parcels against the real particles")
    result.add_figure(fig, outdir, "coarse_graining.png")
