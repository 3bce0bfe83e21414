"""``rollingdem validate --experiment contact-laws``: the Walton-Braun, Walton tangential and JKR checks.

Each check sets up the textbook situation of its law and compares the measured number with the
closed-form one (docs/models.md §1.4-§1.6; the benchmarks are listed in docs/studies.md, "Contact
laws"): Walton-Braun's restitution, peak overlap, peak force and contact time in binary impacts
(WB-1, WB-1b), its forces along a prescribed overlap path (WB-2), a sphere dropped on a plane
(WB-3); Walton's tangential curve (WB-4); JKR's pull-off force, zero-load overlap, separation and
sticking velocity; a bonded pair's mode periods (BP-1), pure-mode break loads (BP-2) and energy
(BP-4), a bonded chain bending and stretching under its weight (BP-3, BP-3b), an agglomerate
breaking.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from rollingdem.experiments.registry import Experiment
from rollingdem.experiments.results import Check, ValidationResult, pyplot
from rollingdem.physics.bonds import BOND_INPUTS, BOND_INTACT, parallel_bond
from rollingdem.physics.contact.cohesion import JKR_HISTORY, jkr_cohesion
from rollingdem.physics.contact.frame import contact_frame
from rollingdem.physics.contact.model import ContactModel
from rollingdem.physics.contact.normal import (
    WALTON_BRAUN_HISTORY,
    WALTON_BRAUN_PARAMETERS,
    WaltonBraun,
    walton_braun_normal,
)
from rollingdem.physics.contact.tangential import WALTON_TANGENTIAL_HISTORY, walton_tangential
from rollingdem.physics.records import BOND_PARAMETERS, BOND_STATE, contact_inputs
from rollingdem.scene.bonds import ParallelBond
from rollingdem.scene.materials import Material
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.walls import Plane

CASE = "contact-laws"
K1 = 1e5  # N/m, WB-1
RESTITUTIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


def _wb_pair(e: float, speed: float):
    """Two spheres of 2 kg each (m* = 1 kg) meeting head on at ``speed`` (relative), k1 = 1e5 N/m,
    no gravity, no friction, dt = T2 / 200 with T2 = 2 pi sqrt(m* / k2)."""
    radius = 0.05
    density = 2.0 / (4.0 / 3.0 * math.pi * radius ** 3)
    sim = Simulation(contact=ContactModel(normal=WaltonBraun(loading_stiffness=K1)), gravity=(0, 0, 0))
    sim.add_material(Material("m", youngs_modulus=1e9, poisson_ratio=0.3, density=density, friction=0.0,
                              restitution=e))
    gap = 1e-4
    sim.add_particles([[-radius - gap, 0, 0], [radius + gap, 0, 0]], radius=radius, material="m",
                      velocity=[[0.5 * speed, 0, 0], [-0.5 * speed, 0, 0]])
    sim.dt = 2 * math.pi * math.sqrt(1.0 / (K1 / e ** 2)) / 200
    return sim, radius


def wb_impact(e: float, speed: float) -> dict:
    """WB-1: the outgoing over incoming relative speed, the largest overlap, the largest force and
    the time from touching to F = 0 (the overlap is then still delta_0 > 0). Touching is found
    from the first step's overlap at the incoming speed, F = 0 by extrapolating the last two
    forces on the k2 line, where F falls linearly."""
    sim, radius = _wb_pair(e, speed)
    while sim.number_of_contacts() == 0:
        sim.run(steps=1)
    overlap = 2 * radius - (sim.positions[1, 0] - sim.positions[0, 0])
    t0 = sim.time - overlap / speed
    deepest, force_max, t_end, last = overlap, abs(sim.forces[0, 0]), math.nan, (sim.time, abs(sim.forces[0, 0]))
    before = last
    while sim.number_of_contacts():
        sim.run(steps=1)
        deepest = max(deepest, 2 * radius - (sim.positions[1, 0] - sim.positions[0, 0]))
        force = abs(sim.forces[0, 0])
        force_max = max(force_max, force)
        if force == 0.0 and math.isnan(t_end):
            (ta, fa), (tb, fb) = before, last
            t_end = tb + (tb - ta) * fb / (fa - fb)
        before, last = last, (sim.time, force)
    after = sim.velocities[1, 0] - sim.velocities[0, 0]
    return {"restitution": after / speed, "overlap_max": deepest, "force_max": force_max, "contact_time": t_end - t0}


def wb_path() -> dict:
    """WB-2: the law stepped along the benchmark's overlap path (docs/studies.md) (k1 = 1e5 N/m, e = 0.5): the forces at its
    turning points, and the energy the first loop (0 -> 1 mm -> 0.75 mm) dissipates."""
    p = np.zeros(len(WALTON_BRAUN_PARAMETERS))
    P = WALTON_BRAUN_PARAMETERS
    p[[P.loading_stiffness, P.unloading_ratio, P.tangential_stiffness_ratio, P.reported_stiffness_ratio]] = (
        K1, 4.0, 1.0, 1.0)
    legs = [(0.0, 1.0), (1.0, 0.9), (0.9, 1.0), (1.0, 1.2), (1.2, 1.0), (1.0, 0.9), (0.9, 0.5), (0.5, 1.0)]
    hist = np.zeros((1, len(WALTON_BRAUN_HISTORY)))
    ends, first_loop = [], 0.0
    for n, (a, b) in enumerate(legs):
        for d in np.linspace(a, b, int(round(abs(b - a) / 0.01)) + 1)[1:] * 1e-3:
            out = walton_braun_normal(hist, 0, 0, d, 0.0, 0.01, 1.0, p, 0)
        ends.append(out[0])
    hist[:] = 0.0
    for d in np.concatenate([np.linspace(0, 1, 101)[1:], np.linspace(1, 0.75, 26)[1:]]) * 1e-3:
        first_loop += walton_braun_normal(hist, 0, 0, d, 0.0, 0.01, 1.0, p, 0)[5]
    return {"forces": ends, "first_loop": first_loop}


def wb_drop() -> float:
    """WB-3: R = 5 mm, rho = 2500 kg/m^3, k1 = 1e4 N/m, e = 0.5, dropped from 0.1 m onto a plane: the
    rebound over the impact speed, both where the centre passes z = R (interpolated in the step)."""
    radius = 0.005
    sim = Simulation(contact=ContactModel(normal=WaltonBraun(loading_stiffness=1e4)), dt=1e-6)
    sim.add_material(Material("m", youngs_modulus=1e9, poisson_ratio=0.3, density=2500.0, friction=0.5,
                              restitution=0.5))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, radius + 0.1]], radius=radius, material="m")
    sim.run(math.sqrt(2 * 0.1 / 9.81) - 2e-4)

    def crossing(going_down: bool) -> float:
        z0, v0 = sim.positions[0, 2], sim.velocities[0, 2]
        while True:
            sim.run(steps=1)
            z1, v1 = sim.positions[0, 2], sim.velocities[0, 2]
            if (z1 < radius) if going_down else (z1 > radius and v1 > 0):
                s = (radius - z0) / (z1 - z0)
                return abs(v0 + s * (v1 - v0))
            z0, v0 = z1, v1

    impact = crossing(True)
    return crossing(False) / impact


def wb_tangential() -> dict:
    """WB-4: Walton's law at N = 10 N, mu = 0.5, K_T0 = 1e5 N/m driven in steps of s*/2000: T at
    s*/2, and after a turn at full slip, T at s*/2 back (Masing: mu N - 2 mu N [1 - (3/4)^(3/2)])."""
    n, mu, k0 = 10.0, 0.5, 1e5
    s_star = 3 * mu * n / (2 * k0)
    ds = s_star / 2000
    hist = np.zeros((1, len(WALTON_TANGENTIAL_HISTORY)))
    p = np.array([0.0, 0.0, mu, 0.0, 0.0, 0.0, 1.0 / 3.0])
    frame = contact_frame(0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0)
    g = contact_inputs()
    forces = [-walton_tangential(hist, 0, 0, g, frame, (step, 0.0, 0.0), (n, n, 1e5, k0, 0.0), 1.0, p, 6)[0]
              for step in [ds] * 2400 + [-ds] * 1000]
    return {"half": forces[999], "back": forces[-1], "s_star": s_star, "limit": mu * n}


# JKR: 100 um spheres of a soft solid (E = 10 MPa, nu = 0.3, rho = 2500 kg/m^3), w = 0.1 J/m^2
JKR_SET = {"radius": 1e-4, "youngs_modulus": 1e7, "poisson_ratio": 0.3, "density": 2500.0, "surface_energy": 0.1}


def _jkr_constants():
    s = JKR_SET
    e_star = s["youngs_modulus"] / (2 * (1 - s["poisson_ratio"] ** 2))
    r_eff = s["radius"] / 2
    m_eff = s["density"] * 4 / 3 * math.pi * s["radius"] ** 3 / 2
    return e_star, r_eff, m_eff, s["surface_energy"]


def jkr_curve() -> dict:
    """The pull-off (least force along the curve, sampled every 1/4000 of [delta_c, 2 |delta_c|]), the
    force at the zero-load overlap, the separation the law keeps in its history."""
    e_star, r_eff, _, w = _jkr_constants()
    p = np.array([e_star, 0, 0, 0, 0, 0, w])

    def force(overlap, hist):
        hertz = 4 / 3 * e_star * math.sqrt(r_eff) * max(overlap, 0.0) ** 1.5
        g = contact_inputs(overlap=overlap, r_eff=r_eff)
        return jkr_cohesion(hist, 0, 0, g, (hertz, hertz, 0.0, 0.0, 0.0), p, 6)[0] + hertz

    hist = np.zeros((1, len(JKR_HISTORY)))
    force(0.0, hist)
    limit = float(hist[0, JKR_HISTORY.separation_limit])
    pull = min(force(d, np.zeros_like(hist)) for d in np.linspace(-limit, 2 * limit, 4000))
    a0 = (9 * math.pi * w * r_eff ** 2 / (2 * e_star)) ** (1 / 3)
    return {"pull_off": -pull, "zero_load_force": force(a0 ** 2 / (3 * r_eff), np.zeros_like(hist)),
            "separation": limit}


def jkr_sticks(speed: float) -> bool:
    """Two spheres meeting head on at ``speed`` (relative), no dashpot, dt = T / 400 (T the
    zero-load oscillation period): in contact after 40 periods."""
    s = JKR_SET
    sim = Simulation(contact=ContactModel(cohesion="jkr"), gravity=(0, 0, 0))
    sim.add_material(Material("m", youngs_modulus=s["youngs_modulus"], poisson_ratio=s["poisson_ratio"],
                              density=s["density"], restitution=1.0, friction=0.5, surface_energy=s["surface_energy"]))
    r = s["radius"]
    sim.add_particles([[-r - 1e-7, 0, 0], [r + 1e-7, 0, 0]], radius=r, material="m",
                      velocity=[[0.5 * speed, 0, 0], [-0.5 * speed, 0, 0]])
    limit = [v for label, v in sim.time_step_limits() if label.startswith("JKR")][0]
    sim.dt = limit * 50 / 400
    sim.run(steps=16000)
    return sim.number_of_contacts() == 1


def jkr_sticking_velocity(quick: bool) -> tuple[float, float]:
    """(measured, analytic) sticking velocity: bisection on the impact speed to 1 % (quick: 2 %),
    and sqrt(2 W / m*) with W = int_delta_c^0 |F| d(delta) by quadrature over the contact radius."""
    from scipy.integrate import quad  # deferred: slow to load, used here only

    e_star, r_eff, m_eff, w = _jkr_constants()

    def f(a):
        return 4 * e_star * a ** 3 / (3 * r_eff) - math.sqrt(8 * math.pi * w * e_star * a ** 3)

    def slope(a):
        return 2 * a / r_eff - 0.5 * math.sqrt(2 * math.pi * w / (e_star * a))

    a_f = (math.pi * w * r_eff ** 2 / (8 * e_star)) ** (1 / 3)
    a_touch = (2 * math.pi * w * r_eff ** 2 / e_star) ** (1 / 3)
    tail = -quad(lambda a: f(a) * slope(a), a_f, a_touch, epsabs=0, epsrel=1e-12)[0]
    analytic = math.sqrt(2 * tail / m_eff)
    lo, hi = 0.7 * analytic, 1.3 * analytic
    while hi - lo > (0.02 if quick else 0.01) * analytic:
        mid = 0.5 * (lo + hi)
        if jkr_sticks(mid):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi), analytic


# BP: the bond set B1 of docs/studies.md (R = 1 cm, rho = 2500 kg/m^3, E = 1e8 Pa, kappa = 2.5, sigma_c = c = 1 MPa)
BOND_R, BOND_RHO, BOND_GAP = 0.01, 2500.0, 1e-4


def _b1(strength=1e6):
    return ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=strength, cohesion=strength)


def bonded_pair(velocity, angular_velocity, dt, strength=1e6):
    """Two B1 spheres 0.1 mm apart (their contact out of the way), bonded: the first at -x."""
    r = BOND_R
    sim = Simulation(gravity=(0, 0, 0), dt=dt)
    sim.add_material(Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=BOND_RHO, restitution=0.5))
    sim.add_particles([[-r - BOND_GAP / 2, 0, 0], [r + BOND_GAP / 2, 0, 0]], radius=r, material="m",
                      velocity=velocity, angular_velocity=angular_velocity)
    sim.add_bonds(_b1(strength), gap=2 * BOND_GAP)
    return sim


def bond_mode_period(mode: str) -> tuple[float, float]:
    """BP-1: (measured, expected) period of one of a B1 pair's modes, each started alone, over
    about ten cycles at dt = 1e-6 s (upward crossings of the mean, interpolated)."""
    r = BOND_R
    mass = BOND_RHO * 4 / 3 * math.pi * r ** 3
    inertia = 0.4 * mass * r ** 2
    lever = r + BOND_GAP / 2
    k = dict(zip(BOND_PARAMETERS._fields, _b1().parameter_row(r, r)))
    v, w, signal, omega2 = {
        "axial": (((-1e-3, 0, 0), (1e-3, 0, 0)), ((0, 0, 0), (0, 0, 0)), lambda s: s.positions[1, 0],
                  2 * k["normal_stiffness"] / mass),
        "bending": (((0, 0, 0), (0, 0, 0)), ((0, 0, 0.1), (0, 0, -0.1)), lambda s: s.angular_velocities[0, 2],
                    2 * k["bending_stiffness"] / inertia),
        "twisting": (((0, 0, 0), (0, 0, 0)), ((0.1, 0, 0), (-0.1, 0, 0)), lambda s: s.angular_velocities[0, 0],
                     2 * k["twisting_stiffness"] / inertia),
        "shear": (((0, 1e-3, 0), (0, -1e-3, 0)), ((0, 0, 0), (0, 0, 0)), lambda s: s.forces[0, 1],
                  k["shear_stiffness"] * (2 / mass + 2 * lever ** 2 / inertia))}[mode]
    sim = bonded_pair(v, w, 1e-6)
    expected = 2 * math.pi / math.sqrt(omega2)
    samples = []
    for _ in range(int(10 * expected / sim.dt)):
        sim.run(steps=1)
        samples.append(signal(sim))
    d = np.asarray(samples) - np.mean(samples)
    up = np.where((d[:-1] < 0) & (d[1:] >= 0))[0]
    times = (up + d[up] / (d[up] - d[up + 1])) * sim.dt
    return float(np.diff(times).mean()), expected


def bond_energy_drift(dt: float) -> float:
    """BP-4: the B1 pair with the benchmark's velocities and spins, 0.2 s: the largest relative change of
    kinetic plus bond strain energy (200 samples)."""
    sim = bonded_pair(((0, 0, -0.02), (0.01, 0.03, 0.01)), ((3, -2, 5), (-4, 1, 2)), dt, strength=1e9)
    e0 = sum(sim.kinetic_energy())
    drift = 0.0
    for _ in range(200):
        sim.run(steps=int(round(0.2 / dt / 200)))
        drift = max(drift, abs(sum(sim.kinetic_energy()) + sim.bond_energy() - e0) / e0)
    return drift


def bond_break_loads() -> dict:
    """BP-2: B1 driven in each pure mode through the bond law (1/2000 of the break per step): the
    load at the break."""
    r = BOND_R
    p = np.array(_b1().parameter_row(r, r))
    out = {}
    for mode, rv, wi, wj, key in (("tension", (1e-7, 0, 0), (0, 0, 0), (0, 0, 0), "normal_force"),
                                  ("shear", (0, 2.5e-7, 0), (0, 0, 0), (0, 0, 0), "shear_y"),
                                  ("bending", (0, 0, 0), (0, 0, 5e-6), (0, 0, -5e-6), "bending_z"),
                                  ("twisting", (0, 0, 0), (2.5e-5, 0, 0), (0, 0, 0), "twisting_moment")):
        state = np.zeros((1, len(BOND_STATE)))
        g = np.array([1.0, 0, 0, *rv, *wi, *wj, r, r])
        assert len(g) == len(BOND_INPUTS)
        while True:
            before = state[0].copy()
            if parallel_bond(state, 0, p, g, 1.0)[-1] != BOND_INTACT:
                break
        out[mode] = abs(before[getattr(BOND_STATE, key)])
    return out


def bonded_chain(gravity, bonds: int = 10):
    """BP-3: a chain of ``bonds`` B1 bonds (spheres 0.1 mm apart along x, the first fixed, exclusive
    bonds with dashpots zeta = 0.7) loaded by its own weight for 16 s: (the free end's mean
    displacement over the last 2 s, the bond's parameters by name, L_b the spacing)."""
    r = BOND_R
    lb = 2 * r + BOND_GAP
    sim = Simulation(gravity=gravity)
    sim.add_material(Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=BOND_RHO, restitution=0.5))
    sim.add_particles([[0, 0, 0]], radius=r, material="m", fixed=True)
    sim.add_particles([[k * lb, 0, 0] for k in range(1, bonds + 1)], radius=r, material="m")
    bond = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e9, cohesion=1e9,
                        damping_ratio=0.7, contact_while_bonded="exclusive")
    sim.add_bonds(bond, pairs=[[k - 1, k] for k in range(1, bonds + 1)])
    sim.dt = 0.5 * sim.stable_time_step()
    tip = []
    for _ in range(320):
        sim.run(0.05)
        tip.append(sim.positions[bonds] - (bonds * lb, 0, 0))
    return np.mean(tip[-40:], axis=0), dict(zip(BOND_PARAMETERS._fields, bond.parameter_row(r, r))), lb


def twisting_chain_period(bonds: int = 10) -> tuple[float, float]:
    """BP-3c: a chain of ``bonds`` B1 bonds from a fixed sphere, twisting about its axis in its
    slowest mode: (measured, expected) period over about ten cycles. The spheres are a chain of
    torsion springs K_t and inertias I = 2/5 m R^2; sphere n starts spinning at sin(n q),
    q = pi/(2N + 1), the mode shape, and the mode's omega = 2 sqrt(K_t/I) sin(q/2) (the static
    twist under a tip torque T, N T/K_t, is the same springs in series)."""
    r = BOND_R
    lb = 2 * r + BOND_GAP
    q = math.pi / (2 * bonds + 1)
    sim = Simulation(gravity=(0, 0, 0))
    sim.add_material(Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=BOND_RHO, restitution=0.5))
    sim.add_particles([[0, 0, 0]], radius=r, material="m", fixed=True)
    sim.add_particles([[n * lb, 0, 0] for n in range(1, bonds + 1)], radius=r, material="m",
                      angular_velocity=[[0.1 * math.sin(n * q), 0, 0] for n in range(1, bonds + 1)])
    bond = _b1(1e9)
    sim.add_bonds(bond, pairs=[[n - 1, n] for n in range(1, bonds + 1)])
    inertia = 0.4 * BOND_RHO * 4 / 3 * math.pi * r ** 5
    k_t = dict(zip(BOND_PARAMETERS._fields, bond.parameter_row(r, r)))["twisting_stiffness"]
    expected = 2 * math.pi / (2 * math.sqrt(k_t / inertia) * math.sin(q / 2))
    sim.dt = expected / 1000
    samples = []
    for _ in range(10 * 1000 + 100):
        sim.run(steps=1)
        samples.append(sim.angular_velocities[bonds, 0])
    d = np.asarray(samples)
    up = np.where((d[:-1] < 0) & (d[1:] >= 0))[0]
    times = (up + d[up] / (d[up] - d[up + 1])) * sim.dt
    return float(np.diff(times).mean()), expected


def hinged_chain_deflection(force: float, bonds: int, spacing: float, bending_stiffness: float,
                            shear_stiffness: float) -> float:
    """The tip deflection of a chain of ``bonds`` bonds from a clamp, a transverse ``force`` on each
    free sphere: bond k (contact point at x_k = (k - 1/2) L_b) carries V_k = (N - k + 1) F and
    M_k = F sum_{m >= k} (m L_b - x_k); the part beyond it turns by M_k / K_b about the contact point
    and shifts by V_k / K_s: sum_k M_k / K_b (N L_b - x_k) + V_k / K_s. (For one force at the tip this
    is the closed form F L^3/(3 E I) (1 - 1/(4 N^2)) + N F / K_s.)"""
    total = 0.0
    for b in range(1, bonds + 1):
        xc = (b - 0.5) * spacing
        moment = force * sum(m * spacing - xc for m in range(b, bonds + 1))
        total += moment / bending_stiffness * (bonds * spacing - xc) + (bonds - b + 1) * force / shear_stiffness
    return total


AGGLOMERATE_SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)  # m/s


def agglomerate_breakage(speed: float, cells: int = 4) -> dict:
    """A bonded agglomerate dropped on a plate: spheres of R = 2 mm (E = 100 MPa, 2500 kg/m^3, mu =
    0.5, EPSD mu_r = 0.1) on a simple cubic lattice (spacing 2.002 R) cut to a ball of ``cells``
    spacings (257 spheres for 4), every touching pair bonded (E = 100 MPa, sigma_c = c = 0.2 MPa),
    launched at the plate at ``speed`` from 1 mm above it and run 20 ms: the share of bonds broken."""
    r = 0.002
    sim = Simulation(contact=ContactModel(rolling="epsd"))
    sim.add_material(Material("m", youngs_modulus=1e8, poisson_ratio=0.3, density=2500.0, restitution=0.5,
                              friction=0.5, rolling_friction=0.1))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    spacing = 2.002 * r
    k = np.arange(-cells, cells + 1)
    lattice = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3) * spacing
    lattice = lattice[np.linalg.norm(lattice, axis=1) <= cells * spacing]
    x = lattice + (0.0, 0.0, cells * spacing + r + 1e-3)
    sim.add_particles(x, radius=r, material="m", velocity=np.tile((0.0, 0.0, -speed), (len(x), 1)))
    bonds = sim.add_bonds(ParallelBond(youngs_modulus=1e8, tensile_strength=2e5, cohesion=2e5), gap=0.01 * r)
    sim.dt = 0.5 * sim.stable_time_step()
    sim.run(0.02)
    counts = sim.bond_counts()
    return {"spheres": len(x), "bonds": bonds,
            "broken": (counts["bonds_broken_tension"] + counts["bonds_broken_shear"]) / bonds,
            "broken_in_tension": counts["bonds_broken_tension"] / bonds}


def contact_laws(models=None, quick=False, outdir=None, progress=None, runner=map) -> ValidationResult:
    """The contact-law checks (``models`` and ``runner`` are not used: each check is its own law)."""
    start = time.perf_counter()
    checks, rows = [], []

    def check(model, quantity, measured, reference, tolerance, relative=True, source="", bound="two-sided"):
        checks.append(Check(CASE, model, quantity, float(measured), float(reference), tolerance, relative=relative,
                            bound=bound, source=source))
        rows.append({"law": model, "quantity": quantity, "measured": float(measured), "reference": float(reference)})
        if progress:
            progress()

    spec = "docs/models.md §1.4"
    for e in (RESTITUTIONS[::2] if quick else RESTITUTIONS):
        r = wb_impact(e, 1.0)
        check("walton_braun", f"WB-1 e_out at e = {e}, 1 m/s", r["restitution"], e, 5e-4, relative=False,
              source=spec + ": e = sqrt(k1/k2)")
        check("walton_braun", f"WB-1 delta_max at e = {e} (m)", r["overlap_max"], math.sqrt(1.0 / K1), 2e-3,
              source="v0 sqrt(m*/k1)")
        check("walton_braun", f"WB-1 F_max at e = {e} (N)", r["force_max"], math.sqrt(K1), 2e-3,
              source="v0 sqrt(m* k1)")
        check("walton_braun", f"WB-1 contact time at e = {e} (s)", r["contact_time"],
              0.5 * math.pi * math.sqrt(1.0 / K1) * (1 + e), 2e-3, source="(pi/2) sqrt(m*/k1) (1 + e)")
    for speed in (0.1, 10.0):
        r = wb_impact(0.5, speed)
        check("walton_braun", f"WB-1b e_out at e = 0.5, {speed:g} m/s", r["restitution"], 0.5, 5e-4,
              relative=False, source="the same e at every speed")
    path = wb_path()
    for n, (f, ref) in enumerate(zip(path["forces"], (100.0, 60.0, 100.0, 120.0, 40.0, 0.0, 0.0, 40.0))):
        check("walton_braun", f"WB-2 force at the path's turning point {n + 1} (N)", f, ref, 1e-9, relative=False,
              source="the classical form along the path, exact")
    check("walton_braun", "WB-2 first loop's dissipation (J)", path["first_loop"], 0.0375, 1e-9,
          source="(1 - e^2) 1/2 k1 delta_max^2")
    check("walton_braun", "WB-3 rebound / impact speed at z = R", wb_drop(), 0.49617, 2e-3,
          source="converged integration with gravity during the contact")
    t = wb_tangential()
    check("walton", "WB-4 T at s*/2 (N)", t["half"], t["limit"] * (1 - 0.5 ** 1.5), 2e-3 * t["limit"], relative=False,
          source="Mindlin: mu N [1 - (1 - s/s*)^(3/2)]")
    check("walton", "WB-4 T at s*/2 after a turn at full slip (N)", t["back"],
          t["limit"] - 2 * t["limit"] * (1 - 0.75 ** 1.5), 2e-3 * t["limit"], relative=False,
          source="Masing: mu N - 2 mu N [1 - (1 - u/(2 s*))^(3/2)]")
    e_star, r_eff, _, w = _jkr_constants()
    curve = jkr_curve()
    check("jkr", "pull-off force (N)", curve["pull_off"], 1.5 * math.pi * w * r_eff, 0.01, source="3/2 pi w R*")
    check("jkr", "force at the zero-load overlap / pull-off", curve["zero_load_force"] / curve["pull_off"], 0.0, 1e-9,
          relative=False, source="delta_0 = a_0^2 / (3 R*)")
    check("jkr", "separation |delta_c| (m)", curve["separation"],
          0.75 * (math.pi ** 2 * w ** 2 * r_eff / e_star ** 2) ** (1 / 3), 1e-9,
          source="3/4 (pi^2 w^2 R* / E*^2)^(1/3)")
    measured, analytic = jkr_sticking_velocity(quick)
    check("jkr", "sticking velocity (m/s)", measured, analytic, 0.05, source="sqrt(2 W / m*), W the tail's work")
    for mode in ("axial", "bending", "twisting", "shear"):
        period, expected = bond_mode_period(mode)
        check("parallel_bond", f"BP-1 {mode} period of a bonded pair (s)", period, expected, 2e-3,
              source="omega^2 = 2 K_n/m, 2 K_b/I, 2 K_t/I, K_s (2/m + 2 L^2/I)")
    loads = bond_break_loads()
    area, bending, polar = math.pi * BOND_R ** 2, math.pi * BOND_R ** 4 / 4, math.pi * BOND_R ** 4 / 2
    for mode, reference in (("tension", 1e6 * area), ("shear", 1e6 * area), ("bending", 1e6 * bending / BOND_R),
                            ("twisting", 1e6 * polar / BOND_R)):
        check("parallel_bond", f"BP-2 {mode} break load (N or N m)", loads[mode], reference, 1e-3,
              source="sigma_c A, c A, sigma_c I / R, c J / R")
    check("parallel_bond", "BP-4 energy drift over 0.2 s at dt = 2e-6 s", bond_energy_drift(2e-6), 1e-4, 0.0,
          bound="upper", source="bound 1e-4, second-order integration")
    weight = BOND_RHO * 4 / 3 * math.pi * BOND_R ** 3 * 9.81
    (_, sag, _), k, lb = bonded_chain((0, -9.81, 0))
    check("parallel_bond", "BP-3 chain of 10 bonds under its weight: tip deflection (m)", -sag,
          hinged_chain_deflection(weight, 10, lb, k["bending_stiffness"], k["shear_stiffness"]), 1e-3,
          source="statically determinate chain of hinged springs")
    (stretch, _, _), k, lb = bonded_chain((9.81, 0, 0))
    check("parallel_bond", "BP-3b chain of 10 bonds hanging along its axis: extension (m)", stretch,
          weight * 10 * 11 / (2 * k["normal_stiffness"]), 1e-3, source="m g N (N + 1) / (2 K_n)")
    period, expected = twisting_chain_period()
    check("parallel_bond", "BP-3c chain of 10 bonds twisting in its slowest mode: period (s)", period, expected,
          1e-4, source="torsion springs in series: omega = 2 sqrt(K_t/I) sin(pi/(2 (2N + 1)))")
    breakage = {v: agglomerate_breakage(v) for v in AGGLOMERATE_SPEEDS}
    shares = [breakage[v]["broken"] for v in AGGLOMERATE_SPEEDS]
    check("parallel_bond", "agglomerate: smallest rise of the share of bonds broken between successive impact "
          f"speeds ({', '.join(f'{v:g}' for v in AGGLOMERATE_SPEEDS)} m/s)", float(np.diff(shares).min()), 0.0, 0.0,
          relative=False, bound="lower", source="more impact energy breaks more bonds")
    result = ValidationResult(CASE, "Contact laws: Walton-Braun, Walton's tangential law, JKR, the parallel bond",
                        pd.DataFrame(rows), checks)
    result.notes.append("Agglomerate (" + f"{breakage[1.0]['spheres']} spheres, {breakage[1.0]['bonds']} bonds): "
                        + ", ".join(f"{v:g} m/s {100 * b['broken']:.0f} % broken" for v, b in breakage.items()))
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(5, 3.5))
        ax.plot(AGGLOMERATE_SPEEDS, [100 * b["broken"] for b in breakage.values()], "o-", label="all")
        ax.plot(AGGLOMERATE_SPEEDS, [100 * b["broken_in_tension"] for b in breakage.values()], "s--",
                label="in tension")
        ax.set_xscale("log")
        ax.set_xticks(AGGLOMERATE_SPEEDS, [f"{v:g}" for v in AGGLOMERATE_SPEEDS])
        ax.minorticks_off()
        ax.set_xlabel("impact speed (m/s)")
        ax.set_ylabel("bonds broken (%)")
        ax.set_title("Bonded agglomerate dropped on a plate")
        ax.legend()
        result.add_figure(fig, outdir, "agglomerate_breakage.png")
    result.wall_time = time.perf_counter() - start
    return result


class ContactLaws(Experiment):
    """The contact laws checked one at a time against their closed forms (docs/models.md §1)."""

    name = CASE
    description = "the contact laws against their closed forms: restitution, paths, sticking, bonds"

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return contact_laws(models, quick=quick, outdir=outdir, progress=progress, runner=runner)
