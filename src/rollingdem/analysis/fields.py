"""Continuum fields of a particle system by coarse graining (Goldhirsch 2010, Granular Matter 12:239;
Weinhart et al. 2012, Granular Matter 14:289), on a regular grid: mass density, velocity,
kinetic stress, contact stress and couple stress (numpy arrays in, SI units; stresses
compressive positive).

A particle's mass and momentum are spread over the grid's nodes with the weights of a kernel
``phi`` of width ``w`` about its centre; a contact's force f (on particle i, from j) times its
branch vector b = x_i - x_j (or, for a wall contact, from the contact point to x_i) along the
branch, at Gauss-Legendre points s in [0, 1] of x_i - s b:

    rho(r)       = sum_i m_i phi(r - x_i)
    phi_s(r)     = sum_i V_i phi(r - x_i)                (solid fraction, with volumes V_i)
    rho V(r)     = sum_i m_i v_i phi(r - x_i)
    sigma_k(r)   = sum_i m_i v'_i v'_i phi(r - x_i),     v'_i = v_i - V(r)
    sigma_c(r)   = sum_c f_c b_c  int_0^1 phi(r - x_i + s b_c) ds
    mu(r)        = sum_c M_c b_c  int_0^1 phi(r - x_i + s b_c) ds

with M_c the contact's pure moment on i (rolling and twisting resistance): the couple stress that
rolling resistance carries (components mu_ab = M_a b_b, N/m).

On the grid the weights of each point are scaled to sum to one over the nodes it reaches, so the
fields' sums over the grid (times a cell's volume) are the particles' mass and momentum and the
contacts' virial sum sum_c f_c b_c exactly, for any kernel and grid spacing; a point whose kernel
reaches past a non-periodic side of the grid puts all of its weight inside it, so the grid should
reach a kernel's cutoff beyond the material (or be periodic there). The points are spread on
Numba's threads in contiguous chunks, each into a grid of its own, summed in order: the fields
depend on the thread count at round-off only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

import numba
from numba import njit, prange

from rollingdem.errors import ParameterError, check_positive

__all__ = ["Gaussian", "Lucy", "Grid", "Fields", "coarse_grain", "profile"]


GAUSSIAN, LUCY = 0, 1


@njit(cache=True, inline="always")
def _kernel(kind, factor, length, cutoff, r):
    """The value at distance r of the kernel ``compiled()`` describes."""
    if r >= cutoff:
        return 0.0
    if kind == GAUSSIAN:
        return factor * math.exp(-0.5 * (r / length) ** 2)
    u = r / length
    return factor * (1.0 + 3.0 * u) * (1.0 - u) ** 3


@njit(cache=True)
def _spread_add(lo, hi, points, values, lower, spacing, shape, periodic, reach, kernel, out, mean_velocity):
    """Add the row of ``values`` of each point lo..hi-1 to the nodes its kernel reaches, with
    weights summing to 1 / cell volume over them (the nodes of a non-periodic side's far side left
    out); with a ``mean_velocity`` per node (rows: nodes), ``values`` are (m, vx, vy, vz) and the
    six components m v'v' with v' = v - V(node) are added instead. Returns the index of a point
    that reaches no node, or -1."""
    kind, factor, length, cutoff = kernel
    cutoff2 = cutoff * cutoff  # nodes this far or farther get nothing: skipped before the root
    volume = spacing[0] * spacing[1] * spacing[2]
    kinetic = mean_velocity.shape[0] != 0
    base = np.empty(3, dtype=np.int64)
    window = (2 * reach[0] + 1) * (2 * reach[1] + 1) * (2 * reach[2] + 1)
    nodes = np.empty(window, dtype=np.int64)  # the nodes a point reaches and their weights
    weights = np.empty(window)
    for q in range(lo, hi):
        for a in range(3):
            base[a] = int(math.floor((points[q, a] - lower[a]) / spacing[a] - 0.5))
        found = 0
        total = 0.0
        for i in range(base[0] - reach[0], base[0] + reach[0] + 1):
            dx = lower[0] + (i + 0.5) * spacing[0] - points[q, 0]
            if dx * dx >= cutoff2 or (not periodic[0] and (i < 0 or i >= shape[0])):
                continue
            for j in range(base[1] - reach[1], base[1] + reach[1] + 1):
                dy = lower[1] + (j + 0.5) * spacing[1] - points[q, 1]
                if dx * dx + dy * dy >= cutoff2 or (not periodic[1] and (j < 0 or j >= shape[1])):
                    continue
                for k in range(base[2] - reach[2], base[2] + reach[2] + 1):
                    dz = lower[2] + (k + 0.5) * spacing[2] - points[q, 2]
                    r2 = dx * dx + dy * dy + dz * dz
                    if r2 >= cutoff2 or (not periodic[2] and (k < 0 or k >= shape[2])):
                        continue
                    w = _kernel(kind, factor, length, cutoff, math.sqrt(r2))
                    if w > 0.0:
                        nodes[found] = ((i % shape[0]) * shape[1] + j % shape[1]) * shape[2] + k % shape[2]
                        weights[found] = w
                        total += w
                        found += 1
        if found == 0:
            return q
        for f in range(found):
            node = nodes[f]
            w = weights[f] / (total * volume)
            if kinetic:
                m = values[q, 0]
                ux = values[q, 1] - mean_velocity[node, 0]
                uy = values[q, 2] - mean_velocity[node, 1]
                uz = values[q, 3] - mean_velocity[node, 2]
                out[node, 0] += w * m * ux * ux
                out[node, 1] += w * m * uy * uy
                out[node, 2] += w * m * uz * uz
                out[node, 3] += w * m * ux * uy
                out[node, 4] += w * m * ux * uz
                out[node, 5] += w * m * uy * uz
            else:
                for c in range(values.shape[1]):
                    out[node, c] += w * values[q, c]
    return -1


@njit(cache=True, parallel=True)
def _spread_chunks(points, values, lower, spacing, shape, periodic, reach, kernel, outs, mean_velocity, missed):
    """``_spread_add`` on as many contiguous chunks of the points as ``outs`` has buffers, in
    parallel, each into its own buffer (summed in order afterwards: no two threads add to one
    node); ``missed[chunk]``: its point that reaches no node, or -1."""
    n, chunks = points.shape[0], outs.shape[0]
    for c in prange(chunks):
        missed[c] = _spread_add(c * n // chunks, (c + 1) * n // chunks, points, values, lower, spacing, shape,
                                periodic, reach, kernel, outs[c], mean_velocity)


@njit(cache=True)
def _kernel_values(kind, factor, length, cutoff, r, out):
    for q in range(r.shape[0]):
        out[q] = _kernel(kind, factor, length, cutoff, r[q])


class Kernel:
    """A kernel of width ``width`` (m) that vanishes from ``cutoff`` on; called with distances (m),
    its values (1/m^3)."""

    width: float
    cutoff: float

    def __call__(self, r) -> np.ndarray:
        r = np.asarray(r, dtype=np.float64)
        out = np.empty(r.size)
        _kernel_values(*self.compiled(), np.ascontiguousarray(r.ravel()), out)
        return out.reshape(r.shape)

    def compiled(self) -> tuple[int, float, float, float]:
        """(kind, factor, length, cutoff) for ``_kernel``."""
        raise NotImplementedError


class Gaussian(Kernel):
    """phi(r) = exp(-r^2 / 2 w^2), cut at 3 w, normalised over the ball it is cut to (a coordinate's
    standard deviation is then 0.97 w)."""

    name = "gaussian"

    def __init__(self, width: float):
        self.width = check_positive("kernel width", width, "m")
        self.cutoff = 3.0 * self.width
        # int_{|x| < 3w} exp(-r^2/2w^2) d^3x = (2 pi w^2)^(3/2) [erf(3/sqrt 2) - sqrt(2/pi) 3 exp(-9/2)]
        inside = math.erf(3.0 / math.sqrt(2.0)) - math.sqrt(2.0 / math.pi) * 3.0 * math.exp(-4.5)
        self._norm = 1.0 / ((2.0 * math.pi * self.width ** 2) ** 1.5 * inside)

    def compiled(self) -> tuple[int, float, float, float]:
        return GAUSSIAN, self._norm, self.width, self.cutoff


class Lucy(Kernel):
    """Lucy's polynomial, phi(r) = 105 / (16 pi c^3) (1 + 3 r/c) (1 - r/c)^3 for r < c, with the
    cutoff c = 2 w (a coordinate's standard deviation c / sqrt 12 = 0.58 w)."""

    name = "lucy"

    def __init__(self, width: float):
        self.width = check_positive("kernel width", width, "m")
        self.cutoff = 2.0 * self.width

    def compiled(self) -> tuple[int, float, float, float]:
        return LUCY, 105.0 / (16.0 * math.pi * self.cutoff ** 3), self.cutoff, self.cutoff


@dataclass(frozen=True)
class Grid:
    """Nodes ``lower + (k + 1/2) h`` along each axis, ``shape`` of them (cell centres of the box
    from ``lower`` to ``upper``), each axis periodic or not."""

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    shape: tuple[int, int, int]
    periodic: tuple[bool, bool, bool] = (False, False, False)

    def __post_init__(self):
        lo, hi = np.asarray(self.lower, float), np.asarray(self.upper, float)
        if lo.shape != (3,) or hi.shape != (3,) or not (hi > lo).all():
            raise ParameterError(f"grid lower = {self.lower!r}, upper = {self.upper!r} is not allowed: must be "
                                 "three numbers each, upper above lower on every axis (m)")
        if len(self.shape) != 3 or any(int(n) != n or n < 1 for n in self.shape):
            raise ParameterError(f"grid shape = {self.shape!r} is not allowed: must be three whole numbers >= 1 "
                                 "(nodes along x, y, z)")

    @property
    def spacing(self) -> np.ndarray:
        return (np.asarray(self.upper, float) - np.asarray(self.lower, float)) / np.asarray(self.shape)

    @property
    def cell_volume(self) -> float:
        return float(np.prod(self.spacing))

    def axes(self) -> list[np.ndarray]:
        """Each axis' node coordinates (m)."""
        return [lo + (np.arange(n) + 0.5) * h for lo, n, h in zip(self.lower, self.shape, self.spacing)]


@dataclass
class Fields:
    """Fields on a grid's nodes, arrays of the grid's shape (then the components): ``density``
    (kg/m^3), ``momentum`` (kg/m^2/s), ``velocity`` (m/s, 0 where there is no mass),
    ``kinetic_stress`` and ``contact_stress`` (Pa, 3 x 3, compressive positive), ``couple_stress``
    (N/m, 3 x 3: mu_ab = sum M_a b_b ..., zero without contact moments), ``solid_fraction`` (1,
    None without the particles' volumes)."""

    grid: Grid
    density: np.ndarray
    momentum: np.ndarray
    velocity: np.ndarray
    kinetic_stress: np.ndarray
    contact_stress: np.ndarray
    couple_stress: np.ndarray
    solid_fraction: np.ndarray | None = None

    @property
    def stress(self) -> np.ndarray:
        """The total stress, kinetic and contact (Pa)."""
        return self.kinetic_stress + self.contact_stress


def _spread(grid: Grid, kernel, points: np.ndarray, values: np.ndarray, out: np.ndarray, mean_velocity=None):
    """``_spread_add`` on ``grid`` (refusing a point that reaches no node)."""
    h = grid.spacing
    reach = np.ceil(kernel.cutoff / h).astype(np.int64)
    chunks = max(1, min(numba.get_num_threads(), len(points) // 64))
    outs = np.zeros((chunks,) + out.shape)
    missed = np.full(chunks, -1, dtype=np.int64)
    _spread_chunks(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(values, dtype=np.float64),
                   np.asarray(grid.lower, float), h, np.asarray(grid.shape, dtype=np.int64),
                   np.asarray(grid.periodic, dtype=np.bool_), reach, kernel.compiled(), outs,
                   np.zeros((0, 3)) if mean_velocity is None else mean_velocity, missed)
    if (missed >= 0).any():
        k = int(missed[missed >= 0][0])
        raise ParameterError(f"a point at {points[k].tolist()} m reaches no node of the grid: the grid must cover "
                             "the particles and contacts (or widen the kernel)")
    for chunk in outs:  # in order: the same sums for the same thread count
        out += chunk


def coarse_grain(grid: Grid, kernel, positions, masses, velocities, contacts=None, quadrature: int = 4,
                 volumes=None) -> Fields:
    """The fields of particles at ``positions`` (N x 3, m) with ``masses`` (kg) and ``velocities``
    (m/s) on ``grid``, with ``kernel`` (``Gaussian`` or ``Lucy``), and of ``contacts``: (x_i, b,
    f) arrays (M x 3 each: the centre of the particle the force acts on, the branch vector from
    the other particle's centre or the wall's contact point to it, the force on it), their line
    integral by Gauss-Legendre with ``quadrature`` points; a fourth array, the contacts' pure
    moments on i (M x 3, N m), gives the couple stress. ``contacts`` may also be the mapping
    ``Simulation.contact_forces`` returns (``i`` indexing ``positions``, ``branch``, ``force``,
    ``moment``). With the particles' ``volumes`` (m^3), the solid fraction too."""
    x = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    m = np.broadcast_to(np.asarray(masses, dtype=np.float64), (len(x),))
    v = np.asarray(velocities, dtype=np.float64).reshape(-1, 3)
    if len(v) != len(x):
        raise ParameterError(f"velocities with {len(v)} rows is not allowed for {len(x)} positions: one per particle")
    half_diagonal = 0.5 * float(np.linalg.norm(grid.spacing))
    if kernel.cutoff <= half_diagonal:  # a point in a cell's middle would reach no node
        raise ParameterError(f"kernel width = {kernel.width:g} m is not allowed on a grid of spacing "
                             f"{', '.join(f'{h:g}' for h in grid.spacing)} m: its cutoff ({kernel.cutoff:g} m) must "
                             f"exceed half a cell's diagonal, {half_diagonal:g} m")
    size = int(np.prod(grid.shape))
    spread = [m, m[:, None] * v] + ([np.broadcast_to(np.asarray(volumes, dtype=np.float64), (len(x),))]
                                     if volumes is not None else [])
    mass_momentum = np.zeros((size, 4 + (volumes is not None)))
    _spread(grid, kernel, x, np.column_stack(spread), mass_momentum)
    density, momentum = mass_momentum[:, 0], mass_momentum[:, 1:4]
    velocity = np.divide(momentum, density[:, None], out=np.zeros_like(momentum), where=density[:, None] > 0.0)
    six = np.zeros((size, 6))  # xx, yy, zz, xy, xz, yz of m v'v', v' about each node's mean velocity
    _spread(grid, kernel, x, np.column_stack([m, v]), six, velocity)
    kinetic = six[:, [[0, 3, 4], [3, 1, 5], [4, 5, 2]]]
    if isinstance(contacts, dict):
        contacts = (x[np.asarray(contacts["i"], dtype=np.int64)], contacts["branch"], contacts["force"],
                    *([contacts["moment"]] if "moment" in contacts else []))
    loads = np.zeros((size, 18))  # f_a b_b, then M_a b_b
    if contacts is not None:
        xi, branch, force, *moment = (np.asarray(c, dtype=np.float64).reshape(-1, 3) for c in contacts)
        products = np.concatenate([(force[:, :, None] * branch[:, None, :]).reshape(-1, 9),
                                   (moment[0][:, :, None] * branch[:, None, :]).reshape(-1, 9) if moment
                                   else np.zeros((len(force), 9))], axis=1)
        s, ws = np.polynomial.legendre.leggauss(int(quadrature))
        s, ws = 0.5 * (s + 1.0), 0.5 * ws  # on [0, 1]
        # every quadrature point in one spread: one grid per thread to clear and sum, not one per point
        _spread(grid, kernel, (xi[None, :, :] - s[:, None, None] * branch[None, :, :]).reshape(-1, 3),
                (ws[:, None, None] * products[None, :, :]).reshape(-1, 18), loads)
    contact, couple = loads[:, :9].reshape(size, 3, 3), loads[:, 9:].reshape(size, 3, 3)
    shape = tuple(grid.shape)
    return Fields(grid, density.reshape(shape), momentum.reshape(shape + (3,)), velocity.reshape(shape + (3,)),
                  kinetic.reshape(shape + (3, 3)), contact.reshape(shape + (3, 3)), couple.reshape(shape + (3, 3)),
                  mass_momentum[:, 4].reshape(shape) if volumes is not None else None)


#: the columns of ``profile``: name, unit, and the field and component they take
PROFILE_COLUMNS = (("density", "kg/m^3"), ("velocity_x", "m/s"), ("velocity_y", "m/s"), ("velocity_z", "m/s"),
                   *((f"stress_{a}{b}", "Pa") for a, b in ("xx", "yy", "zz", "xy", "xz", "yz")),
                   *((f"kinetic_stress_{a}{b}", "Pa") for a, b in ("xx", "yy", "zz")),
                   *((f"couple_stress_{a}{b}", "N/m") for a, b in ("xx", "yy", "zz", "xy", "yx", "xz", "zx", "yz",
                                                                  "zy")))


def profile(fields: Fields, axis: str) -> dict:
    """The fields averaged over the grid's two other axes, along ``axis`` ("x", "y" or "z"): a
    mapping of column names with their units ("z (m)", "density (kg/m^3)", "stress_zz (Pa)", ...;
    ``PROFILE_COLUMNS``) to arrays, one value per node. The velocity is the averaged momentum over
    the averaged density (the mass-weighted mean). With a solid fraction, its column follows the axis."""
    if axis not in ("x", "y", "z"):
        raise ParameterError(f"profile axis = {axis!r} is not allowed: must be 'x', 'y' or 'z'")
    a = "xyz".index(axis)
    others = tuple(k for k in range(3) if k != a)

    def mean(field):
        return field.mean(axis=others)

    density, momentum = mean(fields.density), mean(fields.momentum)
    velocity = np.divide(momentum, density[:, None], out=np.zeros_like(momentum), where=density[:, None] > 0.0)
    tensors = {"stress": mean(fields.stress), "kinetic_stress": mean(fields.kinetic_stress),
               "couple_stress": mean(fields.couple_stress)}
    values = {"density": density, **{f"velocity_{c}": velocity[:, k] for k, c in enumerate("xyz")}}
    for name, _ in PROFILE_COLUMNS[len(values):]:
        tensor, (row, column) = name.rsplit("_", 1)
        values[name] = tensors[tensor][:, "xyz".index(row), "xyz".index(column)]
    solid = {} if fields.solid_fraction is None else {"solid_fraction (1)": mean(fields.solid_fraction)}
    return {f"{axis} (m)": fields.grid.axes()[a], **solid,
            **{f"{name} ({unit})": values[name] for name, unit in PROFILE_COLUMNS}}
