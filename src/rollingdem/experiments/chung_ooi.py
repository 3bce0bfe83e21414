"""``rollingdem validate --experiment chung-ooi``: the eight benchmark tests of Chung & Ooi (2011),
"Benchmark tests for verifying discrete element modelling codes at particle impact level",
Granular Matter 13, 643-656, each against the closed form the paper compares it with
(docs/models.md §19):

1. two identical spheres meeting head on, elastic (glass, limestone): peak force, peak overlap and
   contact time against Hertz;
2. a sphere hitting a rigid plane, elastic (aluminium and magnesium alloys): the same;
3. a sphere hitting a rigid plane at restitution 0.2-1 (aluminium oxide, cast iron): the rebound's
   restitution against the one asked for;
4. oblique impacts on a plane at a constant speed (aluminium oxide, aluminium alloy): the tangential
   restitution, the spin and the rebound angle against the rigid-body limits of gross sliding;
5. oblique impacts on a plane at a constant normal speed (steel, polyethylene): the normalised
   recoil angle and spin against the same limits;
6. a spinning sphere hitting a plane (aluminium alloy, nylon): the tangential restitution of the
   contact point and the recoil angle against the limits;
7. two identical spheres spinning in opposite senses meeting head on (aluminium alloy, copper):
   their surfaces move together, so the spins and the sideways speeds are unchanged;
8. a spinning sphere hitting a sphere five times larger held fixed (aluminium alloy, nylon): as 6.

The materials, speeds and angles are the paper's as the public inputs of LIGGGHTS-PFM, Kratos and
Yade record them. Gravity is off; the rigid plane is a wall of the sphere's Poisson ratio and a
Young's modulus 1e6 times the sphere's, and the closed forms take the pair's exact E* and G*.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pandas as pd
from scipy.special import beta as beta_function

from rollingdem.experiments.registry import Experiment
from rollingdem.experiments.results import Check, ValidationResult, pyplot
from rollingdem.physics.contact.model import ContactModel
from rollingdem.physics.contact.normal import Hooke, Linear, WaltonBraun, equivalent_stiffness, hertz_damping_factor
from rollingdem.scene.materials import Material
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.walls import Plane

CASE = "chung-ooi"
RIGID = 1e6  # the plane's Young's modulus over the sphere's: E* within 1e-6 of the rigid plane's
STEPS_PER_CONTACT = 1000  # dt = the Hertz contact time / this (quick: / QUICK_STEPS)
QUICK_STEPS = 250


@dataclass(frozen=True)
class Solid:
    """A benchmark material: Young's modulus E (Pa), Poisson ratio nu and density rho (kg/m^3)."""

    name: str
    youngs_modulus: float
    poisson_ratio: float
    density: float

    @property
    def shear_modulus(self) -> float:
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


#: the paper's materials (its aluminium alloy has nu = 0.30, rho = 2699 in test 2, 0.33 and 2700 after)
SOLIDS = {s.name: s for s in (
    Solid("glass", 4.8e10, 0.20, 2800.0), Solid("limestone", 2.0e10, 0.25, 2500.0),
    Solid("aluminium alloy (test 2)", 7.0e10, 0.30, 2699.0), Solid("magnesium alloy", 4.0e10, 0.35, 1800.0),
    Solid("aluminium oxide", 3.8e11, 0.23, 4000.0), Solid("cast iron", 1.0e11, 0.25, 7000.0),
    Solid("aluminium alloy", 7.0e10, 0.33, 2700.0), Solid("steel", 2.08e11, 0.30, 7850.0),
    Solid("polyethylene", 1.0e9, 0.40, 1400.0), Solid("nylon", 2.5e9, 0.40, 1000.0),
    Solid("copper", 1.2e11, 0.35, 8900.0))}


def effective_moduli(a: Solid, b: Solid | None = None) -> tuple[float, float]:
    """(E*, G*): 1/E* = (1 - nu_a^2)/E_a + (1 - nu_b^2)/E_b and 1/G* = (2 - nu_a)/G_a + (2 - nu_b)/G_b
    (docs/models.md §1.1); ``b`` None: the rigid plane of this module (a's nu, RIGID times a's E)."""
    b = b or Solid("plane", RIGID * a.youngs_modulus, a.poisson_ratio, a.density)
    e_star = 1.0 / ((1 - a.poisson_ratio ** 2) / a.youngs_modulus + (1 - b.poisson_ratio ** 2) / b.youngs_modulus)
    g_star = 1.0 / ((2 - a.poisson_ratio) / a.shear_modulus + (2 - b.poisson_ratio) / b.shear_modulus)
    return e_star, g_star


def sphere_mass(solid: Solid, radius: float) -> float:
    return solid.density * 4.0 / 3.0 * math.pi * radius ** 3


#: t_c = HERTZ_TIME delta_max / v: 2 int_0^1 dx / sqrt(1 - x^(5/2)) = (4/5) B(2/5, 1/2) = 2.9432
HERTZ_TIME = 0.8 * float(beta_function(0.4, 0.5))


def hertz_impact(e_star: float, r_eff: float, m_eff: float, speed: float) -> dict:
    """An elastic Hertz impact at the closing speed ``speed``: energy m* v^2 / 2 = (8/15) E* sqrt(R*)
    delta_max^(5/2) gives delta_max = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5), F_max = (4/3) E* sqrt(R*)
    delta_max^(3/2), and t_c = 2 int_0^delta_max d delta / delta' = HERTZ_TIME delta_max / v
    (Johnson 1985, ch. 11)."""
    overlap = (15.0 * m_eff * speed ** 2 / (16.0 * e_star * math.sqrt(r_eff))) ** 0.4
    return {"overlap_max": overlap, "force_max": 4.0 / 3.0 * e_star * math.sqrt(r_eff) * overlap ** 1.5,
            "contact_time": HERTZ_TIME * overlap / speed}


def spring_impact(stiffness: float, m_eff: float, speed: float) -> dict:
    """An elastic impact on a linear spring k: delta_max = v sqrt(m*/k), F_max = k delta_max,
    t_c = pi sqrt(m*/k) (half a period)."""
    overlap = speed * math.sqrt(m_eff / stiffness)
    return {"overlap_max": overlap, "force_max": stiffness * overlap, "contact_time": math.pi * math.sqrt(m_eff / stiffness)}


#: the normal contact laws the normal tests run, each with the history spring
NORMAL_LAWS = ("hertz", "hooke", "linear", "walton_braun")
#: the tangential laws the oblique tests run, each on Hertz's normal law
TANGENTIAL_LAWS = ("history", "walton")


def contact_model(law: str, tangential: str = "history", e_star: float = 0.0, r_eff: float = 0.0,
                  m_eff: float = 0.0, speed: float = 0.0):
    """The contact law ``law`` with the tangential law ``tangential``: Hertz-Mindlin takes E and nu;
    Hooke and Walton-Braun take the Hertz-equivalent spring at the impact's closing ``speed``
    (characteristic velocity V_c = speed), and ``linear`` the same spring given as k_n = k_s, so that
    each peaks at Hertz's overlap."""
    if law == "hertz":
        normal = "hertz"
    elif law == "hooke":
        normal = Hooke(characteristic_velocity=speed)
    elif law == "linear":
        k = float(equivalent_stiffness(e_star, r_eff, m_eff, speed))
        normal = Linear(normal_stiffness=k, shear_stiffness=k)
    elif law == "walton_braun":
        normal = WaltonBraun(characteristic_velocity=speed)
    else:
        raise ValueError(law)
    return ContactModel(normal=normal, tangential=tangential)


def law_impact(law: str, e_star: float, r_eff: float, m_eff: float, speed: float) -> dict:
    """The closed form of an elastic impact under ``law`` at the closing ``speed``: Hertz's, or the
    Hertz-equivalent spring's k = m* v^2 / delta_H^2 (``spring_impact``), whose peak overlap is Hertz's."""
    hertz = hertz_impact(e_star, r_eff, m_eff, speed)
    if law == "hertz":
        return hertz
    return spring_impact(m_eff * speed ** 2 / hertz["overlap_max"] ** 2, m_eff, speed)


@dataclass
class Body:
    """A sphere of the scene: its material, radius (m), centre, velocity and angular velocity, and
    whether it is held fixed (infinite mass: its contacts take the free sphere's)."""

    solid: Solid
    radius: float
    position: tuple
    velocity: tuple = (0.0, 0.0, 0.0)
    angular_velocity: tuple = (0.0, 0.0, 0.0)
    fixed: bool = False


def scene(bodies: list[Body], model, friction: float, restitution: float, dt: float, plane: bool = False):
    """The spheres ``bodies`` (and, with ``plane``, the rigid plane z = 0 under them), gravity off,
    every pair at ``friction`` and ``restitution``."""
    sim = Simulation(contact=model, gravity=(0.0, 0.0, 0.0))
    for solid in {b.solid.name: b.solid for b in bodies}.values():
        sim.add_material(Material(solid.name, youngs_modulus=solid.youngs_modulus, poisson_ratio=solid.poisson_ratio,
                                  density=solid.density, friction=friction, restitution=restitution))
    if plane:
        solid = bodies[0].solid
        sim.add_material(Material("plane", youngs_modulus=RIGID * solid.youngs_modulus,
                                  poisson_ratio=solid.poisson_ratio, density=solid.density, friction=friction,
                                  restitution=restitution))
        sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="plane"))
    for b in bodies:
        sim.add_particles([b.position], radius=b.radius, material=b.solid.name, velocity=[b.velocity],
                          angular_velocity=[b.angular_velocity], fixed=b.fixed)
    sim.dt = dt
    return sim


def run_through_contact(sim, steps: int, watch=None) -> None:
    """Step ``sim`` until its spheres have touched and parted (at most 20 ``steps``-long contacts),
    calling ``watch(sim)`` after every step if given, else stepping ``steps`` / 50 at a time."""
    chunk = 1 if watch else max(1, steps // 50)
    touched = False
    for _ in range(20 * steps // chunk):
        sim.run(steps=chunk)
        if watch:
            watch(sim)
        contacts = sim.number_of_contacts()
        touched = touched or contacts > 0
        if touched and contacts == 0:
            return
    raise RuntimeError("the spheres did not part within 20 contact times")


def normal_impact(law: str, solid: Solid, radius: float, speed: float, restitution: float = 1.0, plane: bool = False,
                  steps: int = STEPS_PER_CONTACT, curve: bool = False) -> dict:
    """Two identical spheres meeting head on at the closing ``speed`` (each at speed/2) or, with
    ``plane``, one hitting the rigid plane at ``speed``, under ``law`` at dt = t_c / ``steps`` (t_c of
    the elastic impact): the largest overlap and normal force seen at the steps, the contact time
    (touching found from the first step's overlap at the incoming speed, parting by interpolating
    the overlap to zero between the last two steps), the restitution (outgoing over incoming normal
    speed) and, with ``curve``, (time, overlap, force) at every step of the contact."""
    mass = sphere_mass(solid, radius)
    e_star, _ = effective_moduli(solid, None if plane else solid)
    r_eff, m_eff = (radius, mass) if plane else (radius / 2, mass / 2)
    dt = law_impact(law, e_star, r_eff, m_eff, speed)["contact_time"] / steps
    gap = 2.0 * speed * dt
    if plane:
        bodies = [Body(solid, radius, (0.0, 0.0, radius + gap), (0.0, 0.0, -speed))]

        def state(s):
            return radius - s.positions[0, 2], s.forces[0, 2], s.velocities[0, 2]
    else:
        bodies = [Body(solid, radius, (-radius - gap / 2, 0.0, 0.0), (speed / 2, 0.0, 0.0)),
                  Body(solid, radius, (radius + gap / 2, 0.0, 0.0), (-speed / 2, 0.0, 0.0))]

        def state(s):
            x = s.positions
            return 2 * radius - (x[1, 0] - x[0, 0]), s.forces[1, 0], s.velocities[1, 0] - s.velocities[0, 0]
    sim = scene(bodies, contact_model(law, e_star=e_star, r_eff=r_eff, m_eff=m_eff, speed=speed), 0.0, restitution,
                dt, plane)
    rows = []
    run_through_contact(sim, steps, lambda s: rows.append((s.time, *state(s))))
    t, overlap, force, _ = np.array(rows).T
    inside = np.flatnonzero(overlap > 0)
    first, last = inside[0], inside[-1]
    touch = t[first] - overlap[first] / speed
    part = t[last] + (t[last + 1] - t[last]) * overlap[last] / (overlap[last] - overlap[last + 1])
    out = {"overlap_max": float(overlap.max()), "force_max": float(force.max()), "contact_time": part - touch,
           "restitution": rows[-1][3] / speed}
    if curve:
        out["curve"] = (t[first:last + 1] - touch, overlap[first:last + 1], force[first:last + 1])
    return out


def rebound(bodies: list[Body], tangential: str, friction: float, restitution: float, plane: bool,
            steps: int = STEPS_PER_CONTACT) -> list[tuple[np.ndarray, np.ndarray]]:
    """``bodies`` (the first one free) meeting under Hertz's normal law and the ``tangential`` law, at
    dt = the elastic Hertz contact time of the first body's normal approach / ``steps``: each body's
    (velocity, angular velocity) once they have parted."""
    a = bodies[0]
    partner = None if plane else bodies[1]
    e_star, _ = effective_moduli(a.solid, None if plane else partner.solid)
    mass = sphere_mass(a.solid, a.radius)
    if plane or partner.fixed:
        m_eff = mass
    else:
        m_eff = 1.0 / (1.0 / mass + 1.0 / sphere_mass(partner.solid, partner.radius))
    r_eff = a.radius if plane else 1.0 / (1.0 / a.radius + 1.0 / partner.radius)
    if plane:
        closing = -a.velocity[2]
    else:
        direction = np.subtract(partner.position, a.position)
        closing = float(np.dot(np.subtract(a.velocity, partner.velocity), direction) / np.linalg.norm(direction))
    dt = hertz_impact(e_star, r_eff, m_eff, closing)["contact_time"] / steps
    sim = scene(bodies, contact_model("hertz", tangential), friction, restitution, dt, plane)
    run_through_contact(sim, steps)
    order = np.argsort(sim.particle_field("ids"))
    return [(sim.velocities[i].copy(), sim.angular_velocities[i].copy()) for i in order]


def plane_impact(solid: Solid, radius: float, normal_speed: float, tangential_speed: float, spin: float,
                 tangential: str, friction: float, restitution: float, steps: int = STEPS_PER_CONTACT,
                 partner_radius: float | None = None) -> dict:
    """A sphere hitting the rigid plane z = 0 (or, with ``partner_radius``, a fixed sphere of that
    radius and the same material below it) at ``normal_speed``, sliding along x at
    ``tangential_speed`` and spinning at ``spin`` about -y (the sense in which its bottom, the
    contact point, moves along +x at R spin): the rebound's normal speed, its speed along x, its
    spin ``forward`` (about +y: the sense of rolling along +x) and the contact point's speed along x."""
    gap = 1e-3 * radius
    bodies = [Body(solid, radius, (0.0, 0.0, radius + gap), (tangential_speed, 0.0, -normal_speed), (0.0, -spin, 0.0))]
    plane = partner_radius is None
    if not plane:
        bodies.append(Body(solid, partner_radius, (0.0, 0.0, -partner_radius), fixed=True))
    (v, w), *_ = rebound(bodies, tangential, friction, restitution, plane, steps)
    return {"normal_speed_after": float(v[2]), "tangential_speed_after": float(v[0]),
            "forward_spin_after": float(w[1]), "contact_speed_after": float(v[0] - radius * w[1])}


@lru_cache(maxsize=None)
def hertz_impulses(restitution: float) -> dict:
    """A damped Hertz impact (docs/models.md §1.2) integrated on its own (scipy, 1e-12): in units of
    delta_0 = (m* v^2 / k)^(2/5) and delta_0 / v (k = 4/3 E* sqrt(R*)) it reads x'' = -x^(3/2) -
    sqrt(3/2) c x^(1/4) x' with c from e alone. Returns the impulses over m* v: of the total force
    (1 + e), of its positive part (the history spring's Coulomb cap takes max(F_n, 0): larger
    than 1 + e where the dashpot pulls before parting) and of the elastic force (Walton's cap takes
    it: 1 + e too, the dashpot's impulse int gamma(x) dx vanishing over a contact)."""
    from scipy.integrate import solve_ivp  # deferred: slow to load, used here only

    c = math.sqrt(1.5) * hertz_damping_factor(restitution)

    def rates(t, y):
        x = max(y[0], 0.0)
        elastic = x ** 1.5
        total = elastic + c * x ** 0.25 * y[1]
        return [y[1], -total, max(total, 0.0), elastic]

    def parted(t, y):
        return y[0] if t > 1e-6 else 1.0
    parted.terminal, parted.direction = True, -1
    sol = solve_ivp(rates, (0.0, 50.0), [0.0, 1.0, 0.0, 0.0], events=parted, rtol=1e-12, atol=1e-14, max_step=1e-3)
    return {"total": float(1.0 - sol.y[1, -1]), "positive": float(sol.y[2, -1]), "elastic": float(sol.y[3, -1])}


#: which normal force each tangential law's Coulomb cap takes (``hertz_impulses``' key)
CAP_FORCE = {"history": "positive", "walton": "elastic"}


def rigid_sliding(normal_speed: float, contact_speed: float, friction: float, restitution: float,
                  tangential: str = "walton") -> dict | None:
    """The rebound of a solid sphere (I = 2/5 m R^2) sliding on a plane, or on a sphere held fixed,
    throughout the impact: the friction impulse is mu J (J = m V_n times ``hertz_impulses``' impulse
    under the ``tangential`` law's cap; (1 + e) m V_n for a rigid body), so V_t' = V_t - mu J / m,
    R omega' = R omega + (5/2) mu J / m (in the sense of rolling forward) and the contact point's speed
    falls by (7/2) mu J / m; None when that would reverse the slip (the contact sticks)."""
    impulse = friction * hertz_impulses(restitution)[CAP_FORCE[tangential]] * normal_speed
    if 3.5 * impulse >= contact_speed:
        return None
    return {"tangential_speed_change": -impulse, "spin_change_times_radius": 2.5 * impulse,
            "contact_speed": contact_speed - 3.5 * impulse, "normal_speed": restitution * normal_speed}


def spinning_pair(solid: Solid, radius: float, speed: float, spin: float, tangential: str, friction: float,
                  restitution: float, steps: int = STEPS_PER_CONTACT) -> dict:
    """Two identical spheres meeting head on along x, each at ``speed``, the one on the left spinning
    at ``spin`` about +z and the other at ``spin`` about -z: at the contact both surfaces move along
    +y at R spin, so they do not slip on each other. Their spins and sideways (y) speeds after."""
    gap = 1e-3 * radius
    bodies = [Body(solid, radius, (-radius - gap, 0.0, 0.0), (speed, 0.0, 0.0), (0.0, 0.0, spin)),
              Body(solid, radius, (radius + gap, 0.0, 0.0), (-speed, 0.0, 0.0), (0.0, 0.0, -spin))]
    (v1, w1), (v2, w2) = rebound(bodies, tangential, friction, restitution, False, steps)
    return {"spin_left": float(w1[2]), "spin_right": float(-w2[2]), "sideways_left": float(v1[1]),
            "sideways_right": float(v2[1]), "normal_speed": float(v2[0] - v1[0]) / 2}


#: each test's sweep: the paper's (as LIGGGHTS-PFM's inputs give it); quick: the points CI runs
SWEEPS = {
    "full": {"restitutions": (0.2, 0.4, 0.6, 0.8, 1.0), "angles": tuple(range(5, 90, 5)),
             "tangential_speeds": (0.1, 0.3, 0.45, 0.6, 0.9, 1.2, 1.5, 1.8, 2.25, 2.7, 3.0, 3.75, 4.5, 5.25, 6.0,
                                   7.5, 9.0, 12.0, 15.0, 18.0, 21.0),
             "spins": (0.175, 0.3, 0.42, 0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 2.4, 2.8, 3.0, 3.5, 4.0, 6.0, 8.0, 10.0, 12.0,
                       14.0, 21.0),
             "steps": STEPS_PER_CONTACT},
    "quick": {"restitutions": (0.2, 0.6, 1.0), "angles": (5, 25, 45, 65, 85), "tangential_speeds": (0.1, 3.0, 15.0),
              "spins": (0.3, 2.0, 6.0, 21.0), "steps": QUICK_STEPS}}


def psi(solid: Solid, contact_speed: float, normal_speed: float, friction: float) -> float:
    """Maw et al.'s (1976) impact angle, 2 (1 - nu) / (2 - nu) tan(theta) / mu, tan(theta) the
    contact point's incoming speed over the normal speed: 4 G*/E* tan(theta) / mu on a rigid plane,
    the ratio of the history spring's first force k_t v_t dt to mu F_n, both growing as t^(3/2):
    at psi >= 1 the contact slides from its first step."""
    nu = solid.poisson_ratio
    return 2 * (1 - nu) / (2 - nu) * contact_speed / normal_speed / friction


def restitution_tolerance(restitution: float, steps: int) -> float:
    """How far an impact resolved in ``steps`` steps may rebound from the restitution e asked for:
    a linear dashpot still pulls with gamma e V_n = 2 zeta omega m* e V_n as the overlap reaches zero,
    and the last step may apply it for up to a whole step dt = pi / (omega ``steps``): 2 zeta e pi /
    steps (zeta the damping ratio of e; Hertz's dashpot, vanishing at zero overlap, does less), plus
    Verlet's (pi / steps)^2."""
    e = restitution
    zeta = -math.log(e) / math.hypot(math.log(e), math.pi) if e < 1 else 0.0
    return 2 * zeta * e * math.pi / steps + (math.pi / steps) ** 2


def oblique_row(test: int, name: str, radius: float, normal_speed: float, tangential_speed: float, spin: float,
                tangential: str, friction: float, restitution: float, steps: int, point: float) -> dict:
    """One impact of test 4, 5, 6 or 8 (8: onto a fixed sphere of 5 R) as the row ``oblique_checks``
    reads: what went in (``point``, the swept value), the rebound (``plane_impact``), psi and
    ``lever`` = delta_max / R of the elastic Hertz impact at the normal speed."""
    solid = SOLIDS[name]
    partner = 5 * radius if test == 8 else None
    e_star, _ = effective_moduli(solid, None if partner is None else solid)
    r_eff = radius if partner is None else radius * partner / (radius + partner)
    got = plane_impact(solid, radius, normal_speed, tangential_speed, spin, tangential, friction, restitution, steps,
                       partner_radius=partner)
    incoming = tangential_speed + radius * spin
    lever = hertz_impact(e_star, r_eff, sphere_mass(solid, radius), normal_speed)["overlap_max"] / radius
    return {"test": test, "law": tangential, "material": name, "point": point, "normal_speed": normal_speed,
            "tangential_speed": tangential_speed, "spin": spin, "contact_speed_in": incoming, "radius": radius,
            "friction": friction, "restitution": restitution, "lever": lever,
            "psi": psi(solid, incoming, normal_speed, friction), **got}


def oblique_checks(table: pd.DataFrame, order1: float) -> list[Check]:
    """The checks of tests 4, 5, 6 and 8: each impact that slides from its first step (psi >= 1) to
    its last (``rigid_sliding`` has it slide on at 5 % or more of its incoming contact speed)
    against the rigid-body rebound with the law's friction impulse mu J. Tolerances: the impulse to
    ``order1`` = pi / N relative (the cap is reached within the contact's first step, and its last
    step is cut short by up to one), and for the spin also delta_max / R (``lever``: the force acts
    at the contact point, R - delta/2 from the centre, where the rigid body has R)."""
    checks = []
    for _, r in table.iterrows():
        theory = rigid_sliding(r["normal_speed"], r["contact_speed_in"], r["friction"], r["restitution"], r["law"])
        if theory is None or r["psi"] < 1.0 or theory["contact_speed"] < 0.05 * r["contact_speed_in"]:
            continue  # not sliding throughout: no closed form (figures only)
        test = int(r["test"])
        where = f"test {test}: {r['material']}, " \
                f"{'angle' if test == 4 else 'tangential speed' if test == 5 else 'spin'} {r['point']:g}"
        dv, dw = -theory["tangential_speed_change"], theory["spin_change_times_radius"]
        src = "rigid body sliding throughout: friction impulse mu J"
        if test == 4:
            checks.append(Check(CASE, r["law"], f"{where}: tangential restitution V_t'/V_t",
                                r["tangential_speed_after"] / r["tangential_speed"], 1 - dv / r["tangential_speed"],
                                dv / r["tangential_speed"] * order1, relative=False, source=src))
        checks.append(Check(CASE, r["law"], f"{where}: spin R omega' (m/s)", r["radius"] * r["forward_spin_after"],
                            -r["radius"] * r["spin"] + dw, dw * (order1 + r["lever"]), relative=False,
                            source=src + "; lever arm R - delta/2"))
        checks.append(Check(CASE, r["law"], f"{where}: contact point's speed after (m/s)", r["contact_speed_after"],
                            theory["contact_speed"], dv * order1 + dw * (order1 + r["lever"]), relative=False,
                            source=src))
    return checks


def chung_ooi(quick=False, outdir=None, progress=None) -> ValidationResult:
    """The eight tests, their checks (docs/models.md §19) and a figure each."""
    start = time.perf_counter()
    size = SWEEPS["quick" if quick else "full"]
    steps = size["steps"]
    order2 = (math.pi / steps) ** 2  # Verlet's relative error in a contact resolved by `steps` steps
    order1 = math.pi / steps  # first order: what the contact's first and last steps add
    checks, rows, curves = [], [], {}

    def check(test, model, quantity, measured, reference, tolerance, relative=True, source=""):
        checks.append(Check(CASE, model, f"test {test}: {quantity}", float(measured), float(reference), tolerance,
                            relative=relative, source=source))
        if progress:
            progress()

    # 1 and 2: elastic normal impacts against Hertz and the Hertz-equivalent spring
    for test, names, radius, speed, plane in ((1, ("glass", "limestone"), 0.01, 20.0, False),
                                              (2, ("aluminium alloy (test 2)", "magnesium alloy"), 0.1, 0.2, True)):
        for name in names:
            solid = SOLIDS[name]
            mass = sphere_mass(solid, radius)
            e_star, _ = effective_moduli(solid, None if plane else solid)
            r_eff, m_eff = (radius, mass) if plane else (radius / 2, mass / 2)
            for law in NORMAL_LAWS:
                got = normal_impact(law, solid, radius, speed, plane=plane, steps=steps, curve=law == "hertz")
                ref = law_impact(law, e_star, r_eff, m_eff, speed)
                for key, label in (("force_max", "peak force (N)"), ("overlap_max", "peak overlap (m)"),
                                   ("contact_time", "contact time (s)")):
                    check(test, law, f"{name}, {label}", got[key], ref[key], order2,
                          source="Hertz (Johnson 1985, ch. 11)" if law == "hertz" else
                          "linear spring k = m* v^2 / delta_Hertz^2")
                    rows.append({"test": test, "law": law, "material": name, "quantity": key,
                                 "measured": got[key], "reference": ref[key]})
                if law == "hertz":
                    curves[(test, name)] = (got["curve"], e_star, r_eff, m_eff, speed)
    # 3: restitution
    for name in ("aluminium oxide", "cast iron"):
        for law in NORMAL_LAWS:
            for e in size["restitutions"]:
                got = normal_impact(law, SOLIDS[name], 0.0025, 3.9, restitution=e, plane=True, steps=steps)
                check(3, law, f"{name}, restitution at e = {e:g}", got["restitution"], e,
                      restitution_tolerance(e, steps), relative=False,
                      source="the dashpot's force at parting, for one step: 2 zeta e pi / N")
                rows.append({"test": 3, "law": law, "material": name, "quantity": "restitution", "input": e,
                             "measured": got["restitution"], "reference": e})
    # 4-6 and 8: oblique and spinning impacts against the limits of sliding throughout
    obliques = []
    for test, names, radius, mu, e, points in (
            (4, ("aluminium oxide", "aluminium alloy"), 0.0025, 0.092, 0.98,
             [(3.9 * math.cos(math.radians(a)), 3.9 * math.sin(math.radians(a)), 0.0, a) for a in size["angles"]]),
            (5, ("steel", "polyethylene"), 1e-5, 0.3, 1.0, [(5.0, v, 0.0, v) for v in size["tangential_speeds"]]),
            (6, ("aluminium alloy", "nylon"), 0.1, 0.4, 0.5, [(0.2, 0.0, w, w) for w in size["spins"]]),
            (8, ("aluminium alloy", "nylon"), 0.1, 0.4, 0.5, [(0.2, 0.0, w, w) for w in size["spins"]])):
        for name in names:
            for law in TANGENTIAL_LAWS:
                for vn, vt, spin, label in points:
                    obliques.append(oblique_row(test, name, radius, vn, vt, spin, law, mu, e, steps, label))
    table = pd.DataFrame(obliques)
    checks += oblique_checks(table, order1)
    # 7: two spheres whose surfaces do not slip
    for name in ("aluminium alloy", "copper"):
        for law in TANGENTIAL_LAWS:
            for spin in size["spins"]:
                got = spinning_pair(SOLIDS[name], 0.1, 0.2, spin, law, 0.4, 0.5, steps)
                rows.append({"test": 7, "law": law, "material": name, "input": spin, "quantity": "spin",
                             "measured": got["spin_left"], "reference": spin})
                check(7, law, f"{name}, spin {spin:g}: spin after (rad/s)", got["spin_left"], spin, 1e-9,
                      source="no slip at the contact: no tangential force")
                check(7, law, f"{name}, spin {spin:g}: sideways speed after (m/s)", got["sideways_left"], 0.0,
                      1e-9 * 0.1 * spin, relative=False, source="no slip at the contact: no tangential force")
    result = ValidationResult(CASE, "Chung & Ooi (2011): the DEM code benchmarks at particle impact level",
                              pd.concat([pd.DataFrame(rows), table], ignore_index=True), checks)
    small = table[(table["test"] == 5) & (table["point"] == min(size["tangential_speeds"]))]
    for _, r in small.iterrows():
        x = r["tangential_speed"] / (r["friction"] * r["normal_speed"])
        result.notes.append(f"test 5, {r['material']}, {r['law']}: at V_t/(mu V_n) = {x:.3g} the recoil "
                            f"{r['contact_speed_after'] / (r['friction'] * r['normal_speed_after']):.4f}; "
                            f"the no-slip limit {-stick_restitution(SOLIDS[r['material']].poisson_ratio) * x:.4f}")
    if outdir is not None:
        figures(result, outdir, curves, pd.DataFrame(rows), table)
    result.wall_time = time.perf_counter() - start
    return result


@lru_cache(maxsize=None)
def stick_restitution(poisson_ratio: float) -> float:
    """Maw et al.'s no-slip limit (psi -> 0) of an elastic impact on a rigid plane: the contact point's
    tangential restitution beta = -u_after/u_before when it never slips, from the tangential
    oscillator u'' = -(7/2) (k_t / m) u, k_t = 8 G* a = 2 (1 - nu)/(2 - nu) times the normal law's
    tangent stiffness 2 E* a, over the Hertz contact (integrated with scipy, 1e-11). Mindlin's
    incremental spring and the total-form spring k_t xi give the same beta here: k_t(t) is symmetric
    about the middle of an elastic contact, and the two are the cosine- and sine-like solutions of
    the same Hill equation."""
    from scipy.integrate import solve_ivp  # deferred: slow to load, used here only

    ratio = 2 * (1 - poisson_ratio) / (2 - poisson_ratio)

    def rates(t, y):  # units: m = R = E* = 1, V_n = 1
        x = max(y[0], 0.0)
        return [y[1], -(4.0 / 3.0) * x ** 1.5, y[3], -3.5 * ratio * 2.0 * math.sqrt(x) * y[2]]

    def parted(t, y):
        return y[0] if t > 1e-9 else 1.0
    parted.terminal, parted.direction = True, -1
    sol = solve_ivp(rates, (0.0, 100.0), [0.0, 1.0, 0.0, 1.0], events=parted, rtol=1e-11, atol=1e-13, max_step=0.01)
    return float(-sol.y[3, -1])


def figures(result: ValidationResult, outdir, curves: dict, rows: pd.DataFrame, table: pd.DataFrame) -> None:
    """A figure per test, as the paper draws it, with the closed form."""
    from scipy.integrate import solve_ivp  # deferred: slow to load, used here only

    plt = pyplot()
    for test in (1, 2):
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.5))
        for (t, name), ((time_, overlap, force), e_star, r_eff, m_eff, speed) in curves.items():
            if t != test:
                continue
            k = 4.0 / 3.0 * e_star * math.sqrt(r_eff)
            ode = solve_ivp(lambda _, y: [y[1], -k / m_eff * max(y[0], 0.0) ** 1.5], (0.0, 1.2 * time_[-1]),
                            [0.0, speed], max_step=time_[-1] / 400, rtol=1e-10)
            inside = ode.y[0] >= 0
            line, = a1.plot(1e6 * ode.t[inside], 1e-3 * k * ode.y[0][inside] ** 1.5, "-", label=f"{name}: Hertz")
            a1.plot(1e6 * time_[::20], 1e-3 * force[::20], "o", ms=3, color=line.get_color(), label=f"{name}: rollingdem")
            grid = np.linspace(0.0, overlap.max(), 100)
            a2.plot(1e6 * grid, 1e-3 * k * grid ** 1.5, "-", color=line.get_color())
            a2.plot(1e6 * overlap[::20], 1e-3 * force[::20], "o", ms=3, color=line.get_color())
        a1.set_xlabel("time (µs)")
        a1.set_ylabel("normal force (kN)")
        a2.set_xlabel("overlap (µm)")
        a1.legend(fontsize=7)
        fig.suptitle(f"Test {test}: elastic normal impact " + ("of two spheres" if test == 1 else "on a plane"))
        result.add_figure(fig, outdir, f"chung_ooi_test{test}.png")
    fig, ax = plt.subplots(figsize=(5, 4))
    r3 = rows[rows["test"] == 3]
    for (law, name), g in r3.groupby(["law", "material"]):
        ax.plot(g["input"], g["measured"], "o", ms=4, label=f"{law}, {name}")
    ax.plot([0, 1], [0, 1], "k-", lw=0.8, label="e out = e in")
    ax.set_xlabel("restitution asked for")
    ax.set_ylabel("restitution of the rebound")
    ax.legend(fontsize=6)
    ax.set_title("Test 3: normal impact on a plane")
    result.add_figure(fig, outdir, "chung_ooi_test3.png")
    oblique_figures(result, outdir, table, plt)


def oblique_figures(result, outdir, table: pd.DataFrame, plt) -> None:
    """Tests 4-8 against the limits of sliding throughout (and, for test 5, of no slip)."""
    markers = {"history": "o", "walton": "s"}
    t4 = table[table["test"] == 4]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for (law, name), g in t4.groupby(["law", "material"]):
        axes[0].plot(g["point"], g["tangential_speed_after"] / g["tangential_speed"], markers[law], ms=4,
                     label=f"{law}, {name}")
        axes[1].plot(g["point"], g["forward_spin_after"], markers[law], ms=4)
        axes[2].plot(g["point"], np.degrees(np.arctan2(g["contact_speed_after"], g["normal_speed_after"])),
                     markers[law], ms=4)
    angle = np.linspace(1, 89, 200)
    vn, vt = 3.9 * np.cos(np.radians(angle)), 3.9 * np.sin(np.radians(angle))
    impulse = 0.092 * 1.98 * vn
    sliding = vt > 3.5 * impulse
    axes[0].plot(angle[sliding], 1 - impulse[sliding] / vt[sliding], "k-", lw=0.8, label="sliding throughout")
    axes[1].plot(angle[sliding], 2.5 * impulse[sliding] / 0.0025, "k-", lw=0.8)
    axes[2].plot(angle[sliding], np.degrees(np.arctan((vt - 3.5 * impulse)[sliding] / (0.98 * vn[sliding]))), "k-",
                 lw=0.8)
    for ax, label in zip(axes, ("tangential restitution V_t'/V_t", "spin after (rad/s, rolling forward)",
                                "rebound angle at the contact point (deg)")):
        ax.set_xlabel("impact angle (deg)")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=6)
    fig.suptitle("Test 4: oblique impact on a plane at 3.9 m/s")
    fig.tight_layout()
    result.add_figure(fig, outdir, "chung_ooi_test4.png")
    t5 = table[table["test"] == 5]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
    for (law, name), g in t5.groupby(["law", "material"]):
        x = g["tangential_speed"] / (g["friction"] * g["normal_speed"])
        a1.plot(x, g["contact_speed_after"] / (g["friction"] * g["normal_speed_after"]), markers[law], ms=4,
                label=f"{law}, {name}")
        a2.plot(x, g["radius"] * g["forward_spin_after"] / (g["friction"] * g["normal_speed"]), markers[law], ms=4)
    x = np.linspace(0, 14, 200)
    a1.plot(x[x > 7], x[x > 7] - 7, "k-", lw=0.8, label="sliding throughout")
    for name in ("steel", "polyethylene"):
        a1.plot(x[x < 1.5], -stick_restitution(SOLIDS[name].poisson_ratio) * x[x < 1.5], "--", lw=0.8,
                label=f"no slip, {name}")
    a2.axhline(5.0, color="k", lw=0.8)
    a1.set_xlabel("V_t / (mu V_n)")
    a2.set_xlabel("V_t / (mu V_n)")
    a1.set_ylabel("recoil: contact point's V_t' / (mu V_n')")
    a2.set_ylabel("spin: R omega' / (mu V_n)")
    a1.legend(fontsize=6)
    fig.suptitle("Test 5: oblique impact on a plane at V_n = 5 m/s")
    fig.tight_layout()
    result.add_figure(fig, outdir, "chung_ooi_test5.png")
    for test, title in ((6, "a spinning sphere on a plane"), (8, "a spinning sphere on a fixed sphere 5 R")):
        tt = table[table["test"] == test]
        if tt.empty:
            continue
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(9, 3.6))
        for (law, name), g in tt.groupby(["law", "material"]):
            x = 3.5 * g["friction"] * (1 + g["restitution"]) * g["normal_speed"] / g["contact_speed_in"]
            a1.plot(x, -g["contact_speed_after"] / g["contact_speed_in"], markers[law], ms=4, label=f"{law}, {name}")
            a2.plot(g["contact_speed_in"] / g["normal_speed"], g["contact_speed_after"] / g["normal_speed_after"],
                    markers[law], ms=4)
        x = np.linspace(0.05, 1, 100)
        a1.plot(x, x - 1, "k-", lw=0.8, label="sliding throughout, J = (1 + e) m V_n")
        tan_in = np.linspace(1.05 * 3.5 * 0.4 * 1.5, 12, 100)
        a2.plot(tan_in, (tan_in - 3.5 * 0.4 * 1.5) / 0.5, "k-", lw=0.8)
        a1.set_xlabel("7/2 mu (1 + e) V_n / (R omega)")
        a1.set_ylabel("beta = -contact point's V_t' / (R omega)")
        a2.set_xlabel("tan of the incident angle, R omega / V_n")
        a2.set_ylabel("tan of the recoil angle")
        a1.legend(fontsize=6)
        fig.suptitle(f"Test {test}: {title}")
        fig.tight_layout()
        result.add_figure(fig, outdir, f"chung_ooi_test{test}.png")
    r7 = result.table[result.table["test"] == 7]
    fig, ax = plt.subplots(figsize=(5, 3.6))
    for (law, name), g in r7.groupby(["law", "material"]):
        ax.plot(g["input"], g["measured"] / g["input"], markers[law], ms=4, label=f"{law}, {name}")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("spin before (rad/s)")
    ax.set_ylabel("spin after / before")
    ax.legend(fontsize=6)
    ax.set_title("Test 7: two spheres whose surfaces do not slip")
    result.add_figure(fig, outdir, "chung_ooi_test7.png")


class ChungOoi(Experiment):
    """Chung & Ooi's (2011) eight benchmark tests of a DEM code at the level of one impact."""

    name = CASE
    description = "Chung & Ooi's eight impact benchmarks against Hertz, restitution and the rigid-body limits"

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return chung_ooi(quick=quick, outdir=outdir, progress=progress)
