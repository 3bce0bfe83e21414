"""Periodic boundaries of a scene (``Simulation(periodic={"x": (lo, hi), ...})``): the checks and
the periodic images the scene side needs. The engine wraps positions and takes minimum images
itself (``rollingdem.engine.state.periodic_box``)."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import ParameterError, short_repr
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


def with_images(periodic: dict, x: np.ndarray, r: np.ndarray, reach: float):
    """``x``, ``r`` and the periodic images of those within ``reach`` of a periodic end;
    returns (positions, radii, index of each one's original)."""
    source = np.arange(len(x))
    for axis, (lo, hi) in periodic.items():
        a, length = "xyz".index(axis), hi - lo
        low, high = x[:, a] < lo + reach, x[:, a] > hi - reach
        up, down = x[low].copy(), x[high].copy()
        up[:, a] += length
        down[:, a] -= length
        x = np.concatenate([x, up, down])
        r = np.concatenate([r, r[low], r[high]])
        source = np.concatenate([source, source[low], source[high]])
    return x, r, source
