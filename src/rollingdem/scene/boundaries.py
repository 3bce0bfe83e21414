"""Outlets and inflows: boundaries that take particles out of a scene and put them in during a run.

    sim.add_outlet(rd.BoxRegion((-0.1, -0.1, -0.5), (0.1, 0.1, -0.2)), name="orifice")
    sim.add_inflow(rd.CylinderRegion(0.03, 0.25, 0.3), rate=2000, radius=0.002, material="glass")

Both are operations of the simulation's schedule (``rollingdem.scene.schedule``): they act at
whole steps, every ``interval`` seconds of simulated time (rounded to steps, counted from step 0, so
a run cut into pieces or restarted from a checkpoint acts at the same steps), between calls of the
step loop: removal first, then insertion, then the observers. Their counts go into the time series
(``TimeSeries``) and into checkpoints. ``Boundaries`` adds them to a simulation and reads them.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_integer, check_non_negative, check_positive, check_vector
from rollingdem.scene import periodic as periodic_box
from rollingdem.scene.clumps import Clump, random_orientations
from rollingdem.scene.mesh import MeshRegion, TriangleMesh
from rollingdem.scene.particles import PARTICLE_DECLARED, sphere_mass
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, Face, FacePrism, MeshFace, Rectangle, Region
from rollingdem.scene.schedule import INSERT, REMOVE, Operation
from rollingdem.scene.size_distributions import (
    Constant,
    Discrete,
    MassFractions,
    Normal,
    Parcels,
    SieveCurve,
    Uniform,
    as_distribution,
    fractions_line,
    parcels_of,
)

DEFAULT_INTERVAL = 1e-3
"""Seconds between two actions of an outlet or inflow, unless given: a sphere falling at 1 m/s goes
1 mm further into an outlet before it is taken out, and an inflow of 10^4 particles/s inserts 10 at a
time."""

PLACEMENT_ATTEMPTS = 100
"""Random candidate centres per sphere an inflow tries before it leaves the sphere for later."""


def region_to_dict(region: Region) -> dict:
    if hasattr(region, "to_dict"):  # a face's prism, a mesh's volume
        return region.to_dict()
    if isinstance(region, BoxRegion):
        return {"type": "box", "lo": region.lo.tolist(), "hi": region.hi.tolist()}
    return {"type": "cylinder", "radius": region.radius, "z_min": region.z_min, "z_max": region.z_max,
            "center": list(region.center)}


def region_from_dict(d: dict) -> Region:
    if d["type"] == "box":
        return BoxRegion(d["lo"], d["hi"])
    if d["type"] == "face":
        return FacePrism(face_from_dict(d["face"]), d["depth"])
    if d["type"] == "mesh":
        return MeshRegion(TriangleMesh(d["vertices"], d["triangles"], label=d["label"]))
    return CylinderRegion(d["radius"], d["z_min"], d["z_max"], center=d["center"])


def face_from_dict(d: dict) -> Face:
    d = dict(d)
    kind = d.pop("type")
    if kind == "mesh_face":
        return MeshFace(TriangleMesh(d["vertices"], d["triangles"], label=d["label"]), d["normal"])
    return {"disk": Disk, "rectangle": Rectangle}[kind](**d)


def distribution_to_dict(dist) -> dict:
    if isinstance(dist, Parcels):
        return {"distribution": "parcels", "alpha": dist.alpha, "real": distribution_to_dict(dist.real)}
    if isinstance(dist, Constant):
        return {"distribution": "constant", "radius": dist.radius}
    if isinstance(dist, Uniform):
        return {"distribution": "uniform", "low": dist.low, "high": dist.high}
    if isinstance(dist, Normal):
        return {"distribution": "normal", "mean": dist.mean, "std": dist.std, "low": dist.low, "high": dist.high}
    if isinstance(dist, MassFractions):
        return {"distribution": "mass_fractions", "radii": dist.values.tolist(), "fractions": dist.fractions.tolist()}
    if isinstance(dist, SieveCurve):
        return {"distribution": "sieve", "diameters": dist.diameters.tolist(), "passing": dist.passing.tolist()}
    return {"distribution": "discrete", "values": dist.values.tolist(), "weights": dist.weights.tolist()}


def distribution_from_dict(d: dict):
    kind = d["distribution"]
    if kind == "parcels":
        return Parcels(distribution_from_dict(d["real"]), d["alpha"])
    args = {k: v for k, v in d.items() if k != "distribution"}
    return {"constant": Constant, "uniform": Uniform, "normal": Normal, "discrete": Discrete,
            "mass_fractions": MassFractions, "sieve": SieveCurve}[kind](**args)


def _check_region(what: str, region) -> Region:
    if not isinstance(region, Region):
        faces = ", or a face (rd.Disk, Rectangle, MeshFace)" if what == "inflow" else ""
        raise ParameterError(f"{what} region = {region!r} is not allowed: must be a rd.BoxRegion, CylinderRegion or "
                             f"MeshRegion{faces}")
    return region


def _check_name(what: str, name) -> str | None:
    if name is not None and (not isinstance(name, str) or not name or not all(c.isalnum() or c in "-_" for c in name)):
        raise ParameterError(f"{what} name = {name!r} is not allowed: must be letters, digits, '-' and '_' (it names "
                             "time-series columns)")
    return name


class Boundary(Operation):
    """What outlets and inflows share: a region, a name, and the steps they act at."""

    kind = ""

    def __init__(self, region, name, interval):
        self.region = _check_region(self.kind, region)
        self.name = _check_name(self.kind, name)
        self.interval = DEFAULT_INTERVAL if interval is None else check_positive(f"{self.kind} interval", interval,
                                                                                 "s")
        self.room_checked = False  # its region checked for room (``Boundaries.check_room``), once

    def every(self, dt: float) -> int:
        """Steps between two actions."""
        return max(1, int(round(self.interval / dt)))

    def next_step(self, sim) -> int:
        """The first step after ``sim.step`` this boundary acts at."""
        every = self.every(sim.dt)
        return (sim.step // every + 1) * every

    def due(self, step: int, dt: float) -> bool:
        return step > 0 and step % self.every(dt) == 0

    def columns(self, key: str) -> list[str]:
        return [f"{self.kind}_{key}_{q}" for q in self.COLUMNS]

    def describe(self) -> dict:
        return {"region": region_to_dict(self.region), "name": self.name, "interval": self.interval}


class Outlet(Boundary):
    """Takes out every free particle whose centre is inside ``region``; counts them and their mass,
    cumulative (``count``, ``mass``): the discharge rate is the slope of ``mass`` over time.

    With a ``refill`` region each sphere taken out is put back at once, at rest, with its radius
    and material, at a random place in ``refill`` where it overlaps neither a particle nor a wall
    (reproducibly from ``seed``): the bed keeps its mass and its size distribution, and a silo its
    head. A clump is put back whole, as it is inserted: its bounding sphere placed as a sphere is,
    the clump in it at a random orientation. What finds no room waits for the next action
    (``waiting``; one warning the first time)."""

    kind = "outlet"
    order = REMOVE
    COLUMNS = ("count", "mass")
    declared = {"region": Declared("the region the particles are taken out of", kind="region"),
                "name": Declared("label of the outlet in outputs and measurements", kind="text"),
                "interval": Declared("time between its actions (default 1 ms)", "s", low=0.0, low_open=True),
                "refill": Declared("the region each sphere taken out is put back in (none: not put back)",
                                   kind="region"),
                "seed": Declared("seed of the places drawn for the spheres put back", kind="whole", low=0)}

    def __init__(self, region, name=None, interval=None, refill=None, seed=0):
        super().__init__(region, name, interval)
        self.refill = None if refill is None else _check_region("outlet refill", refill)
        self.seed = check_integer("outlet seed", seed, low=0)
        self.count = 0
        self.mass = 0.0
        self.waiting_radius = np.zeros(0)  # the spheres to put back: radius (m) and material index
        self.waiting_material = np.zeros(0, dtype=np.int64)
        self.waiting_clumps = []  # the clumps to put back: (members' centres in the principal frame, radii, material)
        self.actions = 0  # put-back actions so far: each draws from its own random stream (seed, action)
        self.warned = False

    def inside(self, x: np.ndarray) -> np.ndarray:
        return self.region.contains(x, np.zeros(len(x)))

    def update(self, sim) -> None:
        """Take out the free particles inside, if due, and put back what a refill holds."""
        st = sim.particle_set.state
        if not self.due(sim.step, sim.dt) or st.n == 0:
            return
        gone = st.whole_clumps(self.inside(st.x) & ~st.is_fixed)
        if gone.any():
            self.count += int(gone.sum())
            self.mass += float(st.mass[gone].sum())
            if self.refill is not None:
                self.wait_for(st, gone)
            st.remove(gone)
        if self.refill is not None and (len(self.waiting_radius) or self.waiting_clumps):
            self.put_back(sim)

    def wait_for(self, st, gone) -> None:
        """Queue the spheres and the clumps of the slots ``gone`` to be put back."""
        spheres = gone & (st.clump < 0) if len(st.clump) else gone
        self.waiting_radius = np.concatenate([self.waiting_radius, st.radius[spheres]])
        self.waiting_material = np.concatenate([self.waiting_material, st.mat[spheres].astype(np.int64)])
        if len(st.clump) and (gone & (st.clump >= 0)).any():
            st.index_clumps()
            for c in np.unique(st.clump[gone & (st.clump >= 0)]):
                members = st.clump_members[st.clump_start[c]:st.clump_start[c + 1]]
                self.waiting_clumps.append((st.body_offset[members].copy(), st.radius[members].copy(),
                                            int(st.mat[members[0]])))

    def put_back(self, sim) -> None:
        templates = [Clump(centres, radii, connected=False) for centres, radii, _ in self.waiting_clumps]
        radii = np.concatenate([self.waiting_radius, [t.reach() for t in templates]])
        x = free_places(sim, self.refill, radii, float(radii.max()), np.random.default_rng([self.seed, self.actions, 2]))
        turns = random_orientations(np.random.default_rng([self.seed, self.actions, 3]), len(templates))
        self.actions += 1
        placed = np.isfinite(x[:, 0])
        k = len(self.waiting_radius)
        for m in np.unique(self.waiting_material[placed[:k]]):
            take = placed[:k] & (self.waiting_material == m)
            sim.particle_set.add(x[:k][take], self.waiting_radius[take], int(m), allow_overlap=True, parcels=True)
        for j, (template, (_, _, material)) in enumerate(zip(templates, self.waiting_clumps)):
            if placed[k + j]:
                sim.add_clumps(template, x[k + j:k + j + 1], int(material), turns[j:j + 1], allow_overlap=True)
        self.waiting_clumps = [w for j, w in enumerate(self.waiting_clumps) if not placed[k + j]]
        self.waiting_radius, self.waiting_material = self.waiting_radius[~placed[:k]], self.waiting_material[~placed[:k]]
        waiting = len(self.waiting_radius) + len(self.waiting_clumps)
        if waiting and not self.warned:
            self.warned = True
            warnings.warn(f"outlet {self.name or ''!r} at t = {sim.time:.6g} s: {waiting} sphere(s) or clump(s) "
                          f"found no room in its refill region {self.refill!r}; they are put back as room frees up; "
                          "use a larger refill region", RuntimeWarning, stacklevel=5)

    def values(self) -> list:
        return [self.count, self.mass]

    def describe(self) -> dict:
        d = {**super().describe(), "count": self.count, "mass": self.mass}
        if self.refill is not None:
            d.update(refill=region_to_dict(self.refill), seed=self.seed, actions=self.actions, warned=self.warned,
                     waiting_radius=self.waiting_radius.tolist(), waiting_material=self.waiting_material.tolist(),
                     waiting_clumps=[[c.tolist(), r.tolist(), m] for c, r, m in self.waiting_clumps])
        return d

    @classmethod
    def from_description(cls, d: dict) -> "Outlet":
        refill = region_from_dict(d["refill"]) if d.get("refill") else None
        out = cls(region_from_dict(d["region"]), d["name"], d["interval"], refill=refill, seed=d.get("seed", 0))
        out.count, out.mass = int(d["count"]), float(d["mass"])
        if refill is not None:
            out.actions, out.warned = int(d["actions"]), bool(d["warned"])
            out.waiting_radius = np.asarray(d["waiting_radius"], dtype=float)
            out.waiting_material = np.asarray(d["waiting_material"], dtype=np.int64)
            out.waiting_clumps = [(np.asarray(c, dtype=float).reshape(-1, 3), np.asarray(r, dtype=float), int(m))
                                  for c, r, m in d.get("waiting_clumps", [])]
        return out


class Inflow(Boundary):
    """Inserts particles into ``region`` at ``rate`` (particles/s) or ``mass_rate`` (kg/s) from
    ``start`` (s, default when it is added): by time t it has asked for rate (t - start) of them
    (or as many as make up that mass). Each action places what is due where it overlaps neither a
    particle nor a wall; what finds no room is the ``shortfall``, carried to the next action (one
    warning the first time). ``count`` and ``mass`` are what it inserted, cumulative."""

    kind = "inflow"
    order = INSERT
    COLUMNS = ("count", "mass", "shortfall")
    declared = {"region": Declared("the region the particles are inserted into, or a face they enter through "
                                   "(disk, rectangle, mesh_face) at velocity", kind="region"),
                **{key: PARTICLE_DECLARED[key] for key in ("radius", "material")},
                "rate": Declared("particles inserted per second (or give mass_rate)", "1/s", low=0.0, low_open=True),
                "mass_rate": Declared("mass inserted per second (instead of rate)", "kg/s", low=0.0, low_open=True),
                "velocity": Declared("velocity of the particles inserted", "m/s", "vector"),
                "seed": Declared("seed of the places and sizes drawn", kind="whole", low=0),
                "name": Declared("label of the inflow in outputs and measurements", kind="text"),
                "interval": Declared("time between its actions (default 1 ms)", "s", low=0.0, low_open=True),
                "start": Declared("time of its first action (default: when it is added)", "s", low=0.0)}

    def __init__(self, region, radius, material, rate=None, mass_rate=None, velocity=None, seed=0, name=None,
                 interval=None, start=0.0):
        if isinstance(region, Face):  # through a face: placed behind it, as deep as they go in an interval
            v = check_vector("inflow velocity", (0.0, 0.0, 0.0) if velocity is None else velocity)
            ahead = float(np.asarray(v) @ region.normal)
            if ahead < 0.0:
                raise ParameterError(f"inflow velocity = {list(v)} is not allowed through {region!r}: it points "
                                     "back through the face (against its normal)")
            every = DEFAULT_INTERVAL if interval is None else check_positive("inflow interval", interval, "s")
            region = region.prism(max(FACE_DEPTH * as_distribution(radius).max_radius, ahead * every))
        super().__init__(region, name, interval)
        if (rate is None) == (mass_rate is None):
            raise ParameterError(f"inflow rate = {rate!r}, mass_rate = {mass_rate!r} is not allowed: give exactly one, "
                                 "rate (particles/s) or mass_rate (kg/s)")
        self.rate = None if rate is None else check_positive("inflow rate", rate, "particles/s")
        self.mass_rate = None if mass_rate is None else check_positive("inflow mass_rate", mass_rate, "kg/s")
        self.radius = as_distribution(radius)
        rmax = self.radius.max_radius
        if not self.region.fits(rmax):
            raise ParameterError(f"inflow region {self.region!r} is not allowed: a sphere of radius {rmax:g} m does not "
                                 "fit in it; must be larger than one particle")
        self.material = material
        self.velocity = (0.0, 0.0, 0.0) if velocity is None else check_vector("inflow velocity", velocity)
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ParameterError(f"inflow seed = {seed!r} is not allowed: must be a whole number >= 0")
        self.seed = int(seed)
        self.start = check_non_negative("inflow start", start, "s")
        self.count = 0
        self.mass = 0.0
        self.shortfall = 0
        self.actions = 0  # actions so far: each draws from its own random stream (seed, action)
        self.warned = False
        self.waiting = np.zeros(0)  # radii drawn that found no room yet (m): the shortfall
        self.queue = np.zeros(0)  # radii drawn for a mass rate, not yet due (m)
        # what it inserted of each size class, for a distribution by mass (m^3): its realised fractions
        self.class_volume = (np.zeros(len(self.radius.asked)) if hasattr(self.radius, "class_volumes") else None)

    def values(self) -> list:
        return [self.count, self.mass, self.shortfall]

    def describe(self) -> dict:
        return {**super().describe(), "radius": distribution_to_dict(self.radius), "material": self.material, "rate": self.rate,
                "mass_rate": self.mass_rate, "velocity": list(self.velocity), "seed": self.seed, "start": self.start,
                "count": self.count, "mass": self.mass, "shortfall": self.shortfall, "actions": self.actions,
                "warned": self.warned, "class_volume": None if self.class_volume is None else self.class_volume.tolist(),
                "waiting": self.waiting.tolist(), "queue": self.queue.tolist()}

    def totals(self) -> dict:
        """What it inserted: count, mass (kg), the last shortfall, and for a distribution by mass the
        realised and the asked mass fractions (summary.json)."""
        out = {"name": self.name, "count": self.count, "mass": self.mass, "shortfall": self.shortfall}
        if self.class_volume is not None:
            total = max(float(self.class_volume.sum()), 1e-300)
            out.update(mass_fractions=(self.class_volume / total).tolist(), asked=np.asarray(self.radius.asked).tolist())
        return out

    def realised(self) -> str | None:
        """What it inserted so far, in words: the count and mass, and for a distribution by mass the
        realised mass fractions beside those asked."""
        label = f"inflow {self.name!r}" if self.name else "inflow"
        text = f"{label}: {self.count} spheres, {self.mass:.4g} kg"
        if self.class_volume is not None and self.class_volume.sum() > 0:
            text += "; " + fractions_line(self.class_volume / self.class_volume.sum(), self.radius.asked)
        return text

    def update(self, sim) -> None:
        """Insert what is due, if due, where it finds room."""
        if not self.due(sim.step, sim.dt) or sim.time < self.start:
            return
        density = sim.materials[self.material].density
        # those that found no room before go first, as drawn: drawing them again would favour the sizes
        # that find room more easily (the small ones in a crowded region)
        radii = np.concatenate([self.waiting, self.radii_due(sim.time, density)])
        x = free_places(sim, self.region, radii, self.radius.max_radius,
                        np.random.default_rng([self.seed, self.actions, 1]))
        placed = np.isfinite(x[:, 0])
        self.waiting = radii[~placed]
        if placed.any():
            r = radii[placed]
            sim.particle_set.add(x[placed], r, self.material, velocity=self.velocity, allow_overlap=True, parcels=True)
            if self.class_volume is not None:
                self.class_volume += self.radius.class_volumes(r)
            self.count += int(placed.sum())
            self.mass += float(sphere_mass(density, r).sum())
        self.actions += 1
        self.note_shortfall(len(self.waiting), sim.time)

    def restore_counters(self, d: dict) -> None:
        for key in ("count", "mass", "shortfall", "actions", "warned"):
            setattr(self, key, type(getattr(self, key))(d[key]))
        if d.get("class_volume") is not None:
            self.class_volume = np.asarray(d["class_volume"], dtype=float)
        if d.get("waiting") is not None:  # an older checkpoint draws its shortfall again
            self.waiting = np.asarray(d["waiting"], dtype=float)
            self.queue = np.asarray(d["queue"], dtype=float)

    def radii_due(self, time: float, density: float) -> np.ndarray:
        """The radii of the spheres due at ``time`` (drawn from this action's random stream)."""
        rng = np.random.default_rng([self.seed, self.actions, 0])
        elapsed = max(time - self.start, 0.0)
        if self.rate is not None:
            due = int(math.floor(self.rate * elapsed * (1.0 + 1e-12))) - self.count - len(self.waiting)
            return np.asarray(self.radius.sample(rng, due), dtype=float) if due > 0 else np.zeros(0)
        deficit = self.mass_rate * elapsed - self.mass - float(sphere_mass(density, self.waiting).sum())
        # the spheres drawn are taken in the order drawn, each once it is due: when the mass still
        # due is at least half its own (a sphere left over waits for the next action; dropping and
        # drawing again would favour the small ones, which fit a small remainder more often)
        taken, draw = [], 64
        while True:
            if not len(self.queue):
                self.queue = np.asarray(self.radius.sample(rng, draw), dtype=float)
                draw *= 2
            mass = sphere_mass(density, self.queue)
            due = np.cumsum(mass) - 0.5 * mass <= deficit
            k = len(self.queue) if due.all() else int(np.argmin(due))
            taken.append(self.queue[:k])
            deficit -= float(mass[:k].sum())
            self.queue = self.queue[k:]
            if len(self.queue):
                return np.concatenate(taken)

    def note_shortfall(self, missing: int, time: float) -> None:
        self.shortfall = missing
        if missing and not self.warned:
            self.warned = True
            label = f"inflow {self.name!r}" if self.name else "an inflow"
            warnings.warn(f"{label} at t = {time:.6g} s: {missing} particle(s) found no room in "
                          f"{self.region!r}; the region is too full for the rate. They are inserted as room frees up "
                          "(the time series' inflow shortfall column counts them); use a larger region or a lower "
                          "rate", RuntimeWarning, stacklevel=5)

    @classmethod
    def from_description(cls, d: dict) -> "Inflow":
        inflow = cls(region_from_dict(d["region"]), distribution_from_dict(d["radius"]), d["material"], rate=d["rate"], mass_rate=d["mass_rate"],
                     velocity=d["velocity"], seed=d["seed"], name=d["name"], interval=d["interval"], start=d["start"])
        inflow.restore_counters(d)
        return inflow


#: the least depth behind a face an inflow places its spheres in, in largest radii (a layer of them)
FACE_DEPTH = 4.0
#: centres drawn in an inflow's region to see that the walls leave room in it (``Boundaries.check_room``)
ROOM_SAMPLES = 1000


def free_places(sim, region, radii: np.ndarray, largest: float, rng) -> np.ndarray:
    """``place_spheres`` in ``region`` of ``sim``: among its walls as they are now and its particles
    with their periodic images, for spheres of radius at most ``largest`` (m)."""
    st = sim.particle_set.state
    walls = sim.walls
    reach = 2.0 * float(max(st.radius.max(initial=0.0), largest))
    near_x, near_r, _ = periodic_box.with_images(sim.periodic, st.x, st.radius, reach, st.contact_list.box)
    return place_spheres(region, radii, near_x, near_r, walls, rng)


def place_spheres(region, radii: np.ndarray, existing_x, existing_r, walls, rng) -> np.ndarray:
    """Centres in ``region`` for as many of ``radii`` as find room (in order; the rest NaN): each
    sphere takes the first of ``PLACEMENT_ATTEMPTS`` random candidates that overlaps no wall, no
    particle of ``existing_x`` and no sphere placed before it."""
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    n = len(radii)
    out = np.full((n, 3), np.nan)
    if n == 0:
        return out
    lo, hi = region.bounds()
    rmax = float(radii.max())
    near = np.zeros(len(existing_x), dtype=bool)
    if len(existing_x):
        gap = np.maximum(lo - existing_x, 0.0) + np.maximum(existing_x - hi, 0.0)
        near = np.linalg.norm(gap, axis=1) < existing_r + rmax
    ex, er = existing_x[near], existing_r[near]
    cand_r = np.repeat(radii, PLACEMENT_ATTEMPTS)
    cand = region.sample(rng, cand_r)
    ok = np.ones(len(cand), dtype=bool)
    for wall in walls:
        ok &= wall.overlap(cand, cand_r) <= 0.0
    if len(ex):
        reach = rmax + float(er.max())
        sdm = cKDTree(cand).sparse_distance_matrix(cKDTree(ex), reach, output_type="ndarray")
        hit = sdm["v"] < cand_r[sdm["i"]] + er[sdm["j"]]
        ok[np.unique(sdm["i"][hit])] = False
    placed_x = np.zeros((0, 3))
    placed_r = np.zeros(0)
    for k in range(n):
        options = np.flatnonzero(ok[k * PLACEMENT_ATTEMPTS:(k + 1) * PLACEMENT_ATTEMPTS]) + k * PLACEMENT_ATTEMPTS
        if len(placed_x) and len(options):
            d = np.linalg.norm(cand[options, None, :] - placed_x[None, :, :], axis=-1)
            options = options[(d >= radii[k] + placed_r[None, :]).all(axis=1)]
        if len(options):
            out[k] = cand[options[0]]
            placed_x = np.vstack([placed_x, cand[options[0]]])
            placed_r = np.append(placed_r, radii[k])
    return out


class Boundaries:
    """The outlets and inflows of a simulation, kept in its ``schedule``; checked against its
    ``materials``, ``periodic`` box and ``walls`` (its ``WallSet``)."""

    def __init__(self, state, schedule, materials, periodic: dict, walls):
        self.state = state  # the engine state, the same object for the simulation's life
        self.schedule, self.materials, self.periodic, self.walls = schedule, materials, periodic, walls

    @property
    def outlets(self) -> list:
        return self.schedule.of(Outlet)

    @property
    def inflows(self) -> list:
        return self.schedule.of(Inflow)

    def add_outlet(self, region, name=None, interval=None, refill=None, seed=0) -> Outlet:
        """``Simulation.add_outlet``."""
        st = self.state
        outlet = Outlet(region, name, interval, refill, seed)
        self._check_name(outlet)
        free = ~st.is_fixed
        if free.sum() > 1 and outlet.inside(st.x[free]).all():
            raise ParameterError(f"outlet region {region!r} is not allowed: it contains every free particle (all "
                                 f"{int(free.sum())}), so it would empty the scene at once; must cover only the way out")
        for inflow in self.inflows:
            check_outlet_inflow(outlet, inflow)
        if outlet.refill is not None:
            periodic_box.check_region_inside(self.periodic, "outlet refill", outlet.refill)
            check_outlet_refill(outlet)
        return self.schedule.add(outlet)

    def add_inflow(self, region, radius, material, rate=None, mass_rate=None, velocity=None, seed=0, name=None,
                   interval=None, start=None) -> Inflow:
        """``Simulation.add_inflow`` (``start``: given, the façade's clock when not)."""
        alpha = self.materials[material].coarse_graining
        if rate is not None and alpha != 1.0:  # particles represented per second: alpha^3 in a parcel
            rate = check_positive("inflow rate", rate, "particles/s") / alpha ** 3
        inflow = Inflow(region, parcels_of(radius, alpha), material, rate=rate, mass_rate=mass_rate, velocity=velocity,
                        seed=seed, name=name, interval=interval, start=start)
        self._check_name(inflow)
        periodic_box.check_region_inside(self.periodic, "inflow", inflow.region)
        for outlet in self.outlets:
            check_outlet_inflow(outlet, inflow)
        return self.schedule.add(inflow)

    def check_room(self) -> None:
        """Refuse an inflow's region, or an outlet's refill region, that cannot hold its largest sphere
        (smaller than it) or that the walls leave no room in (inside the floor, behind a plane): of
        ``ROOM_SAMPLES`` centres drawn in it for that sphere, none clear of every wall. Each is checked
        once, before its first run."""
        rng = np.random.default_rng(0)
        st = self.state
        largest_free = float(st.radius[~st.is_fixed].max(initial=0.0))
        if len(st.clump) and (st.clump >= 0).any():  # a clump is put back whole: its bounding sphere
            member = st.clump >= 0
            reach = np.linalg.norm(st.x[member] - st.clump_x[st.clump[member]], axis=1) + st.radius[member]
            largest_free = max(largest_free, float(reach.max()))
        places = [(inflow, "inflow region", inflow.region, inflow.radius.max_radius) for inflow in self.inflows]
        places += [(outlet, f"outlet {outlet.name} refill region" if outlet.name else "outlet refill region",
                    outlet.refill, largest_free) for outlet in self.outlets if outlet.refill is not None and largest_free > 0.0]
        for owner, what, region, radius in places:
            if owner.room_checked:
                continue
            if not region.fits(radius):
                raise ParameterError(f"{what} {region!r} is not allowed: a sphere of radius {radius:g} m does not fit "
                                     "in it; make it larger")
            r = np.full(ROOM_SAMPLES, radius)
            x = region.sample(rng, r)
            clear = np.ones(len(x), dtype=bool)
            blocking = None
            for wall in self.walls.in_place():
                inside = wall.overlap(x, r) > 0.0
                if inside.all():
                    blocking = wall
                clear &= ~inside
            if not clear.any():
                by = f" (wall {self.walls.label(blocking)} covers all of it)" if blocking is not None else ""
                raise ParameterError(f"{what} {region!r} is not allowed: the walls leave no room in it for "
                                     f"a sphere of radius {radius:g} m{by}: it lies inside or behind "
                                     "them; move it into the open")
            owner.room_checked = True

    def _check_name(self, new) -> None:
        if new.name is not None and any(b.name == new.name for b in self.outlets + self.inflows if b.kind == new.kind):
            raise ParameterError(f"{new.kind} name = {new.name!r} is not allowed: another {new.kind} has it; names "
                                 "must differ")

    def counts(self) -> dict:
        """``Simulation.boundary_counts``."""
        out = {}
        for group in (self.outlets, self.inflows):
            for k, b in enumerate(group):
                out.update(zip(b.columns(b.name or f"#{k}"), b.values()))
        return out

    def describe(self) -> dict:
        """What a checkpoint keeps of them."""
        return {"outlets": [o.describe() for o in self.outlets], "inflows": [i.describe() for i in self.inflows]}

    def restore(self, meta: dict) -> None:
        """The outlets and inflows a checkpoint kept (``describe``)."""
        for d in meta.get("outlets", []):
            self.schedule.add(Outlet.from_description(d))
        for d in meta.get("inflows", []):
            self.schedule.add(Inflow.from_description(d))


def check_outlet_refill(outlet) -> None:
    """Refuse a refill region that overlaps the outlet's: a sphere put back could be taken out again."""
    lo, hi = outlet.refill.bounds()
    olo, ohi = outlet.region.bounds()
    if np.all(lo < ohi) and np.all(olo < hi):
        raise ParameterError(f"outlet refill region {outlet.refill!r} is not allowed: it overlaps the outlet region "
                             f"{outlet.region!r}; must lie apart from it (above the bed)")


def check_outlet_inflow(outlet, inflow) -> None:
    """Refuse an outlet that holds the whole inflow region: it would take out all it inserts."""
    lo, hi = inflow.region.bounds()
    corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
    if outlet.inside(corners).all():
        raise ParameterError(f"outlet region {outlet.region!r} is not allowed with inflow region {inflow.region!r}: "
                             "it contains the whole inflow region, so every inserted particle would be taken "
                             "out at once")
