"""Carrying per-contact vector state with the contact frame (docs/models.md §11.3, §12 step 1).

A history vector (tangential spring, rolling spring moment) lives in the contact's tangent plane;
when the normal turns and the pair spins about it, ``carry_with_frame`` rotates it with the frame,
whose change in the step ``contact_frame`` computes once per contact. The three steps and the
other codes' choices: docs/models.md §11.3."""

from __future__ import annotations

import math

from numba import njit


SERIES_ANGLE = 1e-3  # rad: below it the series are exact to round-off
# (|h . n| / |h|)^2 below which h counts as tangent: 1e-12 relative, far above the round-off of the
# rotations (1e-16) and far below any normal part a flip or a projection-only carry leaves
TANGENT_TOLERANCE2 = 1e-24


@njit(cache=True, inline="always")
def series_cos_sin(phi):
    """(cos phi, sin phi) by their Taylor series to phi^4 and phi^5, for |phi| < ``SERIES_ANGLE``:
    the first omitted terms (phi^6/720, phi^7/5040) are below 2e-21 relative, so exact to round-off."""
    p2 = phi * phi
    return (1.0 - 0.5 * p2 * (1.0 - p2 / 12.0), phi * (1.0 - p2 / 6.0 * (1.0 - 0.05 * p2)))


@njit(cache=True, inline="always")
def cos_sin(phi):
    """(cos phi, sin phi): ``series_cos_sin`` below ``SERIES_ANGLE`` (no libm call for the tiny spin
    angle of a contact in one time step), libm above."""
    if abs(phi) < SERIES_ANGLE:
        return series_cos_sin(phi)
    return math.cos(phi), math.sin(phi)


@njit(cache=True, inline="always")
def _frame_axis(onx, ony, onz, nx, ny, nz):
    """(a = n_old x n, c = n_old . n); a flip of the normal (c <= -1/2) is not a rotation to
    follow: a = 0, c = 1 (step 1 is then the identity and step 3 projects). Selects, no branches."""
    flip = onx * nx + ony * ny + onz * nz <= -0.5
    ax = 0.0 if flip else ony * nz - onz * ny
    ay = 0.0 if flip else onz * nx - onx * nz
    az = 0.0 if flip else onx * ny - ony * nx
    c = 1.0 if flip else onx * nx + ony * ny + onz * nz
    return ax, ay, az, c


@njit(cache=True, inline="always")
def contact_frame(onx, ony, onz, nx, ny, nz, spin_angle):
    """The step's frame change, shared by every history vector of the contact: (n, a = n_old x n,
    c = n_old . n, 1/(1+c), cos phi, sin phi); see ``_frame_axis`` for a flipped normal."""
    ax, ay, az, c = _frame_axis(onx, ony, onz, nx, ny, nz)
    cs, sn = cos_sin(spin_angle)
    return nx, ny, nz, ax, ay, az, c, 1.0 / (1.0 + c), cs, sn


@njit(cache=True, inline="always")
def contact_frame_series(onx, ony, onz, nx, ny, nz, spin_angle):
    """``contact_frame`` for |spin_angle| < ``SERIES_ANGLE`` only, without a branch or a call, so
    that a loop over many contacts can be vectorised (the caller sends larger angles to
    ``contact_frame``)."""
    ax, ay, az, c = _frame_axis(onx, ony, onz, nx, ny, nz)
    cs, sn = series_cos_sin(spin_angle)
    return nx, ny, nz, ax, ay, az, c, 1.0 / (1.0 + c), cs, sn


@njit(cache=True, inline="always")
def carry_with_frame(hist, k, at, frame):
    """Carry the 3-vector ``hist[k, at:at+3]`` through the frame change ``frame`` (``contact_frame``), in place."""
    hx = hist[k, at]
    hy = hist[k, at + 1]
    hz = hist[k, at + 2]
    mag2 = hx * hx + hy * hy + hz * hz
    if mag2 == 0.0:
        return
    nx, ny, nz, ax, ay, az, c, inv_1pc, cs, sn = frame
    # 1. rotation n_old -> n
    ad = (ax * hx + ay * hy + az * hz) * inv_1pc
    rx = c * hx + (ay * hz - az * hy) + ax * ad
    ry = c * hy + (az * hx - ax * hz) + ay * ad
    rz = c * hz + (ax * hy - ay * hx) + az * ad
    # 2. spin about n
    nd = nx * rx + ny * ry + nz * rz
    cx = ny * rz - nz * ry
    cy = nz * rx - nx * rz
    cz = nx * ry - ny * rx
    hx = rx * cs + cx * sn + nx * nd * (1.0 - cs)
    hy = ry * cs + cy * sn + ny * nd * (1.0 - cs)
    hz = rz * cs + cz * sn + nz * nd * (1.0 - cs)
    _store_tangent(hist, k, at, nx, ny, nz, hx, hy, hz, mag2)


@njit(cache=True, inline="always")
def project_onto_plane(hist, k, at, nx, ny, nz):
    """LAMMPS's carry: remove the normal part of ``hist[k, at:at+3]`` and restore its magnitude."""
    hx = hist[k, at]
    hy = hist[k, at + 1]
    hz = hist[k, at + 2]
    mag2 = hx * hx + hy * hy + hz * hz
    if mag2 != 0.0:
        _store_tangent(hist, k, at, nx, ny, nz, hx, hy, hz, mag2)


@njit(cache=True, inline="always")
def _store_tangent(hist, k, at, nx, ny, nz, hx, hy, hz, mag2):
    """3. store h, projected onto the tangent plane and rescaled to |h|^2 = mag2 if it has a normal
    part beyond round-off. After the exact rotations a tangent h stays tangent to round-off and the
    rescale factor would be 1 + O(eps): the sqrt and division are skipped unless the normal part is
    real (a flip, a projection-only carry, a vector stored at the plane); LAMMPS's rolling sds
    makes the same test before it rescales."""
    nd = nx * hx + ny * hy + nz * hz
    if nd * nd <= TANGENT_TOLERANCE2 * mag2:
        hist[k, at] = hx
        hist[k, at + 1] = hy
        hist[k, at + 2] = hz
        return
    hx -= nd * nx
    hy -= nd * ny
    hz -= nd * nz
    m2 = hx * hx + hy * hy + hz * hz
    if m2 > 0.0:
        s = math.sqrt(mag2 / m2)
        hist[k, at] = hx * s
        hist[k, at + 1] = hy * s
        hist[k, at + 2] = hz * s
    else:
        hist[k, at] = 0.0
        hist[k, at + 1] = 0.0
        hist[k, at + 2] = 0.0


@njit(cache=True, inline="always")
def stored_normal(hist, k, nx, ny, nz):
    """The contact normal of the last step, kept in ``hist[k, 0:3]``; n itself for a new contact
    (nothing stored yet). Selects, no branch."""
    onx = hist[k, 0]
    ony = hist[k, 1]
    onz = hist[k, 2]
    fresh = onx == 0.0 and ony == 0.0 and onz == 0.0
    return (nx if fresh else onx), (ny if fresh else ony), (nz if fresh else onz)


@njit(cache=True, inline="always")
def spin_angle(nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz, dt):
    """phi = 1/2 (omega_i + omega_j) . n dt: the pair's rigid spin about n in the step."""
    return 0.5 * ((wix + wjx) * nx + (wiy + wjy) * ny + (wiz + wjz) * nz) * dt
