"""Angle of repose of a conical pile of spheres: a robust cone fit to the tops of the free-surface
particles, and line fits per azimuthal slice for the pile's asymmetry.

Works on plain numpy arrays (``sim.positions``, ``sim.radii``, ``sim.velocities``, or a user's own
data); SI units, angles in degrees. The method (its steps 1-6), its safeguards and its measured
accuracy: docs/analysis.md."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rollingdem.errors import (
    ParameterError,
    SimulationError,
    check_finite,
    check_non_negative,
    check_positive,
    check_range,
)

__all__ = ["ReposeAngle", "default_max_speed", "plot_pile", "repose_angle", "settled", "touching"]

#: Fewest particles accepted: a cone fit has up to 4 parameters, and a pile needs several layers.
MIN_PARTICLES = 20
#: Fewest free-surface particles for the cone fit (4 parameters, plus redundancy).
MIN_SURFACE = 10
#: Fewest surface particles in one slice for its line fit (2 parameters, plus one).
MIN_SLICE = 3
#: Surface tops must lie this many mean diameters above the floor (fitted cone) to be fitted.
TOE_CLEARANCE = 3.0
#: Sectors used for the median pile radius.
_RADIUS_SECTORS = 16
#: Bottom height above the floor, in mean diameters, of the particles that define the pile radius.
_LIFTED_LAYERS = 1.25
#: Fraction of the pile height whose particles locate the centre.
_TOP_FRACTION = 0.2
#: Default settling threshold, in units of sqrt(g d).
_SPEED_FACTOR = 1e-3


@dataclass(frozen=True, eq=False)  # eq=False: array fields make field-wise == ambiguous
class ReposeAngle:
    """Result of :func:`repose_angle`. Angles in degrees, lengths in m.

    Attributes
    ----------
    angle : cone fit angle :math:`\\alpha` to the free-surface particle tops.
    slice_angles : one angle per azimuthal slice (line fit on that slice's envelope).
    slice_mean, slice_std : mean and sample standard deviation of ``slice_angles``.
    r_squared : coefficient of determination of the cone fit (top height vs radius).
    apex : (x0, y0, h), the apex of the fitted cone through the particle tops.
    surface : bool mask over the particles, True for the free-surface particles used in the fit.
    fit_range : (rho_min, rho_max), the radial range about the apex used for the fit.
    """

    angle: float
    slice_angles: np.ndarray
    slice_mean: float
    slice_std: float
    r_squared: float
    apex: tuple[float, float, float]
    surface: np.ndarray = field(repr=False)
    fit_range: tuple[float, float]

    def as_dict(self) -> dict:
        """Plain floats, ints and lists, ready for :func:`json.dumps`.

        The surface mask is given as the list of surface particle indices (``surface_indices``)
        and their count (``n_surface``), shorter than a list of N booleans.
        """
        idx = np.flatnonzero(self.surface)
        return {
            "angle": float(self.angle),
            "slice_angles": [float(a) for a in self.slice_angles],
            "slice_mean": float(self.slice_mean),
            "slice_std": float(self.slice_std),
            "r_squared": float(self.r_squared),
            "apex": [float(c) for c in self.apex],
            "fit_range": [float(c) for c in self.fit_range],
            "n_surface": int(idx.size),
            "surface_indices": [int(i) for i in idx],
        }


# --------------------------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------------------------

def _as_positions(positions: Any, min_particles: int = MIN_PARTICLES) -> np.ndarray:
    try:
        x = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"positions = {positions!r:.80} is not allowed: "
                             "must be an (N, 3) array of numbers (m)") from None
    if x.ndim != 2 or x.shape[1] != 3:
        raise ParameterError(f"positions with shape {x.shape} are not allowed: need (N, 3) (m)")
    bad = ~np.isfinite(x).all(axis=1)
    if bad.any():
        raise ParameterError(f"positions are not allowed to be NaN or infinite: {int(bad.sum())} rows are, "
                             f"first at index {int(np.flatnonzero(bad)[0])}")
    if x.shape[0] < min_particles:
        raise ParameterError(f"positions has {x.shape[0]} particles: at least {min_particles} are needed "
                             "to fit a cone")
    return x


def _as_radii(radii: Any, n: int) -> np.ndarray:
    try:
        a = np.asarray(radii, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"radii = {radii!r:.80} is not allowed: must be a number or an (N,) array (m)") from None
    if a.ndim == 0:
        return np.full(n, check_positive("radii", float(a), "m"))
    if a.shape != (n,):
        raise ParameterError(f"radii with shape {a.shape} is not allowed: need a scalar or ({n},), one per particle")
    bad = ~(np.isfinite(a) & (a > 0.0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ParameterError(f"radii[{i}] = {a[i]:g} is not allowed: every radius must be finite and > 0 (m)")
    return a


def _as_velocities(velocities: Any, n: int) -> np.ndarray:
    try:
        v = np.asarray(velocities, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"velocities = {velocities!r:.80} is not allowed: must be an (N, 3) array (m/s)") from None
    if v.shape != (n, 3):
        raise ParameterError(f"velocities with shape {v.shape} is not allowed: need ({n}, 3), one per particle (m/s)")
    if not np.isfinite(v).all():
        raise ParameterError("velocities are not allowed to be NaN or infinite: the run has blown up")
    return v


def _as_center(center: Any) -> tuple[float, float]:
    try:
        seq = [float(c) for c in center]
    except (TypeError, ValueError):
        raise ParameterError(f"center = {center!r} is not allowed: "
                             "must be (x, y) in m, or None to estimate it") from None
    if len(seq) not in (2, 3) or not all(math.isfinite(c) for c in seq):
        raise ParameterError(f"center = {center!r} is not allowed: must be two finite numbers (x, y) in m "
                             "(a third, z, is ignored), or None to estimate it")
    return seq[0], seq[1]


def _check_exclusion(name: str, value: Any) -> float:
    return check_range(name, value, 0.0, 0.5, high_open=True)


def _check_n_slices(n_slices: Any) -> int:
    if isinstance(n_slices, bool) or not isinstance(n_slices, (int, np.integer)) or n_slices < 1:
        raise ParameterError(f"n_slices = {n_slices!r} is not allowed: must be an integer >= 1")
    return int(n_slices)


# --------------------------------------------------------------------------------------------
# settling
# --------------------------------------------------------------------------------------------

def default_max_speed(radii: Any, gravity: float = 9.81) -> float:
    r"""Default settling threshold :math:`v_\mathrm{max} = 10^{-3}\sqrt{g\bar d}` (m/s).

    :math:`\bar d` is the mean particle diameter (m), ``gravity`` :math:`g` (m/s^2).
    """
    g = check_positive("gravity", gravity, "m/s^2")
    a = _as_radii(radii, np.size(radii))
    return _SPEED_FACTOR * math.sqrt(g * 2.0 * float(a.mean()))


def settled(velocities: Any, radii: Any, gravity: float = 9.81, max_speed: float | None = None) -> tuple[bool, float]:
    r"""Is the pile at rest? Returns ``(is_settled, v_max_measured)``.

    Criterion: the largest particle speed :math:`\max_i |\mathbf{v}_i|` (m/s) must lie below
    ``max_speed``, by default :math:`10^{-3}\sqrt{g\bar d}` with :math:`\bar d` the mean diameter
    (m) and :math:`g` = ``gravity`` (m/s^2). :math:`\sqrt{g\bar d}` is the speed scale of a
    particle falling by about one diameter; at a thousandth of it a particle needs
    :math:`10^3\sqrt{\bar d/g}` (about 20 s for 4 mm spheres) to move one diameter.

    ``velocities`` is (N, 3) in m/s; ``radii`` a scalar or (N,) in m.
    """
    v = np.asarray(velocities, dtype=np.float64) if velocities is not None else None
    if v is None or v.ndim != 2:
        raise ParameterError(f"velocities with shape {np.shape(velocities)} is not allowed: need (N, 3) (m/s)")
    v = _as_velocities(v, v.shape[0])
    a = _as_radii(radii, v.shape[0])
    g = check_positive("gravity", gravity, "m/s^2")
    limit = _SPEED_FACTOR * math.sqrt(g * 2.0 * float(a.mean())) if max_speed is None else \
        check_positive("max_speed", max_speed, "m/s")
    vmax = float(np.sqrt(np.einsum("ij,ij->i", v, v)).max()) if v.shape[0] else 0.0
    return vmax < limit, vmax


def touching(positions: Any, radii: Any, gap: float = 0.05) -> np.ndarray:
    r"""Mask of the particles that touch another one: surface gap below ``gap`` times the smaller radius.

    A sphere that rolled away from the pile and rolls on alone over the floor touches nothing;
    it does not change the pile, so :func:`settled` may be asked of the others only. Uses a
    k-d tree (:class:`scipy.spatial.cKDTree`), O(N log N).
    """
    from scipy.spatial import cKDTree  # deferred: slow to load, used here only

    x = _as_positions(positions, min_particles=0)
    a = _as_radii(radii, x.shape[0])
    gap = check_non_negative("gap", gap)
    pairs = cKDTree(x).query_pairs(2.0 * float(a.max()) * (1.0 + gap), output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    near = np.linalg.norm(x[i] - x[j], axis=1) < a[i] + a[j] + gap * np.minimum(a[i], a[j])
    mask = np.zeros(x.shape[0], dtype=bool)
    mask[i[near]] = True
    mask[j[near]] = True
    return mask


# --------------------------------------------------------------------------------------------
# geometry helpers
# --------------------------------------------------------------------------------------------

def _estimate_center(x: np.ndarray, top: np.ndarray, floor: float) -> tuple[float, float]:
    """xy centroid of the particles in the upper part of the pile, weighted by height (docs/analysis.md step 2)."""
    level = floor + (1.0 - _TOP_FRACTION) * (top.max() - floor)
    k = min(10, top.size)
    # at least the k highest particles, so that a pile topped by a single sphere still averages
    level = min(level, np.partition(top, top.size - k)[top.size - k])
    sel = top >= level
    w = top[sel] - level + 1e-12 * (top.max() - floor + 1.0)
    return float(np.dot(w, x[sel, 0]) / w.sum()), float(np.dot(w, x[sel, 1]) / w.sum())


def _pile_radius(rho: np.ndarray, theta: np.ndarray, a: np.ndarray, lifted: np.ndarray) -> float:
    """Median over azimuthal sectors of the largest rho + a of the particles above the second layer
    (docs/analysis.md step 3)."""
    if lifted.any():
        rho, theta, a = rho[lifted], theta[lifted], a[lifted]
    sector = np.minimum((theta * (_RADIUS_SECTORS / (2 * np.pi))).astype(np.int64), _RADIUS_SECTORS - 1)
    ext = np.zeros(_RADIUS_SECTORS)
    np.maximum.at(ext, sector, rho + a)
    return float(np.median(ext))


def _polar(x: np.ndarray, c: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    dx = x[:, 0] - c[0]
    dy = x[:, 1] - c[1]
    return np.hypot(dx, dy), np.mod(np.arctan2(dy, dx), 2 * np.pi)


def _envelope(rho: np.ndarray, theta: np.ndarray, top: np.ndarray, width: float) -> np.ndarray:
    """Indices of the highest particle top in each (ring, azimuth) bin about one width wide
    (docs/analysis.md step 4)."""
    ring = (rho / width).astype(np.int64)
    n_az = np.maximum(1, np.floor(2 * np.pi * (np.arange(ring.max() + 1) + 0.5)).astype(np.int64))
    offset = np.concatenate(([0], np.cumsum(n_az)[:-1]))
    az = np.minimum((theta / (2 * np.pi) * n_az[ring]).astype(np.int64), n_az[ring] - 1)
    bin_id = offset[ring] + az
    order = np.lexsort((top, bin_id))  # by bin, then by top height within the bin
    b = bin_id[order]
    last = np.empty(b.size, dtype=bool)
    last[:-1] = b[1:] != b[:-1]
    last[-1] = True
    return order[last]


def _fit_cone(x: np.ndarray, top: np.ndarray, p0: np.ndarray, center: tuple[float, float] | None,
              scale: float) -> np.ndarray:
    """Robust least-squares cone t = h - tan(alpha) rho; returns (h, tan_alpha, x0, y0) (docs/analysis.md step 5)."""
    if center is None:
        def res(p):
            return top - (p[0] - p[1] * np.hypot(x[:, 0] - p[2], x[:, 1] - p[3]))
        lower = [-np.inf, 0.0, -np.inf, -np.inf]
        upper = [np.inf, np.inf, np.inf, np.inf]
        q0 = p0
    else:
        rho = np.hypot(x[:, 0] - center[0], x[:, 1] - center[1])

        def res(p):
            return top - (p[0] - p[1] * rho)
        lower, upper, q0 = [-np.inf, 0.0], [np.inf, np.inf], p0[:2]
    q0 = np.array(q0, dtype=np.float64)
    q0[1] = max(q0[1], 1e-6)  # start strictly inside the bound tan(alpha) >= 0
    from scipy.optimize import least_squares  # deferred: slow to load, used here only

    sol = least_squares(res, q0, bounds=(lower, upper), loss="soft_l1", f_scale=scale, x_scale="jac")
    if center is None:
        return sol.x
    return np.array([sol.x[0], sol.x[1], center[0], center[1]])


def _cone_residuals(x: np.ndarray, top: np.ndarray, p: np.ndarray) -> np.ndarray:
    return top - (p[0] - p[1] * np.hypot(x[:, 0] - p[2], x[:, 1] - p[3]))


def _select_and_fit(x, a, top, floor, c, fixed_center, exclude_apex, exclude_toe, d_mean, p_prev):
    """One pass: surface candidates about centre c, robust cone fit, outlier trim, refit."""
    rho, theta = _polar(x, c)
    big_r = _pile_radius(rho, theta, a, x[:, 2] - a - floor >= _LIFTED_LAYERS * d_mean)
    r_lo, r_hi = exclude_apex * big_r, (1.0 - exclude_toe) * big_r
    if p_prev is not None and p_prev[1] > 0:
        # toe limit: where the fitted surface of tops is TOE_CLEARANCE diameters above the floor
        r_hi = min(r_hi, (p_prev[0] - floor - TOE_CLEARANCE * d_mean) / p_prev[1])
    cand = _envelope(rho, theta, top, d_mean)
    keep = (rho[cand] >= r_lo) & (rho[cand] <= r_hi) & (x[cand, 2] - floor >= 2.0 * a[cand])
    cand = cand[keep]
    if r_hi <= r_lo or cand.size < MIN_SURFACE:
        raise ParameterError(
            f"positions give only {cand.size if r_hi > r_lo else 0} free-surface particles in the fit "
            f"range [{r_lo:g}, {max(r_hi, r_lo):g}] m (pile radius {big_r:g} m, mean diameter {d_mean:g} m): "
            f"at least {MIN_SURFACE} are needed; the pile is too small or too flat (its surface must rise "
            f"more than {TOE_CLEARANCE:g} diameters above the floor), or exclude_apex / exclude_toe are "
            "too large")
    if p_prev is None:
        # start from an ordinary line fit of top height vs radius
        slope, icpt = np.polyfit(rho[cand], top[cand], 1)
        p0 = np.array([icpt, max(-slope, 1e-3), c[0], c[1]])
    else:
        p0 = np.array([p_prev[0], p_prev[1], c[0], c[1]])
    scale = 0.5 * d_mean
    p = _fit_cone(x[cand], top[cand], p0, fixed_center, scale)
    r = _cone_residuals(x[cand], top[cand], p)
    med = np.median(r)
    sigma = max(1.4826 * np.median(np.abs(r - med)), 0.05 * d_mean)
    inl = np.abs(r - med) <= 3.0 * sigma
    if inl.sum() >= MIN_SURFACE and not inl.all():
        cand = cand[inl]
        p = _fit_cone(x[cand], top[cand], p, fixed_center, scale)
    return cand, p, (r_lo, r_hi)


# --------------------------------------------------------------------------------------------
# main entry
# --------------------------------------------------------------------------------------------

def repose_angle(positions: Any, radii: Any, *, floor: float = 0.0, center: Any = None,
                 velocities: Any = None, max_speed: float | None = None, n_slices: int = 8,
                 exclude_apex: float = 0.15, exclude_toe: float = 0.15, gravity: float = 9.81) -> ReposeAngle:
    r"""Angle of repose of a conical pile of spheres (method: docs/analysis.md).

    Parameters
    ----------
    positions : (N, 3) particle centres (m); gravity along -z.
    radii : scalar or (N,) radii (m), > 0.
    floor : height of the horizontal floor the pile rests on (m).
    center : (x, y) of the pile axis (m); None to estimate it and fit it with the cone.
    velocities : (N, 3) particle velocities (m/s); if given, the pile must be settled
        (:func:`settled`), else :class:`~rollingdem.errors.SimulationError`.
    max_speed : settling threshold on the largest particle speed (m/s); default
        :math:`10^{-3}\sqrt{g\bar d}`. Only with ``velocities``.
    n_slices : number of azimuthal slices for the per-slice angles, >= 1.
    exclude_apex, exclude_toe : fractions of the pile radius R left out at the apex
        (:math:`\rho < \epsilon_a R`) and at the toe (:math:`\rho > (1-\epsilon_t) R`), in [0, 0.5).
    gravity : magnitude g of gravity (m/s^2), used only for the default ``max_speed``.

    Returns
    -------
    ReposeAngle

    Raises
    ------
    ParameterError : bad input (shape, NaN, radius <= 0, too few particles, n_slices < 1,
        exclusions outside [0, 0.5), too few surface particles in the fit range or in a slice).
    SimulationError : the pile is still moving.
    """
    x = _as_positions(positions)
    n = x.shape[0]
    a = _as_radii(radii, n)
    floor = check_finite("floor", floor)
    n_slices = _check_n_slices(n_slices)
    exclude_apex = _check_exclusion("exclude_apex", exclude_apex)
    exclude_toe = _check_exclusion("exclude_toe", exclude_toe)
    fixed_center = None if center is None else _as_center(center)
    if max_speed is not None:
        check_positive("max_speed", max_speed, "m/s")
        if velocities is None:
            raise ParameterError(f"max_speed = {max_speed:g} m/s is given but velocities is None: "
                                 "pass velocities to check that the pile is settled")
    if velocities is not None:
        v = _as_velocities(velocities, n)
        g = check_positive("gravity", gravity, "m/s^2")
        limit = _SPEED_FACTOR * math.sqrt(g * 2.0 * float(a.mean())) if max_speed is None else float(max_speed)
        ok, vmax = settled(v, a, g, limit)
        if not ok:
            raise SimulationError(
                f"the pile is not settled: the largest particle speed is {vmax:.3g} m/s, the limit is "
                f"max_speed = {limit:.3g} m/s"
                + (" (default 1e-3 sqrt(g d))" if max_speed is None else "")
                + "; run the simulation longer until the pile is at rest, then measure")
    bottom = x[:, 2] - a
    if bottom.min() < floor - a.max():
        raise ParameterError(f"floor = {floor:g} m is not allowed: particles reach down to {bottom.min():g} m, "
                             f"more than one radius ({a.max():g} m) below it; give the floor height of the pile")

    d_mean = 2.0 * float(a.mean())
    top = x[:, 2] + a
    if top.max() - floor < 2.0 * d_mean:
        raise ParameterError(f"positions form a pile only {top.max() - floor:g} m high above floor = {floor:g} m: "
                             f"at least two diameters ({2 * d_mean:g} m) are needed to fit a cone")

    # steps 2-5: centre, pile radius, surface envelope, cone fit; iterate the centre if free
    c = fixed_center if fixed_center is not None else _estimate_center(x, top, floor)
    p = None
    fit_range = (np.nan, np.nan)
    for it in range(8):
        cand, p, new_range = _select_and_fit(x, a, top, floor, c, fixed_center, exclude_apex, exclude_toe,
                                             d_mean, p)
        shift = math.hypot(p[2] - c[0], p[3] - c[1])
        c = (float(p[2]), float(p[3]))
        moved = abs(new_range[1] - fit_range[1]) if it else np.inf
        fit_range = new_range
        # converged when the centre and the toe limit (both set by the previous fit) stay put
        if shift < 0.05 * d_mean and moved < 0.25 * d_mean:
            break

    surface = np.zeros(n, dtype=bool)
    surface[cand] = True
    res = _cone_residuals(x[cand], top[cand], p)
    ss_tot = float(np.sum((top[cand] - top[cand].mean()) ** 2))
    r_squared = 1.0 - float(np.sum(res ** 2)) / ss_tot if ss_tot > 0 else float("nan")
    angle = math.degrees(math.atan(p[1]))

    # step 6: ordinary least-squares line per azimuthal sector, from sums (no Python loop over particles)
    rho, theta = _polar(x[cand], (p[2], p[3]))
    k = np.minimum((theta * (n_slices / (2 * np.pi))).astype(np.int64), n_slices - 1)
    cnt = np.bincount(k, minlength=n_slices).astype(np.float64)
    if cnt.min() < MIN_SLICE:
        j = int(np.argmin(cnt))
        raise ParameterError(f"n_slices = {n_slices} is too many for this pile: slice {j} holds only "
                             f"{int(cnt[j])} surface particles, at least {MIN_SLICE} are needed; use fewer slices")
    t = top[cand]
    s_r = np.bincount(k, rho, n_slices)
    s_t = np.bincount(k, t, n_slices)
    s_rr = np.bincount(k, rho * rho, n_slices)
    s_rt = np.bincount(k, rho * t, n_slices)
    var = s_rr - s_r * s_r / cnt
    cov = s_rt - s_r * s_t / cnt
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(var > 0, cov / var, np.nan)
    slice_angles = np.degrees(np.arctan(-slope))
    slice_mean = float(np.mean(slice_angles))
    slice_std = float(np.std(slice_angles, ddof=1)) if n_slices > 1 else 0.0

    return ReposeAngle(angle=angle, slice_angles=slice_angles, slice_mean=slice_mean, slice_std=slice_std,
                       r_squared=r_squared, apex=(float(p[2]), float(p[3]), float(p[0])), surface=surface,
                       fit_range=(float(fit_range[0]), float(fit_range[1])))


# --------------------------------------------------------------------------------------------
# plot
# --------------------------------------------------------------------------------------------

def plot_pile(positions: Any, radii: Any, result: ReposeAngle, path: Any = None, ax: Any = None):
    r"""Side view of the pile and of the fitted cone; returns the matplotlib Figure.

    Horizontal axis: signed distance from the fitted apex axis, :math:`\rho_i\,\mathrm{sign}(x_i - x_0)`
    (m), so that the whole pile folds into one vertical plane and the surface particles of every
    azimuth lie on the two fitted lines :math:`t = h - \tan\alpha\,|s|` (drawn bold over the fit
    range). All particles are drawn at true size in grey, surface particles coloured by slice.
    Saves a PNG at ``path`` if given. Draws into ``ax`` if given, else into a new
    :class:`matplotlib.figure.Figure` (no pyplot state, works headless).
    """
    import matplotlib  # deferred: slow to load, figures only
    from matplotlib.collections import EllipseCollection  # deferred: slow to load, figures only
    from matplotlib.figure import Figure  # deferred: slow to load, figures only

    x = _as_positions(positions)
    a = _as_radii(radii, x.shape[0])
    surf = np.asarray(result.surface, dtype=bool)
    if surf.shape != (x.shape[0],):
        raise ParameterError(f"result.surface has shape {surf.shape}: it does not belong to these {x.shape[0]} "
                             "positions; pass the result of repose_angle on the same pile")
    x0, y0, h = result.apex
    rho, theta = _polar(x, (x0, y0))
    r_out = float(np.max(rho + a))
    floor_z = float(np.min(x[:, 2] - a))  # lowest particle bottom, drawn as the floor
    z_hi = max(float(np.max(x[:, 2] + a)), h)
    if ax is None:
        # width 9 in, height to the pile's aspect ratio (plus room for labels)
        aspect = 1.15 * (z_hi - floor_z) / (2.1 * r_out)
        fig = Figure(figsize=(9.0, float(np.clip(9.0 * aspect + 1.3, 3.0, 9.0))), layout="constrained")
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    s = np.where(x[:, 0] >= x0, rho, -rho)
    tan_a = math.tan(math.radians(result.angle))

    def circles(mask, **kw):
        return EllipseCollection(2 * a[mask], 2 * a[mask], np.zeros(mask.sum()), units="xy",
                                 offsets=np.column_stack([s[mask], x[mask, 2]]), offset_transform=ax.transData, **kw)

    rest = ~surf
    ax.add_collection(circles(rest, facecolors="0.8", edgecolors="0.6", linewidths=0.2))
    n_sl = max(len(result.slice_angles), 1)
    k = np.minimum((theta[surf] * (n_sl / (2 * np.pi))).astype(np.int64), n_sl - 1)
    colours = matplotlib.colormaps["tab10" if n_sl <= 10 else "hsv"](np.arange(n_sl) / max(10, n_sl))
    ax.add_collection(circles(surf, facecolors=colours[k], edgecolors="k", linewidths=0.2))

    r_cone = min(r_out, (h - floor_z) / tan_a) if tan_a > 0 else r_out  # stop the cone at the floor
    ss = np.linspace(-r_cone, r_cone, 401)
    ax.plot(ss, h - tan_a * np.abs(ss), "k--", lw=0.8, label="fitted cone (tops)")
    lo, hi = result.fit_range
    for sign in (-1.0, 1.0):
        seg = sign * np.linspace(lo, hi, 50)
        ax.plot(seg, h - tan_a * np.abs(seg), "r-", lw=2.0, label="fit range" if sign > 0 else None)
        for r_edge in (lo, hi):
            ax.axvline(sign * r_edge, color="r", lw=0.5, ls=":")
    ax.axhline(floor_z, color="k", lw=0.8)
    ax.set_xlim(-1.05 * r_out, 1.05 * r_out)
    ax.set_ylim(floor_z - 0.05 * (z_hi - floor_z), z_hi + 0.1 * (z_hi - floor_z))
    ax.set_aspect("equal")
    ax.set_xlabel(r"signed radius $\rho\,\mathrm{sign}(x-x_0)$ (m)")
    ax.set_ylabel("z (m)")
    ax.set_title(f"angle of repose {result.angle:.2f}°  (slices {result.slice_mean:.2f} ± {result.slice_std:.2f}°, "
                 f"$R^2$ = {result.r_squared:.3f}, {int(surf.sum())} surface particles)", fontsize=9)
    ax.legend(loc="upper right", fontsize=8)
    if path is not None:
        fig.savefig(path, dpi=150)
    return fig
