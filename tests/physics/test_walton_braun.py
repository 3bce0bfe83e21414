"""Walton-Braun's hysteretic normal law (rollingdem.physics.contact.normal.walton_braun_normal): a
prescribed overlap path against the classical form, and binary impacts whose restitution is e at
every speed."""

import math

import numpy as np
import pytest

import rollingdem as rd
from conftest import R
from rollingdem.physics.contact.normal import WALTON_BRAUN_HISTORY, WALTON_BRAUN_PARAMETERS, walton_braun_normal
from rollingdem.errors import ParameterError

K1 = 1e5  # N/m


def classical(path, k1, k2):
    """Walton & Braun's classical form along ``path``: on the loading line (delta >= delta_max)
    F = k1 delta and delta_max, delta_0 = delta_max (1 - k1/k2) follow; below it F = max(0, k2
    (delta - delta_0))."""
    d_max = d0 = 0.0
    out = []
    for d in path:
        if d >= d_max:
            d_max, d0 = d, d * (1.0 - k1 / k2)
            out.append(k1 * d)
        else:
            out.append(max(0.0, k2 * (d - d0)))
    return np.array(out)


def law_row(k1, unloading_ratio, tangential_ratio=1.0, damping_factor=0.0, reported_ratio=1.0):
    """The law's parameter row with k1 given (no characteristic velocity)."""
    p = np.zeros(len(WALTON_BRAUN_PARAMETERS))
    P = WALTON_BRAUN_PARAMETERS
    p[[P.loading_stiffness, P.unloading_ratio, P.tangential_stiffness_ratio, P.damping_factor,
       P.reported_stiffness_ratio]] = (k1, unloading_ratio, tangential_ratio, damping_factor, reported_ratio)
    return p


def incremental(path, k1, k2):
    """The compiled law stepped along ``path`` on one contact's history row."""
    p = law_row(k1, k2 / k1)
    hist = np.zeros((1, len(WALTON_BRAUN_HISTORY)))
    return np.array([walton_braun_normal(hist, 0, 0, d, 0.0, R, 1e-3, p, 0) for d in path])


def test_a_prescribed_overlap_path_gives_the_classical_forces():
    """e = 0.5 (k2 = 4 k1): load to 1 mm (100 N), unload to 0.8 mm (20 N: the k2 line from
    delta_0 = 0.75 mm), on to 0.5 mm (no force, below delta_0), reload to 0.8 mm (20 N again: from
    delta_0, not from 0.5 mm, which would give 120 N), load past the old maximum to 1.2 mm (back on
    the k1 line: 120 N), unload to 1 mm (40 N from the new delta_0 = 0.9 mm). In steps of 10 um the
    forces equal the classical form's to round-off."""
    k2 = K1 / 0.5 ** 2
    legs = [(0.0, 1.0), (1.0, 0.8), (0.8, 0.5), (0.5, 0.8), (0.8, 1.2), (1.2, 1.0)]
    path = np.concatenate([np.linspace(a, b, int(round(abs(b - a) / 0.01)) + 1)[1:] for a, b in legs]) * 1e-3
    f = incremental(path, K1, k2)[:, 0]
    np.testing.assert_allclose(f, classical(path, K1, k2), rtol=1e-9, atol=1e-9)
    ends = np.cumsum([int(round(abs(b - a) / 0.01)) for a, b in legs]) - 1
    np.testing.assert_allclose(f[ends], [100.0, 20.0, 0.0, 20.0, 120.0, 40.0], rtol=1e-9, atol=1e-9)


def test_the_hysteresis_dissipates_the_area_of_the_loop():
    """Load to 1 mm along k1 (50 mJ stored), unload along k2 = 4 k1 to delta_0 = 0.75 mm (12.5 mJ
    given back): the steps' dissipation sums to the loop's area, (1 - e^2) 1/2 k1 delta_max^2 =
    37.5 mJ, to round-off (the law's work is taken with the mean force of the step, exact on a
    line); a reload along k2 back to 1 mm dissipates nothing more."""
    up = np.linspace(0.0, 1.0, 101)[1:] * 1e-3
    down = np.linspace(1.0, 0.75, 26)[1:] * 1e-3
    again = np.linspace(0.75, 1.0, 26)[1:] * 1e-3
    out = incremental(np.concatenate([up, down, again]), K1, 4 * K1)
    loop = out[: len(up) + len(down), 5].sum()
    assert loop == pytest.approx((1 - 0.5 ** 2) * 0.5 * K1 * 1e-6, rel=1e-9)
    assert loop == pytest.approx(0.0375, rel=1e-9)
    assert abs(out[len(up) + len(down):, 5]).sum() < 1e-12


def test_the_optional_dashpot_and_the_stiffnesses_it_reports():
    """With the damping factor c = 2 zeta the dashpot force is -c sqrt(m* k2) v_n (k2, the elastic
    line it damps); k_n = k1 (or k2 with kn_source "unloading") goes to the rolling springs, k_t =
    ratio k1 to the tangential one."""
    m_eff, zeta, vn, e = 1e-3, 0.05, -0.2, 0.5
    k2 = K1 / e ** 2
    for source, kn_expected in (("loading", K1), ("unloading", k2)):
        law = rd.WaltonBraun(loading_stiffness=K1, tangential_stiffness_ratio=0.3, damping_ratio=zeta,
                             kn_source=source)
        p = np.array(law.pair_row(type("Pair", (), {"restitution": e})()))
        f_el, f_damp, kn, kt_out, gamma_t, _ = walton_braun_normal(np.zeros((1, 2)), 0, 0, 1e-4, vn, R, m_eff, p, 0)
        assert f_el == pytest.approx(K1 * 1e-4, rel=1e-12)
        assert f_damp == pytest.approx(-2 * zeta * math.sqrt(m_eff * k2) * vn, rel=1e-12)
        assert (kn, kt_out, gamma_t) == pytest.approx((kn_expected, 0.3 * K1, 0.0), rel=1e-12)


def test_a_characteristic_velocity_gives_the_hertz_peak_overlap(table1):
    """With V_c instead of k1 the loading line is the Hertz-equivalent spring: an impact at V_c
    reaches the Hertz peak overlap delta_H = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5) (the linear spring
    stores at delta_H the energy Hertz would). Two spheres meet head on at 2 x 0.5 m/s, V_c = 1 m/s:
    the largest overlap equals delta_H within 1 % (a step of dt v = 1e-3 delta_H)."""
    v = 0.5
    sim = rd.Simulation(contact=rd.ContactModel(normal=rd.WaltonBraun(characteristic_velocity=2 * v)),
                        gravity=(0, 0, 0), track_energy=True)  # the impact test's kernel: one compile fewer
    mat = table1(restitution=0.5, friction=0.5)
    sim.add_material(mat)
    sim.add_particles([[-R - 1e-4, 0, 0], [R + 1e-4, 0, 0]], radius=R, material="m",
                      velocity=[[v, 0, 0], [-v, 0, 0]])
    m_eff = 0.5 * mat.density * 4.0 / 3.0 * math.pi * R ** 3
    e_star = 1.0 / (2 * (1 - mat.poisson_ratio ** 2) / mat.youngs_modulus)
    delta_h = (15 * m_eff * (2 * v) ** 2 / (16 * e_star * math.sqrt(R / 2))) ** 0.4
    sim.dt = 1e-3 * delta_h / (2 * v)
    deepest = 0.0
    while sim.velocities[0, 0] > 0:
        sim.run(steps=10)
        deepest = max(deepest, 2 * R - (sim.positions[1, 0] - sim.positions[0, 0]))
    assert deepest == pytest.approx(delta_h, rel=0.01)


def head_on(e, table1, speed):
    sim = rd.Simulation(contact=rd.ContactModel(normal=rd.WaltonBraun(loading_stiffness=K1)), gravity=(0, 0, 0),
                        track_energy=True)
    sim.add_material(table1(restitution=e, friction=0.5))
    gap = 0.2 * R
    sim.add_particles([[-R - gap, 0, 0], [R + gap, 0, 0]], radius=R, material="m",
                      velocity=[[speed, 0, 0], [-speed, 0, 0]])
    return sim


@pytest.mark.parametrize("e", [0.1, 0.5, 0.9])
def test_a_binary_impact_rebounds_with_e_at_every_speed(e, table1):
    """Two equal spheres meet head on at 0.2 and 2 m/s: the relative speed after is e times the
    speed before at both (the hysteresis loses 1 - e^2 of the energy whatever the speed), within
    1 %: the turning point is found up to one step late, an error of order dt / t_c with the
    contact resolved in over 50 steps of the stiff k2 branch (dt below a tenth of its period)."""
    m_eff = 0.5 * 1056.0 * 4.0 / 3.0 * math.pi * R ** 3
    period_k2 = 2 * math.pi * math.sqrt(m_eff / (K1 / e ** 2))
    for speed in (0.1, 1.0):
        sim = head_on(e, table1, speed)
        sim.dt = period_k2 / 60
        sim.track_energy = True
        while sim.number_of_contacts() == 0:
            sim.run(steps=20)
        while sim.number_of_contacts():
            sim.run(steps=1)
        after = sim.velocities[1, 0] - sim.velocities[0, 0]
        assert after / (2 * speed) == pytest.approx(e, rel=0.01)
        # the hysteresis is counted in the normal channel, and closes the energy budget: the kinetic
        # energy lost, within 1 % (the turning-point step's share, of order dt / t_c)
        lost = 0.5 * m_eff * ((2 * speed) ** 2 - after ** 2)
        assert sim.dissipated_energy()["normal_damping"] == pytest.approx(lost, rel=0.01)


def test_the_time_step_check_takes_the_unloading_stiffness(table1):
    """The stiffer line is k2 = k1 / e^2: at e = 0.3 a tenth of its period for two of the spheres
    (m* = m / 2) is 9.9 us, three times shorter than k1's; a dt between the two is refused."""
    e = 0.3
    m_eff = 0.5 * 1056.0 * 4.0 / 3.0 * math.pi * R ** 3
    limit = 0.1 * 2 * math.pi * math.sqrt(m_eff / (K1 / e ** 2))
    sim = rd.Simulation(contact=rd.ContactModel(normal=rd.WaltonBraun(loading_stiffness=K1)), dt=1.5 * limit)
    sim.add_material(table1(restitution=e, friction=0.5))
    sim.add_particles([[0, 0, 0], [3 * R, 0, 0]], radius=R, material="m")
    with pytest.raises(ParameterError, match=f"normal spring period {10 * limit:.4g} s / 10"):
        sim.run(steps=1)


def test_walton_braun_refusals():
    with pytest.raises(ParameterError, match="loading_stiffness"):
        rd.WaltonBraun(loading_stiffness=0.0)
    with pytest.raises(ParameterError, match="characteristic_velocity = 1.0 is not allowed together"):
        rd.WaltonBraun(loading_stiffness=1e5, characteristic_velocity=1.0)
    with pytest.raises(ParameterError, match="characteristic_velocity"):
        rd.WaltonBraun(characteristic_velocity=-1.0)
    with pytest.raises(ParameterError, match="kn_source = 'secant' is not known"):
        rd.WaltonBraun(kn_source="secant")
    with pytest.raises(ParameterError, match="damping_ratio"):
        rd.WaltonBraun(damping_ratio=-0.1)


@pytest.mark.parametrize("e", [0.3, 0.8])
def test_a_sphere_dropped_on_a_plane_rebounds_with_e(e, table1):
    """WB-3: a sphere dropped from 0.2 m onto a plane (a wall contact keeps the law's history as a
    pair contact does): e = sqrt(rebound height / drop height) within 1 %. Gravity acting during
    the contact shifts e by about g t_c / v_0 (t_c = (pi/2) sqrt(m/k1) (1 + e), 2 ms here against
    v_0 = 2 m/s: 1 %), so the tolerance is 2 %."""
    sim = rd.Simulation(contact=rd.ContactModel(normal=rd.WaltonBraun(loading_stiffness=K1)), dt=5e-6,
                        track_energy=True)  # the impact test's kernel
    sim.add_material(table1(restitution=e, friction=0.5))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    h0 = 0.2
    sim.add_particles([[0, 0, R + h0]], radius=R, material="m")
    sim.run(math.sqrt(2 * h0 / 9.81) * 1.1)  # through the impact
    assert sim.velocities[0, 2] > 0, "the sphere should be on its way up"
    apex = 0.0
    while sim.velocities[0, 2] > 0:
        sim.run(steps=100)
        apex = max(apex, sim.positions[0, 2] - R)
    assert math.sqrt(apex / h0) == pytest.approx(e, rel=0.02)


@pytest.mark.parametrize("kn_source", ["loading", "unloading"])
def test_rolling_resistance_on_walton_braun(table1, kn_source):
    """A rolling model on Walton-Braun takes its force as F_n: a sphere set rolling without slip at
    v0 = 0.3 m/s on a plane, CDT with mu_r = 0.2 (M = mu_r R F_n, F_n = m g once at rest), stops
    after 7 v0^2 / (10 mu_r g) = 32.1 mm (the report's T2 without its sliding phase), within 1 %:
    the residual normal oscillation along the k2 line, damped by the dashpot, and the spin-up of
    the contact's rotational spring are far below that. kn_source does not change it (CDT has no
    spring). The tangential law is Walton's (no slip here, so it does not matter; the sliding
    test of tests/physics/test_walton_tangential.py runs the same kernel: one compile fewer)."""
    mu_r, v0, g = 0.2, 0.3, 9.81
    sim = rd.Simulation(contact=rd.ContactModel(
        normal=rd.WaltonBraun(loading_stiffness=K1, damping_ratio=0.5, kn_source=kn_source), tangential="walton",
        rolling="cdt"), dt=5e-6)
    sim.add_material(table1(restitution=0.5, friction=0.5, rolling_friction=mu_r))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R]], radius=R, material="m")
    sim.run(0.02)  # at rest on the plane
    x0 = sim.positions[0, 0]
    sim.set_velocities([0], velocity=(v0, 0, 0), angular_velocity=(0, v0 / R, 0))
    stop = 7 * v0 / (5 * mu_r * g)  # the deceleration is 5/7 mu_r g
    sim.run(1.2 * stop)
    assert abs(sim.velocities[0, 0]) < 1e-3
    assert sim.positions[0, 0] - x0 == pytest.approx(7 * v0 ** 2 / (10 * mu_r * g), rel=0.01)
