"""Helpers several test files share: ideal piles of a known angle, a generated case file compared
with the one shipped, the measurements' material, a cluster of colliding spheres. A test file
imports them from here, never from another test file."""

import math

import numpy as np
import pytest

import rollingdem as rd
from conftest import R

# --- ideal piles ----------------------------------------------------------------------

RADIUS = 2e-3  # m: the spheres of an ideal pile
D = 2 * RADIUS
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def column_lattice(rng, half_width, d):
    """Column positions on a square lattice of spacing d, from -half_width d to half_width d each
    way, jittered by +-0.1 d in x and y: (x, y, distance from the axis)."""
    g = np.arange(-half_width, half_width + 1) * d
    gx, gy = np.meshgrid(g, g, indexing="ij")
    cx = gx.ravel() + rng.uniform(-0.1, 0.1, gx.size) * d
    cy = gy.ravel() + rng.uniform(-0.1, 0.1, gy.size) * d
    return cx, cy, np.hypot(cx, cy)


def ideal_pile(alpha_deg, *, n_base=30, envelope="exact", stacks=0.0, stack_height=3, foot_layers=0,
               foot_width=10, center=(0.0, 0.0), seed=0):
    """Spheres of radius 2 mm in columns on a square lattice of spacing d (jittered by +-0.1 d in x, y),
    standing on a first layer on the floor (z = a); the cone of tops has angle alpha_deg and base
    radius n_base d. Returns positions (N, 3) in m; the radius is RADIUS.

    envelope "exact": the top sphere of every column has its top exactly on the cone (t = h - tan(alpha)
    rho): the surface has no discretisation error. "even": the top sphere lies a depth delta in [0, d)
    below, delta taken from the golden-ratio sequence in order of rho, so every radial window holds
    evenly spread depths (the envelope of a random packing, without the seed scatter of a random one).
    stacks: that fraction of the columns in the outer half carries a stack of stack_height spheres
    on its top (bumps). foot_layers: layers 0.82 d apart (a sphere in the dimples of the layer below)
    on the first layer, out to foot_width diameters beyond the cone, wherever the cone is lower (the
    flat foot a collapse leaves around its heap)."""
    rng = np.random.default_rng(seed)
    d = D
    big_r = n_base * d
    tan_a = math.tan(math.radians(alpha_deg))
    cx, cy, rho = column_lattice(rng, n_base + 12, d)
    depth = np.zeros(rho.size)
    if envelope == "even":
        order = np.argsort(rho)
        depth[order] = (np.arange(rho.size) * GOLDEN + rng.uniform()) % 1.0 * d
    top_z = RADIUS + (big_r - rho) * tan_a - depth  # centre of each column's top sphere
    nz = np.where(top_z >= RADIUS + d, np.floor((top_z - RADIUS) / d).astype(int), 0)  # above the first layer
    col = np.repeat(np.arange(rho.size), nz)
    lev = np.arange(col.size) - np.repeat(np.cumsum(nz) - nz, nz)  # 0: the top sphere
    first = rho < big_r + foot_width * d
    parts = [np.column_stack([cx[first], cy[first], np.full(first.sum(), RADIUS)]),
             np.column_stack([cx[col], cy[col], top_z[col] - lev * d])]
    for k in range(1, foot_layers + 1):
        zc = RADIUS + k * 0.82 * d
        m = first & (top_z < zc)
        parts.append(np.column_stack([cx[m], cy[m], np.full(m.sum(), zc)]))
    if stacks:
        on = (nz > 0) & (rho > 0.5 * big_r) & (rng.random(rho.size) < stacks)
        parts += [np.column_stack([cx[on], cy[on], top_z[on] + k * d]) for k in range(1, stack_height + 1)]
    return np.vstack(parts) + [center[0], center[1], 0.0]


# --- case files -------------------------------------------------------------------------------

def _flat(data, prefix=""):
    if isinstance(data, dict):
        return {k: v for key, value in data.items() for k, v in _flat(value, f"{prefix}{key}.").items()}
    if isinstance(data, (list, tuple)):
        return {k: v for i, value in enumerate(data) for k, v in _flat(value, f"{prefix}{i}.").items()}
    return {prefix.rstrip("."): data}


def assert_same_case(data: dict, name: str, rel: float, leave_out=("output.",)) -> None:
    """The case file data ``data`` and the shipped case file ``name``, as the case file reader
    completes them, hold the same entries, numbers equal within ``rel`` (the figures the file
    writes), the entries whose path has one of ``leave_out`` aside."""
    from rollingdem.experiments.case_file import shipped_cases
    from rollingdem.io.casefile import load_case

    ours, shipped = (_flat(load_case(d).model_dump()) for d in (data, shipped_cases()[name]))
    keep = sorted(k for k in ours if not any(part in k for part in leave_out))
    assert keep == sorted(k for k in shipped if not any(part in k for part in leave_out))
    for k in keep:
        if isinstance(ours[k], float):
            assert ours[k] == pytest.approx(shipped[k], rel=rel, abs=1e-12), k
        else:
            assert ours[k] == shipped[k], k


# --- materials and scenes ---------------------------------------------------------------------

def measurement_material(**kw):
    params = dict(youngs_modulus=40e6, poisson_ratio=0.49, density=1056.0, friction=0.3, rolling_friction=0.1,
                  restitution=0.5, rolling_damping=0.3)
    params.update(kw)
    return rd.Material("m", **params)


def cluster(table1, n_side=5, rolling="cdt", seed=1, gravity=(0, 0, 0), speed=0.3, spacing=2.05, fast_spin=0.0):
    """A cube of n_side^3 spheres with random velocities and spins, close enough to collide; every
    third sphere spins at ``fast_spin`` (rad/s) if it is given."""
    rng = np.random.default_rng(seed)
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling), gravity=gravity, dt=2e-6,
                        track_energy=True)
    sim.add_material(table1())
    g = np.arange(n_side) * spacing * R
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    x += rng.uniform(-0.01 * R, 0.01 * R, x.shape)
    radii = R * rng.uniform(0.97, 1.0, len(x))
    spin = rng.normal(0, speed / R, x.shape)
    if fast_spin:
        spin[::3] *= fast_spin / np.linalg.norm(spin[::3], axis=1)[:, None]
    sim.add_particles(x, radii, "m", velocity=rng.normal(0, speed, x.shape), angular_velocity=spin)
    return sim


# --- a settled bed ---------------------------------------------------------------------


def settled_glass_bed(side: float, height: float, count: int, seed: int):
    """``count`` glass spheres (radius 0.9-1.1 mm, EPSD rolling resistance mu_r 0.2, E = 5 MPa)
    inserted in a box ``side`` wide, periodic along x and y, and ``height`` high over a floor, then
    settled (``rd.Settled``)."""
    sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), periodic={"x": (0.0, side), "y": (0.0, side)})
    sim.add_material(rd.Material("glass", youngs_modulus=5e6, poisson_ratio=0.3, density=2500.0, restitution=0.3,
                                 friction=0.5, rolling_friction=0.2))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    sim.insert(rd.BoxRegion((0, 0, 0), (side, side, height)), count=count, radius=rd.Uniform(0.0009, 0.0011),
               material="glass", seed=seed)
    assert sim.run(1.0, until=rd.Settled()).startswith("settled")
    return sim
