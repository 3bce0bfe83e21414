"""The clumps of a scene: rigid bodies of member spheres (``rd.Clump`` templates) placed, read and
moved as bodies. ``Simulation.add_clumps`` hands its calls here; the step loop moves them
(``engine.rigid_body.clump_rows``), docs/models.md §17.

Each member is a particle of the engine state: it touches walls and other particles with every
contact law and rolling and twisting model, as any sphere does, and carries its share of the
clump's mass in proportion to its own sphere's volume (so sums of particle masses, gravity and the
outlets' mass counts hold). Members of one clump never touch each other.
"""

from __future__ import annotations

import numpy as np

from rollingdem.engine.layout import I_FORCES_VALID
from rollingdem.errors import ParameterError, check_finite, check_positive, short_repr
from rollingdem.scene import periodic as periodic_box
from rollingdem.scene.clumps import Clump, random_orientations
from rollingdem.scene.insertion import MAX_PACKING_FRACTION, fill_region
from rollingdem.scene.particles import SOLID_SPHERE, vectors_of


def quaternion_product(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """p q for rows of unit quaternions (w, x, y, z): the turn q, then p."""
    pw, pv, qw, qv = p[..., :1], p[..., 1:], q[..., :1], q[..., 1:]
    return np.concatenate([pw * qw - np.sum(pv * qv, axis=-1, keepdims=True),
                           pw * qv + qw * pv + np.cross(pv, qv)], axis=-1)


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """(m, 3, 3) rotation matrices of rows of unit quaternions (w, x, y, z)."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def matrix_quaternion(a: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix (scipy's, reordered)."""
    from scipy.spatial.transform import Rotation  # deferred: slow to load, used here only

    x, y, z, w = Rotation.from_matrix(a).as_quat()
    return np.array([w, x, y, z])


def orientations_of(orientations, m: int) -> np.ndarray:
    """(m, 4) unit quaternions from None (the template's frame), one or m of them, normalised."""
    if orientations is None:
        return np.tile([1.0, 0.0, 0.0, 0.0], (m, 1))
    try:
        q = np.array(orientations, dtype=float, ndmin=2)
    except (TypeError, ValueError):
        q = None
    if q is None or isinstance(orientations, str) or q.ndim != 2 or q.shape[1] != 4 or len(q) not in (1, m):
        raise ParameterError(f"orientations = {short_repr(orientations)} is not allowed: must be one unit "
                             f"quaternion (w, x, y, z) or one for each of the {m} clumps")
    norm = np.linalg.norm(q, axis=1)
    bad = ~(np.isfinite(norm) & (norm > 0))
    if bad.any():
        raise ParameterError(f"orientations[{int(np.argmax(bad))}] = {q[np.argmax(bad)].tolist()} is not allowed: "
                             "a quaternion must be finite and nonzero")
    return np.broadcast_to(q / norm[:, None], (m, 4)).copy()


def refuse_coarse_graining(material) -> None:
    """Clumps are not coarse-grained: the rule for a parcel of clumps is not known."""
    if material.coarse_graining != 1.0:
        raise ParameterError(f"material {material.name!r}: coarse_graining = {material.coarse_graining:g} is not allowed "
                             "for clumps: coarse graining is for spheres (a clump's parcel has no known rule); give "
                             "the clumps a material with coarse_graining 1")


class ClumpSet:
    """The clumps of a simulation, in its engine state's per-clump fields: ``materials`` its table,
    ``periodic`` its box, ``particles`` and ``walls`` its ``Particles`` and ``WallSet`` (a clump's
    members go in clear of both), ``on_change`` called when the scene changes."""

    def __init__(self, state, materials, periodic: dict, particles, walls, on_change):
        self.state = state  # the engine state, the same object for the simulation's life
        self.materials, self.periodic, self.particles, self.walls = materials, periodic, particles, walls
        self.on_change = on_change

    def add(self, clump, positions, material, orientations=None, velocity=None, angular_velocity=None,
            fixed=False, allow_overlap=False) -> np.ndarray:
        """``Simulation.add_clumps``."""
        st = self.state
        if not isinstance(clump, Clump):
            raise ParameterError(f"clump = {short_repr(clump)} is not allowed: must be a rollingdem.Clump")
        try:
            X = np.array(positions, dtype=np.float64, ndmin=2)
        except (TypeError, ValueError):
            X = None
        if X is None or X.ndim != 2 or X.shape[1] != 3 or not np.isfinite(X).all():
            raise ParameterError(f"positions = {short_repr(positions)} is not allowed: must be N finite points of "
                                 "three numbers, the clumps' centres of mass (m)")
        m, k = len(X), len(clump.radii)
        q_user = orientations_of(orientations, m)
        V = vectors_of("velocity", velocity, m)
        omega = vectors_of("angular_velocity", angular_velocity, m)
        if not isinstance(fixed, (bool, np.bool_)):
            raise ParameterError(f"fixed = {short_repr(fixed)} is not allowed: must be True or False")
        if fixed and (V.any() or omega.any()):
            raise ParameterError("velocity / angular_velocity of fixed clumps is not allowed: a fixed clump never "
                                 "moves; leave them out")
        if isinstance(material, (list, tuple, np.ndarray)):
            raise ParameterError(f"material = {short_repr(material)} is not allowed: a clump's members are of one "
                                 "material; add clumps of different materials in separate calls")
        mat = self.materials.index(material)
        refuse_coarse_graining(self.materials[mat])
        periodic_box.check_in_box(self.periodic, X, st.n)
        self.check_periodic_reach(clump)
        props = clump.mass_properties(self.materials.materials[mat].density)
        axes = props.principal_axes  # columns: the principal axes in the template's frame
        body = (clump.centres - props.centre) @ axes  # the members in the principal frame
        q_body = quaternion_product(q_user, np.broadcast_to(matrix_quaternion(axes), (m, 4)))
        turn = rotation_matrices(q_body)  # (m, 3, 3) principal frame -> space
        r = np.einsum("cij,kj->cki", turn, body)  # (m, k, 3) members from the centres
        x = (X[:, None, :] + r).reshape(-1, 3)
        radius = np.tile(clump.radii, m)
        labels = np.repeat(np.arange(m), k)
        if not allow_overlap:
            self.particles.check_no_overlap(x, radius, walls=not fixed, bodies=labels)
        volumes = clump.radii ** 3
        share = np.tile(props.mass * volumes / volumes.sum(), m)
        # L = R diag(I) R^T omega
        body_omega = np.einsum("cji,cj->ci", turn, omega)
        L = np.einsum("cij,cj->ci", turn, body_omega * props.principal_moments)
        v = (V[:, None, :] + np.cross(omega[:, None, :], r)).reshape(-1, 3)
        first = st.n_clumps
        st.append_particles(x=x, v=v, w=np.repeat(omega, k, axis=0), radius=radius, mass=share,
                            inertia=SOLID_SPHERE * share * radius ** 2, mat=np.full(m * k, mat, dtype=np.int32),
                            fixed=np.full(m * k, bool(fixed), dtype=np.uint8))
        st.add_clumps(labels, np.tile(body, (m, 1)), clump_x=X, clump_v=V, clump_q=q_body, clump_L=L,
                      clump_mass=np.full(m, props.mass), clump_moments=np.tile(props.principal_moments, (m, 1)))
        self.on_change()
        return np.arange(first, first + m)

    def insert(self, region, count, clump, material, seed=0, velocity=None, max_attempts=200, mass=None,
               fraction=None, radius=None) -> np.ndarray:
        """``Simulation.insert`` with a clump: each clump's bounding sphere (its ``reach`` about its
        centre of mass) placed as the spheres are (wholly inside ``region``, clear of the particles and
        walls there), the clump in it at a random orientation (``random_orientations``, from ``seed``),
        as LIGGGHTS inserts its multispheres. ``mass`` or ``fraction`` of the region's volume give the
        count of clumps nearest them."""
        if not isinstance(clump, Clump):
            raise ParameterError(f"clump = {short_repr(clump)} is not allowed: must be a rollingdem.Clump")
        if radius is not None:
            raise ParameterError(f"radius = {short_repr(radius)} is not allowed with a clump: its members' radii "
                                 "are the clump's; leave radius out")
        if material is None or isinstance(material, (list, tuple, np.ndarray)):
            raise ParameterError(f"material = {short_repr(material)} is not allowed: give the clumps' one material")
        refuse_coarse_graining(self.materials[material])
        given = [(k, v) for k, v in (("count", count), ("mass", mass), ("fraction", fraction)) if v is not None]
        if len(given) != 1:
            raise ParameterError(f"{', '.join(f'{k} = {v!r}' for k, v in given) or 'count = None'} is not allowed: "
                                 "give exactly one of count, mass (kg) and fraction (of the region's volume)")
        volume = clump.mass_properties(1.0).volume
        if mass is not None:
            count = max(1, round(check_positive("mass", mass, "kg") / (self.materials[material].density * volume)))
        elif fraction is not None:
            fraction = check_finite("fraction", fraction)
            if not 0.0 < fraction <= MAX_PACKING_FRACTION:
                raise ParameterError(f"fraction = {fraction:g} is not allowed: must be in (0, {MAX_PACKING_FRACTION}]")
            count = max(1, round(fraction * region.volume() / volume))
        try:
            centres, _ = fill_region(region, count, clump.reach(), seed=seed, existing_positions=self.state.x,
                                     existing_radii=self.state.radius, walls=self.walls.in_place(), max_attempts=max_attempts)
        except ParameterError as err:  # it placed the clumps' bounding spheres: say so
            raise ParameterError(str(err).replace(" spheres in ", " clumps (their bounding spheres, radius "
                                                  f"{clump.reach():.3g} m) in ", 1)) from None
        turns = random_orientations(np.random.default_rng([seed, 46]), len(centres))
        return self.add(clump, centres, material, turns, velocity)

    def set_velocities(self, indices, velocity=None, angular_velocity=None) -> None:
        """``Simulation.set_clump_velocities``: the centre's velocity (m/s) and the angular velocity
        (rad/s, space frame) of some clumps; their members follow at the next step."""
        st = self.state
        arr = np.atleast_1d(np.asarray(indices))
        if arr.dtype.kind not in "iu" or arr.ndim != 1 or ((arr < 0) | (arr >= st.n_clumps)).any():
            raise ParameterError(f"indices = {short_repr(indices)} is not allowed: must be clump indices (whole "
                                 f"numbers in [0, {st.n_clumps - 1}])" if st.n_clumps else
                                 f"indices = {short_repr(indices)} is not allowed: there are no clumps")
        first = st.clump_start[arr]
        if len(st.fixed) and st.fixed[st.clump_members[first]].any() and (
                np.any(velocity) or np.any(angular_velocity)):
            raise ParameterError(f"indices = {short_repr(indices)} is not allowed with a nonzero velocity: a fixed "
                                 "clump never moves")
        if velocity is not None:
            st.clump_v[arr] = vectors_of("velocity", velocity, len(arr))
        if angular_velocity is not None:
            omega = vectors_of("angular_velocity", angular_velocity, len(arr))
            turn = rotation_matrices(st.clump_q[arr])
            body = np.einsum("cji,cj->ci", turn, omega) * st.clump_moments[arr]
            st.clump_L[arr] = np.einsum("cij,cj->ci", turn, body)
        st.info[I_FORCES_VALID] = 0

    def check_periodic_reach(self, clump: Clump) -> None:
        """Refuse a clump that spans half a periodic length: its members would meet its own image."""
        for axis, (lo, hi) in self.periodic.items():
            if 4.0 * clump.reach() > hi - lo:
                raise ParameterError(f"clump {clump!r} of reach {clump.reach():.3g} m is not allowed in a box periodic "
                                     f"along {axis} of length {hi - lo:.3g} m: a clump must span less than half "
                                     "the periodic length (4 x its reach), or it would touch its own image")

    def table(self) -> dict:
        """``Simulation.clumps``."""
        st = self.state
        turn = rotation_matrices(st.clump_q) if st.n_clumps else np.zeros((0, 3, 3))
        body_w = np.einsum("cji,cj->ci", turn, st.clump_L) / np.where(st.clump_moments > 0, st.clump_moments, 1.0)
        return {"centre": st.clump_x.copy(), "velocity": st.clump_v.copy(),
                "angular_velocity": np.einsum("cij,cj->ci", turn, body_w), "orientation": st.clump_q.copy(),
                "axes": turn, "mass": st.clump_mass.copy(), "moments": st.clump_moments.copy(),
                "angular_momentum": st.clump_L.copy()}

    def kinetic_energy(self) -> tuple[float, float]:
        """The clumps' (translational, rotational) kinetic energy (J): 1/2 M V^2, 1/2 L . omega."""
        st = self.state
        if not st.n_clumps:
            return 0.0, 0.0
        t = self.table()
        trans = 0.5 * float(np.dot(st.clump_mass, np.einsum("ij,ij->i", st.clump_v, st.clump_v)))
        rot = 0.5 * float(np.einsum("ij,ij->", t["angular_momentum"], t["angular_velocity"]))
        return trans, rot

