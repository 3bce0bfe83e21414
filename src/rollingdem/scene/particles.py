"""The spheres of a scene: adding them (one by one or filling a region), reading their values in
the order they were added, and setting some of them. ``Simulation`` hands these calls here."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.engine.layout import I_FORCES_VALID
from rollingdem.engine.neighbors import spatial_order
from rollingdem.engine.schema import PER_PARTICLE, SCHEMA
from rollingdem.errors import Declared, ParameterError, check_finite, check_positive, short_repr
from rollingdem.physics.records import ENERGY_CHANNELS
from rollingdem.scene import periodic as periodic_box
from rollingdem.scene.insertion import MAX_PACKING_FRACTION, check_count, fill_region
from rollingdem.scene.size_distributions import parcels_of, realised_line

SOLID_SPHERE = 0.4
"""A solid sphere's moment of inertia over m R^2: I = 2/5 m R^2."""


#: the parameters of the calls that add particles (``Simulation.add_particles``, ``insert``,
#: ``add_clumps``, ``add_inflow``), written once: the case file's particle and inflow blocks follow them
PARTICLE_DECLARED = {
    "positions": Declared("centres of the spheres (of the clumps' centres of mass)", "m", "vectors"),
    "radius": Declared("radius: one for all, one per sphere, or a size distribution", "m", "radius"),
    "material": Declared("name of the material (or one per sphere)", kind="text"),
    "velocity": Declared("initial velocity (one for all, or one per sphere)", "m/s", "velocities"),
    "angular_velocity": Declared("initial angular velocity (one for all, or one per sphere)", "rad/s", "velocities"),
    "allow_overlap": Declared("accept particles that overlap each other or a wall", kind="flag"),
    "fixed": Declared("particles that never move: a rough base, an obstacle", kind="flag"),
    "region": Declared("the region filled", kind="region"),
    "count": Declared("how many (or give mass or fraction)", kind="whole", low=0),
    "mass": Declared("their total mass (instead of count)", "kg", low=0.0, low_open=True),
    "fraction": Declared("the share of the region's volume they fill (instead of count)", "-", low=0.0,
                         high=MAX_PACKING_FRACTION, low_open=True),
    "seed": Declared("seed of the random places, sizes and orientations", kind="whole", low=0),
    "max_attempts": Declared("tries to place each sphere before the fill gives up", kind="whole", low=1),
    "clump": Declared("the clump template of each rigid body", kind="clump"),
    "orientations": Declared("unit quaternions w, x, y, z turning the template (default its own frame)", "-",
                             "quaternions"),
}


def sphere_mass(density, radius):
    """m = 4/3 pi rho R^3 (kg)."""
    return density * (4.0 / 3.0) * math.pi * radius ** 3


def radii_of(radius, m: int) -> np.ndarray:
    """One radius per sphere from a number or a sequence of m numbers."""
    try:
        r = np.asarray(radius, dtype=np.float64)
    except (TypeError, ValueError):
        r = None
    if r is None or isinstance(radius, (str, bool)) or r.ndim > 1:
        raise ParameterError(f"radius = {short_repr(radius)} is not allowed: must be a number or one number per "
                             "sphere (m)")
    if r.ndim == 1 and r.shape[0] != m:
        raise ParameterError(f"radius with {r.shape[0]} values is not allowed for {m} positions: must be one "
                             f"radius or one per sphere ({m})")
    return np.broadcast_to(r, (m,)).copy()


def vectors_of(name: str, value, m: int) -> np.ndarray:
    """(m, 3) vectors from one 3-vector or m of them (zeros for None)."""
    if value is None:
        return np.zeros((m, 3))
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = None
    if arr is None or isinstance(value, str) or not (arr.shape == (3,) or arr.shape == (m, 3)):
        raise ParameterError(f"{name} = {short_repr(value)} is not allowed: must be three numbers, or three "
                             f"for each of the {m} spheres")
    arr = np.broadcast_to(arr, (m, 3)).copy()
    if not np.isfinite(arr).all():
        raise ParameterError(f"{name} = {short_repr(value)} is not allowed: components must be finite")
    return arr


class Particles:
    """The spheres of a simulation: its engine state holds them, sorted in space; this collection
    numbers them as the user added them (``by_id``) and checks what goes in: against ``materials``
    (its table), ``periodic`` (its box) and ``walls`` (its ``WallSet``), refusals naming ``hints``
    (how to turn a check off); ``on_change`` is called when the scene changes."""

    def __init__(self, state, materials, periodic: dict, hints: dict, walls, on_change):
        self.state = state  # the engine state, the same object for the simulation's life
        self.materials, self.periodic, self.hints, self.walls = materials, periodic, hints, walls
        self.on_change = on_change
        self.fills: list[str] = []  # each insert's count, region and realised size distribution, in words

    def by_id(self, name: str) -> np.ndarray:
        """A per-particle array of the state in the order the particles were added."""
        return self.state.by_id(getattr(self.state, name))

    def add(self, positions, radius, material, velocity=None, angular_velocity=None, allow_overlap=False,
            fixed=False, parcels=False) -> np.ndarray:
        """``Simulation.add_particles``: ``radius`` the real particles', which a coarse-grained material
        turns into its parcels' (times alpha, docs/models.md §18); ``parcels``: the radii are the
        parcels' already (an inflow's, an outlet's refill)."""
        try:
            x = np.array(positions, dtype=np.float64, ndmin=2)
        except (TypeError, ValueError):
            raise ParameterError(f"positions = {short_repr(positions)} is not allowed: must be N points of three "
                                 "numbers (m)") from None
        if x.ndim != 2 or x.shape[1] != 3:
            raise ParameterError(f"positions with shape {x.shape} are not allowed: must be N points of three "
                                 "numbers, shape (N, 3)")
        m = x.shape[0]
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            k = int(np.nonzero(bad)[0][0])
            raise ParameterError(f"position of particle {k} = {x[k].tolist()} is not allowed: must be finite")
        r = radii_of(radius, m)
        badr = ~(np.isfinite(r) & (r > 0))
        if badr.any():
            k = int(np.nonzero(badr)[0][0])
            raise ParameterError(f"radius of particle {k} = {r[k]:g} is not allowed: must be > 0 (m)")
        v = vectors_of("velocity", velocity, m)
        w = vectors_of("angular_velocity", angular_velocity, m)
        if not isinstance(fixed, (bool, np.bool_)):
            raise ParameterError(f"fixed = {short_repr(fixed)} is not allowed: must be True or False")
        if fixed and (v.any() or w.any()):
            raise ParameterError("velocity / angular_velocity of fixed particles is not allowed: a fixed particle "
                                 "never moves; leave them out (or add the particles with fixed=False)")
        mats = self.material_indices(material, m)
        if not parcels:
            r = r * self.materials.coarse_graining_factors()[mats]
        periodic_box.check_in_box(self.periodic, x, self.state.n)
        if not allow_overlap:
            alphas = self.materials.coarse_graining_factors()[mats]
            k = int(np.argmax(alphas)) if m else 0
            note = "" if parcels or not m or alphas[k] == 1.0 else (
                f"; they are parcels of coarse_graining {alphas[k]:g}, of radius alpha r = {r[k]:.4g} m for r = "
                f"{r[k] / alphas[k]:.4g} m: place them alpha times farther apart, or give a smaller coarse_graining")
            self.check_no_overlap(x, r, walls=not fixed, note=note)  # walls never touch a fixed particle
        density = np.array([self.materials.materials[k].density for k in mats])
        mass = sphere_mass(density, r)
        first = self.state.n
        self.state.append_particles(x=x, v=v, w=w, radius=r, mass=mass, inertia=SOLID_SPHERE * mass * r ** 2,
                                    mat=mats, fixed=np.full(m, bool(fixed), dtype=np.uint8))
        self.on_change()
        return np.arange(first, first + m)

    def material_indices(self, material, m: int) -> np.ndarray:
        """One material index per sphere from one material (name or index) or m of them."""
        materials = self.materials
        if not isinstance(material, (list, tuple, np.ndarray)):
            return np.full(m, materials.index(material), dtype=np.int32)
        if len(material) != m:
            raise ParameterError(f"material with {len(material)} entries is not allowed for {m} positions: "
                                 "must be one material or one per sphere")
        return np.array([materials.index(mm) for mm in material], dtype=np.int32)

    def check_no_overlap(self, x, r, tolerance=1e-12, walls=True, bodies=None, note=""):
        """Refuse new spheres (``x``, ``r``) that overlap a sphere before them (or its periodic
        image) or, with ``walls``, a wall in place; ``bodies`` (one label per new sphere): new
        spheres of one label (a clump's members) may overlap each other."""
        from scipy.spatial import cKDTree  # deferred: slow to load, used here only

        st = self.state
        first = st.n
        allx = np.concatenate([st.x, x])
        allr = np.concatenate([st.radius, r])
        imgx, imgr, source = periodic_box.with_images(self.periodic, allx, allr, 2.0 * float(allr.max()),
                                                      st.contact_list.box)
        tree = cKDTree(imgx)
        # each new sphere against every sphere (or periodic image) before it within its radius plus
        # the largest radius
        for k, near in enumerate(tree.query_ball_point(x, r + allr.max())):
            near = np.asarray(near, dtype=np.int64)
            i = first + k
            near = near[source[near] < i]
            if bodies is not None:
                new = source[near] - first
                near = near[(new < 0) | (bodies[np.maximum(new, 0)] != bodies[k])]
            if near.size == 0:
                continue
            gap = np.linalg.norm(imgx[near] - allx[i], axis=1) - imgr[near] - allr[i]
            bad = gap < -tolerance * (imgr[near] + allr[i])
            if bad.any():
                j = int(source[near[np.argmax(bad)]])
                j = int(st.ids[j]) if j < first else j  # as the user numbers them
                g = float(gap[np.argmax(bad)])
                raise ParameterError(f"particles {min(i, j)} and {max(i, j)} overlap by {-g:.3g} m at insertion{note}: "
                                     f"positions must not overlap ({self.hints['allow_overlap']} to accept it)")
        for wl in self.walls.in_place() if walls else ():
            ov = wl.overlap(x, r)
            k = int(np.argmax(ov)) if len(ov) else 0
            if len(ov) and ov[k] > tolerance * r[k]:
                raise ParameterError(f"particle {first + k} overlaps wall {self.walls.label(wl)} by {ov[k]:.3g} m "
                                     f"at insertion{note} ({self.hints['allow_overlap']} to accept it)")

    def insert(self, region, count, radius, material, seed=0, velocity=None, max_attempts=200, mass=None,
               fraction=None) -> np.ndarray:
        """``Simulation.insert``."""
        if radius is None or material is None:
            raise ParameterError(f"{'radius' if radius is None else 'material'} = None is not allowed: give the "
                                 "spheres' radius (m, or a size distribution) and material")
        alpha = self.coarse_graining(material)  # an unknown material is refused before a long fill
        if velocity is not None:
            vectors_of("velocity", velocity, 1)
        given = [(k, v) for k, v in (("count", count), ("mass", mass), ("fraction", fraction)) if v is not None]
        if len(given) != 1:
            raise ParameterError(f"{', '.join(f'{k} = {v!r}' for k, v in given) or 'count = None'} is not allowed: "
                                 "give exactly one of count, mass (kg) and fraction (of the region's volume)")
        volume = None
        if mass is not None or fraction is not None:
            if isinstance(material, (list, tuple, np.ndarray)):
                raise ParameterError(f"material = {short_repr(material)} is not allowed with {given[0][0]}: give one "
                                     "material (its density turns the mass into a volume)")
            if mass is not None:
                volume = check_positive("mass", mass, "kg") / self.materials[material].density
            else:
                fraction = check_finite("fraction", fraction)
                if not 0.0 < fraction <= MAX_PACKING_FRACTION:
                    raise ParameterError(f"fraction = {fraction:g} is not allowed: must be in (0, {MAX_PACKING_FRACTION}] "
                                         "(random insertion tops out near 0.3-0.35; insert less and let it settle)")
                volume = fraction * region.volume()
        placed = parcels_of(radius, alpha)
        if alpha != 1.0 and not region.fits(placed.max_radius):
            raise ParameterError(f"coarse_graining = {alpha:g} is not allowed for {region!r}: its parcels, up to "
                                 f"{placed.max_radius:.3g} m in radius, do not fit in it; lower the material's "
                                 "coarse_graining (or use a larger region)")
        if count is not None and alpha != 1.0:  # the real particles to stand for, alpha^3 in a parcel
            count = max(1, int(round(check_count("count", count) / alpha ** 3)))
        x, r = fill_region(region, count, placed, seed=seed, existing_positions=self.state.x,
                           existing_radii=self.state.radius, walls=self.walls.in_place(), max_attempts=max_attempts,
                           volume=volume)
        what = "spheres" if alpha == 1.0 else f"parcels (alpha {alpha:g}, {len(r) * alpha ** 3:.4g} particles)"
        self.fills.append(f"{len(r)} {what} in {region!r}: {realised_line(placed, r)}")
        order = spatial_order(x, 2.0 * float(r.max()))  # neighbors in space get nearby indices
        return self.add(x[order], r[order], material, velocity=velocity, parcels=True)

    def coarse_graining(self, material) -> float:
        """The coarse-graining factor alpha of ``material`` (a name, an index, or one per sphere, all of
        one alpha)."""
        materials = self.materials
        given = material if isinstance(material, (list, tuple, np.ndarray)) else [material]
        alphas = sorted({materials[mat].coarse_graining for mat in given})
        if len(alphas) > 1:
            raise ParameterError(f"material = {short_repr(material)} is not allowed: its materials are coarse-grained "
                                 f"by different factors {alphas}; insert each material on its own")
        return alphas[0] if alphas else 1.0

    def unwrapped_positions(self) -> np.ndarray:
        """``Simulation.unwrapped_positions``."""
        st = self.state
        box = st.contact_list.box
        return st.by_id(st.x + st.image * box[3:6]) if len(box) else st.by_id(st.x).copy()

    def indices(self, indices, name="indices") -> np.ndarray:
        """Particle indices as int64, each in [0, n_particles)."""
        n = self.state.n
        arr = np.atleast_1d(np.asarray(indices, dtype=object if isinstance(indices, str) else None))
        if arr.size and (arr.dtype.kind not in "iu" or arr.ndim != 1):
            raise ParameterError(f"{name} = {short_repr(indices)} is not allowed: must be particle indices (whole "
                                 f"numbers in [0, {n - 1}])")
        arr = arr.astype(np.int64)
        bad = (arr < 0) | (arr >= n)
        if bad.any():
            k = int(arr[np.argmax(bad)])
            allowed = f"must be in [0, {n - 1}]" if n else "there are no particles"
            raise ParameterError(f"{name} = {short_repr(indices)} is not allowed: particle {k} does not exist; {allowed}")
        return arr

    def set_velocities(self, indices, velocity=None, angular_velocity=None) -> None:
        """``Simulation.set_velocities``."""
        st = self.state
        ids = self.indices(indices)
        idx = st.slots(ids)
        held = st.is_fixed[idx]
        if held.any() and any(np.any(vec) for vec in (velocity, angular_velocity) if vec is not None):
            raise ParameterError(f"indices = {short_repr(indices)} is not allowed with a nonzero velocity: particle "
                                 f"{int(ids[np.argmax(held)])} is fixed and never moves; leave the fixed particles "
                                 "out (sim.fixed says which they are)")
        self.refuse_members(ids, idx, "velocity / angular_velocity")
        if velocity is not None:
            st.v[idx] = vectors_of("velocity", velocity, len(idx))
        if angular_velocity is not None:
            st.w[idx] = vectors_of("angular_velocity", angular_velocity, len(idx))
        st.info[I_FORCES_VALID] = 0

    def refuse_members(self, ids, idx, what: str) -> None:
        """Refuse setting ``what`` of a clump's members (slots ``idx``, ids ``ids``): their clump moves
        them, and would overwrite it."""
        st = self.state
        if st.n_clumps and (st.clump[idx] >= 0).any():
            k = int(np.argmax(st.clump[idx] >= 0))
            raise ParameterError(f"indices = {short_repr(ids.tolist())} is not allowed for {what}: particle {int(ids[k])} "
                                 f"is a member of clump {int(st.clump[idx[k]])}, which moves as one body; set the "
                                 "clump's with sim.set_clump_velocities")

    def field(self, name: str):
        """The schema's per-particle field ``name``; else a refusal naming the fields."""
        fields = {f.name: f for f in SCHEMA.of(PER_PARTICLE)}
        if name not in fields:
            raise ParameterError(f"field = {name!r} is not allowed: the per-particle fields are {', '.join(fields)}")
        return fields[name]

    def set_field(self, name: str, indices, values) -> None:
        """``Simulation.set_particle_field``."""
        st = self.state
        field = self.field(name)
        if not field.settable:
            raise ParameterError(f"field = {name!r} is not allowed: the engine keeps it; settable are "
                                 + ", ".join(f.name for f in SCHEMA.of(PER_PARTICLE) if f.settable))
        ids = self.indices(indices)
        idx = st.slots(ids)
        if field.name in ("x", "v", "w"):
            self.refuse_members(ids, idx, field.name)
        array = getattr(st, field.name)
        if field.lazy and len(array) != st.n:  # no rows yet: every particle at the fill
            array = field.rows(st.n, st.history_size)
            setattr(st, field.name, array)
        try:
            array[idx] = np.asarray(values, dtype=field.dtype)
        except (TypeError, ValueError):
            raise ParameterError(f"values = {short_repr(values)} is not allowed for {name}: one value, or one for each "
                                 f"of the {len(idx)} particles") from None
        st.info[I_FORCES_VALID] = 0

    def kinetic_energy(self, bodies) -> tuple[float, float]:
        """(translational, rotational) kinetic energy (J): 1/2 sum m v^2, 1/2 sum I w^2 over the
        spheres, and over the clumps as bodies (``bodies``, the ``ClumpSet``), not their members."""
        st = self.state
        free = st.clump < 0 if len(st.clump) else slice(None)
        trans = 0.5 * float(np.dot(st.mass[free], np.einsum("ij,ij->i", st.v[free], st.v[free])))
        rot = 0.5 * float(np.dot(st.inertia[free], np.einsum("ij,ij->i", st.w[free], st.w[free])))
        clump_trans, clump_rot = bodies.kinetic_energy()
        return trans + clump_trans, rot + clump_rot

    def dissipated_energy(self, track_energy: bool) -> dict[str, float]:
        """``Simulation.dissipated_energy``."""
        st = self.state
        if not track_energy and not st.energy.any() and not st.energy_removed.any():
            raise ParameterError("dissipated_energy: track_energy = False, so no dissipated energy was summed; "
                                 "create the Simulation with track_energy=True (or set sim.track_energy = True "
                                 "before the run)")
        in_place = st.energy.sum(axis=0) if len(st.energy) else np.zeros(len(ENERGY_CHANNELS))
        return dict(zip(ENERGY_CHANNELS, (in_place + st.energy_removed).tolist()))

    def represented(self) -> float:
        """The real particles the spheres stand for: alpha^3 for a parcel of a material coarse-grained by
        alpha, 1 for any other sphere (docs/models.md §18)."""
        return float(np.sum(self.materials.coarse_graining_factors()[self.state.mat[:self.state.n]] ** 3))

    def coarse_graining_note(self) -> str:
        """"; parcels of alpha A, standing for N particles" when a material is coarse-grained, else ""."""
        alphas = sorted({m.coarse_graining for m in self.materials.materials} - {1.0})
        if not alphas:
            return ""
        return f"; parcels of alpha {alphas[0]:g}, standing for {self.represented():.6g} particles"

    def largest_radius(self, inflows=()) -> float:
        """The largest radius in place or to come from ``inflows`` (0 when none)."""
        return max([float(self.state.radius.max(initial=0.0))] + [i.radius.max_radius for i in inflows])
