"""Silo discharge: a flat-bottomed silo discharging through a circular orifice, and its flow rate.

:func:`silo_case` sizes the shipped case file ``cases/silo.yaml`` (``rollingdem experiments show
silo``): a cylindrical silo (a triangle mesh: wall and a floor around a central orifice,
``rollingdem.MeshWall.shape("silo")``) filled behind a gate, which is removed once the bed has
settled; an outlet below the floor takes out the spheres and puts each back on top of the bed, so
the fill height stays and the flow is steady for as long as it is measured. :func:`silo_run` runs
it as ``rollingdem run`` does. The steady mass flow rate W is the slope of the discharged mass
over time (:func:`discharge_rate`); Beverloo's law, W = C rho_b sqrt(g) (D0 - k d)^(5/2), relates
it to the orifice's diameter D0 (:func:`beverloo_fit`). docs/studies.md, "Silo discharge"."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rollingdem.errors import ParameterError, check_integer
from rollingdem.experiments.case_file import run_case_data
from rollingdem.experiments.pile import PileMaterial
from rollingdem.experiments.registry import UNBOUNDED, BedExperiment, Parameter, granular_parameters, resolve_rolling
from rollingdem.experiments.results import Check, ValidationResult, pyplot, run_points
from rollingdem.experiments.single_sphere import RADIUS
from rollingdem.io.case_check import check_case
from rollingdem.io.casefile import load_case
from rollingdem.io.mapping_file import read_mapping

BLOCKS = 5  # sub-windows whose rates give the 95 % interval of W
SEGMENTS = 96  # polygon sides of the silo and its orifice: the orifice's area is 0.07 % short of the circle's


@dataclass(frozen=True)
class SiloSetup:
    """The silo, in mean particle diameters d: the orifice's diameter D0 (``orifice_diameters``),
    the silo's (``silo_diameters``; None: max(2.5 D0, D0 + 30 d), wide enough that its wall does
    not change the flow) and the bed's settled height (``fill_diameters``; None: 20 d, at least
    2 D0). ``gravity`` g (m/s^2). W is measured over ``measured`` spheres out (real ones: a parcel counts alpha^3), after the first
    ``transient`` (the opening's); ``max_time`` s of discharge at most, and ``clog_time`` s
    without a sphere out count as a clogged orifice."""

    orifice_diameters: float = 6.0
    silo_diameters: float | None = None
    fill_diameters: float | None = None
    gravity: float = 9.81
    transient: int = 200
    measured: int = 1000
    max_time: float = 60.0
    clog_time: float = 1.0

    def sizes(self) -> tuple[float, float, float]:
        """(D0, silo diameter, fill height) in diameters."""
        d0 = self.orifice_diameters
        ds = self.silo_diameters if self.silo_diameters is not None else max(2.5 * d0, d0 + 30.0)
        return d0, ds, self.fill_diameters if self.fill_diameters is not None else max(20.0, 2.0 * d0)


@dataclass
class SiloRun:
    """A discharge: times (s) and discharged mass (kg), the discharged masses between which W is
    measured (``window``), the bed's mass and bulk density before the orifice opened, the solid
    fraction sampled near the orifice while W is measured."""

    t: np.ndarray
    discharged: np.ndarray
    window: tuple[float, float]
    bed_mass: float
    bulk_density: float
    orifice_density: float
    particles: int
    clogged: bool
    orifice: float  # m
    diameter: float  # m, the mean particle diameter
    wall_time: float = math.nan


def solid_fraction(positions, radii, points) -> float:
    """The share of ``points`` inside a sphere: the solid fraction of the region they fill evenly."""
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    x = np.asarray(positions, float)
    if not len(x):
        return 0.0
    r = np.broadcast_to(np.asarray(radii, float), (len(x),))
    k = min(8, len(x))
    dist, idx = cKDTree(x).query(points, k=k)
    dist, idx = dist.reshape(len(points), k), idx.reshape(len(points), k)
    return float(np.mean((dist < r[idx]).any(axis=1)))


def cylinder_points(radius, z_lo, z_hi, n=4000, seed=0) -> np.ndarray:
    """``n`` points spread evenly at random in the cylinder about the z axis."""
    rng = np.random.default_rng(seed)
    rho = radius * np.sqrt(rng.random(n))
    phi = 2.0 * math.pi * rng.random(n)
    return np.column_stack([rho * np.cos(phi), rho * np.sin(phi), rng.uniform(z_lo, z_hi, n)])


def discharge_rate(t, discharged, window, blocks=1) -> tuple[float, float]:
    """The slope (kg/s) of the discharged mass over time between the discharged masses ``window``
    (kg; least squares over the samples within), and with ``blocks`` > 1 the 95 % Student-t
    half-width over the slopes of that many equal sub-windows; NaN where the discharge did not
    reach the window's end."""
    from scipy import stats  # deferred: slow to load, used here only

    t, m = np.asarray(t, float), np.asarray(discharged, float)
    lo, hi = window
    if not len(m) or not hi > lo or m[-1] < hi:
        return math.nan, math.nan
    edges = np.linspace(lo, hi, blocks + 1)

    def slope(a, b):
        sel = (m >= a) & (m <= b)
        return np.polyfit(t[sel], m[sel], 1)[0] if sel.sum() >= 3 else math.nan

    w = slope(lo, hi)
    if blocks < 2:
        return float(w), math.nan
    parts = np.array([slope(a, b) for a, b in zip(edges[:-1], edges[1:])])
    parts = parts[np.isfinite(parts)]
    half = stats.t.ppf(0.975, len(parts) - 1) * parts.std(ddof=1) / math.sqrt(len(parts)) if len(parts) > 1 else math.nan
    return float(w), float(half)


def _beverloo_line(d0, w, sigma, scale, n):
    """For the exponent n: the weighted least-squares line through W^(1/n) = C^(1/n) (D0 - k d)
    (W^(1/n)'s error is W^(1/n) sigma / (n W)), and the weighted sum of squares in W it leaves."""
    y = (w / scale) ** (1.0 / n)
    slope, intercept = np.polyfit(d0, y, 1, w=n * w / (y * sigma))
    return slope, intercept, float(np.sum(((w - scale * np.maximum(slope * d0 + intercept, 0) ** n) / sigma) ** 2))


def beverloo_fit(orifices, rates, bulk_density, diameter, gravity=9.81, exponent=None, errors=None):
    """Beverloo's law W = C rho_b sqrt(g) (D0 - k d)^n fitted to flow rates ``rates`` (kg/s) at
    orifice diameters ``orifices`` (m): (C, k, n), with n held at ``exponent`` (5/2 for Beverloo's
    law) or, with None, fitted too (bounded to [1, 6]). Least squares on W^(1/n), linear in D0 for
    a given n, and n by the least sum of squares in W; with ``errors`` (the rates' standard errors,
    kg/s) both weighted by them, so that a rate known to 1 % counts as much as it should beside one
    known to 10 %."""
    from scipy.optimize import minimize_scalar  # deferred: slow to load, used here only

    d0, w = np.asarray(orifices, float), np.asarray(rates, float)
    sigma = np.ones_like(w) if errors is None else np.asarray(errors, float)
    scale = bulk_density * math.sqrt(gravity)
    if exponent is None:
        n = minimize_scalar(lambda n: _beverloo_line(d0, w, sigma, scale, n)[2], bounds=(1.0, 6.0),
                            method="bounded").x
    else:
        n = exponent
    slope, intercept, _ = _beverloo_line(d0, w, sigma, scale, n)
    return float(slope ** n), float(-intercept / slope / diameter), float(n)


def beverloo_exponent_interval(orifices, rates, errors, bulk_density, diameter, gravity=9.81,
                               grid=np.linspace(1.0, 6.0, 501)) -> tuple[float, float]:
    """The 95 % interval of Beverloo's exponent n fitted freely (with C and k) to ``rates`` with
    standard errors ``errors``: the n on ``grid`` whose best weighted sum of squares is within
    3.84 (chi-square, one degree of freedom) of the least, after scaling the errors so that the
    best fit's reduced chi-square is at least 1 (the errors of few blocks can understate the
    scatter between orifices)."""
    d0, w, sigma = (np.asarray(v, float) for v in (orifices, rates, errors))
    scale = bulk_density * math.sqrt(gravity)
    chi2 = np.array([_beverloo_line(d0, w, sigma, scale, n)[2] for n in grid])
    chi2 = chi2 / max(1.0, chi2.min() / max(len(w) - 3, 1))
    inside = grid[chi2 <= chi2.min() + 3.84]
    return float(inside.min()), float(inside.max())


def beverloo_checks(table, sizes: dict, diameter: float, quick: bool, model: str):
    """The silo validation's checks on its table of runs (one row per orifice and fill height:
    ``orifice_diameters``, ``fill_diameters``, ``orifice`` (m), ``flow_rate`` and its 95 % half-width
    ``flow_rate_ci`` (kg/s), ``bulk_density``): Beverloo's C and k at the exponent 5/2 within the
    measured ranges, at the full size 5/2 within the freely fitted exponent's 95 % interval, and the
    rate at half the fill height equal to the full's. Returns (checks, the fit and the rows it used)."""
    from scipy import stats  # deferred: slow to load, used here only

    d = diameter
    full = table[np.isclose(table["fill_diameters"], sizes["fill"])]
    ok = full[np.isfinite(full["flow_rate"])]
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
                     source="Beverloo et al. (1961), Nedderman (1992): C from 0.45 to 0.75")]
    if not quick:  # over the quick size's 5-8 d the interval runs to the search's bound: reported, not checked
        checks.append(Check("silo-discharge", model, f"exponent of (D0 - k d), fitted freely, 95 % interval "
                            f"[{n_lo:.2f}, {n_hi:.2f}]", n, 2.5, (n - n_lo) if n > 2.5 else (n_hi - n),
                            relative=False,
                            source="Beverloo: W ~ (D0 - k d)^(5/2), dimensional analysis; tolerance: 5/2 within "
                                   "the fitted exponent's 95 % interval"))
    at = table[np.isclose(table["orifice_diameters"], sizes["orifices"][0])].set_index("fill_diameters")
    high, low = at.loc[sizes["fill"]], at.loc[0.5 * sizes["fill"]]
    ratio = low["flow_rate"] / high["flow_rate"]
    spread = ratio * math.hypot(low["flow_rate_ci"] / low["flow_rate"], high["flow_rate_ci"] / high["flow_rate"])
    checks.append(Check("silo-discharge", model, f"W(fill {0.5 * sizes['fill']:g} d) / W(fill {sizes['fill']:g} d) "
                        f"at D0 = {sizes['orifices'][0]:g} d", ratio, 1.0,
                        max(0.05, spread) if math.isfinite(spread) else 0.05,
                        source="the flow rate does not depend on the fill height (Janssen); tolerance 5 % or "
                               "the 95 % interval of the ratio, if wider"))
    return checks, {"ok": ok, "rho_b": rho_b, "c": c, "k": k, "n": n, "n_lo": n_lo, "n_hi": n_hi, "low": low}


SHIPPED = Path(__file__).parent / "cases" / "silo.yaml"
"""The silo's case file (``rollingdem experiments show silo``): what :func:`silo_case` sizes."""


def silo_case(rolling="epsd", twisting="none", material: PileMaterial = PileMaterial(), setup: SiloSetup = SiloSetup(),
              radius: float = RADIUS, polydispersity: float = 0.2, seed: int = 1, dt: float | None = None) -> dict:
    """The shipped silo case file, sized and filled as ``setup`` says.

    Spheres of radius uniform in ``radius`` (1 +- ``polydispersity``) of ``material`` fill the
    silo (``SEGMENTS`` sides) to about ``setup.fill_diameters`` d at a bulk solid fraction of 0.6,
    poured from a loose column (the random insertion packs at about 0.3) and settled behind the
    gate for twice the fall time from its top, plus 0.2 s. The outlet below the floor puts each
    sphere it takes out back into a layer 2 d thick whose spheres' centres are 1.5 d or more
    above the bed's expected top (``refill``), so the
    fill height stays. The discharge ends once ``setup.transient + setup.measured`` spheres are out,
    or when the bed has settled for ``setup.clog_time`` s (a clogged orifice), or after
    ``setup.max_time`` s."""
    for what, value, kind in (("material", material, PileMaterial), ("setup", setup, SiloSetup)):
        if not isinstance(value, kind):
            raise ParameterError(f"{what} = {value!r} is not allowed: must be a rollingdem.experiments.silo.{kind.__name__}")
    check_integer("transient", setup.transient, low=0)
    check_integer("measured", setup.measured, low=10)  # the 5 sub-windows of W need a few spheres each
    d = 2.0 * radius
    d0, ds, fill = (v * d for v in setup.sizes())
    alpha = material.coarse_graining
    r_max = radius * (1.0 + polydispersity)
    placed_d, placed_r_max = alpha * d, alpha * r_max  # the spheres simulated: parcels of alpha
    if d0 < 2.0 * placed_r_max:
        raise ParameterError(f"orifice_diameters = {d0 / d:g} is not allowed with coarse_graining = {alpha:g}: the orifice "
                             f"({d0:.3g} m) is narrower than the largest parcel ({2.0 * placed_r_max:.3g} m); "
                             "lower coarse_graining (an orifice of 6 parcels or more flows as the real one, "
                             "docs/models.md §18)")
    if not d0 < ds:
        raise ParameterError(f"silo_diameters = {ds / d:g} is not allowed: must exceed orifice_diameters = {d0 / d:g}")
    g = setup.gravity
    # <r^3> = R^3 (1 + p^2) for radii uniform in R (1 +- p)
    count = int(round(0.6 * math.pi / 4.0 * ds ** 2 * fill
                      / (4.0 / 3.0 * math.pi * radius ** 3 * (1.0 + polydispersity ** 2))))
    poured = 2.2 * fill + 2.0 * d  # the random insertion packs at about 0.3
    top = poured + 4.0 * placed_d
    inner = 0.5 * ds - placed_r_max
    data, _ = read_mapping(SHIPPED)
    data["dt"] = dt
    data["gravity"] = [0.0, 0.0, -g]
    data["materials"] = [material.as_material("beads").to_dict()]
    data["contact"] = {"normal": "hertz", "rolling": rolling, "twisting": twisting, "cohesion": material.cohesion}
    walls = "beads"
    if material.cohesion != "none":  # cohesive spheres, not cohesive to the silo
        walls = "wall"
        data["materials"].append(material.wall_material("wall").to_dict())
        data["pairs"] = [{"materials": ["beads", "wall"], "surface_energy": 0.0, "cohesion_energy_density": 0.0}]
    silo, gate = data["walls"]
    silo.update(material=walls, size={"radius": 0.5 * ds, "height": top, "orifice_radius": 0.5 * d0,
                                      "segments": SEGMENTS, "rings": max(1, int(round(top / (math.pi * ds / SEGMENTS))))})
    gate["material"] = walls
    insert = data["particles"][0]
    insert.update(insert={"type": "cylinder", "radius": inner, "z_min": placed_r_max, "z_max": poured - placed_r_max},
                  count=count,
                  radius={"distribution": "uniform", "low": radius * (1.0 - polydispersity), "high": r_max}
                  if polydispersity else radius, seed=seed)
    outlet = data["outlets"][0]
    outlet.update(region={"type": "box", "lo": [-ds, -ds, -ds], "hi": [ds, ds, -2.0 * placed_r_max]}, seed=seed,
                  refill={"type": "cylinder", "radius": inner, "z_min": fill + 1.5 * placed_d,
                          "z_max": fill + 3.5 * placed_d})
    settle = 2.0 * math.sqrt(2.0 * poured / g) + 0.2  # the fall from the top, then as long again to settle
    bed, discharge, zone = data["measurements"]
    # 3 d off the wall, the floor and the top (a quarter of the height in a shallow bed)
    bed.update(region={"type": "cylinder", "radius": 0.5 * ds - 3 * d, "z_min": min(3 * d, 0.25 * fill),
                       "z_max": max(fill - 3 * d, 0.75 * fill)}, window=[settle - 0.05, settle])
    discharge["window"] = zone["window"] = None  # silo_run finds the window from the count
    zone["region"] = {"type": "cylinder", "radius": 0.5 * d0, "z_min": 0.0, "z_max": 0.5 * d0}
    fill_stage, run = data["stages"]
    fill_stage["duration"] = settle
    run.update(until={"measurement": "discharge.count", "above": parcels_out(setup.transient + setup.measured, alpha),
                      "settled": {"hold": setup.clog_time}}, max_duration=setup.max_time)
    data["output"] = {"time_series": {"interval": 0.05}, "snapshots": None, "plot": False, "report": None}
    return data


def parcels_out(particles: int, alpha: float) -> int:
    """The outlet's count (of parcels of a material coarse-grained by ``alpha``) for ``particles``
    real particles out."""
    return int(round(particles / alpha ** 3))


def silo_run(rolling="epsd", twisting="none", material: PileMaterial = PileMaterial(), setup: SiloSetup = SiloSetup(),
             radius: float = RADIUS, polydispersity: float = 0.2, seed: int = 1, dt: float | None = None,
             edit=None) -> SiloRun:
    """The case of :func:`silo_case`, run as ``rollingdem run`` runs it (in a folder removed
    afterwards), and read: the discharged mass from the opening on, the window of the
    ``setup.measured`` spheres after the first ``setup.transient``, the settled bed's bulk density
    (the probe's, over the last 0.05 s before the opening) and the orifice zone's over the window.
    ``edit``, a function of the case's data, may change it before it runs (the clumps' study fills
    the silo with clumps, ``experiments.clump_stand_in``); the counts of ``setup`` are of the
    outlet's particles (a clump's members each)."""
    tic = time.perf_counter()
    data = silo_case(rolling, twisting, material, setup, radius, polydispersity, seed, dt)
    if edit is not None:
        data = edit(data)
    summary, read = run_case_data(data, ("discharge", "orifice_zone"), "silo")
    out, zone = read["discharge"], read["orifice_zone"]
    opened = data["stages"][0]["duration"]
    flow = out[out["time"] >= opened - 1e-9]
    t, mass, count = (flow[c].to_numpy(float) for c in ("time", "mass", "count"))
    wanted = parcels_out(setup.transient + setup.measured, material.coarse_graining)
    done = len(count) and count[-1] >= wanted
    after = count >= parcels_out(setup.transient, material.coarse_graining)
    start = float(mass[after][0]) if after.any() else math.nan
    in_window = zone["time"].to_numpy() >= (t[after][0] if after.any() else math.inf)
    bed = summary["measurements"]["bed"]
    return SiloRun(t - opened, mass, (start, float(mass[-1]) if done else math.nan), math.nan,
                   float(bed["bulk_density"]["value"]),
                   float(zone["bulk_density"][in_window].mean()) if in_window.any() else math.nan,
                   int(data["particles"][0]["count"]), not done, setup.orifice_diameters * 2.0 * radius, 2.0 * radius,
                   time.perf_counter() - tic)


class SiloDischarge(BedExperiment):
    """A flat-bottomed silo discharging through a circular orifice at a steady head (docs/studies.md,
    "Silo discharge")."""

    name = "silo-discharge"
    description = "a flat-bottomed silo discharging at a steady head: the case file silo, sized (docs/studies.md)"
    parameters = (granular_parameters()
                  + (Parameter("orifice_diameters", 6.0, "orifice diameter D0 in mean sphere diameters d", low=1.0),
                     Parameter("silo_diameters", 0.0, "silo diameter in d (0: max(2.5 D0, D0 + 30 d))", low=0.0),
                     Parameter("fill_diameters", 0.0, "settled fill height in d, held during the discharge (0: 20 d, "
                                                      "at least 2 D0)", low=0.0),
                     Parameter("gravity", 9.81, "gravitational acceleration g", "m/s^2", low=0.0, low_open=True),
                     Parameter("transient", 200, "spheres out after the opening before W is measured", low=0,
                               integer=True),
                     Parameter("measured", 1000, "spheres out over which W is measured", low=10, integer=True),
                     Parameter("max_time", 60.0, "longest discharge", "s", low=0.0, low_open=True),
                     Parameter("clog_time", 1.0, "time without a particle out that counts as clogged", "s", low=0.0,
                               low_open=True)))
    observables = {
        "flow_rate": "kg/s, steady mass flow rate W: slope of the discharged mass over the measured spheres",
        "flow_rate_ci": "kg/s, 95 % Student-t half-width over 5 sub-windows",
        "flow_rate_first": "kg/s, W over the first half of the measured spheres",
        "flow_rate_second": "kg/s, W over the second half",
        "bulk_density": "kg/m^3, of the settled bed before the orifice opens",
        "orifice_density": "kg/m^3, in the cylinder D0 wide and D0/2 high above the orifice, while W is measured",
        "clogged": "1 when the orifice clogged", "orifice": "m, the orifice diameter D0",
        "particles": "spheres in the silo"}
    default_observable = "flow_rate"
    targets = {"flow_rate": UNBOUNDED, "bulk_density": UNBOUNDED}
    #: what ``validate`` runs: orifices D0 (d), from 5 d: below about 4.9 d a silo of spheres clogs
    #: after avalanches of finite mean size (Zuriguel et al. 2005), so a run may stop before W is
    #: measured; the silo's diameter max(2.5 D0, D0 + ``gap``) d; the fill height (d), held; the
    #: spheres measured per run. The full sizes keep 30 d of wall gap; the quick silo keeps 2.5 D0
    #: but only 10 d
    sizes = {"quick": {"orifices": (5.0, 6.0, 7.0, 8.0), "gap": 10.0, "fill": 12.0, "measured": 1000},
             "full": {"orifices": (5.0, 6.25, 7.5, 8.75, 10.0), "gap": 30.0, "fill": 20.0, "measured": 2000}}
    #: the validation's material: a glass-bead-like friction (Beverloo's C and k ranges are for
    #: glass beads and sand)
    material = {"mu": 0.5, "mur": 0.1}

    @staticmethod
    def _arguments(p: dict) -> tuple:
        """:func:`silo_case`'s arguments for the resolved parameters ``p``."""
        setup = SiloSetup(orifice_diameters=p["orifice_diameters"], silo_diameters=p["silo_diameters"] or None,
                          fill_diameters=p["fill_diameters"] or None, gravity=p["gravity"], transient=p["transient"],
                          measured=p["measured"], max_time=p["max_time"], clog_time=p["clog_time"])
        return (resolve_rolling(p["model"]), p["twisting"], PileMaterial.from_parameters(p), setup, p["radius"],
                p["polydispersity"], p["seed"], p["dt"])

    def check(self, params: dict) -> None:
        """The silo of ``params`` built and checked as ``rollingdem check`` checks its case file."""
        check_case(load_case(silo_case(*self._arguments(self.resolve(params)))))

    def observe(self, params: dict) -> dict:
        """A flat-bottomed silo discharging at a steady head: the mass flow rate and the rest."""
        run = silo_run(*self._arguments(self.resolve(params)))
        lo, hi = run.window
        w, half = discharge_rate(run.t, run.discharged, run.window, blocks=BLOCKS)
        return {"flow_rate": w, "flow_rate_ci": half,
                "flow_rate_first": discharge_rate(run.t, run.discharged, (lo, 0.5 * (lo + hi)))[0],
                "flow_rate_second": discharge_rate(run.t, run.discharged, (0.5 * (lo + hi), hi))[0],
                "bulk_density": run.bulk_density, "orifice_density": run.orifice_density, "clogged": int(run.clogged),
                "orifice": run.orifice, "particles": run.particles}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        """The silo at 4 (quick) or 5 orifice sizes from 5 d to 8 or 10 d, one seed each, at a steady
        head; the smallest orifice again at half the fill height. Checks: Beverloo's law with the
        exponent 5/2 fits with k between 1 and 3 and C between 0.45 and 0.75 (the range of measured
        and simulated glass beads and sand); at the full size, 5/2 lies within the 95 % interval of
        the exponent fitted freely (over the quick size's 5 to 8 d that interval runs to the
        search's bound of 6, so the exponent is reported, not checked); W at half the fill height
        equals W at the full within 5 % (or the 95 % interval of their ratio, if wider): it does not
        depend on the fill height."""
        tic = time.perf_counter()
        sizes = self.sizes["quick" if quick else "full"]

        def point(d0, fill):
            return {"model": model, **self.material, "orifice_diameters": d0, "measured": sizes["measured"],
                    "silo_diameters": max(2.5 * d0, d0 + sizes["gap"]), "fill_diameters": fill}

        points = [point(d0, sizes["fill"]) for d0 in sizes["orifices"]]
        points.append(point(sizes["orifices"][0], 0.5 * sizes["fill"]))
        runs = run_points(self, points, [1], runner, progress)
        table = runs[["orifice_diameters", "silo_diameters", "fill_diameters", "orifice", "particles", "flow_rate",
                      "flow_rate_ci", "flow_rate_first", "flow_rate_second", "bulk_density", "orifice_density",
                      "clogged"]].copy()
        d = 2 * self.by_name["radius"].default
        checks, fit = beverloo_checks(table, sizes, d, quick, model)
        ok, rho_b, c, k, n, n_lo, n_hi, low = (fit[key] for key in ("ok", "rho_b", "c", "k", "n", "n_lo", "n_hi", "low"))
        result = ValidationResult("silo-discharge", f"Silo discharge ({model}{', quick' if quick else ''})", table, checks,
                            notes=[f"mu = {self.material['mu']}, mu_r = {self.material['mur']}; silos max(2.5 D0, D0 + "
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
