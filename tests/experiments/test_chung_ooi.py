"""Chung & Ooi's (2011) benchmark tests (rollingdem.experiments.chung_ooi): the closed forms by hand,
a few impacts of each kind at the quick resolution (250 steps per contact), and the checks that
``validate`` makes on known tables. The whole quick set (180 checks) runs in
``rollingdem validate --experiment chung-ooi --quick``."""

import math

import numpy as np
import pandas as pd
import pytest

from rollingdem.experiments import chung_ooi as co

STEPS = co.QUICK_STEPS
ORDER2 = (math.pi / STEPS) ** 2  # 1.6e-4: Verlet's relative error at 250 steps per contact


def test_hertz_closed_form_of_two_glass_spheres_by_hand():
    """The issue's reviewer numbers: two glass spheres (E = 48 GPa, nu = 0.2, rho = 2800 kg/m^3,
    R = 10 mm) closing at 20 m/s peak at about 10.7 kN and 274 um after a contact of about 40 us.
    By hand: E* = E / (2 (1 - nu^2)) = 25 GPa, R* = 5 mm, m* = 5.864 g; delta = (15 m* v^2 /
    (16 E* sqrt(R*)))^(2/5) = 274.1 um; F = 4/3 E* sqrt(R*) delta^(3/2) = 10.70 kN; t_c = 2.9432
    delta / v = 40.34 us (2.9432 = (4/5) B(2/5, 1/2), Johnson 1985)."""
    glass = co.SOLIDS["glass"]
    e_star, _ = co.effective_moduli(glass, glass)
    assert e_star == pytest.approx(48e9 / (2 * 0.96), rel=1e-12)
    m_eff = co.sphere_mass(glass, 0.01) / 2
    assert m_eff == pytest.approx(2800 * 4 / 3 * math.pi * 1e-6 / 2, rel=1e-12)
    h = co.hertz_impact(e_star, 0.005, m_eff, 20.0)
    assert h["overlap_max"] == pytest.approx(274.1e-6, rel=1e-3)
    assert h["force_max"] == pytest.approx(10.70e3, rel=1e-3)
    assert h["contact_time"] == pytest.approx(40.34e-6, rel=1e-3)
    assert co.HERTZ_TIME == pytest.approx(2.9432, abs=1e-4)


def test_rigid_plane_moduli_and_the_spring_closed_form_by_hand():
    """The plane has 1e6 times the sphere's E at its nu: E* = E / (1 - nu^2) and G* = G / (2 - nu)
    within 1e-6. A spring k = 100 N/m hit at 2 m/s by m* = 1 kg: delta = 0.2 m, F = 20 N, t = pi/10 s.
    Catches: a plane of the sphere's own stiffness (E* halved), a period instead of half of one."""
    steel = co.SOLIDS["steel"]
    e_star, g_star = co.effective_moduli(steel)
    assert e_star == pytest.approx(2.08e11 / (1 - 0.09), rel=2e-6)
    assert g_star == pytest.approx(2.08e11 / 2.6 / 1.7, rel=2e-6)
    s = co.spring_impact(100.0, 1.0, 2.0)
    assert (s["overlap_max"], s["force_max"], s["contact_time"]) == pytest.approx((0.2, 20.0, math.pi / 10), rel=1e-12)


def test_damped_hertz_impulses():
    """The damped Hertz impact integrated on its own: its total impulse is (1 + e) m* v (c gives e
    exactly: docs/models.md §1.2), the elastic force's too (the dashpot's int gamma(delta) d delta
    vanishes over a contact), and the positive part's is larger for e < 1 (the dashpot pulls before
    parting), equal at e = 1. Catches a wrong damping factor or exponent in the integration."""
    for e in (0.2, 0.5, 0.98):
        j = co.hertz_impulses(e)
        assert j["total"] == pytest.approx(1 + e, abs=1e-8)
        assert j["elastic"] == pytest.approx(1 + e, abs=1e-8)
        assert j["positive"] > 1 + e + 1e-5
    assert co.hertz_impulses(1.0)["positive"] == pytest.approx(2.0, abs=1e-8)


def test_rigid_sliding_by_hand():
    """mu = 0.4, e = 0.5, V_n = 0.2 m/s, Walton's cap (J = 1.5 m V_n): mu J/m = 0.12 m/s; V_t falls
    by 0.12, R omega rises by 0.3 and the contact point slows by 0.42: from 0.6 m/s to 0.18. From
    0.42 m/s it would stop: None (it sticks). Catches 7/2 or 5/2 wrong (the sphere's I = 2/5 m R^2)."""
    r = co.rigid_sliding(0.2, 0.6, 0.4, 0.5, "walton")
    assert r["tangential_speed_change"] == pytest.approx(-0.12, rel=1e-9)
    assert r["spin_change_times_radius"] == pytest.approx(0.3, rel=1e-9)
    assert r["contact_speed"] == pytest.approx(0.18, rel=1e-8)
    assert r["normal_speed"] == pytest.approx(0.1, rel=1e-12)
    assert co.rigid_sliding(0.2, 0.42, 0.4, 0.5, "walton") is None
    assert co.psi(co.SOLIDS["steel"], 3.0, 5.0, 0.3) == pytest.approx(2 * 0.7 / 1.7 * 0.6 / 0.3, rel=1e-12)


def test_no_slip_limit():
    """Without tangential stiffness (nu = 1: 2 (1 - nu)/(2 - nu) = 0) the contact point keeps its
    speed, beta = -1. At nu = 0.3 the total-form spring's beta equals Mindlin's incremental spring's
    (integrated here on its own): the docstring's claim. Catches a wrong 7/2 or stiffness ratio."""
    from scipy.integrate import solve_ivp

    assert co.stick_restitution(1.0) == pytest.approx(-1.0, abs=1e-9)
    ratio = 2 * 0.7 / 1.7

    def incremental(t, y):  # F' = k_t u, u' = -(7/2) F
        x = max(y[0], 0.0)
        return [y[1], -(4 / 3) * x ** 1.5, ratio * 2 * math.sqrt(x) * y[3], -3.5 * y[2]]

    def parted(t, y):
        return y[0] if t > 1e-9 else 1.0
    parted.terminal, parted.direction = True, -1
    sol = solve_ivp(incremental, (0, 100), [0, 1, 0, 1], events=parted, rtol=1e-11, atol=1e-13, max_step=0.01)
    assert co.stick_restitution(0.3) == pytest.approx(-sol.y[3, -1], abs=1e-6)
    assert -1.0 < co.stick_restitution(0.3) < -0.9


@pytest.mark.parametrize("law", co.NORMAL_LAWS)
def test_elastic_impacts_against_their_closed_forms(law):
    """Tests 1 and 2 at 250 steps per contact: peak force, peak overlap and contact time within
    (pi/250)^2 = 1.6e-4 of Hertz (or of the Hertz-equivalent spring, which peaks at Hertz's overlap),
    and the rebound elastic. Catches E* or R* or m* wrong, the 4/3 of Hertz's force."""
    for name, radius, speed, plane in (("glass", 0.01, 20.0, False), ("magnesium alloy", 0.1, 0.2, True)):
        solid = co.SOLIDS[name]
        got = co.normal_impact(law, solid, radius, speed, plane=plane, steps=STEPS)
        mass = co.sphere_mass(solid, radius)
        e_star, _ = co.effective_moduli(solid, None if plane else solid)
        ref = co.law_impact(law, e_star, radius if plane else radius / 2, mass if plane else mass / 2, speed)
        for key in ("force_max", "overlap_max", "contact_time"):
            assert got[key] == pytest.approx(ref[key], rel=ORDER2), (name, key)
        assert got["restitution"] == pytest.approx(1.0, abs=ORDER2)


@pytest.mark.parametrize("law,e", [("hertz", 0.2), ("linear", 0.4), ("walton_braun", 0.6)])
def test_restitution_on_a_plane(law, e):
    """Test 3 (aluminium oxide, 2.5 mm, 3.9 m/s): the rebound's restitution within
    ``restitution_tolerance`` of the e asked for (linear at 0.4: 7.2e-3 at 250 steps)."""
    got = co.normal_impact(law, co.SOLIDS["aluminium oxide"], 0.0025, 3.9, restitution=e, plane=True, steps=STEPS)
    assert got["restitution"] == pytest.approx(e, abs=co.restitution_tolerance(e, STEPS))


def test_restitution_tolerance_by_hand():
    """e = 0.4: zeta = -ln 0.4 / sqrt(ln^2 0.4 + pi^2) = 0.279997; 2 zeta e pi / 250 + (pi/250)^2 =
    2.973e-3; e = 1: (pi/250)^2 only."""
    assert co.restitution_tolerance(0.4, 250) == pytest.approx(2 * 0.279997 * 0.4 * math.pi / 250 + ORDER2, rel=1e-5)
    assert co.restitution_tolerance(1.0, 250) == pytest.approx(ORDER2, rel=1e-12)


def test_a_sliding_oblique_impact_and_a_spinning_one_rebound_as_sliding_friction_gives():
    """Test 4 at 45 deg (aluminium oxide, mu = 0.092, e = 0.98, psi = 9.5: it slides throughout) and
    test 6 at R omega = 0.6 m/s (aluminium alloy, V_n = 0.2 m/s, mu = 0.4, e = 0.5), history spring:
    each within the tolerance of ``oblique_checks``. Test 6 is the one the history spring failed by
    29 % when it was backed out through a dashpot above the cap."""
    rows = [co.oblique_row(4, "aluminium oxide", 0.0025, 3.9 * math.cos(math.pi / 4), 3.9 * math.sin(math.pi / 4),
                           0.0, "history", 0.092, 0.98, STEPS, 45),
            co.oblique_row(6, "aluminium alloy", 0.1, 0.2, 0.0, 6.0, "history", 0.4, 0.5, STEPS, 6.0)]
    checks = co.oblique_checks(pd.DataFrame(rows), math.pi / STEPS)
    assert len(checks) == 5
    assert all(c.passed for c in checks), [(c.quantity, c.measured, c.reference) for c in checks if not c.passed]


def test_oblique_checks_on_known_tables():
    """``oblique_checks`` on made-up rows: one at the rigid-body values passes; moved by twice its
    tolerance it fails; a row that sticks (psi < 1) or stops sliding gets no check."""
    base = {"test": 6, "law": "walton", "material": "nylon", "point": 6.0, "normal_speed": 0.2, "tangential_speed": 0.0,
            "spin": 6.0, "contact_speed_in": 0.6, "radius": 0.1, "friction": 0.4, "restitution": 0.5, "lever": 0.0,
            "psi": 4.8, "tangential_speed_after": -0.12, "forward_spin_after": (-0.6 + 0.3) / 0.1,
            "contact_speed_after": 0.18, "normal_speed_after": 0.1}
    order1 = 0.01
    good = co.oblique_checks(pd.DataFrame([base]), order1)
    assert len(good) == 2 and all(c.passed for c in good)
    moved = dict(base, contact_speed_after=0.18 + 2 * (0.12 + 0.3) * order1)
    assert not co.oblique_checks(pd.DataFrame([moved]), order1)[1].passed
    spun = dict(base, forward_spin_after=base["forward_spin_after"] + 2 * 0.3 * order1 / 0.1)
    assert not co.oblique_checks(pd.DataFrame([spun]), order1)[0].passed
    assert co.oblique_checks(pd.DataFrame([dict(base, psi=0.9)]), order1) == []
    assert co.oblique_checks(pd.DataFrame([dict(base, spin=4.0, contact_speed_in=0.4)]), order1) == []


def test_two_spheres_whose_surfaces_move_together_keep_their_spins():
    """Test 7 (aluminium alloy, R = 0.1 m, each at 0.2 m/s, spins of 10 rad/s in opposite senses):
    the surfaces meet moving the same way, no tangential force, spins and sideways speeds kept to
    round-off. Catches a wrong sign of one sphere's omega x r in the relative velocity."""
    got = co.spinning_pair(co.SOLIDS["aluminium alloy"], 0.1, 0.2, 10.0, "history", 0.4, 0.5, STEPS)
    assert got["spin_left"] == pytest.approx(10.0, rel=1e-9)
    assert got["spin_right"] == pytest.approx(10.0, rel=1e-9)
    assert abs(got["sideways_left"]) < 1e-9 and abs(got["sideways_right"]) < 1e-9
    assert got["normal_speed"] == pytest.approx(0.5 * 0.2, rel=1e-2)  # e = 0.5 of 0.2 m/s each


def test_the_experiment_is_registered_with_its_sweeps():
    """``rollingdem validate --experiment chung-ooi`` finds it; the full sweep is the paper's 17
    angles from 5 to 85 deg, 21 tangential speeds, 20 spins."""
    from rollingdem.experiments import EXPERIMENTS

    assert "chung-ooi" in EXPERIMENTS
    full = co.SWEEPS["full"]
    assert full["angles"] == tuple(range(5, 90, 5)) and len(full["tangential_speeds"]) == 21
    assert len(full["spins"]) == 20 and np.all(np.diff(full["spins"]) > 0)
