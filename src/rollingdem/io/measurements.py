"""Measurements: named quantities sampled during a run, written with their units and summed up at
its end, as EDEM's sensors or LIGGGHTS's ``fix massflow/mesh`` and ``compute`` + ``fix ave/time``.

Each measurement is an observer (``rollingdem.scene.schedule.Observer``) with a ``name``, an
``interval`` (s), and quantities with units. It keeps its rows (``series()``), writes them to
``{name}.csv`` when given a folder (a ``# units:`` comment line first: ``pandas.read_csv(path,
comment="#")``) and sums them up over a time ``window`` (``summary()``): the final value, and the
mean with its standard error from batch means (the samples of a run are correlated, so the spread
of ten batch means, not of the samples, gives the error). Which quantities each kind has, and how
it measures them: docs/measurements.md.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_finite, check_positive, check_vector
from rollingdem.scene.schedule import Observer

#: Batches of the batch-means standard error.
BATCHES = 10


def batch_standard_error(values) -> float:
    """Standard error of the mean of correlated samples: the standard deviation of the means of
    ``BATCHES`` consecutive equal batches over sqrt(BATCHES) (NaN with fewer than two samples per
    batch)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    per = len(v) // BATCHES
    if per < 2:
        return math.nan
    means = v[:per * BATCHES].reshape(BATCHES, per).mean(axis=1)
    return float(means.std(ddof=1) / math.sqrt(BATCHES))


def slope_with_error(t, y) -> tuple[float, float]:
    """Least-squares slope of ``y`` over ``t`` and its standard error from the slopes of
    ``BATCHES`` consecutive batches (NaN with fewer than three samples per batch)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if len(t) < 2 or np.ptp(t) == 0:
        return math.nan, math.nan
    slope = float(np.polyfit(t, y, 1)[0])
    per = len(t) // BATCHES
    if per < 3:
        return slope, math.nan
    parts = [np.polyfit(t[k * per:(k + 1) * per], y[k * per:(k + 1) * per], 1)[0] for k in range(BATCHES)]
    return slope, float(np.std(parts, ddof=1) / math.sqrt(BATCHES))


class Measurement(Observer):
    """Base class: ``QUANTITIES`` maps each quantity to its unit; ``values(sim)`` measures them now.

    ``window`` = (t0, t1) in s: the samples the summary's mean and error are over (default: the
    second half of the samples' time span)."""

    kind = "measurement"
    #: The interval (s) when none is given: a few samples per millisecond of flow; the angles, which
    #: fit a surface each time, less often.
    INTERVAL = 1e-3
    QUANTITIES: dict[str, str] = {}
    #: The quantities whose summary is a rate: the least-squares slope of a cumulative quantity.
    RATES: dict[str, str] = {}
    #: Cumulative quantities: the summary line shows their final value.
    CUMULATIVE: tuple[str, ...] = ()
    #: what the constructor's parameters are; each kind adds its own
    declared = {"name": Declared("the measurement's name: its file and summary key (letters, digits, - or _)",
                                 kind="text"),
                "interval": Declared("time between samples (default the kind's own)", "s", low=0.0, low_open=True),
                "window": Declared("[t0, t1] from the run's start, or a window from a stage's start, over which "
                                   "the summary averages (default the second half of the samples)", "s", "window")}

    def __init__(self, name: str, interval: float | None = None, window=None):
        super().__init__(self.INTERVAL if interval is None else interval)
        if not isinstance(name, str) or not name or not all(c.isalnum() or c in "-_" for c in name):
            raise ParameterError(f"measurement name = {name!r} is not allowed: must be letters, digits, - or _")
        self.name = name
        self.window = None if window is None else window_of(window)
        self.directory = None
        self._rows: list[tuple[float, int, list]] = []
        self._file = None

    # --- what each kind defines --------------------------------------------------------------------
    def values(self, sim) -> list[float]:
        """The quantities now, in the order of ``QUANTITIES``."""
        raise NotImplementedError

    def describe(self) -> str:
        """What is measured, in words."""
        return self.kind

    # --- sampling ----------------------------------------------------------------------------------
    def write_to(self, directory) -> "Measurement":
        """Write the rows to ``directory/{name}.csv`` from the next sample on."""
        self.directory = Path(directory)
        return self

    def start(self, sim) -> None:
        super().start(sim)
        if self.directory is not None and self._file is None:
            self.directory.mkdir(parents=True, exist_ok=True)
            path = self.directory / f"{self.name}.csv"
            new = not path.exists() or path.stat().st_size == 0
            self._file = open(path, "a", newline="")
            if new:
                units = " ".join(f"{q}={u}" for q, u in {"time": "s", "step": "1", **self.QUANTITIES}.items())
                self._file.write(f"# {self.name}: {self.describe()}; units: {units}\n")
                csv.writer(self._file).writerow(["time", "step", *self.QUANTITIES])

    def observe(self, sim) -> None:
        self._record(sim, self.values(sim))

    def _record(self, sim, values) -> None:
        """Keep a sample's quantities, and write them to the CSV."""
        row = [float(v) for v in values]
        self._rows.append((sim.time, sim.step, row))
        if self._file is not None:
            csv.writer(self._file).writerow([repr(sim.time), sim.step, *map(repr, row)])
            self._file.flush()

    def finish(self, sim, failure=None) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def value(self, sim, quantity: str) -> float:
        """One quantity now (what a stage condition reads)."""
        return float(self.values(sim)[list(self.QUANTITIES).index(quantity)])

    def series(self):
        """The rows so far as a pandas DataFrame: time, step and each quantity."""
        import pandas as pd  # deferred: slow to load, tables only

        return pd.DataFrame([[t, s, *row] for t, s, row in self._rows], columns=["time", "step", *self.QUANTITIES])

    # --- the end -----------------------------------------------------------------------------------
    def summary(self) -> dict:
        """{quantity: {unit, final, mean, standard_error, value}, window: [t0, t1]}; a rate quantity's
        mean is the least-squares slope of its cumulative quantity over the window; ``value`` is what
        the measurement stands for (a cumulative quantity's final value, else the mean): what a
        calibration reads."""
        if not self._rows:
            return {"kind": self.kind, "what": self.describe(), "samples": 0}
        t, (t0, t1), sel = self._inwindow_of()
        data = np.array([r[2] for r in self._rows], float).reshape(len(t), -1)
        out = {"kind": self.kind, "what": self.describe(), "samples": int(sel.sum()), "window": [float(t0), float(t1)]}
        for k, (q, unit) in enumerate(self.QUANTITIES.items()):
            entry = {"unit": unit, "final": float(data[-1, k])}
            mean, err = self._mean_and_error(q, t[sel], data[sel])
            out[q] = entry | {"mean": mean, "standard_error": err,
                              "value": entry["final"] if q in self.CUMULATIVE else mean}
        return out

    def estimate(self, quantity: str, since: float = -math.inf) -> tuple[float, float, int]:
        """(the mean of ``quantity`` over the samples taken at or after ``since`` and inside the
        window as far as it has come, its standard error, the samples): as ``summary`` computes
        them (a rate: the slope of its cumulative quantity), on the samples so far."""
        if quantity in self.CUMULATIVE:
            raise ParameterError(f"{self.name}.{quantity} is not allowed here: its value is the last sample's (a "
                                 "cumulative or end-state quantity), not a mean over samples")
        t = np.array([r[0] for r in self._rows])
        keep = t >= since - 1e-12
        if self.window is not None:
            keep &= (t >= self.window[0] - 1e-12) & (t <= self.window[1] + 1e-12)
        if not keep.any():
            return math.nan, math.nan, 0
        data = np.array([r[2] for r in self._rows], float).reshape(len(t), -1)[keep]
        return (*self._mean_and_error(quantity, t[keep], data), int(keep.sum()))

    def _mean_and_error(self, quantity: str, t: np.ndarray, data: np.ndarray) -> tuple[float, float]:
        """(mean, standard error) of ``quantity`` over the samples at times ``t`` (rows of ``data``): a
        rate's least-squares slope of its cumulative quantity, else the mean and its batch-means error."""
        names = list(self.QUANTITIES)
        if quantity in self.RATES:
            return slope_with_error(t, data[:, names.index(self.RATES[quantity])])
        vals = data[:, names.index(quantity)]
        return (float(np.nanmean(vals)) if np.isfinite(vals).any() else math.nan), batch_standard_error(vals)

    def _inwindow_of(self):
        """(the samples' times, the summary's window (t0, t1), which samples lie in it); samples exist."""
        t = np.array([r[0] for r in self._rows])
        t0, t1 = self.window if self.window is not None else (t[0] + 0.5 * (t[-1] - t[0]), t[-1])
        return t, (t0, t1), (t >= t0 - 1e-12) & (t <= t1 + 1e-12)

    def summary_line(self) -> str:
        """The summary in one line of words, for the run's end."""
        s = self.summary()
        if not s["samples"]:
            return f"{self.name}: no samples in the window"
        parts = []
        for q in self.headline():
            e = s[q]
            if q in self.CUMULATIVE:
                parts.append(f"{q} {e['final']:.4g}{_unit(e['unit'])} at the end")
                continue
            err = f" ± {e['standard_error']:.3g}" if math.isfinite(e["standard_error"]) else ""
            parts.append(f"{q} {e['mean']:.4g}{err}{_unit(e['unit'])}")
        t0, t1 = s["window"]
        return f"{self.name} ({self.describe()}): {', '.join(parts)} (mean over {t0:.3g}-{t1:.3g} s)"

    def headline(self) -> list[str]:
        """The quantities the summary line shows."""
        return list(self.QUANTITIES)[:3]


def fixed_top(sim) -> float:
    """The top of the highest fixed particle (a rough base's), else 0: the floor a pile stands on."""
    fixed = sim.fixed
    return float(np.max(sim.positions[fixed, 2] + sim.radii[fixed])) if fixed.any() else 0.0


def drum_frame(sim, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(across, up) of a drum's cross-section: ``up`` against gravity, square to ``axis``."""
    g = np.asarray(sim.gravity, float)
    up = -(g - (g @ axis) * axis)
    up /= np.linalg.norm(up)
    return np.cross(up, axis), up


def _unit(unit: str) -> str:
    return "" if unit in ("1", "") else f" {unit}"


def window_of(window) -> tuple[float, float]:
    try:
        t0, t1 = (check_finite("measurement window start", window[0]),
                  check_finite("measurement window end", window[1]))
    except (TypeError, IndexError):
        raise ParameterError(f"measurement window = {window!r} is not allowed: must be [t0, t1] (s)") from None
    if not t1 > t0:
        raise ParameterError(f"measurement window = {list(window)!r} is not allowed: need t0 < t1 (s)")
    return t0, t1


class MassFlow(Measurement):
    """Mass through a plane (``point``, ``normal``), or a disk of ``radius`` about ``point`` in it:
    ``count`` and ``mass`` (kg) crossed along ``normal`` minus those crossed back, cumulative, and
    ``rate`` (kg/s; the summary's rate is the least-squares slope of ``mass`` over the window).

    A particle has crossed when its centre lies on the other side of the plane than at the last
    sample, along its displacement since then (periodic images followed: a jump across a periodic
    boundary is no crossing); for a disk, where that displacement meets the plane lies within the
    radius. Each crossing counts once; so, for a plane, the mass crossed equals the change of the
    mass on its far side (particles put in or taken out aside). Only free particles count."""

    kind = "mass_flow"
    QUANTITIES = {"count": "1", "mass": "kg", "rate": "kg/s"}
    RATES = {"rate": "mass"}
    CUMULATIVE = ("count", "mass")

    declared = {**Measurement.declared, "point": Declared("a point of the counting plane", "m", "vector"),
                "normal": Declared("the direction counted positive (made unit length)", "-", "vector"),
                "radius": Declared("radius of the counting disk about point (none: the whole plane)", "m", low=0.0,
                                   low_open=True)}

    def __init__(self, name: str, point, normal, radius: float | None = None, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        self.point = np.array(check_vector("mass flow point", point))
        self.normal = np.array(check_vector("mass flow normal", normal, unit=True))
        self.radius = None if radius is None else check_positive("mass flow radius", radius, "m")
        self.count, self.mass = 0, 0.0
        self._tags = None  # the particles' numbers, heights above the plane and unwrapped positions at the last sample
        self._height = None
        self._unwrapped = None
        self._last = (0.0, 0.0, 0.0)  # (time, mass, rate) of the last row, for the rate

    def describe(self):
        where = f"disk r = {self.radius:g} m" if self.radius is not None else "plane"
        return f"mass flow through the {where} at {tuple(self.point.tolist())} along {tuple(self.normal.tolist())}"

    def check(self, sim):
        _check_inside_domain(sim, f"mass flow {self.name!r} point", self.point)

    def track(self, sim) -> None:
        """Count the crossings since the last call (every sample does; a condition may call it more often)."""
        free = ~sim.fixed
        tags = sim.particle_ids[free]
        x = sim.positions[free]
        u = sim.unwrapped_positions[free]
        height = (x - self.point) @ self.normal
        if self._tags is not None and len(self._tags) and len(tags):
            k = np.minimum(np.searchsorted(self._tags, tags), len(self._tags) - 1)
            known = self._tags[k] == tags  # particles put in since the last sample have no side yet
            k, x_now, u_now = k[known], x[known], u[known]
            old = self._height[k]
            step = u_now - self._unwrapped[k]
            new = old + step @ self.normal  # along the path: a periodic jump is no crossing
            crossed = (old < 0.0) != (new < 0.0)
            if self.radius is not None:
                f = -old / np.where(crossed, new - old, 1.0)
                at = x_now - step + f[:, None] * step  # where the path meets the plane
                lateral = (at - self.point) - ((at - self.point) @ self.normal)[:, None] * self.normal
                crossed &= np.einsum("ij,ij->i", lateral, lateral) <= self.radius ** 2
            sign = np.where(new[crossed] >= 0.0, 1, -1)
            self.count += int(sign.sum())
            self.mass += float(sign @ sim.masses[free][known][crossed])
        order = np.argsort(tags, kind="stable")
        self._tags, self._height, self._unwrapped = tags[order], height[order], u[order]

    def start(self, sim):
        super().start(sim)
        if self._tags is None:
            self.track(sim)
            self._last = (sim.time, self.mass, 0.0)

    def values(self, sim):
        self.track(sim)
        return [self.count, self.mass, self._rate(sim)]

    def observe(self, sim):
        super().observe(sim)
        self._last = (sim.time, self.mass, self._rows[-1][2][2])

    def _rate(self, sim) -> float:
        """Since the last sample; at the sample's own step, over the interval it closed."""
        dt = sim.time - self._last[0]
        return (self.mass - self._last[1]) / dt if dt > 0 else self._last[2]


def scene_bounds(sim) -> tuple[np.ndarray, np.ndarray]:
    """Where particles can be, roughly: the box around the particles, the mesh walls, the regions of
    the outlets and inflows, and the periodic box, widened on each side by its largest size (a
    sensor outside is misplaced, often by a length in mm where the scene is in m)."""
    boxes = []
    if sim.n_particles:
        r = sim.radii[:, None]
        boxes.append((np.min(sim.positions - r, axis=0), np.max(sim.positions + r, axis=0)))
    boxes += [(m.vertices.min(axis=0), m.vertices.max(axis=0)) for m in sim.mesh_walls().values()]
    boxes += [b.region.bounds() for b in (*sim.outlets, *sim.inflows)]
    for axis, (lo, hi) in (sim.periodic or {}).items():
        k = "xyz".index(axis)
        for b in boxes:
            b[0][k], b[1][k] = lo, hi
    if not boxes:
        return np.full(3, -np.inf), np.full(3, np.inf)
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    margin = (hi - lo).max()
    return lo - margin, hi + margin


class MeshFlow(MassFlow):
    """Mass through a triangle mesh surface (``mesh``: a ``TriangleMesh``, in place; open or
    closed), as LIGGGHTS's ``fix massflow/mesh``: a particle has crossed when its displacement since
    the last sample passes through a triangle (Moller-Trumbore, the segment from the old centre to
    the new), counted along the triangle's normal (its vertices' right-hand order) and back
    against it; through an edge or vertex that triangles share, once. ``count``, ``mass`` and
    ``rate`` as ``MassFlow``'s."""

    kind = "mesh_flow"

    def __init__(self, name: str, mesh, interval: float | None = None, window=None):
        tri = np.asarray(mesh.vertices, float)[np.asarray(mesh.triangles)]
        super().__init__(name, point=tri.reshape(-1, 3).mean(axis=0), normal=(0.0, 0.0, 1.0), interval=interval,
                         window=window)
        self.triangles = tri
        self._positions = None

    def describe(self):
        return f"mass flow through a mesh of {len(self.triangles)} triangles"

    def check(self, sim):
        _check_inside_domain(sim, f"mesh flow {self.name!r} centre", self.point)

    def track(self, sim) -> None:
        free = ~sim.fixed
        tags, x, u = sim.particle_ids[free], sim.positions[free], sim.unwrapped_positions[free]
        if self._tags is not None and len(self._tags) and len(tags):
            k = np.minimum(np.searchsorted(self._tags, tags), len(self._tags) - 1)
            known = self._tags[k] == tags
            step = u[known] - self._unwrapped[k[known]]
            start = self._positions[k[known]]
            sign = self._crossings(start, step)
            self.count += int(sign.sum())
            self.mass += float(sign @ sim.masses[free][known])
        order = np.argsort(tags, kind="stable")
        self._tags, self._unwrapped, self._positions = tags[order], u[order], x[order]

    def _crossings(self, start: np.ndarray, step: np.ndarray) -> np.ndarray:
        """+1 / -1 / 0 per segment: through a triangle along its normal, against it, or not at all."""
        out = np.zeros(len(start), dtype=np.int64)
        moved = np.einsum("ij,ij->i", step, step) > 0
        v0, e1, e2 = self.triangles[:, 0], self.triangles[:, 1] - self.triangles[:, 0], \
            self.triangles[:, 2] - self.triangles[:, 0]
        normal = np.cross(e1, e2)
        for lo in range(0, len(start), 1024):
            idx = np.flatnonzero(moved[lo:lo + 1024]) + lo
            if not len(idx):
                continue
            o, d = start[idx][:, None, :], step[idx][:, None, :]
            pv = np.cross(d, e2[None])
            det = np.einsum("ptk,tk->pt", pv, e1)
            ok = np.abs(det) > 1e-300
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
            sv = o - v0[None]
            bu = np.einsum("ptk,ptk->pt", sv, pv) * inv
            qv = np.cross(sv, e1[None])
            bv = np.einsum("ptk,ptk->pt", d, qv) * inv
            t = np.einsum("tk,ptk->pt", e2, qv) * inv
            hit = ok & (bu >= 0) & (bv >= 0) & (bu + bv <= 1) & (t >= 0) & (t < 1)
            direction = np.sign(np.einsum("pk,tk->pt", step[idx], normal)).astype(np.int64)
            out[idx] = (hit * direction).sum(axis=1)
            for p in np.flatnonzero(hit.sum(axis=1) > 1):  # through a shared edge or vertex: one crossing
                where = np.flatnonzero(hit[p])
                _, first = np.unique(np.round(t[p, where], 9), return_index=True)
                out[idx[p]] = int(direction[p, where[first]].sum())
        return out


def _check_inside_domain(sim, what: str, point) -> None:
    """Refuse a sensor point outside where particles can be (``scene_bounds``): often a length in
    mm where the scene is in m."""
    lo, hi = scene_bounds(sim)
    if not ((point >= lo) & (point <= hi)).all():
        fmt = lambda v: "(" + ", ".join(f"{c:.4g}" for c in v) + ")"  # noqa: E731
        raise ParameterError(f"{what} = {fmt(point)} is not allowed: it is outside the scene, which spans "
                             f"{fmt(lo)} to {fmt(hi)} m (particles, meshes, outlets and inflows)")


class Probe(Measurement):
    """The free particles whose centres are in ``region`` (a ``BoxRegion``, ``CylinderRegion`` or
    ``MeshRegion``, the volume a closed mesh encloses):
    ``count``, ``mass`` (kg), ``bulk_density`` (their mass over the region's volume, kg/m^3),
    ``solid_fraction`` (their volume over the region's), the mean velocity ``vx, vy, vz`` (m/s,
    mass-weighted), ``kinetic_energy`` (J, translational and rotational; a clump's member counts its
    mass share of the clump's energy as a body) and ``coordination`` (the
    mean number of other particles a particle in it touches, ``coordination``). Counting by centres
    makes the densities uncertain by about a diameter over the region's width: make it wide."""

    kind = "probe"
    QUANTITIES = {"count": "1", "mass": "kg", "bulk_density": "kg/m^3", "solid_fraction": "1", "vx": "m/s",
                  "vy": "m/s", "vz": "m/s", "kinetic_energy": "J", "coordination": "1"}

    declared = {**Measurement.declared, "region": Declared("the region whose particles are measured (a box, a "
                                                           "cylinder or a closed mesh)", kind="region")}

    def __init__(self, name: str, region, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        if not hasattr(region, "contains") or not hasattr(region, "volume"):
            raise ParameterError(f"probe region = {region!r} is not allowed: must be a BoxRegion, CylinderRegion or MeshRegion")
        self.region = region

    def describe(self):
        lo, hi = self.region.bounds()
        return (f"particles in the {type(self.region).__name__.removesuffix('Region').lower()} "
                f"{tuple(np.round(lo, 6).tolist())}-{tuple(np.round(hi, 6).tolist())}")

    def check(self, sim):
        lo, hi = self.region.bounds()
        _check_inside_domain(sim, f"probe {self.name!r} region centre", 0.5 * (np.asarray(lo) + np.asarray(hi)))

    def values(self, sim):
        x = sim.positions
        inside = self.region.contains(x, np.zeros(len(x))) & ~sim.fixed
        m, r = sim.masses[inside], sim.radii[inside]
        v, w = sim.velocities[inside], sim.angular_velocities[inside]
        volume = self.region.volume()
        mass = float(m.sum())
        mean_v = (m @ v) / mass if mass > 0 else np.zeros(3)
        inertia = sim.particle_field("inertia")[inside]
        each = 0.5 * (m * np.einsum("ij,ij->i", v, v) + inertia * np.einsum("ij,ij->i", w, w))
        clumps = sim.particle_field("clump")  # empty without clumps
        if len(clumps):
            # a member carries its mass share of its clump's energy as a body, 1/2 M V^2 + 1/2 L . omega
            clump = clumps[inside]
            member = clump >= 0
            if member.any():
                bodies = sim.clumps
                body = 0.5 * (bodies["mass"] * np.einsum("ij,ij->i", bodies["velocity"], bodies["velocity"])
                              + np.einsum("ij,ij->i", bodies["angular_momentum"], bodies["angular_velocity"]))
                each[member] = m[member] / bodies["mass"][clump[member]] * body[clump[member]]
        energy = float(each.sum())
        return [int(inside.sum()), mass, mass / volume, float((4.0 / 3.0 * math.pi * r ** 3).sum()) / volume,
                *mean_v, energy, coordination(sim, inside)]

    def headline(self):
        return ["count", "bulk_density", "solid_fraction"]


def coordination(sim, which) -> float:
    """The mean number of particles (free or fixed) that each particle of ``which`` (a mask)
    touches, centres nearer than the sum of the radii, across periodic boundaries too; NaN for none."""
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    if not which.any():
        return math.nan
    reach = 2.0 * float(sim.radii.max())
    x, r, source = sim.shear.with_images(sim.positions, sim.radii, reach)
    pairs = cKDTree(x).query_pairs(reach, output_type="ndarray")
    d = x[pairs[:, 0]] - x[pairs[:, 1]]
    touching = source[pairs[np.einsum("ij,ij->i", d, d) < (r[pairs[:, 0]] + r[pairs[:, 1]]) ** 2]]
    touching = np.unique(np.sort(touching, axis=1), axis=0)  # a pair seen again through its images: once
    touching = touching[touching[:, 0] != touching[:, 1]]
    counts = np.bincount(touching.ravel(), minlength=sim.n_particles)
    return float(counts[which].mean())


class OutletTotals(Measurement):
    """What an outlet took out: ``count``, ``mass`` (kg), cumulative, and ``rate`` (kg/s; the
    summary's is the least-squares slope of ``mass`` over the window)."""

    kind = "outlet"
    QUANTITIES = {"count": "1", "mass": "kg", "rate": "kg/s"}
    RATES = {"rate": "mass"}
    CUMULATIVE = ("count", "mass")

    declared = {**Measurement.declared, "outlet": Declared("name of the outlet", kind="text")}

    def __init__(self, name: str, outlet: str, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        self.outlet = outlet
        self._last = None

    def describe(self):
        return f"outlet {self.outlet!r}"

    def _find(self, sim):
        for k, o in enumerate(sim.outlets):
            if (o.name or f"#{k}") == self.outlet:
                return o
        names = [o.name or f"#{k}" for k, o in enumerate(sim.outlets)]
        raise ParameterError(f"measurement {self.name!r}: outlet = {self.outlet!r} is not allowed: no outlet has that "
                             f"name; outlets are {', '.join(map(repr, names)) or 'none'}")

    def check(self, sim):
        self._find(sim)

    def values(self, sim):
        o = self._find(sim)
        t0, m0, rate = self._last if self._last is not None else (sim.time, o.mass, 0.0)
        # at the sample's own step (a condition checked there), the rate over the interval it closed
        rate = (o.mass - m0) / (sim.time - t0) if sim.time > t0 else rate
        return [o.count, o.mass, rate]

    def observe(self, sim):
        super().observe(sim)
        self._last = (sim.time, self._find(sim).mass, self._rows[-1][2][2])


class WallLoad(Measurement):
    """The load on a wall: force ``fx, fy, fz`` (N) and torque ``tx, ty, tz`` (N m, about the wall's
    own point, ``Simulation.wall_loads``) from the particles, ``power`` (W): what the wall's motion
    gives the particles, -(F . v + T . omega) with the velocity of its last step (a program's
    included), and where the wall's point is, ``x, y, z`` (m; a mesh's turns with it): a servo
    lid's travel, a vibrating table's stroke."""

    kind = "wall"
    QUANTITIES = {"fx": "N", "fy": "N", "fz": "N", "tx": "N m", "ty": "N m", "tz": "N m", "power": "W",
                  "x": "m", "y": "m", "z": "m"}

    declared = {**Measurement.declared, "wall": Declared("name of the wall", kind="text")}

    def __init__(self, name: str, wall: str, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        self.wall = wall

    def describe(self):
        return f"load on wall {self.wall!r}"

    def measured_wall(self, sim):
        return next((w for w in sim.walls if sim.wall_set.key(w) == self.wall), None)

    def check(self, sim):
        if self.measured_wall(sim) is None:
            keys = [sim.wall_set.key(w) for w in sim.walls]
            raise ParameterError(f"measurement {self.name!r}: wall = {self.wall!r} is not allowed: no wall in place has "
                                 f"that name; walls are {', '.join(map(repr, keys)) or 'none'}")

    def values(self, sim):
        load = sim.wall_loads().get(self.wall)
        wall = self.measured_wall(sim)
        if load is None or wall is None:  # removed by an earlier stage
            return [math.nan] * len(self.QUANTITIES)
        f, t = np.array(load["force"]), np.array(load["torque"])
        velocity, angular_velocity = wall.present_velocity()
        power = -(f @ velocity + t @ angular_velocity)
        return [*f, *t, float(power), *wall.point]

    def headline(self):
        return ["fz", "power"]


class Function(Measurement):
    """Any function of the state: ``function(sim)`` returns a number or a dict of numbers (the
    quantities, named at the first sample; ``units`` maps them to units)."""

    kind = "function"

    def __init__(self, name: str, function, interval: float | None = None, window=None, units=None):
        super().__init__(name, interval, window)
        if not callable(function):
            raise ParameterError(f"measurement {name!r}: function = {function!r} is not allowed: must be callable, "
                                 "function(sim) -> number or dict")
        self.function = function
        self.units = dict(units or {})
        self.QUANTITIES = None

    def describe(self):
        return f"function {getattr(self.function, '__name__', 'of the state')}"

    def _measure(self, sim) -> dict:
        raw = self.function(sim)
        out = raw if isinstance(raw, dict) else {"value": raw}
        try:
            return {str(k): float(v) for k, v in out.items()}
        except (TypeError, ValueError):
            raise ParameterError(f"measurement {self.name!r}: function returned {raw!r}: must be a number or a dict "
                                 "of numbers") from None

    def start(self, sim):
        if self.QUANTITIES is None:
            self.QUANTITIES = {q: self.units.get(q, "") for q in self._measure(sim)}
        super().start(sim)

    def values(self, sim):
        got = self._measure(sim)
        return [got.get(q, math.nan) for q in self.QUANTITIES]


__all__ = ["BATCHES", "Function", "MassFlow", "Measurement", "MeshFlow", "OutletTotals", "Probe", "WallLoad",
           "batch_standard_error", "coordination", "drum_frame", "fixed_top", "scene_bounds", "slope_with_error",
           "window_of"]
