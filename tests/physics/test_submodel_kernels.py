"""Each contact sub-model kernel called on its own, against numbers worked out by hand from the
formula in its docstring and the literature (docs/models.md §1, §3-§6, §4.8, §11, §12).

Every expected value below is written from the published formula with the inputs typed in this
file (E, nu, e, mu, mu_r, ... of two materials), never from the code's own helpers or output: a
wrong factor in a kernel or in its pair parameters (``ContactModel.pair_table``) makes one of them
fail. Each test's docstring names the wrong factors it catches.

Tolerances. One kernel call is a few dozen floating-point operations on O(1)-conditioned inputs,
so kernel and hand formula agree to a few ulps; ``RT = 1e-12`` relative (about 5000 ulps) is the
round-off allowance, and the smallest factor error we look for (2.25 -> 2.0 is 11 %, a halved
dashpot 50 %, sqrt(5/6) -> sqrt(2/3) 11 %) is ten orders of magnitude above it.
"""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.physics.records import contact_inputs
from rollingdem.physics.contact.frame import contact_frame
from rollingdem.physics.contact.normal import hertz_normal, hooke_normal, linear_normal
from rollingdem.physics.contact.tangential import history_spring
from rollingdem.physics.contact.twisting import spring_twisting

RT = 1e-12  # relative round-off allowance of one kernel call (see module docstring)

# Two materials, so that the pair mixing rules enter (docs/models.md §1.1).
E_A, NU_A = 40e6, 0.49
E_B, NU_B = 2e8, 0.30
MAT_A = rd.Material("a", E_A, NU_A, 1056.0, friction=0.8, rolling_friction=0.2, restitution=0.5,
                    rolling_damping=0.3)
MAT_B = rd.Material("b", E_B, NU_B, 2500.0, friction=0.4, rolling_friction=0.1, restitution=0.7,
                    rolling_damping=0.1)
# Hand mixing: 1/E* = sum (1 - nu^2)/E; 1/G* = sum 2 (2 - nu)(1 + nu)/E; coefficients: arithmetic means.
E_STAR = 1.0 / ((1 - NU_A ** 2) / E_A + (1 - NU_B ** 2) / E_B)
G_STAR = 1.0 / (2 * (2 - NU_A) * (1 + NU_A) / E_A + 2 * (2 - NU_B) * (1 + NU_B) / E_B)
MU = 0.6       # (0.8 + 0.4) / 2
MU_R = 0.15    # (0.2 + 0.1) / 2
E_REST = 0.6   # (0.5 + 0.7) / 2
ETA_R = 0.2    # (0.3 + 0.1) / 2

# A contact state (all made up, O(1) in SI-scaled units of a 5 mm sphere contact).
R_EFF = 0.0025
M_EFF = 4e-4
NO_HISTORY = np.zeros((1, 1))  # the normal laws here declare no history
I_R = 1.75e-8
DT = 1e-5
KN, KT = 2e4, 2e4 * 2 / 7
F_EL = 1.0
F_TOT = 1.3  # differs from F_EL so that a model reading the wrong one is caught


def beta(e):
    """beta = ln e / sqrt(ln^2 e + pi^2) (docs/models.md §1.1)."""
    return math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi ** 2)


def row(model_kw, slot):
    """(parameter row of the pair a-b, the slot's offset, the contact model)."""
    cm = rd.ContactModel(**model_kw)
    table = rd.MaterialTable()
    table.add(MAT_A)
    table.add(MAT_B)
    return cm.pair_table(table.pairs())[0, 1], cm.layout()[slot.upper() + "_PARAMS"], cm


def rot(axis, angle):
    """Rotation matrix about ``axis`` by ``angle`` (Rodrigues' formula in matrix form)."""
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def test_pair_row_common_slots():
    """The common slots of the pair row are E*, G*, mu, mu_r, eta_r, e mixed by hand (docs/models.md §1.1).
    Catches a wrong mixing rule (e.g. 2 (2 - nu)(1 + nu) -> (2 - nu)(1 + nu) in G*)."""
    p, _, _ = row(dict(normal="hertz"), "normal")
    np.testing.assert_allclose(p[:6], [E_STAR, G_STAR, MU, MU_R, ETA_R, E_REST], rtol=RT)


# --- normal ---------------------------------------------------------------------------------------

def test_hertz_normal_by_hand():
    """Hertz-Mindlin (docs/models.md §1.2): a = sqrt(R* delta), k_n = 4/3 E* a, F_el = k_n delta,
    S_n = 2 E* a, S_t = 8 G* a, gamma_n = c sqrt(S_n m*), gamma_t = c sqrt(S_t m*),
    c = -2 sqrt(5/6) beta(e) (LIGGGHTS/EDEM; exact for Hertz).
    Catches: 4/3 -> 1 in k_n, 8 G* -> 4 G* in S_t, 2 E* in S_n, sqrt(5/6) -> sqrt(2/3) in c,
    a halved (or otherwise wrong) tangential dashpot gamma_t, a wrong sign of the normal dashpot."""
    p, off, _ = row(dict(normal="hertz"), "normal")
    delta, vn, r_eff, m_eff = 2e-5, -0.7, 0.003, M_EFF
    f_el, f_damp, kn, kt, gamma_t, hysteresis = hertz_normal(NO_HISTORY, 0, 0, delta, vn, r_eff, m_eff, p, off)
    a = math.sqrt(r_eff * delta)
    c = -2 * math.sqrt(5 / 6) * beta(E_REST)
    gamma_n = c * math.sqrt(2 * E_STAR * a * m_eff)
    assert kn == pytest.approx(4 / 3 * E_STAR * a, rel=RT)
    assert f_el == pytest.approx(4 / 3 * E_STAR * math.sqrt(r_eff) * delta ** 1.5, rel=RT)
    assert f_damp == pytest.approx(-gamma_n * vn, rel=RT) and f_damp > 0  # approaching: pushes apart
    assert kt == pytest.approx(8 * G_STAR * a, rel=RT)
    assert gamma_t == pytest.approx(c * math.sqrt(8 * G_STAR * a * m_eff), rel=RT)
    assert hysteresis == 0.0  # elastic: the dashpot's loss is the kernel's to count


def test_hooke_normal_by_hand():
    """Hooke (docs/models.md §1.3): k_n = m* V_c^2 / delta_H^2 with delta_H = (15 m* V_c^2 / (16 E* sqrt(R*)))^(2/5)
    the Hertz peak overlap at V_c (the derived form, not the code's); k_t = ratio k_n;
    gamma_n = gamma_t = -2 beta(e) sqrt(m* k_n).
    Catches: a wrong 16/15 or 1/5 power in k_n, a wrong 2 or beta in gamma_n, gamma_t != gamma_n,
    the stiffness ratio not applied."""
    vc, ratio = 1.3, 2 / 7
    p, off, _ = row(dict(normal=rd.Hooke(characteristic_velocity=vc, tangential_stiffness_ratio=ratio)), "normal")
    delta, vn, r_eff, m_eff = 3e-5, 0.4, 0.003, M_EFF
    f_el, f_damp, kn, kt, gamma_t, hysteresis = hooke_normal(NO_HISTORY, 0, 0, delta, vn, r_eff, m_eff, p, off)
    delta_h = (15 * m_eff * vc ** 2 / (16 * E_STAR * math.sqrt(r_eff))) ** 0.4
    kn_hand = m_eff * vc ** 2 / delta_h ** 2
    gamma_n = -2 * beta(E_REST) * math.sqrt(m_eff * kn_hand)
    # k_n goes through a 1/5 power: still a few ulps, RT holds
    assert kn == pytest.approx(kn_hand, rel=RT)
    assert f_el == pytest.approx(kn_hand * delta, rel=RT)
    assert f_damp == pytest.approx(-gamma_n * vn, rel=RT) and f_damp < 0  # separating: pulls
    assert kt == pytest.approx(ratio * kn_hand, rel=RT)
    assert gamma_t == pytest.approx(gamma_n, rel=RT)
    assert hysteresis == 0.0


@pytest.mark.parametrize("zeta_n", [None, 0.4])
def test_linear_normal_by_hand(zeta_n):
    """PFC linear (docs/models.md §5): F = k_n delta; gamma_n = 2 zeta_n sqrt(m* k_n) with zeta_n = -beta(e)
    unless given; gamma_t = 2 zeta_s sqrt(m* k_s).
    Catches: a wrong 2 in a dashpot, k_s and k_n swapped in gamma_t, the restitution's damping ratio wrong."""
    kn, ks, zeta_s = 3e4, 1e4, 0.25
    p, off, _ = row(dict(normal=rd.Linear(kn, ks, normal_damping_ratio=zeta_n, shear_damping_ratio=zeta_s)),
                    "normal")
    delta, vn = 4e-5, -0.3
    f_el, f_damp, kn_out, kt_out, gamma_t, hysteresis = linear_normal(NO_HISTORY, 0, 0, delta, vn, 0.003, M_EFF, p, off)
    zn = -beta(E_REST) if zeta_n is None else zeta_n
    assert (f_el, kn_out, kt_out) == (pytest.approx(kn * delta, rel=RT), kn, ks)
    assert f_damp == pytest.approx(-2 * zn * math.sqrt(M_EFF * kn) * vn, rel=RT)
    assert gamma_t == pytest.approx(2 * zeta_s * math.sqrt(M_EFF * ks), rel=RT)
    assert hysteresis == 0.0


# --- tangential -------------------------------------------------------------------------------------

Z = (0.0, 0.0, 1.0)
KT_T, GAMMA_T = 5e3, 0.02


def tangential(hist, v, normal_force, gamma_t=GAMMA_T, n=Z, n_old=None, spin=0.0):
    p, off, _ = row(dict(normal="hertz"), "tangential")
    frame = contact_frame(*(n if n_old is None else n_old), *n, spin)
    res = history_spring(hist, 0, 0, contact_inputs(n), frame, tuple(v), (0.0, normal_force, 0.0, KT_T, gamma_t), DT, p,
                         off)
    return np.array(res[:3]), res[3]


def test_history_spring_spring_and_dashpot():
    """One step from zero history (docs/models.md §1.2): xi = v_t dt and F = -k_t xi - gamma_t v_t, below
    mu F_n. Without the dashpot F = -k_t v_t dt. Catches: a wrong sign or factor of the spring or
    the dashpot (e.g. the dashpot halved), a history not accumulated, a dissipation that counts
    the stored spring energy as lost."""
    v = np.array([0.3, -0.2, 0.0])
    for gamma_t in (0.0, GAMMA_T):
        hist = np.zeros((1, 3))
        f, dissipated = tangential(hist, v, 1.0, gamma_t=gamma_t)
        # |F| = 0.025 N << mu F_n = 0.6 N: elastic
        np.testing.assert_allclose(f, -KT_T * v * DT - gamma_t * v, rtol=RT, atol=0)
        np.testing.assert_allclose(hist[0], v * DT, rtol=RT, atol=0)
        # the dashpot's gamma_t |v|^2 dt, plus the elastic step's residual 1/2 k_t |v|^2 dt^2 (docstring)
        assert dissipated == pytest.approx(gamma_t * (v @ v) * DT + 0.5 * KT_T * (v @ v) * DT ** 2, rel=RT)
    # a second step adds to the history
    f, _ = tangential(hist, v, 1.0)
    np.testing.assert_allclose(f, -KT_T * 2 * v * DT - GAMMA_T * v, rtol=RT, atol=0)


def test_history_spring_coulomb_cap_and_backing_out():
    """|F_t| capped at mu max(F_n, 0) along the trial force (spring + dashpot), and the spring backed
    out so that spring + dashpot sits at the cap: xi = -(F_t + gamma_t v_t)/k_t (LAMMPS mindlin).
    Then steady sliding at the cap stores nothing more and dissipates mu F_n |v| dt, the friction
    work. Catches: a wrong mu or F_n in the limit, a cap on the spring only, a history not backed out
    (or backed out without the dashpot), a wrong dissipation."""
    v = np.array([15.0, -10.0, 0.0])
    hist = np.zeros((1, 3))
    f, _ = tangential(hist, v, 1.0)
    vhat = v / np.linalg.norm(v)
    # trial -(k_t dt + gamma_t) v = -0.07 v, |.| = 1.26 N > 0.6 N; the dashpot's 0.36 N alone is below
    np.testing.assert_allclose(f, -MU * 1.0 * vhat, rtol=RT, atol=0)
    np.testing.assert_allclose(hist[0], -(f + GAMMA_T * v) / KT_T, rtol=RT, atol=0)
    # steady sliding at the cap: the history stays, the work done is all dissipated
    f2, dissipated = tangential(hist, v, 1.0)
    np.testing.assert_allclose(f2, f, rtol=RT, atol=0)
    np.testing.assert_allclose(hist[0], -(f + GAMMA_T * v) / KT_T, rtol=RT, atol=0)
    # the stored energy 1/2 k_t xi^2 (5.8e-6 J) that the kernel subtracts is below the work (1.1e-4 J):
    # its round-off stays within RT of the work
    assert dissipated == pytest.approx(MU * 1.0 * np.linalg.norm(v) * DT, rel=RT)


def test_history_spring_with_the_dashpot_alone_above_the_cap():
    """The dashpot alone, gamma_t |v| = 0.72 N, above the cap mu F_n = 0.6 N (an oblique impact's first
    steps, mu F_n still small): F_t at the cap against the slip, and the spring at zero. Backed out
    through the dashpot it would be xi = (mu F_n - gamma_t |v|)/k_t along -v, and as k_t and mu F_n
    grow over the next steps it pushed the contact along the slip: a sphere spinning onto a plane
    (Chung & Ooi's test 6, e = 0.5) rebounded with a contact point 29 % faster than sliding friction
    allows. Catches that back-out, and a spring zeroed below that point."""
    v = np.array([30.0, -20.0, 0.0])
    hist = np.zeros((1, 3))
    f, _ = tangential(hist, v, 1.0)
    np.testing.assert_allclose(f, -MU * 1.0 * v / np.linalg.norm(v), rtol=RT, atol=0)
    np.testing.assert_array_equal(hist[0], [0.0, 0.0, 0.0])
    # the next step, at a stiffer spring (KT_T is fixed here: the same state again), still at the cap
    f2, _ = tangential(hist, v, 1.0)
    np.testing.assert_allclose(f2, f, rtol=RT, atol=0)


@pytest.mark.parametrize("normal_force", [-0.5, 0.0])
def test_history_spring_pulling_contact_cannot_grip(normal_force):
    """A contact whose normal force is pulling (F_n < 0, the dashpot at the end of an impact) has
    the Coulomb limit mu max(F_n, 0) = 0: no tangential force, however small the slip, and no spring
    (docs/models.md §11.4). Catches |F_n| in the limit (which would give a grip of up to
    mu |F_n| = 0.3 N here)."""
    v = np.array([0.3, -0.2, 0.0])
    hist = np.zeros((1, 3))
    f, _ = tangential(hist, v, normal_force)
    np.testing.assert_array_equal(f, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(hist[0], [0.0, 0.0, 0.0])


@pytest.mark.parametrize("theta,phi", [(0.3, 0.2), (0.0, 0.2), (0.3, 0.0), (2e-4, 3e-4)])
def test_history_spring_turns_with_the_contact_frame(theta, phi):
    """A loaded spring xi0 (in the plane, along neither axis) on normal z; the normal turns by theta
    about y and the pair spins by phi about the new normal, with no slip. The spring must be the
    hand-rotated R(n, phi) R(y, theta) xi0 (docs/models.md §11.3): same magnitude, tangent to the new
    normal. Catches: the history not carried with the frame (it would keep a normal part
    ~ |xi| sin(theta) and miss the spin), a spin about the wrong axis or with the wrong sign (in
    any component). The small-angle case takes the series path of ``contact_frame``."""
    xi0 = np.array([4e-5, -3e-5, 0.0])
    hist = xi0.reshape(1, 3).copy()
    n = np.array([math.sin(theta), 0.0, math.cos(theta)])
    f, _ = tangential(hist, (0.0, 0.0, 0.0), 1.0, n=tuple(n), n_old=Z, spin=phi)
    expected = rot(n, phi) @ rot((0, 1, 0), theta) @ xi0
    # |F| = k_t |xi| = 0.25 N < mu F_n: elastic; the rotations are exact to round-off
    np.testing.assert_allclose(hist[0], expected, rtol=0, atol=RT * np.linalg.norm(xi0))
    np.testing.assert_allclose(f, -KT_T * expected, rtol=0, atol=RT * KT_T * np.linalg.norm(xi0))
    assert abs(f @ n) <= RT * np.linalg.norm(f)


# --- rolling ----------------------------------------------------------------------------------------

N_R = np.array([0.0, 0.0, 1.0])
WI = np.array([1.0, 0.5, 3.0])
WJ = np.array([0.2, -0.3, -1.0])
DW_R = np.array([0.8, 0.8, 0.0])  # (w_i - w_j) without its part along n (the twist 4.0 is removed)
M_MAX = MU_R * R_EFF * F_EL


def rolling(model, hist=None, wi=WI, wj=WJ, f_el=F_EL, f_tot=F_TOT, lever_i=R_EFF, lever_j=R_EFF, n=N_R):
    """One call of the model's own rolling kernel; returns (M_i, M_j, dissipation, history)."""
    p, off, cm = row(dict(normal="hertz", rolling=model), "rolling")
    kern = type(cm.rolling).function
    hist = np.zeros((1, 3)) if hist is None else hist
    g = contact_inputs(n, omega_i=wi, omega_j=wj, lever_i=lever_i, lever_j=lever_j, r_eff=R_EFF, inertia_r=I_R)
    res = kern(hist, 0, 0, g, contact_frame(*n, *n, 0.0), (f_el, f_tot, KN, KT, 0.0), DT, p, off,
               cm.rolling.kernel_modes())
    return np.array(res[:3]), np.array(res[3:6]), res[6], hist


def assert_vec(actual, expected, scale=None):
    """Componentwise within RT of the vector's magnitude (a zero component must be zero to round-off)."""
    scale = np.linalg.norm(expected) if scale is None else scale
    np.testing.assert_allclose(actual, expected, rtol=0, atol=RT * scale)


def c_ratio(eta, k_r):
    """Rolling dashpot of seed report eqs. 10-12: C_r = eta_r 2 sqrt(I_r k_r)."""
    return eta * 2 * math.sqrt(I_R * k_r)


SPRING_CASES = {
    # model, k_r by hand, C_r by hand
    "epsd-eta0": (rd.EPSD(damping_ratio=0.0), 2.25 * KN * MU_R ** 2 * R_EFF ** 2, 0.0),
    "epsd-pair-eta": (rd.EPSD(), 2.25 * KN * MU_R ** 2 * R_EFF ** 2,
                       c_ratio(ETA_R, 2.25 * KN * MU_R ** 2 * R_EFF ** 2)),
    "epsd-own-eta": (rd.EPSD(damping_ratio=0.45), 2.25 * KN * MU_R ** 2 * R_EFF ** 2,
                      c_ratio(0.45, 2.25 * KN * MU_R ** 2 * R_EFF ** 2)),
    "epsd2": (rd.EPSD2(), KT * R_EFF ** 2, 0.0),
    "epsd3-eta0": (rd.EPSD3(stiffness_coefficient=1.7, damping_ratio=0.0), 1.7 * KN * MU_R ** 2 * R_EFF ** 2, 0.0),
    "epsd3-pair-eta": (rd.EPSD3(stiffness_coefficient=1.7), 1.7 * KN * MU_R ** 2 * R_EFF ** 2,
                        c_ratio(ETA_R, 1.7 * KN * MU_R ** 2 * R_EFF ** 2)),
    "rrlinear": (rd.RRLinear(), KT * R_EFF ** 2, 0.0),
    "sds-gamma0": (rd.SDS(rolling_stiffness=3e3), 3e3 * R_EFF ** 2, 0.0),
    "sds": (rd.SDS(rolling_stiffness=3e3, rolling_damping=0.05), 3e3 * R_EFF ** 2, 0.05 * R_EFF ** 2),
    "displacement_damping-nu0": (rd.DisplacementDamping(theta_max=0.035), MU_R * R_EFF * F_EL / 0.035, 0.0),
    "displacement_damping": (rd.DisplacementDamping(theta_max=0.035, damping=0.3), MU_R * R_EFF * F_EL / 0.035,
                             c_ratio(0.3, MU_R * R_EFF * F_EL / 0.035)),
}


@pytest.mark.parametrize("case", list(SPRING_CASES))
def test_spring_rolling_one_step_by_hand(case):
    """One step from zero history with relative rotation rate w (twist part removed):
    M = k_r dw_r dt + C_r dw_r, a pure couple (M_i = M_j), below the cap, with k_r and C_r by hand:
    EPSD 2.25 k_n mu_r^2 R*^2 (seed eq. 18), EPSD3 c k_n mu_r^2 R*^2, EPSD2 / RRLinear k_t R*^2
    (Iwashita-Oda, no dashpot), SDS k_roll R*^2 and gamma_roll R*^2 (LAMMPS), displacement damping
    mu_r R* F_n / theta_max; C_r = eta 2 sqrt(I_r k_r) (seed eqs. 10-12).
    With eta = 0 the spring alone is compared (a wrong prefactor, e.g. 2.25 -> 2.0, mu_r instead
    of mu_r^2, k_n for k_t, F_total for F_el in the displacement-damping stiffness); with eta > 0
    the dashpot is (a missing 2 or sqrt, the pair's eta_r not used or used where the model has none)."""
    model, k_r, c_r = SPRING_CASES[case]
    mi, mj, _, hist = rolling(model)
    expected = k_r * DW_R * DT + c_r * DW_R
    assert np.linalg.norm(expected) < 0.1 * M_MAX  # elastic, far from the cap
    assert_vec(mi, expected)
    np.testing.assert_array_equal(mi, mj)
    assert_vec(hist[0], k_r * DW_R * DT)  # the spring alone is stored


def test_epsd_elastic_cycle_dissipates_only_the_step_residual():
    """Load for N steps at +w, unload for N steps at -w (EPSD, eta = 0): the spring returns to zero
    and the dissipation is only the documented residual of the step, 1/2 k_r |w|^2 dt^2 per step,
    i.e. 2/N of the peak stored energy 1/2 k_r (N |w| dt)^2 (~0 as dt -> 0), never negative.
    Catches a dissipation that counts stored spring energy as lost (it would be ~ N/2 times larger)."""
    model = rd.EPSD(damping_ratio=0.0)
    k_r = 2.25 * KN * MU_R ** 2 * R_EFF ** 2
    hist = np.zeros((1, 3))
    steps, total = 50, 0.0
    for sign in (1.0, -1.0):
        for _ in range(steps):
            _, _, d, _ = rolling(model, hist=hist, wi=sign * WI, wj=sign * WJ)
            assert d >= 0.0
            total += d
    w2 = DW_R @ DW_R
    assert np.linalg.norm(hist[0]) <= 1e-12 * k_r * steps * math.sqrt(w2) * DT
    peak = 0.5 * k_r * (steps * DT) ** 2 * w2
    assert total == pytest.approx(2 * steps * 0.5 * k_r * w2 * DT ** 2, rel=1e-10)  # 100 summed calls
    assert total == pytest.approx(2 / steps * peak, rel=1e-10)


@pytest.mark.parametrize("case", ["epsd-pair-eta", "epsd-eta0", "sds", "displacement_damping"])
def test_spring_rolling_at_the_cap(case):
    """A contact slipping at the cap (recommended: total moment capped at M_m = mu_r R* max(F_el, 0),
    damper kept with f = 1): with the spring at M_m - C_r w (where the last slipping step left it)
    and w unchanged, M = M_m w/|w| exactly, the spring stays at M_m - C_r w, and all the work done,
    M_m |w| dt, is dissipated. From a spring at M_m, the first slipping step backs the spring out
    to M_m w/|w| - C_r w.
    Catches: a wrong cap (F_total instead of F_el, mu_r^2, missing R*), slip_damping f = 0 as
    default (the spring would stay at M_m), a dissipation that is not the work done at the cap."""
    model, k_r, c_r = SPRING_CASES[case]
    what = DW_R / np.linalg.norm(DW_R)
    hist = (M_MAX * what).reshape(1, 3).copy()
    mi, mj, _, _ = rolling(model, hist=hist)
    assert_vec(mi, M_MAX * what)
    assert_vec(hist[0], M_MAX * what - c_r * DW_R, scale=M_MAX)
    mi, _, dissipated, _ = rolling(model, hist=hist)
    assert_vec(mi, M_MAX * what)
    assert_vec(hist[0], M_MAX * what - c_r * DW_R, scale=M_MAX)
    # the dissipation is a difference of spring energies 1/2 |M_k|^2 / k_r of ~ M_m^2 / k_r; with
    # k_r w dt << M_m that loses digits: |M_m|^2 / k_r / (M_m w dt) times RT
    tol = RT * (M_MAX / (k_r * np.linalg.norm(DW_R) * DT) + 1)
    assert dissipated == pytest.approx(M_MAX * np.linalg.norm(DW_R) * DT, rel=tol)


def test_spring_rolling_with_the_dashpot_alone_above_the_cap():
    """docs/models.md §12, as it is (LAMMPS's back-out, unlike the tangential spring of §1.2): EPSD with
    eta_r 0.9 at 50 times the rate, C_r |w| = 1.07e-3 N m above M_m = 3.75e-4 N m. The step gives the
    cap along w, and the spring is set back to M_m w/|w| - C_r w, against w; when the relative
    rotation stops, the moment is the cap reversed, -M_m w/|w|. Catches the spring capped at M_m
    w/|w| instead (f = 0 in the set-back), and a change of the rule that leaves §12 stale."""
    k_r = 2.25 * KN * MU_R ** 2 * R_EFF ** 2
    c_r = c_ratio(0.9, k_r)
    w = 50 * DW_R
    what = w / np.linalg.norm(w)
    assert c_r * np.linalg.norm(w) > 2 * M_MAX
    hist = np.zeros((1, 3))
    mi, _, _, _ = rolling(rd.EPSD(damping_ratio=0.9), hist=hist, wi=50 * WI, wj=50 * WJ)
    assert_vec(mi, M_MAX * what)
    assert_vec(hist[0], M_MAX * what - c_r * w)
    assert hist[0] @ w < 0
    mi, _, _, _ = rolling(rd.EPSD(damping_ratio=0.9), hist=hist, wi=np.zeros(3), wj=np.zeros(3))
    assert_vec(mi, -M_MAX * what, scale=M_MAX)


@pytest.mark.parametrize("model", [rd.EPSD(), rd.EPSD2(), rd.RRLinear(), rd.SDS(3e3, 0.05),
                                   rd.DisplacementDamping(damping=0.3)])
def test_spring_rolling_pulling_contact_has_no_moment(model):
    """Recommended limit M_m = mu_r R* max(F_n,el, 0) (docs/models.md §11.4, §12): a contact whose elastic
    force is negative (F_el = -0.5 N, total +0.7 N) has M_m = 0 and no rolling moment, whatever the
    stored spring. Catches |F_el| or F_total in the recommended limit (M would be up to mu_r R* 0.7)."""
    hist = np.array([[1e-5, -2e-5, 0.0]])
    mi, mj, _, _ = rolling(model, hist=hist, f_el=-0.5, f_tot=0.7)
    np.testing.assert_array_equal(mi, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(mj, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("model", [rd.EPSD(parity="liggghts"), rd.EPSD2(parity="liggghts"),
                                   rd.SDS(3e3, parity="lammps")])
def test_parity_presets_cap_at_the_total_normal_force(model):
    """LIGGGHTS and LAMMPS limit the moment at mu_r R* |F_n,total| (docs/models.md §3.3 step 4, §4.2):
    with F_el = 1 N and F_total = -0.8 N (pulling) the cap is mu_r R* 0.8 N, and a spring loaded
    beyond it comes out at the cap. Catches: F_el or max(F_total, 0) in the parity presets."""
    cap = MU_R * R_EFF * 0.8
    what = DW_R / np.linalg.norm(DW_R)
    hist = (2 * cap * what).reshape(1, 3).copy()
    mi, _, _, _ = rolling(model, hist=hist, f_tot=-0.8)
    assert_vec(mi, cap * what)


def test_liggghts_epsd_caps_the_spring_only():
    """LIGGGHTS EPSD (docs/models.md §3.3 steps 5-6): at the cap M = M_m along the spring, no dashpot, and
    the spring is stored at the cap; below it M = M_s + C_r w uncapped (so M may exceed M_m).
    Catches a total cap or a slip damper in the LIGGGHTS preset."""
    model = rd.EPSD(parity="liggghts")
    k_r = 2.25 * KN * MU_R ** 2 * R_EFF ** 2
    c_r = c_ratio(ETA_R, k_r)
    cap = MU_R * R_EFF * F_TOT
    what = DW_R / np.linalg.norm(DW_R)
    hist = (cap * what).reshape(1, 3).copy()
    mi, _, _, _ = rolling(model, hist=hist)
    assert_vec(mi, cap * what)
    assert_vec(hist[0], cap * what)
    # below the cap, at 99 % of it: the dashpot adds on top, past M_m (it is C_r |w| = 4.7e-6 N m)
    hist = (0.99 * cap * what - k_r * DW_R * DT).reshape(1, 3)
    mi, _, _, _ = rolling(model, hist=hist)
    assert_vec(mi, 0.99 * cap * what + c_r * DW_R)


def test_displacement_damping_mobilises_at_theta_max():
    """STAR-CCM+ displacement damping (seed 004): k_r = mu_r R* F_n / theta_max, so the moment
    reaches M_m after a relative rotation theta_max and stays there. Rotate by 0.9 theta_max in
    90 steps: |M| = 0.9 M_m; by 1.1 theta_max: |M| = M_m. Catches a wrong theta_max or F_n in k_r."""
    theta_max = 0.035
    model = rd.DisplacementDamping(theta_max=theta_max)
    wdt = theta_max / 100
    w = np.array([wdt / DT, 0.0, 0.0])
    hist = np.zeros((1, 3))
    for k in range(110):
        mi, _, _, _ = rolling(model, hist=hist, wi=w, wj=np.zeros(3))
        if k == 89:
            # 90 increments summed: ~100 ulps
            assert mi[0] == pytest.approx(0.9 * M_MAX, rel=1e-12)
    assert_vec(mi, [M_MAX, 0.0, 0.0])


def test_cdt_by_hand():
    """CDT (seed eq. 2, Ai type A): M = mu_r R* max(F_el, 0) dw_r/|dw_r|, twist removed; with the
    STAR-CCM+ limiter f: |M| <= f I_r |dw_r| / dt. Catches: F_total for F_el, |F_el| for
    max(F_el, 0), the twist kept in the direction, a wrong limiter."""
    what = DW_R / np.linalg.norm(DW_R)
    mi, mj, dissipated, _ = rolling(rd.CDT())
    assert_vec(mi, M_MAX * what)
    np.testing.assert_array_equal(mi, mj)
    assert dissipated == pytest.approx(M_MAX * np.linalg.norm(DW_R) * DT, rel=RT)
    mi, _, _, _ = rolling(rd.CDT(), f_el=-0.5, f_tot=0.7)
    np.testing.assert_array_equal(mi, [0.0, 0.0, 0.0])
    f = 0.08
    limited = f * I_R * np.linalg.norm(DW_R) / DT
    assert limited < M_MAX  # the limiter acts
    mi, _, _, _ = rolling(rd.CDT(limiter=f))
    assert_vec(mi, limited * what)


@pytest.mark.parametrize("form,lever", [("zhou", 1), ("kratos", 2)])
def test_viscous_by_hand(form, lever):
    """Viscous (Ai type B, Zhou eq. 4): M = c_v max(F_el, 0) R* dw_r; Kratos/Lethe one more R*.
    Dissipation M . dw_r dt. Catches a missing or extra R*, F_total for F_el."""
    c_v = 0.7
    mi, mj, dissipated, _ = rolling(rd.Viscous(coefficient=c_v, form=form))
    expected = c_v * F_EL * R_EFF ** lever * DW_R
    assert_vec(mi, expected)
    np.testing.assert_array_equal(mi, mj)
    assert dissipated == pytest.approx(expected @ DW_R * DT, rel=RT)
    mi, _, _, _ = rolling(rd.Viscous(coefficient=c_v, form=form), f_el=-0.5)
    np.testing.assert_array_equal(mi, [0.0, 0.0, 0.0])


def test_force_proportional_by_hand():
    """STAR-CCM+ Force Proportional (seed 004): each particle's own in-plane spin is opposed by
    mu_r F_n R'_k omega_k,t/|omega_k,t| (torque -M_i on i, +M_j on j); levers differ.
    Catches swapped levers or spins, the twist kept, F_total for F_el."""
    li, lj = 0.004, 0.002
    mi, mj, dissipated, _ = rolling(rd.ForceProportional(), lever_i=li, lever_j=lj)
    wi_t, wj_t = WI[:2], WJ[:2]
    exp_i = MU_R * F_EL * li * np.append(wi_t / np.linalg.norm(wi_t), 0.0)
    exp_j = -MU_R * F_EL * lj * np.append(wj_t / np.linalg.norm(wj_t), 0.0)
    assert_vec(mi, exp_i)
    assert_vec(mj, exp_j)
    power = MU_R * F_EL * (li * np.linalg.norm(wi_t) + lj * np.linalg.norm(wj_t))
    assert dissipated == pytest.approx(power * DT, rel=RT)


# --- twisting ---------------------------------------------------------------------------------------

N_TW = (0.6, 0.0, 0.8)
DW_TW = (1.0, 2.0, 3.0)   # (w_i - w_j); its part along N_TW is 0.6 + 2.4 = 3.0
SPIN = 3.0
OVERLAP, R_TW = 2e-5, 0.003
KT_TW, GAMMA_T_TW = 5e3, 0.02


def twisting(model, hist, f_el=F_EL, f_tot=F_TOT, dw=DW_TW):
    p, off, _ = row(dict(normal="hertz", twisting=model), "twisting")
    g = contact_inputs(N_TW, overlap=OVERLAP, omega_i=dw, r_eff=R_TW)  # omega_j = 0: w_i - w_j = dw
    return spring_twisting(hist, 0, 0, g, (f_el, f_tot, 0.0, KT_TW, GAMMA_T_TW), DT, p, off)


MARSHALL = dict(k=0.5 * KT_TW * R_TW * OVERLAP, gamma=0.5 * GAMMA_T_TW * R_TW * OVERLAP,
                limit=2 / 3 * math.sqrt(R_TW * OVERLAP) * MU * F_EL)
TW_SDS = dict(k=2e-5, gamma=1e-7, limit=1e-4 * F_EL)
TWISTING_CASES = {"marshall": ("marshall", MARSHALL),
                  "sds": (rd.TwistingSDS(2e-5, 1e-7, 1e-4), TW_SDS)}


@pytest.mark.parametrize("case", list(TWISTING_CASES))
def test_spring_twisting_by_hand(case):
    """Twisting spring-dashpot-slider (docs/models.md §4.8): Omega = (w_i - w_j) . n, xi = Omega dt,
    M = k_tw xi + gamma_tw Omega; at the cap mu_tw max(F_el, 0) the spring is backed out,
    xi = (M - gamma_tw Omega)/k_tw, and steady slip dissipates M Omega dt.
    Marshall (2009): k_tw = k_t a^2/2, gamma_tw = gamma_t a^2/2, mu_tw = 2/3 a mu, a = sqrt(R* delta);
    sds: the given constants, limit mu_tw F_el.
    Catches: a wrong 1/2 in k_tw or gamma_tw, 2/3 -> 1/2 in the Marshall limit, mu for mu_r, the
    full |dw| for the twist part, F_total or |F_el| for max(F_el, 0)."""
    model, c = TWISTING_CASES[case]
    hist = np.zeros((1, 1))
    m, _ = twisting(model, hist)
    assert c["k"] * SPIN * DT + c["gamma"] * SPIN < 0.1 * c["limit"]
    assert m == pytest.approx(c["k"] * SPIN * DT + c["gamma"] * SPIN, rel=RT)
    assert hist[0, 0] == pytest.approx(SPIN * DT, rel=RT)
    # at the cap, and steady slip there
    hist[0, 0] = 2 * c["limit"] / c["k"]
    m, _ = twisting(model, hist)
    assert m == pytest.approx(c["limit"], rel=RT)
    backed = (c["limit"] - c["gamma"] * SPIN) / c["k"]
    assert hist[0, 0] == pytest.approx(backed, rel=RT)
    m, dissipated = twisting(model, hist)
    assert m == pytest.approx(c["limit"], rel=RT)
    assert hist[0, 0] == pytest.approx(backed, rel=RT)
    # the dissipation subtracts spring energies 1/2 k xi^2 of ~ limit^2/k: relative round-off
    # RT limit / (k Omega dt)
    assert dissipated == pytest.approx(c["limit"] * SPIN * DT, rel=RT * (c["limit"] / (c["k"] * SPIN * DT) + 1))
    # spinning the other way from a spring loaded the other way: the cap with the other sign
    hist[0, 0] = -2 * c["limit"] / c["k"]
    m, _ = twisting(model, hist, dw=tuple(-x for x in DW_TW))
    assert m == pytest.approx(-c["limit"], rel=RT)
    # a pulling contact: no twisting moment
    hist[0, 0] = 1e-3
    m, _ = twisting(model, hist, f_el=-0.5, f_tot=0.7)
    assert m == 0.0
