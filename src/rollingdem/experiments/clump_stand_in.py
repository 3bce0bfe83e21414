"""``clump-stand-in``: a pile of clumps against a pile of spheres with the rolling friction that stands
in for them (docs/studies.md, "Clumps and the mu_r that stands in for them").

The same lifted-cylinder pile on a rough base (``repose-rough-base``'s protocol, ``pile.pile_case``)
twice: once of clumps of a named shape (spheres of ``radius``, no rolling resistance of their own:
their shape resists), once of as many spheres of the clump's volume with the rolling friction
``rd.stand_in_rolling_friction`` gives for that shape (the mean over the directions a resting face
may take of tan theta at which the clump tips on a slope), both of the same material; and the
flat-bottomed silo (``silo-discharge``'s protocol, ``silo.silo_case``) filled with each and
discharging at a steady head. It reports both angles and both mass flow rates side by side
and says for each whether the stand-in holds: whether the difference is within the seeds' 95 %
interval of zero.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.analysis.intervals import confidence_interval
from rollingdem.errors import check_choice
from rollingdem.experiments.pile import Collapse, PileMaterial, PileSetup, column_size, pile_run
from rollingdem.experiments.registry import BedExperiment, Parameter, resolve_rolling
from rollingdem.experiments.results import LAWS_REVISION, Check, ValidationResult, kept_run, pyplot
from rollingdem.experiments.silo import BLOCKS, SiloSetup, discharge_rate, silo_run
from rollingdem.scene.clumps import Clump, stand_in_rolling_friction

CASE = "clump-stand-in"
#: the clump shapes by the number of their members (a Parameter is a number): 2 dimer, 3 trimer, 4 tetrahedron
SHAPE_OF_MEMBERS = {2: "dimer", 3: "trimer", 4: "tetrahedron"}
#: deg: a 95 % interval of the angles' difference wider than this tells nothing of the stand-in
VERDICT_WIDTH = 5.0
#: %: the same for the flow rates' relative difference
FLOW_VERDICT_WIDTH = 10.0


def clump_template(members: int, radius: float):
    """The named clump of ``members`` touching spheres of ``radius``."""
    check_choice("members", members, tuple(SHAPE_OF_MEMBERS))
    return getattr(Clump, SHAPE_OF_MEMBERS[members])(radius)


def equal_volume_radius(clump) -> float:
    """The radius of the sphere of the clump's volume (m)."""
    return (3.0 * clump.mass_properties(1.0).volume / (4.0 * math.pi)) ** (1.0 / 3.0)


def taller_column(clump, r_eq: float, region: dict) -> dict:
    """An insertion region of spheres of radius ``r_eq`` made 1.25 (reach / r_eq)^3 times as tall, for
    as many clumps: insertion packs their bounding spheres as it packs spheres, and walls cost the
    larger ones a quarter more room."""
    region = dict(region)
    taller = 1.25 * (clump.reach() / r_eq) ** 3
    region["z_max"] = region["z_min"] + taller * (region["z_max"] - region["z_min"])
    return region


def with_clumps(clump, shape: str, member_radius: float):
    """An edit of a pile case's data (``pile_run(edit=...)``): its column of spheres made a column of
    the same number of clumps, inserted in a region 1.25 times as much taller as their bounding
    spheres are larger than the spheres (insertion packs bounding spheres as it packs spheres, and
    the tube's wall costs the larger ones more room), inside a tube
    as much taller, falling for as much longer."""
    def edit(data: dict) -> dict:
        block = data["particles"][-1]
        region = taller_column(clump, block["radius"], block["insert"])
        data["particles"][-1] = {"clump": {"shape": shape, "radius": member_radius}, "insert": region,
                                 "count": block["count"], "material": block["material"], "seed": block["seed"]}
        tube = next(w for w in data["walls"] if w["name"] == "tube")
        tube["extent"] = [0.0, max(tube["extent"][1], region["z_max"] + 0.1)]
        settle = data["stages"][0]
        settle["duration"] = 2.0 * math.sqrt(2.0 * region["z_max"] / 9.81) + 0.1
        return data
    return edit


def silo_with_clumps(clump, shape: str, member_radius: float):
    """An edit of a silo case's data (``silo_run(edit=...)``): its spheres made as many clumps,
    inserted as their bounding spheres in a column ``taller_column`` makes, clear of the
    wall by a bounding radius (and so the refill's layer), in a silo as much taller, settling for
    the fall from the new top."""
    def edit(data: dict) -> dict:
        block = data["particles"][0]
        r_eq, reach = block["radius"], clump.reach()
        region = taller_column(clump, r_eq, block["insert"])
        region["radius"] = region["radius"] + r_eq - reach
        refill = data["outlets"][0]["refill"]
        refill["radius"] = refill["radius"] + r_eq - reach
        data["particles"][0] = {"clump": {"shape": shape, "radius": member_radius}, "insert": region,
                                "count": block["count"], "material": block["material"], "seed": block["seed"]}
        silo = data["walls"][0]
        size = dict(silo["size"])
        top = region["z_max"] + 4.0 * reach
        size["rings"] = max(1, int(round(size["rings"] * top / size["height"])))
        size["height"] = top
        silo["size"] = size
        settle = 2.0 * math.sqrt(2.0 * region["z_max"] / 9.81) + 0.2
        data["stages"][0]["duration"] = settle
        bed = data["measurements"][0]
        bed["window"] = [settle - 0.05, settle]
        return data
    return edit


class ClumpStandIn(BedExperiment):
    """A pile of clumps against a pile of equal-volume spheres with the stand-in mu_r."""

    name = "clump-stand-in"
    description = ("the lifted-cylinder pile on a rough base of clumps, and of as many equal-volume spheres with the "
                   "rolling friction that stands in for them")
    parameters = (Parameter("model", "epsd", "the spheres' rolling resistance model", choice="rolling"),
                  Parameter("members", 4, "clump shape by its members: 2 dimer, 3 trimer, 4 tetrahedron", low=2,
                            high=4, integer=True),
                  Parameter("mu", 0.6, "sliding friction coefficient", low=0.0, low_open=True),
                  Parameter("count", 500, "clumps (and spheres) in the column", low=50, integer=True),
                  Parameter("radius", 0.0025, "the clumps' spheres' radius", "m", low=0.0, low_open=True),
                  Parameter("seed", 1, "random seed (insertion, orientations, base)", low=0, integer=True),
                  Parameter("dt", 1.5e-5, "time step (below the members' Hertz limit, 1.85e-5 s, at the 2.5 m/s "
                                          "a clump reaches falling from its column's top)", "s", low=0.0,
                            low_open=True),
                  Parameter("max_collapse", 3.0, "longest collapse before a pile counts as unsettled", "s", low=0.0,
                            low_open=True),
                  Parameter("orifice_diameters", 8.0, "the silo's orifice in equal-volume diameters d (0: no silo)",
                            low=0.0),
                  Parameter("silo_diameters", 20.0, "the silo's diameter in d", low=1.0),
                  Parameter("fill_diameters", 10.0, "the silo's fill height in d", low=1.0),
                  Parameter("measured", 1000, "clumps (or spheres) out over which the flow rate is measured, after "
                                              "the first 200", low=10, integer=True))
    observables = {"angle_clumps": "deg, the pile of clumps", "angle_spheres": "deg, the pile of stand-in spheres",
                   "flow_clumps": "kg/s, the silo's mass flow rate of clumps",
                   "flow_spheres": "kg/s, the silo's mass flow rate of stand-in spheres",
                   "mur_stand_in": "the spheres' rolling friction, rd.stand_in_rolling_friction"}
    default_observable = "angle_clumps"
    targets = {"angle_clumps": (0.0, 90.0), "angle_spheres": (0.0, 90.0)}
    sizes = {"quick": {"count": 300, "seeds": (1, 2), "silo": {"silo_diameters": 12.0, "fill_diameters": 6.0,
                                                                 "measured": 300}},
             "full": {"count": 1500, "seeds": (1, 2, 3, 4), "silo": {}}}

    def observe(self, params: dict) -> dict:
        """Both piles and both silos at ``params`` (one seed): their angles, flow rates and the
        stand-in mu_r."""
        p = self.resolve(params)
        clump = clump_template(p["members"], p["radius"])
        r_eq = equal_volume_radius(clump)
        mu_r = stand_in_rolling_friction(clump)
        tube_radius, _ = column_size(p["count"], r_eq, 0.0)
        setup = PileSetup(base="rough", radius=r_eq, tube_radius=tube_radius, base_radius=r_eq,
                          clearance=2.0 * r_eq)
        collapse = Collapse(max_time=p["max_collapse"], sample=0.02, lift_speed=0.1)
        out = {"mur_stand_in": mu_r}
        for what, mur, edit in (("clumps", 0.0, with_clumps(clump, SHAPE_OF_MEMBERS[p["members"]], p["radius"])),
                                ("spheres", mu_r, None)):
            material = PileMaterial(friction=p["mu"], rolling_friction=mur, youngs_modulus=5e6)
            run = pile_run(resolve_rolling(p["model"]), "none", p["count"], p["seed"], material, collapse,
                           polydispersity=0.0, dt=p["dt"], setup=setup, edit=edit)
            out[f"angle_{what}"] = run.angle.angle if run.angle else math.nan
            out[f"note_{what}"] = run.angle_error[:200]
            out[f"flow_{what}"] = math.nan
            if p["orifice_diameters"]:
                out[f"flow_{what}"], out[f"flow_note_{what}"] = silo_flow(p, material, r_eq, clump, what)
        return out

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        return stand_in_study(model, quick=quick, outdir=outdir, progress=progress, runner=runner)


def silo_flow(p: dict, material, r_eq: float, clump, what: str) -> tuple[float, str]:
    """The mass flow rate (kg/s) of the silo of ``params`` ``p`` filled with clumps or with their
    stand-in spheres (``what``), at a steady head (each one out put back on top), over ``measured``
    out after the first 200 (counted in the outlet's particles: a clump's members each); NaN and
    why where it clogged."""
    k = len(clump.radii) if what == "clumps" else 1
    setup = SiloSetup(orifice_diameters=p["orifice_diameters"], silo_diameters=p["silo_diameters"],
                      fill_diameters=p["fill_diameters"], transient=200 * k, measured=p["measured"] * k,
                      max_time=10.0, clog_time=0.5)
    edit = silo_with_clumps(clump, SHAPE_OF_MEMBERS[p["members"]], p["radius"]) if what == "clumps" else None
    run = silo_run(resolve_rolling(p["model"]), "none", material, setup, radius=r_eq, polydispersity=0.0,
                   seed=p["seed"], dt=p["dt"], edit=edit)
    if not math.isfinite(run.window[1]):
        return math.nan, "the orifice clogged" if run.clogged else "the silo ran out of time"
    return discharge_rate(run.t, run.discharged, run.window, blocks=BLOCKS)[0], ""


def stand_in_verdict(differences, width: float = VERDICT_WIDTH, what: str = "the angle",
                     unit: str = "deg") -> tuple[float, float, str]:
    """(mean, 95 % half-width, verdict) of the differences over seeds (spheres - clumps, in
    ``unit``): the stand-in holds for ``what`` where the interval holds 0, does not where it does
    not, and nothing can be told from an interval wider than ``width``."""
    mean, half = confidence_interval(differences)
    if not half <= width:  # NaN too: one seed
        return mean, half, (f"the seeds scatter too much to tell (an interval wider than {width:g} {unit}): run "
                            "more seeds or the full size")
    return mean, half, f"the stand-in {'holds' if abs(mean) <= half else 'does not hold'} for {what} at this size"


def stand_in_study(model="epsd", members=4, quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """Both piles and both silos over the seeds of the size (``ClumpStandIn.sizes``): their angles
    and flow rates, the mean differences with their 95 % Student-t intervals, and whether the
    stand-in holds for each (the interval holds 0). With ``outdir`` each seed's runs are kept in
    ``outdir/clump-stand-in-runs`` as they end (``results.kept_run``). Checks: a pile forms of each (every angle above
    5 deg: a clump's shape resists rolling, and so does the stand-in's mu_r), and each silo drains."""
    tic = time.perf_counter()
    experiment = ClumpStandIn()
    size = experiment.sizes["quick" if quick else "full"]
    points = [{"model": model, "members": members, "count": size["count"], "seed": s, **size["silo"]}
              for s in size["seeds"]]

    def one(point):  # kept in OUT/clump-stand-in-runs: a stopped study goes on from the seeds it has
        folder = None if outdir is None else Path(outdir) / "clump-stand-in-runs"
        return kept_run(folder, [model, members, size, point, LAWS_REVISION], lambda _: experiment.observe(point),
                        {"model": model, "point": point})

    rows = []
    for point, res in zip(points, runner(one, points)):
        rows.append({"seed": point["seed"], **{k: v for k, v in res.items() if "note" not in k}})
        if progress:
            progress()
    table = pd.DataFrame(rows)
    shape = SHAPE_OF_MEMBERS[members]
    plural = {"tetrahedron": "tetrahedra"}.get(shape, shape + "s")
    checks = [Check(CASE, plural, f"pile angle, seed {r['seed']} (deg)", r["angle_clumps"], 5.0, 0.0,
                    bound="lower", source="a clump's shape resists rolling: a pile forms") for r in rows]
    checks += [Check(CASE, f"spheres, {model}, mu_r = {rows[0]['mur_stand_in']:.3f}",
                     f"pile angle, seed {r['seed']} (deg)", r["angle_spheres"], 5.0, 0.0, bound="lower",
                     source="the stand-in's mu_r resists rolling: a pile forms") for r in rows]
    if size["silo"].get("orifice_diameters", 1.0):
        checks += [Check(CASE, f"{plural} and spheres", f"silo flow rate of {what}, seed {r['seed']} (kg/s)",
                         r[f"flow_{what}"], 0.0, 0.0, bound="lower",
                         source="the silo drains (a clogged orifice reads NaN)") for r in rows for what in ("clumps", "spheres")]
    result = ValidationResult(CASE, f"Clumps ({plural}) and the mu_r that stands in for them", table, checks)
    diff = table["angle_spheres"] - table["angle_clumps"]
    if len(diff) >= 2 and np.isfinite(diff).all():
        mean, half, verdict = stand_in_verdict(diff.to_numpy())
        result.notes.append(f"pile angle: {plural} {table['angle_clumps'].mean():.1f} deg, stand-in spheres "
                            f"{table['angle_spheres'].mean():.1f} deg (mu_r = {rows[0]['mur_stand_in']:.3f}); "
                            f"spheres - clumps = {mean:+.1f} +- {half:.1f} deg (95 %, {len(diff)} seeds): {verdict}")
    flows = 100.0 * (table["flow_spheres"] / table["flow_clumps"] - 1.0)
    if len(flows) >= 2 and np.isfinite(flows).all():
        mean, half, verdict = stand_in_verdict(flows.to_numpy(), FLOW_VERDICT_WIDTH, "the silo's flow", "%")
        result.notes.append(f"silo flow rate: {plural} {table['flow_clumps'].mean():.4g} kg/s, stand-in spheres "
                            f"{table['flow_spheres'].mean():.4g} kg/s; spheres / clumps - 1 = {mean:+.1f} +- "
                            f"{half:.1f} % (95 %, {len(flows)} seeds): {verdict}")
    if outdir is not None:
        plt = pyplot()
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(9, 4))
        for axis, column, label in ((ax, "angle", "pile angle (deg)"), (ax2, "flow", "silo flow rate (kg/s)")):
            axis.plot(table["seed"], table[f"{column}_clumps"], "o", label=f"{plural}, no rolling resistance")
            axis.plot(table["seed"], table[f"{column}_spheres"], "s",
                      label=f"spheres, μr = {rows[0]['mur_stand_in']:.3f}")
            axis.set_xlabel("seed")
            axis.set_ylabel(label)
        ax.legend()
        fig.suptitle("Clumps and their stand-in spheres: the pile and the silo")
        result.add_figure(fig, outdir, "clump_stand_in.png")
    result.wall_time = time.perf_counter() - tic
    return result

