"""A rotating drum's bed on its cross-section (positions, velocities and radii as numpy arrays, SI
units, angles in degrees): the angle of its free surface and of its centre of mass, the depth of
its flowing layer, and how closely the bed below it turns with the drum."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.analysis.repose import touching
from rollingdem.errors import ParameterError

__all__ = ["com_angle", "flowing_depth", "flowing_layer", "rotation_ratios", "surface_angle"]


def surface_angle(positions, radii, diameter: float) -> tuple[float, float, float, float]:
    """The angle (deg) of a drum bed's free surface, seen along the drum's axis (z; gravity -y).

    The cross-section is cut into columns one mean ``diameter`` wide along x; a column's surface
    height is the top (y + r) of its highest sphere that touches another (a sphere flying over
    the bed is not the surface). The chord is the span of columns holding spheres; a least-squares
    line through the column tops of its middle third gives the angle, atan(slope), positive when
    the surface rises towards +x. Returns (angle, slope, x, y) with (x, y) the line's point at the
    chord's middle."""
    x = np.asarray(positions, float)
    r = np.broadcast_to(np.asarray(radii, float), (len(x),))
    on = touching(x, r)
    x, r = x[on], r[on]
    col = np.floor(x[:, 0] / diameter).astype(np.int64)
    cols, inverse = np.unique(col, return_inverse=True)
    top = np.full(len(cols), -np.inf)
    np.maximum.at(top, inverse, x[:, 1] + r)
    centre = (cols + 0.5) * diameter
    lo, hi = centre.min(), centre.max()
    middle = (centre >= lo + (hi - lo) / 3.0) & (centre <= hi - (hi - lo) / 3.0)
    if middle.sum() < 3:
        raise ParameterError(f"the bed's surface spans {middle.sum()} columns of one diameter in its middle third: "
                             "at least 3 are needed to fit a line; fill the drum more")
    slope, intercept = np.polyfit(centre[middle], top[middle], 1)
    xm = 0.5 * (lo + hi)
    return math.degrees(math.atan(slope)), float(slope), float(xm), float(intercept + slope * xm)


def com_angle(positions, masses) -> float:
    """The angle (deg) by which the bed's centre of mass has turned from below the axis (the
    origin), positive towards +x: for a flat surface it equals the surface's angle."""
    c = np.average(np.asarray(positions, float)[:, :2], axis=0, weights=masses)
    return math.degrees(math.atan2(c[0], -c[1]))


def flowing_layer(positions, velocities, slope: float, point, diameter: float, strip: float = 2.0):
    """Depth below the surface line (``slope`` through ``point``, from :func:`surface_angle`) and
    downslope speed of the spheres within ``strip`` diameters of the normal through the chord's
    middle: (depth, speed) arrays, for :func:`flowing_depth` to bin."""
    u = np.array([1.0, slope]) / math.hypot(1.0, slope)  # along the surface, upwards
    n = np.array([-slope, 1.0]) / math.hypot(1.0, slope)  # out of the bed
    rel = np.asarray(positions, float)[:, :2] - np.asarray(point, float)
    near = np.abs(rel @ u) < strip * diameter
    return -(rel[near] @ n), -(np.asarray(velocities, float)[near, :2] @ u)


def flowing_depth(depth, speed, diameter: float) -> float:
    """The flowing layer's depth (m): where the mean downslope speed, in bins of half a diameter
    of depth, first falls to zero going down from the surface (linear between bin centres); NaN
    when it never does."""
    depth, speed = np.asarray(depth, float), np.asarray(speed, float)
    keep = depth >= 0.0
    k = np.floor(depth[keep] / (0.5 * diameter)).astype(np.int64)
    if not len(k):
        return math.nan
    count = np.bincount(k)
    mean = np.bincount(k, speed[keep]) / np.maximum(count, 1)
    centre = (np.arange(len(count)) + 0.5) * 0.5 * diameter
    ok = count > 0
    centre, mean = centre[ok], mean[ok]
    below = np.nonzero(mean <= 0.0)[0]
    if not len(below) or below[0] == 0:
        return math.nan if not len(below) else float(centre[0])
    j = below[0]
    return float(centre[j - 1] + mean[j - 1] * (centre[j] - centre[j - 1]) / (mean[j - 1] - mean[j]))


def rotation_ratios(samples, omega: float, drum_radius: float, layer: float, diameter: float,
                    r_max: float) -> tuple[float, float]:
    """How closely the bed below the flowing layer turns with the drum: sum(v . u) / sum(u . u) over
    the spheres of every sample, u = omega (-y, x) the solid-body velocity about the drum's axis.
    Two zones, both deeper than ``layer`` + 2 ``diameter`` below the surface line and within the
    middle third of the arc along which such spheres touch the wall (seen from the axis): the
    passive zone off the wall (radius from half the drum's to 1.5 d short of the wall) and the
    wall layer (the spheres touching it, radius beyond the wall's less 1.05 ``r_max``). Towards
    the arc's ends, where the flowing layer meets the wall, the bed creeps: it lags the drum by
    several per cent (docs/studies.md, "The rotating drum"). ``samples``: (positions, velocities,
    surface slope, a point on the surface line) per sample; 1 is solid-body rotation."""
    sums = np.zeros((2, 2))
    for x, v, slope, point in samples:
        rho = np.hypot(x[:, 0], x[:, 1])
        below = -((x[:, :2] - point) @ (np.array([-slope, 1.0]) / math.hypot(1.0, slope)))
        deep = below > (layer if np.isfinite(layer) else 0.0) + 2 * diameter
        wall = (rho > drum_radius - 1.05 * r_max) & deep
        if not wall.any():
            continue
        phi = np.arctan2(x[:, 0], -x[:, 1])  # about the axis, 0 at the drum's bottom
        lo, hi = phi[wall].min(), phi[wall].max()
        middle = np.abs(phi - 0.5 * (lo + hi)) < (hi - lo) / 6.0
        zones = ((rho > 0.5 * drum_radius) & (rho < drum_radius - 1.5 * diameter) & deep & middle, wall & middle)
        for k, zone in enumerate(zones):
            solid = omega * np.column_stack([-x[zone, 1], x[zone, 0]])
            sums[k] += (np.sum(v[zone, :2] * solid), np.sum(solid * solid))
    ratio = [a / b if b else math.nan for a, b in sums]
    return ratio[0], ratio[1]
