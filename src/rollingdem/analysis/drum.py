"""The angle of a rotating drum's bed: its free surface's and its centre of mass's, on the bed's
cross-section (positions and radii as numpy arrays, SI units, angles in degrees)."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import ParameterError

__all__ = ["com_angle", "surface_angle"]


def surface_angle(positions, radii, diameter: float) -> tuple[float, float, float, float]:
    """The angle (deg) of a drum bed's free surface, seen along the drum's axis (z; gravity -y).

    The cross-section is cut into columns one mean ``diameter`` wide along x; a column's surface
    height is the top (y + r) of its highest sphere that touches another (a sphere flying over
    the bed is not the surface). The chord is the span of columns holding spheres; a least-squares
    line through the column tops of its middle third gives the angle, atan(slope), positive when
    the surface rises towards +x. Returns (angle, slope, x, y) with (x, y) the line's point at the
    chord's middle."""
    from rollingdem.analysis.repose import touching

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
