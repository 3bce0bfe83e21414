"""Periodic boundaries of a scene (``Simulation(periodic={"x": (lo, hi), ...})``): the checks and
the periodic images the scene side needs. The engine wraps positions and takes minimum images
itself (``rollingdem.engine.state.periodic_box``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rollingdem.engine.layout import I_FORCES_VALID, PERIODIC_BOX as PB, PERIODIC_BOX_SIZE
from rollingdem.engine.state import periodic_box
from rollingdem.errors import ParameterError, check_choice, check_finite, short_repr
from rollingdem.physics.records import WALL_PLANE


def check_periodic(periodic) -> dict:
    """``{"x": (lo, hi), ...}`` checked: axes among x, y, z, each lo < hi finite; in x, y, z order."""
    if periodic is None:
        return {}
    if not isinstance(periodic, dict):
        raise ParameterError(f"periodic = {short_repr(periodic)} is not allowed: must be a mapping of axes to "
                             "(min, max), e.g. {'x': (-0.05, 0.05)}")
    out = {}
    for axis, ends in periodic.items():
        if axis not in ("x", "y", "z"):
            raise ParameterError(f"periodic axis = {axis!r} is not allowed: must be 'x', 'y' or 'z'")
        try:
            lo, hi = (float(v) for v in ends)
        except (TypeError, ValueError):
            raise ParameterError(f"periodic {axis} = {short_repr(ends)} is not allowed: must be (min, max) in m") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ParameterError(f"periodic {axis} = ({lo:g}, {hi:g}) is not allowed: must be finite with "
                                 "min < max (m)")
        out[axis] = (lo, hi)
    return {axis: out[axis] for axis in "xyz" if axis in out}


@dataclass(frozen=True)
class LeesEdwards:
    """Lees-Edwards boundaries (Lees & Edwards 1972) on a periodic box: steady simple shear with flow
    along x and its gradient along ``gradient`` ("y" or "z"; both axes periodic). The image of the
    box across the gradient axis's upper end is displaced along x by a shift that grows at the shear
    velocity U = ``shear_rate`` x L_gradient (1/s, positive: v_x grows along the gradient), so a
    sphere leaving through that end comes back at the other with x less the shift and v_x less U;
    pairs across it are ordinary contacts of the shifted image, their history kept. Give
    ``shear_rate`` or ``shear_velocity`` (U, m/s). The spheres keep their whole velocity (streaming
    included); a run starts from the velocities given (an affine profile v_x = shear_rate (g - g_mid)
    starts the flow at once). LAMMPS's ``fix deform`` with ``remap v`` on an xy or xz tilt."""
    shear_rate: float | None = None
    gradient: str = "z"
    shear_velocity: float | None = None

    def to_dict(self) -> dict:
        return {"shear_rate": self.shear_rate, "gradient": self.gradient, "shear_velocity": self.shear_velocity}


class ShearedBox:
    """The periodic box of a scene and its Lees-Edwards shear, if any (``Simulation.shear``): the
    engine's box made from ``periodic`` and ``lees_edwards``, the shear rate to read or set between
    runs, and the shift."""

    def __init__(self, state, periodic: dict, lees_edwards):
        self.state, self.periodic, self.lees_edwards = state, periodic, check_lees_edwards(lees_edwards, periodic)
        le = self.lees_edwards
        if le is None:
            state.contact_list.box = periodic_box(periodic)
            return
        lo, hi = periodic[le.gradient]
        velocity = le.shear_velocity if le.shear_velocity is not None else le.shear_rate * (hi - lo)
        state.contact_list.box = periodic_box(periodic, le.gradient, velocity)

    @property
    def active(self) -> bool:
        return self.lees_edwards is not None

    def _box(self):
        box = self.state.contact_list.box
        if box.shape[0] <= PERIODIC_BOX_SIZE:
            raise ParameterError("shear is not allowed: this simulation has no Lees-Edwards boundaries; pass "
                                 "lees_edwards=rd.LeesEdwards(...) with a periodic box")
        return box

    @property
    def shear_velocity(self) -> float:
        """U (m/s): how fast the image across the gradient end moves along x."""
        return float(self._box()[PB.shear_velocity])

    @property
    def shear_rate(self) -> float:
        """U / L_gradient (1/s); may be set between runs."""
        box = self._box()
        return float(box[PB.shear_velocity] * box[PB.inv_lg])

    @shear_rate.setter
    def shear_rate(self, value):
        box = self._box()
        box[PB.shear_velocity] = check_finite("shear_rate", value) * box[PB.lg]

    @property
    def shift(self) -> float:
        """How far (m) the image across the gradient's upper end is displaced along x, in [0, L_x)."""
        return float(self._box()[PB.shift])

    def set_length(self, axis: str, length: float) -> None:
        """Make the box ``length`` (m) long along the periodic ``axis``, moving every centre affinely
        about its low end (velocities, spins and contact history kept; LAMMPS's ``change_box`` with
        ``remap``): a volume or pressure control. The shear rate is kept (the shear velocity scales
        with the gradient's length) and so is the shift's fraction of L_x. Spheres only: fixed
        spheres, walls, clumps and bonds are refused; the forces are evaluated anew at the next step."""
        if axis not in self.periodic:
            raise ParameterError(f"axis = {axis!r} is not allowed: the box is periodic along "
                                 f"{', '.join(self.periodic) or 'no axis'}")
        length = check_finite("length", length)
        if length <= 0.0:
            raise ParameterError(f"length = {length!r} is not allowed: must be positive (m)")
        st, a = self.state, "xyz".index(axis)
        if st.n_walls or (st.n and st.is_fixed.any()) or any(self.state.features()[:3]):
            raise ParameterError(f"set_length along {axis} is not allowed: the box holds walls, fixed spheres, "
                                 "clumps, bonds or meshes, which would not move with it; only free spheres")
        box = st.contact_list.box
        lo, factor = box[a], length / box[3 + a]
        st.x[:, a] = lo + (st.x[:, a] - lo) * factor
        box[3 + a], box[6 + a] = length, 1.0 / length
        if box.shape[0] > PERIODIC_BOX_SIZE:
            if a == "xyz".index(self.lees_edwards.gradient):
                box[PB.shear_velocity] *= factor
                box[PB.lg], box[PB.inv_lg] = length, 1.0 / length
            if a == 0:
                box[PB.shift] *= factor
        self.periodic[axis] = (lo, lo + length)
        st.info[I_FORCES_VALID] = 0

    def with_images(self, x: np.ndarray, r: np.ndarray, reach: float):
        """``with_images`` of this box (the images across a sheared end displaced by the shift)."""
        return with_images(self.periodic, x, r, reach, self.state.contact_list.box)

    def check_scene(self, walls, backend: str) -> None:
        """Refuse what a sheared box cannot hold: walls other than planes across the third axis
        (checked with the periodic ones), bonds, clumps, triangle meshes; the GPU's step loop."""
        if not self.active:
            return
        bonds, meshes, clumps, _ = self.state.features()
        what = ("a triangle-mesh wall" if meshes else "clumps" if clumps else "bonds" if bonds else
                "a cylinder wall" if any(w.kind != WALL_PLANE for w in walls) else
                "the cuda backend" if backend == "cuda" else None)
        if what:
            raise ParameterError(f"lees_edwards = {self.lees_edwards!r} is not allowed with {what}: a sheared box "
                                 "holds spheres and planes parallel to the flow and the gradient, stepped on the cpu "
                                 "backend")


def check_lees_edwards(value, periodic: dict):
    """``value`` (None or a ``LeesEdwards``) checked against the periodic box."""
    if value is None:
        return None
    if not isinstance(value, LeesEdwards):
        raise ParameterError(f"lees_edwards = {short_repr(value)} is not allowed: must be rd.LeesEdwards(shear_rate=..., "
                             "gradient='y' or 'z')")
    check_choice("lees_edwards gradient", value.gradient, ("y", "z"))
    if (value.shear_rate is None) == (value.shear_velocity is None):
        raise ParameterError(f"lees_edwards = {value!r} is not allowed: give one of shear_rate (1/s) or "
                             "shear_velocity (m/s)")
    check_finite("lees_edwards shear_rate" if value.shear_rate is not None else "lees_edwards shear_velocity",
                 value.shear_rate if value.shear_rate is not None else value.shear_velocity)
    for axis in ("x", value.gradient):
        if axis not in periodic:
            raise ParameterError(f"lees_edwards = {value!r} is not allowed: the flow axis x and the gradient axis "
                                 f"{value.gradient} must be periodic, and {axis} is not (periodic = "
                                 f"{ {a: list(e) for a, e in periodic.items()} })")
    return value


def check_length(periodic: dict, largest_radius: float, skin: float) -> None:
    """Each periodic length holds at least two neighbor-list cutoffs, 2 (2 R_max + skin): a pair
    within the cutoff then has one image within it, the one the minimum image finds."""
    need = 2.0 * (2.0 * largest_radius + skin)
    for axis, (lo, hi) in periodic.items():
        if hi - lo < need:
            raise ParameterError(f"periodic {axis} length = {hi - lo:g} m is not allowed: must be at least "
                                 f"2 (2 R_max + skin) = {need:g} m (R_max = {largest_radius:g} m, skin = {skin:g} m), "
                                 "or a particle could touch two images of another")


def check_scene(sim) -> None:
    """``check_length`` for a simulation, with its largest particle (or inflow particle) and skin;
    and no plane across a periodic axis (a particle leaving through one end would come back on the
    wrong side of it: the wall is not periodic)."""
    if sim.periodic and sim.n_particles:
        check_length(sim.periodic, sim.particle_set.largest_radius(sim.inflows), sim.skin)
    sim.shear.check_scene(sim.walls, sim.backend)
    for wall in sim.walls:
        if wall.kind != WALL_PLANE:
            continue
        for axis in sim.periodic:
            if abs(wall.normal["xyz".index(axis)]) > 1e-12:
                raise ParameterError(f"wall {sim.wall_set.label(wall)}: a plane of normal {list(wall.normal)} is not "
                                     f"allowed with the periodic {axis}: it cuts across that axis, and a particle "
                                     f"leaving at one end of the box would come back on its other side; make {axis} "
                                     "not periodic, or the plane parallel to it")


def check_in_box(periodic: dict, x: np.ndarray, first: int) -> None:
    """Refuse a new position outside the box along a periodic axis (``first``: the first new index)."""
    for axis, (lo, hi) in periodic.items():
        a = "xyz".index(axis)
        bad = (x[:, a] < lo) | (x[:, a] >= hi)
        if bad.any():
            k = int(np.argmax(bad))
            raise ParameterError(f"position of particle {first + k} = {x[k].tolist()} is not allowed: "
                                 f"{axis} must be in the periodic box [{lo:g}, {hi:g}) m")


def check_region_inside(periodic: dict, what: str, region) -> None:
    """Refuse a region that reaches out of the box along a periodic axis."""
    lo, hi = region.bounds()
    for axis, (a_lo, a_hi) in periodic.items():
        a = "xyz".index(axis)
        if lo[a] < a_lo or hi[a] > a_hi:
            raise ParameterError(f"{what} region {region!r} is not allowed: along the periodic {axis} it "
                                 f"reaches [{lo[a]:g}, {hi[a]:g}], outside the box [{a_lo:g}, {a_hi:g}) m; must "
                                 "lie inside it")


def with_images(periodic: dict, x: np.ndarray, r: np.ndarray, reach: float, box=None):
    """``x``, ``r`` and the periodic images of those within ``reach`` of a periodic end;
    returns (positions, radii, index of each one's original). With the engine's ``box``, sheared:
    the images across the gradient's ends are displaced along x by the shift, first, so that the x
    ends then image them too."""
    source = np.arange(len(x))
    sheared = box is not None and box.shape[0] > PERIODIC_BOX_SIZE
    gradient = ("y" if box[PB.gradient_y] != 0.0 else "z") if sheared else None
    for axis in sorted(periodic, key=lambda a: a != gradient):
        (lo, hi), a = periodic[axis], "xyz".index(axis)
        length = hi - lo
        low, high = x[:, a] < lo + reach, x[:, a] > hi - reach
        up, down = x[low].copy(), x[high].copy()
        up[:, a] += length
        down[:, a] -= length
        if axis == gradient:  # the image above is displaced by +shift along x, the one below by -shift
            up[:, 0] += box[PB.shift]
            down[:, 0] -= box[PB.shift]
        x = np.concatenate([x, up, down])
        r = np.concatenate([r, r[low], r[high]])
        source = np.concatenate([source, source[low], source[high]])
    return x, r, source
