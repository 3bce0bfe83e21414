"""Rolling resistance sub-models (docs/models.md §3-§6, §12).

Compiled function of the slot "rolling" (arguments: docs/architecture.md; results: docs/models.md §0)::

    rolling_moment(hist, k, history_at, g, frame, normal, dt, p, params_at, modes)
        -> (mix, miy, miz, mjx, mjy, mjz, dissipation)
"""

from __future__ import annotations

import math

from numba import njit

from rollingdem.errors import ParameterError, check_non_negative, check_positive
from rollingdem.physics.records import CONTACT_INPUTS as IN
from rollingdem.physics.contact.base import P_ROLLING_DAMPING, P_ROLLING_FRICTION, SubModel, nothing_to_scale, slots
from rollingdem.physics.contact.frame import carry_with_frame, project_onto_plane
from rollingdem.physics.contact.properties import ROLLING_DAMPING, ROLLING_FRICTION


@njit(cache=True, inline="always")
def rolling_kinematics(g):
    """(n, omega_i, omega_j, lever_i, lever_j, R*, I_r) of a contact's inputs ``g``, as 13 floats."""
    return (g[IN.nx], g[IN.ny], g[IN.nz], g[IN.wix], g[IN.wiy], g[IN.wiz], g[IN.wjx], g[IN.wjy], g[IN.wjz],
            g[IN.lever_i], g[IN.lever_j], g[IN.r_eff], g[IN.inertia_r])


@njit(cache=True, inline="always")
def relative_rolling_rate(nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz):
    """dw_r = dw - (dw . n) n with dw = omega_i - omega_j: the rolling (bending) part of the relative rotation."""
    dwx = wix - wjx
    dwy = wiy - wjy
    dwz = wiz - wjz
    wn = dwx * nx + dwy * ny + dwz * nz
    return dwx - wn * nx, dwy - wn * ny, dwz - wn * nz


@njit(cache=True, inline="always")
def liggghts_wall_rate(wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff):
    """LIGGGHTS 3.8 rotation rates seen by a rolling model (docs/models.md §3.1).

    A wall contact (lever_j = 0, lever_i = R_i - delta) reads omega_i (R_i - delta/2)/(R_i - delta)
    and never the wall's own angular velocity; a pair is returned unchanged.
    """
    if lever_j != 0.0 or lever_i <= 0.0:
        return wix, wiy, wiz, wjx, wjy, wjz
    factor = 0.5 * (r_eff + lever_i) / lever_i
    return factor * wix, factor * wiy, factor * wiz, 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def no_rolling(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
    """No rolling resistance: M = 0."""
    return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0


CDT_PARAMETERS = slots("limiter", "liggghts_parity")


@njit(cache=True, inline="always")
def constant_directional_torque(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
    """CDT, Ai et al. (2011) type A; seed report eq. 2; STAR-CCM+ Constant Torque.

    M = mu_r R* max(F_n,el, 0) dw_r / |dw_r|, dw_r = dw - (dw . n) n (twist removed), and with the
    optional moment limiter |M| <= f I_r |dw_r| / dt (STAR-CCM+ f = 0.08), so that the torque
    cannot reverse the relative rotation within one step (docs/models.md §11.6).
    LIGGGHTS parity (``liggghts_parity`` = 1) divides by the full |dw| and projects afterwards, so a twist
    shrinks the moment by |dw_r|/|dw|, and walls read omega_i (R - delta/2)/(R - delta) without
    the wall's rotation (docs/models.md §3.2, §12 ``liggghts_cdt``).
    """
    nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, inertia_r = rolling_kinematics(g)
    force_elastic, force_total, kn, kt, _ = normal
    if p[params_at + CDT_PARAMETERS.liggghts_parity] != 0.0:
        wix, wiy, wiz, wjx, wjy, wjz = liggghts_wall_rate(wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff)
    rx, ry, rz = relative_rolling_rate(nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz)
    rate = math.sqrt(rx * rx + ry * ry + rz * rz)
    if rate == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    norm = rate
    if p[params_at + CDT_PARAMETERS.liggghts_parity] != 0.0:
        dwx = wix - wjx
        dwy = wiy - wjy
        dwz = wiz - wjz
        norm = math.sqrt(dwx * dwx + dwy * dwy + dwz * dwz)
    moment = p[P_ROLLING_FRICTION] * r_eff * max(force_elastic, 0.0) * rate / norm
    limiter = p[params_at + CDT_PARAMETERS.limiter]
    if limiter > 0.0:
        moment = min(moment, limiter * inertia_r * rate / dt)
    s = moment / rate
    return s * rx, s * ry, s * rz, s * rx, s * ry, s * rz, moment * rate * dt


class NoRolling(SubModel):
    """No rolling resistance."""

    slot = "rolling"
    name = "none"
    function = staticmethod(no_rolling)
    coarse_graining_exponents = nothing_to_scale


class CDT(SubModel):
    """Constant directional torque (Ai type A, LIGGGHTS ``cdt``, STAR-CCM+ Constant Torque).

    Parameters
    ----------
    limiter: moment limiter factor f (-), >= 0; 0 switches it off (LIGGGHTS). With f > 0 the
        moment is capped at f I_r |dw_r| / dt; STAR-CCM+ uses 0.08.
    parity: None (the seed report's eq. 2 as documented) or "liggghts" (LIGGGHTS 3.8 code:
        normalised by the full |dw|, wall rotation ignored, docs/models.md §3.2).

    CDT chatters at rest (docs/models.md §11.6); it is offered for parity, not as the default.
    """

    slot = "rolling"
    name = "cdt"
    material_properties = (ROLLING_FRICTION,)
    parameters = CDT_PARAMETERS
    function = staticmethod(constant_directional_torque)
    validation_presets = {"cdt": {}, "cdt (liggghts)": {"parity": "liggghts"}, "cdt (limiter 0.08)": {"limiter": 0.08}}

    parities = (None, "liggghts")

    def __init__(self, limiter: float = 0.0, parity=None):
        self.limiter = check_non_negative("cdt limiter", limiter)
        self.parity = check_parity(self.name, parity, self.parities)

    def pair_values(self, pair):
        return (self.limiter, 1.0 if self.parity == "liggghts" else 0.0)

    def coarse_graining_exponents(self):
        return (0, 0)  # M = mu_r R* F_n scales as alpha^3 by itself; the limiter f is a ratio

    def settings(self):
        return {"limiter": self.limiter, "parity": self.parity}


# --- spring-type models: one compiled function, docs/models.md §12 ---------------------------------
SPRING_PARAMETERS = slots("stiffness_mode", "stiffness_coefficient", "damping_mode", "damping", "slip_damping")
SPRING_HISTORY = slots("moment_x", "moment_y", "moment_z")  # the spring moment M_k (N m)
# values of stiffness_mode and damping_mode:
STIFFNESS_NORMAL = 0      # k_r = c k_n mu_r^2 R*^2               (Ai / LIGGGHTS epsd, epsd3)
STIFFNESS_TANGENTIAL = 1  # k_r = c k_t R*^2                       (Iwashita-Oda: epsd2, PFC rrlinear)
STIFFNESS_GIVEN = 2       # k_r = c R*^2, c = k_roll (N/m)          (LAMMPS rolling sds)
STIFFNESS_MOBILISED = 3   # k_r = mu_r R* F_lim / c, c = theta_max  (STAR-CCM+ displacement damping)
DAMPING_RATIO = 0         # C_r = d 2 sqrt(I_r k_r), d = eta_r (< 0: the pair's rolling_damping)
DAMPING_GIVEN = 1         # C_r = d R*^2, d = gamma_roll (N s/m)
CAP_TOTAL = 0             # |spring + dashpot| <= M_m, spring backed out (LAMMPS, recommended)
CAP_SPRING = 1            # |spring| <= M_m, dashpot added uncapped in the elastic regime (LIGGGHTS, Ai)
FORCE_ELASTIC = 0         # F_lim = max(F_n,el, 0) (recommended; PFC)
FORCE_ABS_TOTAL = 1       # F_lim = |F_n,el + F_n,damp| (LIGGGHTS, LAMMPS)
HISTORY_FRAME = 0         # rotate with the contact frame and spin (recommended; PFC's contact-plane frame)
HISTORY_GLOBAL = 1        # never rotated (LIGGGHTS)
HISTORY_PROJECT = 2       # projected on the tangent plane and rescaled (LAMMPS)


@njit(cache=True, inline="always")
def spring_rolling(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
    """Elastic-plastic spring-dashpot rolling resistance (Ai type C), the unified form of docs/models.md §12.

    1. carry the spring moment M_k with the contact frame (or, for parity, not / project only);
    2. M_s = M_k + k_r dw_r dt, dw_r = dw - (dw . n) n;  M_tot = M_s + C_r dw_r;
    3. M_m = mu_r R* F_lim;  if |M_tot| > M_m: M = M_m M_tot/|M_tot|, M_k = M - f C_r dw_r
       (f = 1 keeps the damper active at full mobilisation), else M = M_tot, M_k = M_s.
       LIGGGHTS/Ai (CAP_SPRING): the test is on |M_s|; at the cap M = M_m M_s/|M_s| + f C_r dw_r, M_k = M_m M_s/|M_s|;
       below it M = M_s + C_r dw_r, uncapped (the onset spike of §11.5).
    Dissipation: the work of M minus the energy the spring stores (midpoint rule for the elastic
    trial step, so a purely elastic exchange dissipates only its O(k_r |dw_r|^2 dt^2) residual, never
    less than zero below the cap; at the cap, with f C_r dw_r against the spring, M_k can store more
    than the trial step gave it, and the step's dissipation is negative by that much).
    """
    nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, inertia_r = rolling_kinematics(g)
    force_elastic, force_total, kn, kt, _ = normal
    cap_mode, force_mode, history_mode, wall_rate = modes  # the parity's switches, constants
    stiffness_mode = p[params_at + SPRING_PARAMETERS.stiffness_mode]  # the class's (a branch on them costs
    coefficient = p[params_at + SPRING_PARAMETERS.stiffness_coefficient]  # nothing measurable)
    damping_mode = p[params_at + SPRING_PARAMETERS.damping_mode]
    damping = p[params_at + SPRING_PARAMETERS.damping]
    slip_damping = p[params_at + SPRING_PARAMETERS.slip_damping]
    mu_r = p[P_ROLLING_FRICTION]
    if wall_rate:
        wix, wiy, wiz, wjx, wjy, wjz = liggghts_wall_rate(wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff)

    if history_mode == HISTORY_FRAME:
        carry_with_frame(hist, k, history_at, frame)
    elif history_mode == HISTORY_PROJECT:
        project_onto_plane(hist, k, history_at, nx, ny, nz)
    mkx = hist[k, history_at + SPRING_HISTORY.moment_x]
    mky = hist[k, history_at + SPRING_HISTORY.moment_y]
    mkz = hist[k, history_at + SPRING_HISTORY.moment_z]

    rx, ry, rz = relative_rolling_rate(nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz)

    if force_mode == FORCE_ELASTIC:
        f_lim = max(force_elastic, 0.0)
    else:
        f_lim = abs(force_total)
    moment_max = mu_r * r_eff * f_lim

    if stiffness_mode == STIFFNESS_NORMAL:
        k_r = coefficient * kn * mu_r * mu_r * r_eff * r_eff
    elif stiffness_mode == STIFFNESS_TANGENTIAL:
        k_r = coefficient * kt * r_eff * r_eff
    elif stiffness_mode == STIFFNESS_GIVEN:
        k_r = coefficient * r_eff * r_eff
    else:
        k_r = moment_max / coefficient
    if damping_mode == DAMPING_GIVEN:
        c_r = damping * r_eff * r_eff
    else:
        eta = damping if damping >= 0.0 else p[P_ROLLING_DAMPING]
        c_r = eta * 2.0 * math.sqrt(inertia_r * k_r)

    sx = mkx + k_r * rx * dt
    sy = mky + k_r * ry * dt
    sz = mkz + k_r * rz * dt
    trial_x, trial_y, trial_z = sx, sy, sz
    if cap_mode == CAP_TOTAL:
        mx = sx + c_r * rx
        my = sy + c_r * ry
        mz = sz + c_r * rz
        m2 = mx * mx + my * my + mz * mz
        if m2 > moment_max * moment_max:
            s = moment_max / math.sqrt(m2)
            mx *= s
            my *= s
            mz *= s
            sx = mx - slip_damping * c_r * rx
            sy = my - slip_damping * c_r * ry
            sz = mz - slip_damping * c_r * rz
    else:
        s2 = sx * sx + sy * sy + sz * sz
        if s2 > moment_max * moment_max:
            s = moment_max / math.sqrt(s2)
            sx *= s
            sy *= s
            sz *= s
            mx = sx + slip_damping * c_r * rx
            my = sy + slip_damping * c_r * ry
            mz = sz + slip_damping * c_r * rz
        else:
            mx = sx + c_r * rx
            my = sy + c_r * ry
            mz = sz + c_r * rz
    hist[k, history_at + SPRING_HISTORY.moment_x] = sx
    hist[k, history_at + SPRING_HISTORY.moment_y] = sy
    hist[k, history_at + SPRING_HISTORY.moment_z] = sz
    # The elastic trial step stores exactly the midpoint work 1/2 (M_k + M_trial) . dw_r dt; the rest
    # of the work done by M, and the spring energy released by the cap, are dissipated.
    dissipated = ((mx - 0.5 * (mkx + trial_x)) * rx + (my - 0.5 * (mky + trial_y)) * ry
                  + (mz - 0.5 * (mkz + trial_z)) * rz) * dt
    if k_r > 0.0:
        dissipated += 0.5 * ((trial_x * trial_x + trial_y * trial_y + trial_z * trial_z)
                             - (sx * sx + sy * sy + sz * sz)) / k_r
    return mx, my, mz, mx, my, mz, dissipated


_PARITY = {
    # parity: (cap mode, force mode, history mode, LIGGGHTS wall rate, slip damping f)
    None: (CAP_TOTAL, FORCE_ELASTIC, HISTORY_FRAME, 0, 1.0),
    "liggghts": (CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL, 1, 0.0),
    "lammps": (CAP_TOTAL, FORCE_ABS_TOTAL, HISTORY_PROJECT, 0, 1.0),
    "pfc": (CAP_SPRING, FORCE_ELASTIC, HISTORY_FRAME, 0, 0.0),
}


def check_parity(model_name, parity, allowed):
    """The parity preset name, or a ParameterError naming the allowed ones."""
    if parity not in allowed:
        names = ", ".join(repr(x) for x in allowed)
        raise ParameterError(f"{model_name} parity = {parity!r} is not known: allowed are {names}")
    return parity


class _SpringRolling(SubModel):
    """Shared parameter handling of the spring-type rolling models (one compiled function, ``spring_rolling``)."""

    slot = "rolling"
    parameters = SPRING_PARAMETERS
    history = SPRING_HISTORY
    material_properties = (ROLLING_FRICTION, ROLLING_DAMPING)
    function = staticmethod(spring_rolling)
    parities: tuple = (None,)
    stiffness_mode = STIFFNESS_NORMAL
    damping_mode = DAMPING_RATIO

    def __init__(self, parity=None, slip_damping=None):
        self.parity = check_parity(self.name, parity, self.parities)
        cap, force, history, wall_rate, f = _PARITY[parity]
        self._modes = (cap, force, history, wall_rate)
        self.slip_damping = f if slip_damping is None else check_non_negative(f"{self.name} slip_damping",
                                                                             slip_damping)

    def stiffness_coefficient(self) -> float:
        return 1.0

    def damping_value(self, pair) -> float:
        return 0.0

    def rotational_stiffness(self, normal_stiffness, tangential_stiffness, r_eff, overlap, normal_force, pair):
        c = self.stiffness_coefficient()
        if self.stiffness_mode == STIFFNESS_NORMAL:
            return c * normal_stiffness * pair.rolling_friction ** 2 * r_eff ** 2
        if self.stiffness_mode == STIFFNESS_TANGENTIAL:
            return c * tangential_stiffness * r_eff ** 2
        if self.stiffness_mode == STIFFNESS_GIVEN:
            return self.pair_row(pair)[SPRING_PARAMETERS.stiffness_coefficient] * r_eff ** 2  # as the parcels meet it
        return pair.rolling_friction * r_eff * normal_force / c

    def pair_values(self, pair):
        return (float(self.stiffness_mode), self.stiffness_coefficient(), float(self.damping_mode),
                self.damping_value(pair), self.slip_damping)

    def coarse_graining_exponents(self):
        # k_r from k_n or k_t and R*^2 scales as alpha^3 by itself, and the dashpot's ratio keeps its
        # value; a given stiffness (N/m) scales as alpha and a given damping (N s/m) as alpha^2
        given = self.stiffness_mode == STIFFNESS_GIVEN
        return (0, 1 if given else 0, 0, 2 if self.damping_mode == DAMPING_GIVEN else 0, 0)

    def kernel_modes(self):
        """(cap, force, history, wall rate): the parity preset's switches, one engine module per preset."""
        return self._modes


class EPSD(_SpringRolling):
    """Elastic-plastic spring-dashpot, Ai et al. (2011) type C; seed report §2.2 (LIGGGHTS ``epsd``).

    k_r = 2.25 k_n mu_r^2 R*^2 (seed report eq. 18); C_r = eta_r 2 sqrt(I_r k_r) (eqs. 10-12) with
    eta_r the pair's ``rolling_damping`` unless ``damping_ratio`` is given; the dashpot keeps acting
    at full mobilisation with ``slip_damping`` f (default 1; Ai and LIGGGHTS use 0).
    Default: the recommended formulation (frame-carried history, total moment capped at
    mu_r R* max(F_n,el, 0)). ``parity="liggghts"`` reproduces LIGGGHTS 3.8 (spring-only cap,
    uncapped dashpot below it, |F_n,total|, unrotated history).
    """

    name = "epsd"
    parities = (None, "liggghts")
    validation_presets = {"epsd": {}, "epsd (liggghts)": {"parity": "liggghts"}}

    def __init__(self, damping_ratio=None, parity=None, slip_damping=None):
        super().__init__(parity, slip_damping)
        self.damping_ratio = None if damping_ratio is None else check_non_negative("epsd damping_ratio",
                                                                                    damping_ratio)

    def stiffness_coefficient(self):
        return 2.25

    def damping_value(self, pair):
        return -1.0 if self.damping_ratio is None else self.damping_ratio

    def settings(self):
        return {"damping_ratio": self.damping_ratio, "parity": self.parity, "slip_damping": self.slip_damping}


class EPSD2(_SpringRolling):
    """EPSD2 (seed report §2.3): k_r = k_t R*^2 (Iwashita-Oda), no dashpot (Wensrich-Katterfeld)."""

    name = "epsd2"
    parities = (None, "liggghts")
    stiffness_mode = STIFFNESS_TANGENTIAL

    def settings(self):
        return {"parity": self.parity, "slip_damping": self.slip_damping}


class EPSD3(_SpringRolling):
    """LIGGGHTS ``epsd3``: as EPSD with k_r = c k_n mu_r^2 R*^2, c = ``stiffness_coefficient`` (-)."""

    name = "epsd3"
    parities = (None, "liggghts")

    def __init__(self, stiffness_coefficient=2.25, damping_ratio=None, parity=None, slip_damping=None):
        super().__init__(parity, slip_damping)
        self.stiffness_coefficient_value = check_positive("epsd3 stiffness_coefficient", stiffness_coefficient)
        self.damping_ratio = None if damping_ratio is None else check_non_negative("epsd3 damping_ratio",
                                                                                    damping_ratio)

    def stiffness_coefficient(self):
        return self.stiffness_coefficient_value

    def damping_value(self, pair):
        return -1.0 if self.damping_ratio is None else self.damping_ratio

    def settings(self):
        return {"stiffness_coefficient": self.stiffness_coefficient_value, "damping_ratio": self.damping_ratio,
                "parity": self.parity, "slip_damping": self.slip_damping}


class RRLinear(_SpringRolling):
    """PFC rolling resistance linear model (PFC seed; docs/models.md §5): k_r = k_s R^2 (Iwashita-Oda),
    moment capped at mu_r R F_n,linear (elastic), no rolling dashpot, moment kept in the contact
    frame. Meant with the ``linear`` normal model; ``parity="pfc"`` caps the spring only (the same
    thing here, as there is no dashpot)."""

    name = "rrlinear"
    parities = (None, "pfc")
    stiffness_mode = STIFFNESS_TANGENTIAL

    def settings(self):
        return {"parity": self.parity}


class SDS(_SpringRolling):
    """LAMMPS ``rolling sds k_roll gamma_roll mu_roll`` (docs/models.md §4): torque stiffness k_roll R*^2,
    torque damping gamma_roll R*^2, limit mu_r R* F (mu_roll = the pair's rolling_friction).
    ``parity="lammps"``: |F_n,total| in the limit and project-and-rescale history.

    rolling_stiffness: k_roll (N/m), > 0.  rolling_damping: gamma_roll (N s/m), >= 0.
    """

    name = "sds"
    parities = (None, "lammps")
    stiffness_mode = STIFFNESS_GIVEN
    damping_mode = DAMPING_GIVEN

    def __init__(self, rolling_stiffness, rolling_damping=0.0, parity=None):
        super().__init__(parity, None)
        self.rolling_stiffness = check_positive("sds rolling_stiffness", rolling_stiffness, "N/m")
        self.rolling_damping = check_non_negative("sds rolling_damping", rolling_damping, "N s/m")

    def stiffness_coefficient(self):
        return self.rolling_stiffness

    def damping_value(self, pair):
        return self.rolling_damping

    def settings(self):
        return {"rolling_stiffness": self.rolling_stiffness, "rolling_damping": self.rolling_damping,
                "parity": self.parity}


class DisplacementDamping(_SpringRolling):
    """STAR-CCM+ Displacement Damping (seed 004; docs/models.md §6.3): spring torque with
    k_r = mu_r R* F_n / theta_max, so that it mobilises at theta_max, plus an optional viscous
    damper nu 2 sqrt(I_r k_r), multiplied by f at full mobilisation.

    theta_max: (rad), > 0; STAR's default 0.035.  damping: nu (-), >= 0, 0 = damper off.
    slip_damping: f (-), >= 0.
    """

    name = "displacement_damping"
    parities = (None,)
    stiffness_mode = STIFFNESS_MOBILISED

    def __init__(self, theta_max=0.035, damping=0.0, slip_damping=1.0):
        super().__init__(None, slip_damping)
        self.theta_max = check_positive("displacement_damping theta_max", theta_max, "rad")
        self.damping = check_non_negative("displacement_damping damping", damping)

    def stiffness_coefficient(self):
        return self.theta_max

    def damping_value(self, pair):
        return self.damping

    def settings(self):
        return {"theta_max": self.theta_max, "damping": self.damping, "slip_damping": self.slip_damping}


@njit(cache=True, inline="always")
def force_proportional_moment(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
    """STAR-CCM+ Force Proportional (seed 004, eq. 3275): each particle's own in-plane spin is
    opposed by mu_r |F_n| |r_c| omega_p / |omega_p|, |r_c| = R' (centre to contact point).
    Not objective (a rigidly co-rotating pair is braked: docs/models.md §11.1); offered for parity."""
    nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, inertia_r = rolling_kinematics(g)
    force_elastic, force_total, kn, kt, _ = normal
    f = max(force_elastic, 0.0) * p[P_ROLLING_FRICTION]
    wn = wix * nx + wiy * ny + wiz * nz
    ax = wix - wn * nx
    ay = wiy - wn * ny
    az = wiz - wn * nz
    a = math.sqrt(ax * ax + ay * ay + az * az)
    si = f * lever_i / a if a > 0.0 else 0.0
    wn = wjx * nx + wjy * ny + wjz * nz
    bx = wjx - wn * nx
    by = wjy - wn * ny
    bz = wjz - wn * nz
    b = math.sqrt(bx * bx + by * by + bz * bz)
    sj = -f * lever_j / b if b > 0.0 else 0.0
    dissipated = (si * a * a - sj * b * b) * dt
    return si * ax, si * ay, si * az, sj * bx, sj * by, sj * bz, dissipated


class ForceProportional(SubModel):
    """STAR-CCM+ Force Proportional method (its default rolling resistance; STAR's default mu_r 0.001)."""

    slot = "rolling"
    name = "force_proportional"
    material_properties = (ROLLING_FRICTION,)
    function = staticmethod(force_proportional_moment)
    coarse_graining_exponents = nothing_to_scale


VISCOUS_PARAMETERS = slots("coefficient", "kratos_form")


@njit(cache=True, inline="always")
def viscous_moment(hist, k, history_at, g, frame, normal, dt, p, params_at, modes):
    """Viscous rolling resistance, Ai type B (Zhou et al. 1999 eq. 4): M = c_v F_n (R* |dw_r|) dw_r/|dw_r|
    = c_v F_n R* dw_r, c_v in s; in the Kratos/Lethe form one more factor R* (c_v in s/m).
    It vanishes at rest: it cannot hold a static pile (docs/models.md §13 T5)."""
    nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, inertia_r = rolling_kinematics(g)
    force_elastic, force_total, kn, kt, _ = normal
    rx, ry, rz = relative_rolling_rate(nx, ny, nz, wix, wiy, wiz, wjx, wjy, wjz)
    s = p[params_at + VISCOUS_PARAMETERS.coefficient] * max(force_elastic, 0.0) * r_eff
    if p[params_at + VISCOUS_PARAMETERS.kratos_form] > 0.0:
        s *= r_eff
    return s * rx, s * ry, s * rz, s * rx, s * ry, s * rz, s * (rx * rx + ry * ry + rz * rz) * dt


class Viscous(SubModel):
    """Viscous rolling resistance (Ai type B).

    coefficient: c_v (s for form="zhou", s/m for form="kratos"), >= 0.
    """

    slot = "rolling"
    name = "viscous"
    parameters = VISCOUS_PARAMETERS
    function = staticmethod(viscous_moment)

    def __init__(self, coefficient=0.0, form="zhou"):
        self.coefficient = check_non_negative("viscous coefficient", coefficient, "s" if form == "zhou" else "s/m")
        if form not in ("zhou", "kratos"):
            raise ParameterError(f"viscous form = {form!r} is not known: allowed are 'zhou', 'kratos'")
        self.form = form

    def pair_values(self, pair):
        return (self.coefficient, 1.0 if self.form == "kratos" else 0.0)

    def coarse_graining_exponents(self):
        # M = c_v F_n R* dw (zhou) must scale as alpha^3 with F_n ~ alpha^2, R* ~ alpha and spins
        # ~ 1/alpha (velocities kept): c_v ~ alpha; the kratos form's extra R* makes up for it
        return (0 if self.form == "kratos" else 1, 0)

    def settings(self):
        return {"coefficient": self.coefficient, "form": self.form}
