"""The parallel bond's law (rollingdem.bonds.parallel_bond, docs/models.md §1.7), driven through
prescribed motions of a bonded pair: the section and stiffnesses of the reference set B1, the
pure-mode and combined break loads of Potyondy & Cundall's criteria, and the bond frame carried
through a rigid rotation. The bond list in the engine is not built yet."""

import math

import numpy as np
import pytest

from rollingdem.bonds import (BOND_BROKEN_SHEAR, BOND_BROKEN_TENSION, BOND_INPUTS, BOND_INTACT, BOND_PARAMETERS,
                              BOND_STATE, ParallelBond, bond_energy, parallel_bond)
from rollingdem.errors import ParameterError

# B1: equal spheres of R = 1 cm, lambda = 1, E = 1e8 Pa (k_n = E / 2R = 5e9 Pa/m), kappa = 2.5,
# sigma_c = c = 1 MPa, phi = 0, beta = 1
R = 0.01
B1 = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e6, cohesion=1e6)
N = (1.0, 0.0, 0.0)  # the bond normal, from j to i


def test_b1_section_and_stiffnesses():
    """A = pi R^2 = 3.14159e-4 m^2, I = 7.85398e-9, J = 1.57080e-8 m^4; K_n = k_n A = 1.57080e6 N/m,
    K_s = 6.28319e5 N/m, K_b = k_n I = 39.2699 N m/rad, K_t = k_s J = 31.4159 N m/rad (the spec's
    B1 table, to its 6 digits)."""
    p = dict(zip(BOND_PARAMETERS._fields, B1.parameter_row(R, R)))
    expected = dict(area=3.14159e-4, bending_inertia=7.85398e-9, polar_inertia=1.57080e-8, normal_stiffness=1.57080e6,
                    shear_stiffness=6.28319e5, bending_stiffness=39.2699, twisting_stiffness=31.4159, bond_radius=R)
    for key, value in expected.items():
        assert p[key] == pytest.approx(value, rel=1e-5), key


def drive(rv=(0, 0, 0), wi=(0, 0, 0), wj=(0, 0, 0), steps=100000, bond=B1, state=None, normal=N):
    """Bond b = 0 driven at constant relative velocity and spins, dt = 1 s, until it breaks: (the
    load before the breaking step, the steps taken, the mode, the last forces)."""
    p = np.array(bond.parameter_row(R, R))
    state = np.zeros((1, len(BOND_STATE))) if state is None else state
    g = np.array([*normal, *rv, *wi, *wj, R, R])
    assert len(g) == len(BOND_INPUTS)
    for step in range(1, steps + 1):
        before = state[0].copy()
        out = parallel_bond(state, 0, p, g, 1.0)
        if out[-1] != BOND_INTACT:
            return before, step, out[-1], out
    return state[0].copy(), steps, BOND_INTACT, out


def test_pure_tension_breaks_at_sigma_c_a():
    """Pulled apart at 1e-7 m per step: F_n = K_n u grows to sigma_c A = 314.16 N at u = sigma_c / k_n
    = 2.0e-4 m (one step is 0.157 N); the force on i pulls it back towards j; the strain energy
    before the break is F_n^2 / (2 K_n)."""
    load, steps, mode, _ = drive(rv=(1e-7, 0, 0))
    assert mode == BOND_BROKEN_TENSION
    assert load[BOND_STATE.normal_force] == pytest.approx(314.159, abs=0.16)
    assert steps * 1e-7 == pytest.approx(2.0e-4, abs=1e-7)
    state = np.zeros((1, len(BOND_STATE)))
    out = parallel_bond(state, 0, np.array(B1.parameter_row(R, R)), np.array([*N, 1e-5, 0, 0, *[0.0] * 6, R, R]), 1.0)
    assert out[0] == pytest.approx(-1.5708e6 * 1e-5, rel=1e-5)  # on i, towards j
    assert bond_energy(state, 0, np.array(B1.parameter_row(R, R))) == pytest.approx(15.708 ** 2 / (2 * 1.5708e6),
                                                                                     rel=1e-5)


def test_pure_shear_breaks_at_c_a():
    """Slid across n (no spin, so no bending): |F_s| = K_s u reaches c A = 314.16 N at u = 5.0e-4 m;
    the shear force on i opposes the slip and its torque on i is -R n x F_s."""
    load, steps, mode, out = drive(rv=(0, 1e-7, 0))
    assert mode == BOND_BROKEN_SHEAR
    assert -load[BOND_STATE.shear_y] == pytest.approx(314.159, abs=0.1)
    assert steps * 1e-7 == pytest.approx(5.0e-4, abs=1e-7)
    state = np.zeros((1, len(BOND_STATE)))
    out = parallel_bond(state, 0, np.array(B1.parameter_row(R, R)), np.array([*N, 0, 1e-6, 0, *[0.0] * 6, R, R]), 1.0)
    fy = -6.28319e5 * 1e-6
    assert out[1] == pytest.approx(fy, rel=1e-5)
    assert out[5] == pytest.approx(-R * fy, rel=1e-5) and out[8] == pytest.approx(-R * fy, rel=1e-5)  # z: -R (n x F)_z


def test_pure_bending_breaks_at_sigma_c_i_over_r():
    """Opposite spins across n (w_i = -w_j, centres still: no shear at the contact point): |M_b| =
    K_b theta reaches sigma_c I / (beta R) = 0.7854 N m at theta = 0.0200 rad."""
    load, steps, mode, _ = drive(wi=(0, 0, 1e-6), wj=(0, 0, -1e-6))
    assert mode == BOND_BROKEN_TENSION
    assert abs(load[BOND_STATE.bending_z]) == pytest.approx(0.785398, abs=1e-4)
    assert abs(load[BOND_STATE.shear_y]) < 1e-9
    assert steps * 2e-6 == pytest.approx(0.0200, abs=2e-6)


def test_pure_twisting_breaks_at_c_j_over_r():
    """A spin about n: |M_t| = K_t psi reaches c J / (beta R) = 1.5708 N m at psi = 0.0500 rad."""
    load, steps, mode, _ = drive(wi=(1e-6, 0, 0))
    assert mode == BOND_BROKEN_SHEAR
    assert abs(load[BOND_STATE.twisting_moment]) == pytest.approx(1.570796, abs=1e-4)
    assert steps * 1e-6 == pytest.approx(0.0500, abs=1e-6)


def test_tension_and_bending_together():
    """Pulled at v = 2 w R while bent at w_i = -w_j = w, so that F_n / A and M_b R / I grow alike: the
    bond breaks when they sum to sigma_c, at F_n = 157.08 N and M_b = 0.3927 N m (each half)."""
    w = 1e-6
    load, _, mode, _ = drive(rv=(2 * w * R, 0, 0), wi=(0, 0, w), wj=(0, 0, -w))
    assert mode == BOND_BROKEN_TENSION
    assert load[BOND_STATE.normal_force] == pytest.approx(157.08, abs=0.05)
    assert abs(load[BOND_STATE.bending_z]) == pytest.approx(0.39270, abs=1e-4)


def test_compression_strengthens_in_shear():
    """With phi = 30 degrees a bond compressed to F_n = -157.08 N holds shear up to
    (c + 157.08/A tan 30) A = 404.86 N (tau_c = 1.2887 MPa)."""
    bond = ParallelBond(youngs_modulus=1e8, stiffness_ratio=2.5, tensile_strength=1e6, cohesion=1e6,
                        friction_angle=30.0)
    state = np.zeros((1, len(BOND_STATE)))
    p = np.array(bond.parameter_row(R, R))
    push = -157.08 / 1.5707963e6  # m of approach
    parallel_bond(state, 0, p, np.array([*N, push, 0, 0, *[0.0] * 6, R, R]), 1.0)
    assert state[0, BOND_STATE.normal_force] == pytest.approx(-157.08, rel=1e-6)
    load, _, mode, _ = drive(rv=(0, 1e-7, 0), bond=bond, state=state)
    assert mode == BOND_BROKEN_SHEAR
    assert -load[BOND_STATE.shear_y] == pytest.approx(404.86, abs=0.1)
    assert -load[BOND_STATE.shear_y] / 3.14159265e-4 == pytest.approx(1.2887e6, rel=1e-4)


def test_a_rigid_rotation_carries_the_load_along():
    """A pre-loaded bond (shear and bending across n) turned rigidly at 20 rad/s about an axis across
    it for 2 rad (dt = 1e-4 s, the normal and the centres' velocities those of the rigid turn):
    no relative motion at the contact point, so |F_s| and |M_b| keep their values to 1e-6 and turn
    with the pair (F_s stays across n and along the turned direction)."""
    p = np.array(B1.parameter_row(R, R))
    state = np.zeros((1, len(BOND_STATE)))
    parallel_bond(state, 0, p, np.array([*N, 0, 1e-4, 0, 0, 0, 1e-3, 0, 0, -1e-3, R, R]), 1.0)
    fs0 = state[0, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]].copy()
    mb0 = state[0, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]].copy()
    omega, dt, steps = np.array([0.0, 0.0, 20.0]), 1e-4, 1000
    d = 2 * R
    for s in range(1, steps + 1):
        angle = 20.0 * s * dt
        n = np.array([math.cos(angle), math.sin(angle), 0.0])
        rv = np.cross(omega, d * n)  # v_i - v_j of the rigid turn
        parallel_bond(state, 0, p, np.array([*n, *rv, *omega, *omega, R, R]), dt)
    fs = state[0, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]]
    mb = state[0, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]]
    assert np.linalg.norm(fs) == pytest.approx(np.linalg.norm(fs0), rel=1e-6)
    assert np.linalg.norm(mb) == pytest.approx(np.linalg.norm(mb0), rel=1e-6)
    turn = np.array([[math.cos(2.0), -math.sin(2.0), 0], [math.sin(2.0), math.cos(2.0), 0], [0, 0, 1]])
    np.testing.assert_allclose(fs, turn @ fs0, atol=1e-6 * np.linalg.norm(fs0))
    assert abs(fs @ n) < 1e-9 * np.linalg.norm(fs0)


def test_bond_refusals():
    with pytest.raises(ParameterError, match="bond radius_multiplier = 0"):
        ParallelBond(youngs_modulus=1e8, radius_multiplier=0.0)
    with pytest.raises(ParameterError, match="bond friction_angle = 90"):
        ParallelBond(youngs_modulus=1e8, friction_angle=90.0)
    with pytest.raises(ParameterError, match="bond youngs_modulus"):
        ParallelBond(youngs_modulus=-1.0)
