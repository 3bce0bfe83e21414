"""The rolling kernel on its own (docs/models.md §13 T6): frame carrying, the moment limit, objectivity."""

import math

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.physics.contact.frame import contact_frame
from rollingdem.physics.contact.rolling import spring_rolling
from rollingdem.physics.records import contact_inputs
from rollingdem.engine.codegen import engine_module

R_EFF = 0.0025
KN, KT = 2e4, 2e4 * 2 / 7
F_EL = 1.0
MU_R = 0.2
M_MAX = MU_R * R_EFF * F_EL
I_R = 1.4 * 1e-3 * 0.005 ** 2 / 2


def params(model, mu_r=MU_R, eta=0.3):
    mat = rd.Material("m", 40e6, 0.49, 1056, rolling_friction=mu_r, rolling_damping=eta)
    cm = rd.ContactModel("hertz", rolling=model)
    table = rd.MaterialTable()
    table.add(mat)
    return cm.pair_table(table.pairs())[0, 0], cm.layout()["ROLLING_PARAMS"], cm.rolling.kernel_modes()


def step(model_params, hist, n, n_old, wi, wj, dt=1e-5, spin=0.0, f_total=None):
    p, off, modes = model_params
    frame = contact_frame(n_old[0], n_old[1], n_old[2], n[0], n[1], n[2], spin)
    g = contact_inputs(normal=n, omega_i=wi, omega_j=wj, lever_i=R_EFF, lever_j=R_EFF, r_eff=R_EFF, inertia_r=I_R)
    normal = (F_EL, F_EL if f_total is None else f_total, KN, KT, 0.0)
    res = spring_rolling(hist, 0, 0, g, frame, normal, dt, p, off, modes)
    return np.array(res[:3]), np.array(res[3:6]), res[6]


def load_to_half_limit(model_params, n):
    """Bend the contact about x (normal z) until the spring holds 0.5 M_m; return the history."""
    hist = np.zeros((1, 3))
    k_r = KT * R_EFF ** 2
    rate = 1.0
    steps = int(round(0.5 * M_MAX / (k_r * rate * 1e-5)))
    for _ in range(steps):
        step(model_params, hist, n, n, (rate, 0, 0), (0, 0, 0))
    return hist


@pytest.mark.parametrize("parity,keeps_frame", [(None, True), ("liggghts", False)])
def test_frame_rotated_by_90_degrees(parity, keeps_frame):
    """T6(d): turn a loaded contact by 90 deg about y in 900 steps with no relative rotation. The
    recommended history turns with it (|M| kept, M . n = 0, M along the rotated direction); the
    LIGGGHTS-style global history stays put and ends up along the normal: a spurious twist."""
    p = params(rd.EPSD2(parity=parity))
    n = np.array([0.0, 0.0, 1.0])
    hist = load_to_half_limit(p, n)
    m0 = hist[0].copy()
    assert np.linalg.norm(m0) == pytest.approx(0.5 * M_MAX, rel=0.01)
    nsteps = 900
    for k in range(nsteps):
        a_old, a_new = math.pi / 2 * k / nsteps, math.pi / 2 * (k + 1) / nsteps
        n_old = np.array([math.sin(a_old), 0.0, math.cos(a_old)])
        n_new = np.array([math.sin(a_new), 0.0, math.cos(a_new)])
        mi, mj, _ = step(p, hist, n_new, n_old, (0, 0, 0), (0, 0, 0))
    n_end = np.array([1.0, 0.0, 0.0])
    if keeps_frame:
        assert np.linalg.norm(mi) == pytest.approx(np.linalg.norm(m0), rel=1e-9)
        assert abs(mi @ n_end) < 1e-9 * np.linalg.norm(m0)
        # loaded about x; the 90 deg turn about y carries x to -z, so the moment must now point along -z
        np.testing.assert_allclose(mi / np.linalg.norm(mi), [0, 0, -1], atol=1e-9)
    else:
        assert abs(mi @ n_end) == pytest.approx(np.linalg.norm(m0), rel=1e-9)


@pytest.mark.parametrize("model,bounded", [(rd.EPSD(), True), (rd.EPSD(parity="liggghts"), False)])
def test_moment_never_exceeds_limit_at_onset(model, bounded):
    """T6(e): a fresh contact with a large relative rotation (200 rad/s). The recommended EPSD caps
    spring + dashpot at M_m; LIGGGHTS caps only the spring and the dashpot spikes far above."""
    p = params(model)
    n = np.array([0.0, 0.0, 1.0])
    hist = np.zeros((1, 3))
    worst = 0.0
    for _ in range(50):
        mi, mj, _ = step(p, hist, n, n, (200.0, 0, 0), (0, 0, 0))
        np.testing.assert_array_equal(mi, mj)  # a pure couple
        worst = max(worst, np.linalg.norm(mi))
    if bounded:
        assert worst <= M_MAX * (1 + 1e-12)
    else:
        assert worst > 2 * M_MAX


def rotation(axis, angle):
    """Rotation matrix about ``axis`` by ``angle`` (Rodrigues' formula in matrix form)."""
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def corotate(model, preload=True):
    """Bend a fresh contact (normal z) about x for 20 steps at 2 rad/s (stored spring ~ half the cap
    or less), then turn the pair rigidly at omega = (3, -2, 5) rad/s (both partners, and the normal
    with them) for 100 steps of 1e-4 s. Returns (stored spring before the turn, [(M_i, M_j, n, R)]
    per step with R the rigid rotation so far)."""
    cm = rd.ContactModel("hertz", rolling=model)
    table = rd.MaterialTable()
    table.add(rd.Material("m", 40e6, 0.49, 1056, rolling_friction=0.2, rolling_damping=0.3))
    p, off, modes = cm.pair_table(table.pairs())[0, 0], cm.layout()["ROLLING_PARAMS"], cm.rolling.kernel_modes()
    kern = type(cm.rolling).function
    hist = np.zeros((1, 3))
    dt = 1e-4
    n = np.array([0.0, 0.0, 1.0])
    if preload:
        for _ in range(20):
            kern(hist, 0, 0, contact_inputs(n, omega_i=(2.0, 0, 0), lever_i=R_EFF, lever_j=R_EFF, r_eff=R_EFF,
                                            inertia_r=I_R),
                 contact_frame(*n, *n, 0.0), (F_EL, F_EL, KN, KT, 0.0), dt, p, off, modes)
    m0 = hist[0].copy()
    omega = np.array([3.0, -2.0, 5.0])
    step_rotation = rotation(omega, np.linalg.norm(omega) * dt)
    total = np.eye(3)
    out = []
    for _ in range(100):
        n_new = step_rotation @ n
        total = step_rotation @ total
        spin = 0.5 * (omega + omega) @ n_new * dt  # the engine's spin angle, 1/2 (w_i + w_j) . n dt
        res = kern(hist, 0, 0, contact_inputs(n_new, omega_i=omega, omega_j=omega, lever_i=R_EFF, lever_j=R_EFF,
                                              r_eff=R_EFF, inertia_r=I_R),
                   contact_frame(*n, *n_new, spin), (F_EL, F_EL, KN, KT, 0.0), dt, p, off, modes)
        n = n_new
        out.append((np.array(res[:3]), np.array(res[3:6]), n.copy(), total.copy()))
    return m0, out


FRAME_SPRING_MODELS = [rd.EPSD(), rd.EPSD2(), rd.EPSD3(), rd.RRLinear(), rd.SDS(rolling_stiffness=1e4),
                       rd.DisplacementDamping(damping=0.3)]


@pytest.mark.parametrize("model", FRAME_SPRING_MODELS, ids=lambda m: m.name)
def test_objectivity_rigid_corotation_carries_the_loaded_spring(model):
    """T6(c), docs/models.md §11.1, §11.3: a contact holding a bent spring is turned rigidly (both partners
    spin with the same omega, the normal turns with them). No relative rotation, so no new moment:
    the moment is the stored spring, carried with the pair, M(t) = R(omega t) M_k0: its magnitude
    kept (round-off, 1e-12), tangent to the turning normal (1e-12), along the rotated direction.
    The direction is compared with the hand rotation R(omega t) to N theta^3 (theta = |omega| dt =
    6e-4 rad a step, N = 100 steps; 2e-8): splitting each step's rotation into the turn of n and a
    spin of 1/2 (w_i + w_j) . n dt about the new n is exact to third order in theta (measured 5e-10).
    Catches, for every frame-carried spring model (epsd, epsd2, epsd3, rrlinear, sds,
    displacement_damping): the history not carried with the frame (it would stay fixed in space,
    gaining a normal part ~ |M| x 6e-2 rad), a spin about the wrong axis or sign, a projection only
    (misses the spin, 5e-2 rad), any moment from the co-rotation itself (dashpot or spring on
    omega_i - omega_j != 0)."""
    m0, steps = corotate(model)
    mag = np.linalg.norm(m0)
    assert mag > 0
    theta = math.sqrt(3.0 ** 2 + 2.0 ** 2 + 5.0 ** 2) * 1e-4
    for k, (mi, mj, n, total) in enumerate(steps):
        np.testing.assert_array_equal(mi, mj)
        assert np.linalg.norm(mi) == pytest.approx(mag, rel=1e-12)
        assert abs(mi @ n) <= 1e-12 * mag
        assert np.linalg.norm(mi - total @ m0) <= (k + 1) * theta ** 3 * mag


def test_corotation_lammps_projection_keeps_size_but_misses_the_spin():
    """LAMMPS's project-and-rescale (parity "lammps", docs/models.md §4.2, §11.3) keeps |M| and M tangent,
    but does not follow the spin of the pair about n: after 100 steps the moment lags the rigid
    rotation by about the accumulated spin angle, sum of omega . n dt ~ 5e-2 rad."""
    m0, steps = corotate(rd.SDS(rolling_stiffness=1e4, parity="lammps"))
    mag = np.linalg.norm(m0)
    mi, _, n, total = steps[-1]
    assert np.linalg.norm(mi) == pytest.approx(mag, rel=1e-12)
    assert abs(mi @ n) <= 1e-12 * mag
    spin = sum(np.array([3.0, -2.0, 5.0]) @ s[2] * 1e-4 for s in steps)
    # the projection follows the turn of n only to first order: 10 %
    assert np.linalg.norm(mi - total @ m0) / mag == pytest.approx(abs(spin), rel=0.1)


def test_corotation_liggghts_history_stays_in_space():
    """LIGGGHTS keeps the spring in the global frame (docs/models.md §3.3 step 3, §11.3): under rigid
    co-rotation the moment stays M_k0, fixed in space, and so gains a part along the turning normal
    (a spurious twist) equal to M_k0 . n."""
    m0, steps = corotate(rd.EPSD(parity="liggghts"))
    for mi, _, n, _ in steps:
        np.testing.assert_array_equal(mi, m0)
    assert abs(steps[-1][0] @ steps[-1][2]) > 1e-2 * np.linalg.norm(m0)


@pytest.mark.parametrize("model", ["cdt", "viscous", {"model": "viscous", "coefficient": 0.5}, rd.CDT(limiter=0.08)])
def test_objectivity_rigid_corotation_no_history_models(model):
    """T6(c) for the models without a spring: rigid co-rotation has dw_r = 0, so M = 0 exactly
    (these models hold no state that could be carried). Catches a moment on the own spin omega_i
    instead of omega_i - omega_j."""
    _, steps = corotate(model, preload=False)
    for mi, mj, _, _ in steps:
        assert np.abs(np.concatenate([mi, mj])).max() == 0.0


def test_force_proportional_is_not_objective():
    """The STAR-CCM+ Force Proportional method brakes a rigidly co-rotating pair (docs/models.md §11.1)."""
    cm = rd.ContactModel("hertz", rolling="force_proportional")
    table = rd.MaterialTable()
    table.add(rd.Material("m", 40e6, 0.49, 1056, rolling_friction=0.2))
    p, off, modes = cm.pair_table(table.pairs())[0, 0], cm.layout()["ROLLING_PARAMS"], cm.rolling.kernel_modes()
    g = contact_inputs((0, 0, 1.0), omega_i=(3.0, 0, 0), omega_j=(3.0, 0, 0), lever_i=R_EFF, lever_j=R_EFF,
                       r_eff=R_EFF, inertia_r=I_R)
    res = engine_module(cm).rolling_moment(np.zeros((1, 3)), 0, 0, g, contact_frame(0, 0, 1.0, 0, 0, 1.0, 0.0),
                                           (F_EL, F_EL, KN, KT, 0.0), 1e-5, p, off, modes)
    assert res[0] == pytest.approx(MU_R * F_EL * R_EFF) and res[3] == pytest.approx(-MU_R * F_EL * R_EFF)


def cdt_moment(model, n, wi, wj, lever_i=R_EFF, lever_j=R_EFF, r_eff=R_EFF):
    p, off, modes = params(model)
    kern = engine_module(rd.ContactModel("hertz", rolling=model)).rolling_moment
    g = contact_inputs(n, omega_i=wi, omega_j=wj, lever_i=lever_i, lever_j=lever_j, r_eff=r_eff, inertia_r=I_R)
    res = kern(np.zeros((1, 3)), 0, 0, g, contact_frame(*n, *n, 0.0), (F_EL, F_EL, KN, KT, 0.0), 1e-5, p, off, modes)
    return np.array(res[:3])


def test_liggghts_cdt_normalises_by_the_full_relative_rotation():
    """docs/models.md §3.2: with a twist equal to the bending rate, LIGGGHTS's CDT moment is
    M_m |dw_r| / |dw| = M_m / sqrt(2); the documented CDT keeps the full M_m."""
    n = (0.0, 0.0, 1.0)
    documented = cdt_moment(rd.CDT(), n, (1.0, 0, 1.0), (0, 0, 0))
    liggghts = cdt_moment(rd.CDT(parity="liggghts"), n, (1.0, 0, 1.0), (0, 0, 0))
    np.testing.assert_allclose(documented, [M_MAX, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(liggghts, [M_MAX / math.sqrt(2), 0, 0], rtol=1e-12)


def test_liggghts_cdt_ignores_the_wall_rotation():
    """A sphere held still on a wall turning about x: the documented CDT resists the relative
    rotation (M along -x), LIGGGHTS's code sees omega_i = 0 only and gives no moment."""
    n = (0.0, 0.0, 1.0)
    radius, overlap = 2 * R_EFF, 1e-6
    wall = dict(lever_i=radius - overlap, lever_j=0.0, r_eff=radius)
    documented = cdt_moment(rd.CDT(), n, (0, 0, 0), (2.0, 0, 0), **wall)
    liggghts = cdt_moment(rd.CDT(parity="liggghts"), n, (0, 0, 0), (2.0, 0, 0), **wall)
    np.testing.assert_allclose(documented, [-MU_R * radius * F_EL, 0, 0], rtol=1e-12)
    np.testing.assert_array_equal(liggghts, [0, 0, 0])


def test_parity_presets_compile_their_switches_as_constants():
    """The spring models' parity switches are constants of the generated kernel (the vector loop
    then computes only the branches taken): one kernel per preset, shared by the models of one
    preset; the class's own switches (stiffness, damping) stay in the parameter row."""
    from rollingdem.physics.contact.rolling import CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL

    default = engine_module(rd.ContactModel("hertz", rolling="epsd"))
    assert engine_module(rd.ContactModel("hertz", rolling="epsd2")) is default
    liggghts = engine_module(rd.ContactModel("hertz", rolling=rd.EPSD(parity="liggghts")))
    assert liggghts is not default
    assert liggghts.ROLLING_MODES == (CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL, 1)
    assert engine_module(rd.ContactModel("hertz", rolling=rd.EPSD2(parity="liggghts"))) is liggghts
