"""``rollingdem validate --case contact-laws``: the Walton-Braun, Walton tangential and JKR checks.

Each check sets up the textbook situation of its law and compares the measured number with the
closed-form one (docs/models.md §1.4-§1.6; the benchmarks are listed in docs/studies.md, "Contact
laws"): Walton-Braun's restitution, peak overlap, peak force and contact time in binary impacts
(WB-1, WB-1b), its forces along a prescribed overlap path (WB-2), a sphere dropped on a plane
(WB-3); Walton's tangential curve (WB-4); JKR's pull-off force, zero-load overlap, separation and
sticking velocity. The bonded-particle checks come with the bond model.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from .results import CaseResult, Check

CASE = "contact-laws"
K1 = 1e5  # N/m, WB-1
RESTITUTIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


def _wb_pair(e: float, speed: float):
    """Two spheres of 2 kg each (m* = 1 kg) meeting head on at ``speed`` (relative), k1 = 1e5 N/m,
    no gravity, no friction, dt = T2 / 200 with T2 = 2 pi sqrt(m* / k2)."""
    from .. import ContactModel, Material, Simulation, WaltonBraun

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
    """WB-2: the law stepped along the spec's overlap path (k1 = 1e5 N/m, e = 0.5): the forces at its
    turning points, and the energy the first loop (0 -> 1 mm -> 0.75 mm) dissipates."""
    from ..contact.normal import WALTON_BRAUN_HISTORY, WALTON_BRAUN_PARAMETERS, walton_braun_normal

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
    from .. import ContactModel, Material, Plane, Simulation, WaltonBraun

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
    from ..contact.frame import contact_frame
    from ..contact.tangential import WALTON_TANGENTIAL_HISTORY, walton_tangential
    from ..kernel_layout import contact_inputs

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
    from ..contact.cohesion import JKR_HISTORY, jkr_cohesion
    from ..kernel_layout import contact_inputs

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
    from .. import ContactModel, Material, Simulation

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
    from scipy.integrate import quad

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


def contact_laws(models=None, quick=False, outdir=None, progress=None, runner=map) -> CaseResult:
    """The contact-law checks (``models`` and ``runner`` are not used: each check is its own law)."""
    start = time.perf_counter()
    checks, rows = [], []

    def check(model, quantity, measured, reference, tolerance, relative=True, source=""):
        checks.append(Check(CASE, model, quantity, float(measured), float(reference), tolerance, relative=relative,
                            source=source))
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
              source="MODELS_CONTACTS WB-2 path, exact")
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
    result = CaseResult(CASE, "Contact laws: Walton-Braun, Walton's tangential law, JKR", pd.DataFrame(rows),
                        checks)
    result.notes.append("Bonded-particle checks (BP-1 to BP-5) are not in this case yet: the bond model is not "
                        "built.")
    result.wall_time = time.perf_counter() - start
    return result
