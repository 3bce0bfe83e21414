"""Silo discharge: a flat-bottomed silo discharging through a circular orifice, and its flow rate.

:func:`silo_run` fills a cylindrical silo (a triangle mesh: wall and a floor around a central
orifice, ``rollingdem.MeshWall.shape("silo")``) with the orifice plugged, lets the bed settle,
opens the orifice and counts the mass an outlet below it takes out; each sphere taken out is put
back on top of the bed, so the fill height stays and the flow is steady for as long as it is
measured. The steady mass flow rate W is the slope of the discharged mass over time
(:func:`discharge_rate`); Beverloo's law, W = C rho_b sqrt(g) (D0 - k d)^(5/2), relates it to
the orifice's diameter D0 (:func:`beverloo_fit`). docs/studies.md, "Silo discharge".
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from rollingdem.physics.contact.model import ContactModel
from rollingdem.errors import ParameterError, check_integer
from rollingdem.scene.insertion import BoxRegion, CylinderRegion, Uniform
from rollingdem.scene.mesh import MeshWall
from rollingdem.scene.simulation import Simulation
from rollingdem.experiments.repose import PileMaterial
from rollingdem.experiments.single_sphere import RADIUS

BLOCKS = 5  # sub-windows whose rates give the 95 % interval of W
SEGMENTS = 96  # polygon sides of the silo and its orifice: the orifice's area is 0.07 % short of the circle's


@dataclass(frozen=True)
class SiloSetup:
    """The silo, in mean particle diameters d: the orifice's diameter D0 (``orifice_diameters``),
    the silo's (``silo_diameters``; None: max(2.5 D0, D0 + 30 d), wide enough that its wall does
    not change the flow) and the bed's settled height (``fill_diameters``; None: 20 d, at least
    2 D0). ``gravity`` g (m/s^2). W is measured over ``measured`` spheres out, after the first
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
    from scipy.spatial import cKDTree

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
    from scipy import stats

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
    from scipy.optimize import minimize_scalar

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


def silo_run(rolling="epsd", twisting="none", material: PileMaterial = PileMaterial(), setup: SiloSetup = SiloSetup(),
             radius: float = RADIUS, polydispersity: float = 0.2, seed: int = 1, dt: float | None = None,
             sample: float = 0.02) -> SiloRun:
    """One silo: filled with the orifice plugged, settled, opened, discharged at a steady head.

    Spheres of radius uniform in ``radius`` (1 +- ``polydispersity``) of ``material`` fill the
    silo of ``setup`` to about ``setup.fill_diameters`` d (at a bulk solid fraction of 0.6). Every
    ``sample`` s the spheres the outlet took out are inserted again (new radii from the same
    distribution) in a layer 2 d thick just above the settled bed, so the fill height stays. The
    discharge runs until ``setup.transient + setup.measured`` spheres are out, the orifice clogs
    (``setup.clog_time`` s without a sphere out) or ``setup.max_time`` s pass."""
    for what, value, kind in (("material", material, PileMaterial), ("setup", setup, SiloSetup)):
        if not isinstance(value, kind):
            raise ParameterError(f"{what} = {value!r} is not allowed: must be a rollingdem.experiments.silo.{kind.__name__}")
    check_integer("transient", setup.transient, low=0)
    check_integer("measured", setup.measured, low=10)  # the 5 sub-windows of W need a few spheres each
    tic = time.perf_counter()
    d = 2.0 * radius
    d0, ds, fill = (v * d for v in setup.sizes())
    if not d0 < ds:
        raise ParameterError(f"silo_diameters = {ds / d:g} is not allowed: must exceed orifice_diameters = {d0 / d:g}")
    g = setup.gravity
    r_max = radius * (1.0 + polydispersity)
    dist = Uniform(radius * (1.0 - polydispersity), r_max) if polydispersity else radius
    count = int(round(0.6 * math.pi / 4.0 * ds ** 2 * fill
                      / (4.0 / 3.0 * math.pi * radius ** 3 * (1.0 + polydispersity ** 2))))
    poured = 2.2 * fill + 2.0 * d  # the random insertion packs at about 0.3
    top = poured + 4.0 * d  # room for the layer put back
    contact = ContactModel("hertz", rolling=rolling, twisting=twisting, cohesion=material.cohesion)
    sim = Simulation(contact=contact, gravity=(0.0, 0.0, -g), dt=dt)
    sim.add_material(material.as_material("m"))
    walls = "m"
    if material.cohesion != "none":  # cohesive spheres, not cohesive to the silo
        walls = "wall"
        sim.add_material(material.wall_material(walls))
        sim.set_pair("m", walls, surface_energy=0.0, cohesion_energy_density=0.0)
    rings = max(1, int(round(top / (math.pi * ds / SEGMENTS))))  # near-square wall triangles
    sim.add_wall(MeshWall.shape("silo", radius=0.5 * ds, height=top, orifice_radius=0.5 * d0, segments=SEGMENTS,
                                rings=rings, material=walls, name="silo"))
    plug = sim.add_wall(MeshWall.shape("disk", radius=0.5 * d0, segments=SEGMENTS, material=walls, name="plug"))
    sim.insert(CylinderRegion(0.5 * ds - r_max, r_max, poured - r_max), count, dist, "m", seed=seed)
    sim.run(2.0 * math.sqrt(2.0 * poured / g) + 0.2)  # the fall from the top, then as long again to settle
    bed_mass = float(sim.masses.sum())
    height = float(np.percentile(sim.positions[:, 2] + sim.radii, 95))
    # 3 d off the wall, the floor and the top (a quarter of the height in a shallow bed)
    inner = cylinder_points(0.5 * ds - 3 * d, min(3 * d, 0.25 * height), max(height - 3 * d, 0.75 * height), seed=seed)
    bulk = solid_fraction(sim.positions, sim.radii, inner) * material.as_material("m").density
    sim.remove_wall(plug)
    outlet = sim.add_outlet(BoxRegion((-ds, -ds, -ds), (ds, ds, -2.0 * r_max)), name="orifice", interval=sample / 4)
    refill = CylinderRegion(0.5 * ds - r_max, height + r_max, height + r_max + 2.0 * d)
    near = cylinder_points(0.5 * d0, 0.0, 0.5 * d0, seed=seed + 1)
    t, out, fractions = [0.0], [0.0], []
    last_flow, clogged, start = 0.0, False, math.nan
    while outlet.count < setup.transient + setup.measured and t[-1] < setup.max_time - 1e-9:
        before = outlet.count
        sim.run(sample)
        t.append(t[-1] + sample)
        out.append(outlet.mass)
        if outlet.count > before:
            last_flow = t[-1]
            sim.insert(refill, outlet.count - before, dist, "m", seed=seed * 100_003 + len(t))
        elif t[-1] - last_flow >= setup.clog_time:
            clogged = True
            break
        if outlet.count >= setup.transient:
            if math.isnan(start):
                start = out[-1]
            fractions.append(solid_fraction(sim.positions, sim.radii, near))
    density = material.as_material("m").density
    done = outlet.count >= setup.transient + setup.measured
    return SiloRun(np.array(t), np.array(out), (start, out[-1] if done else math.nan), bed_mass, bulk,
                   float(np.mean(fractions)) * density if fractions else math.nan, count, clogged, d0, d,
                   time.perf_counter() - tic)
