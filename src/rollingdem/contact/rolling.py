"""Rolling resistance sub-models (MODELS.md §3-§6, §12).

Kernel signature (slot "rolling")::

    rolling_moment(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle,
                   dwx, dwy, dwz, normal_stiffness, tangential_stiffness,
                   force_elastic, force_total, r_eff, inertia_r, dt, p, poff)
        -> (mx, my, mz, dissipation)

(dwx, dwy, dwz) is the full relative rotation rate omega_i - omega_j (omega_i - omega_wall for a
wall); a model removes the twist part itself. The resistance moment M acts as -M on particle i
and +M on particle j (MODELS.md §0), so a pure couple. ``inertia_r`` is I_r of seed report eq. 12
(1.4 m R^2 for a wall). ``dissipation`` is the energy (J) dissipated by the couple in the step.
"""

from __future__ import annotations

import math

from numba import njit

from ..errors import ParameterError, check_non_negative
from .base import P_ROLLING_DAMPING, P_ROLLING_FRICTION, SubModel
from .frame import carry_with_frame


@njit(cache=True)
def no_rolling(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle, dwx, dwy, dwz, kn, kt,
               force_elastic, force_total, r_eff, inertia_r, dt, p, poff):
    """No rolling resistance: M = 0."""
    return 0.0, 0.0, 0.0, 0.0


@njit(cache=True)
def constant_directional_torque(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle, dwx, dwy, dwz, kn, kt,
                                force_elastic, force_total, r_eff, inertia_r, dt, p, poff):
    """CDT, Ai et al. (2011) type A; seed report eq. 2; STAR-CCM+ Constant Torque.

    M = mu_r R* max(F_n,el, 0) dw_r / |dw_r|, dw_r = dw - (dw . n) n (twist removed), and with the
    optional moment limiter |M| <= f I_r |dw_r| / dt (STAR-CCM+ f = 0.08), so that the torque
    cannot reverse the relative rotation within one step (MODELS.md §11.6).
    """
    wn = dwx * nx + dwy * ny + dwz * nz
    rx = dwx - wn * nx
    ry = dwy - wn * ny
    rz = dwz - wn * nz
    rate = math.sqrt(rx * rx + ry * ry + rz * rz)
    if rate == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    moment = p[P_ROLLING_FRICTION] * r_eff * max(force_elastic, 0.0)
    limiter = p[poff]
    if limiter > 0.0:
        moment = min(moment, limiter * inertia_r * rate / dt)
    s = moment / rate
    return s * rx, s * ry, s * rz, moment * rate * dt


class NoRolling(SubModel):
    """No rolling resistance."""

    slot = "rolling"
    name = "none"
    kernel = ("rollingdem.contact.rolling", "no_rolling")


class CDT(SubModel):
    """Constant directional torque (Ai type A, LIGGGHTS ``cdt``, STAR-CCM+ Constant Torque).

    Parameters
    ----------
    limiter: moment limiter factor f (-), >= 0; 0 switches it off (LIGGGHTS). With f > 0 the
        moment is capped at f I_r |dw_r| / dt; STAR-CCM+ uses 0.08.

    CDT chatters at rest (MODELS.md §11.6); it is offered for parity, not as the default.
    """

    slot = "rolling"
    name = "cdt"
    kernel = ("rollingdem.contact.rolling", "constant_directional_torque")

    def __init__(self, limiter: float = 0.0):
        self.limiter = check_non_negative("cdt limiter", limiter)

    def pair_parameters(self, pair):
        return (self.limiter,)

    def parameters(self):
        return {"limiter": self.limiter}


# --- spring-type models: one kernel, MODELS.md §12 -----------------------------------------------
# Parameter row after the common slots (poff + k):
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


@njit(cache=True)
def spring_rolling(hist, k, off, nx, ny, nz, onx, ony, onz, spin_angle, dwx, dwy, dwz, kn, kt,
                   force_elastic, force_total, r_eff, inertia_r, dt, p, poff):
    """Elastic-plastic spring-dashpot rolling resistance (Ai type C), the unified form of MODELS.md §12.

    1. carry the spring moment M_k with the contact frame (or, for parity, not / project only);
    2. M_s = M_k + k_r dw_r dt, dw_r = dw - (dw . n) n;  M_tot = M_s + C_r dw_r;
    3. M_m = mu_r R* F_lim;  if |M_tot| > M_m: M = M_m M_tot/|M_tot|, M_k = M - f C_r dw_r
       (f = 1 keeps the damper active at full mobilisation), else M = M_tot, M_k = M_s.
       LIGGGHTS/Ai (CAP_SPRING): the test is on |M_s|; at the cap M = M_m M_s/|M_s| + f C_r dw_r, M_k = M_m M_s/|M_s|;
       below it M = M_s + C_r dw_r, uncapped (the onset spike of §11.5).
    Dissipation = M . dw_r dt - change of the stored energy |M_k|^2 / (2 k_r).
    """
    stiffness_mode = p[poff]
    coefficient = p[poff + 1]
    damping_mode = p[poff + 2]
    damping = p[poff + 3]
    slip_damping = p[poff + 4]
    cap_mode = p[poff + 5]
    force_mode = p[poff + 6]
    history_mode = p[poff + 7]
    mu_r = p[P_ROLLING_FRICTION]

    if history_mode == HISTORY_FRAME:
        carry_with_frame(hist, k, off, onx, ony, onz, nx, ny, nz, spin_angle)
    elif history_mode == HISTORY_PROJECT:
        carry_with_frame(hist, k, off, nx, ny, nz, nx, ny, nz, 0.0)
    mkx = hist[k, off]
    mky = hist[k, off + 1]
    mkz = hist[k, off + 2]

    wn = dwx * nx + dwy * ny + dwz * nz
    rx = dwx - wn * nx
    ry = dwy - wn * ny
    rz = dwz - wn * nz

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

    stored_before = 0.0
    if k_r > 0.0:
        stored_before = 0.5 * (mkx * mkx + mky * mky + mkz * mkz) / k_r
    sx = mkx + k_r * rx * dt
    sy = mky + k_r * ry * dt
    sz = mkz + k_r * rz * dt
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
    hist[k, off] = sx
    hist[k, off + 1] = sy
    hist[k, off + 2] = sz
    stored_after = 0.0
    if k_r > 0.0:
        stored_after = 0.5 * (sx * sx + sy * sy + sz * sz) / k_r
    work = (mx * rx + my * ry + mz * rz) * dt
    return mx, my, mz, work - (stored_after - stored_before)


_PARITY = {
    # parity: (cap mode, force mode, history mode, slip damping f)
    None: (CAP_TOTAL, FORCE_ELASTIC, HISTORY_FRAME, 1.0),
    "liggghts": (CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL, 0.0),
    "lammps": (CAP_TOTAL, FORCE_ABS_TOTAL, HISTORY_PROJECT, 1.0),
    "pfc": (CAP_SPRING, FORCE_ELASTIC, HISTORY_FRAME, 0.0),
}


class _SpringRolling(SubModel):
    """Shared parameter handling of the spring-type rolling models (one kernel, ``spring_rolling``)."""

    slot = "rolling"
    history_size = 3
    kernel = ("rollingdem.contact.rolling", "spring_rolling")
    parities: tuple = (None,)
    stiffness_mode = STIFFNESS_NORMAL
    damping_mode = DAMPING_RATIO

    def __init__(self, parity=None, slip_damping=None):
        if parity not in self.parities:
            allowed = ", ".join(repr(x) for x in self.parities)
            raise ParameterError(f"{self.name} parity = {parity!r} is not known: allowed are {allowed}")
        self.parity = parity
        cap, force, history, f = _PARITY[parity]
        self._modes = (cap, force, history)
        self.slip_damping = f if slip_damping is None else check_non_negative(f"{self.name} slip_damping",
                                                                             slip_damping)

    def stiffness_coefficient(self) -> float:
        return 1.0

    def damping_value(self, pair) -> float:
        return 0.0

    def pair_parameters(self, pair):
        cap, force, history = self._modes
        return (float(self.stiffness_mode), self.stiffness_coefficient(), float(self.damping_mode),
                self.damping_value(pair), self.slip_damping, float(cap), float(force), float(history))


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

    def __init__(self, damping_ratio=None, parity=None, slip_damping=None):
        super().__init__(parity, slip_damping)
        self.damping_ratio = None if damping_ratio is None else check_non_negative("epsd damping_ratio",
                                                                                    damping_ratio)

    def stiffness_coefficient(self):
        return 2.25

    def damping_value(self, pair):
        return -1.0 if self.damping_ratio is None else self.damping_ratio

    def parameters(self):
        return {"damping_ratio": self.damping_ratio, "parity": self.parity, "slip_damping": self.slip_damping}


class EPSD2(_SpringRolling):
    """EPSD2 (seed report §2.3): k_r = k_t R*^2 (Iwashita-Oda), no dashpot (Wensrich-Katterfeld)."""

    name = "epsd2"
    parities = (None, "liggghts")
    stiffness_mode = STIFFNESS_TANGENTIAL

    def parameters(self):
        return {"parity": self.parity, "slip_damping": self.slip_damping}
