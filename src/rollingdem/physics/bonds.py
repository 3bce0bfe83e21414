"""The parallel bond's law: Potyondy & Cundall's (2004) parallel bond in PFC's ``linearpbond``
form (docs/models.md §1.7), the compiled update of one bond and its strain energy.

A bond is a disc of cement of radius R = lambda min(R_i, R_j) at the contact point, carrying a
normal force F_n (tension positive), a shear force F_s, a twisting moment M_t and a bending moment
M_b, updated incrementally with the bond frame. The engine's bond pass (``bond_forces`` of the
step loop) calls ``parallel_bond`` for every intact bond; ``records.BOND_STATE`` is a bond's row of
load and frame, ``records.BOND_PARAMETERS`` its parameters (made by
``rollingdem.scene.bonds.ParallelBond``).
"""

import math

from numba import njit

from rollingdem.physics.contact.frame import carry_with_frame, contact_frame
from rollingdem.physics.records import BOND_PARAMETERS, BOND_STATE, slots


BOND_INTACT, BOND_BROKEN_TENSION, BOND_BROKEN_SHEAR = 0, 1, 2

#: the geometry of a bond: (n, v_i - v_j, w_i, w_j, lever_i, lever_j), levers R_i - delta/2 and
#: R_j - delta/2 from the centres to the contact point (delta < 0 across a gap)
BOND_INPUTS = slots("nx", "ny", "nz", "rvx", "rvy", "rvz", "wix", "wiy", "wiz", "wjx", "wjy", "wjz", "lever_i",
                    "lever_j")


@njit(cache=True)
def parallel_bond(state, b, p, g, dt):
    """One step of bond b (row ``state[b]``, parameters ``p``, inputs ``g`` = ``BOND_INPUTS``):
    the force on i, the torques on i and j, and the bond's state after the step (``BOND_INTACT``,
    or the mode it broke in: then its load is zeroed and the step's forces are 0, as PFC removes a
    broken bond with its force at once).

    1. The stored F_s and M_b are carried with the frame: tilted from the last normal to n and spun
       by 1/2 (w_i + w_j).n dt (``contact.frame``), as contact springs are.
    2. With v_c = (v_i - v_j) - (R'_i w_i + R'_j w_j) x n the relative velocity at the contact point
       and dw = w_i - w_j: F_n += K_n (v_c.n) dt; F_s -= K_s (v_c - (v_c.n) n) dt;
       M_t -= K_t (dw.n) dt; M_b -= K_b (dw - (dw.n) n) dt.
    3. On i: F = -F_n n + F_s, torque -R'_i n x F_s + M_t n + M_b; on j: -F and
       -R'_j n x F_s - M_t n - M_b.
    4. Peak stresses at the bond's rim: sigma = F_n/A + beta |M_b| R / I, tau = |F_s|/A +
       beta |M_t| R / J. It breaks in tension when sigma >= sigma_c, else in shear when
       tau >= c - (F_n/A) tan(phi) (tension weakens, compression strengthens).
    """
    nx, ny, nz = g[BOND_INPUTS.nx], g[BOND_INPUTS.ny], g[BOND_INPUTS.nz]
    wix, wiy, wiz = g[BOND_INPUTS.wix], g[BOND_INPUTS.wiy], g[BOND_INPUTS.wiz]
    wjx, wjy, wjz = g[BOND_INPUTS.wjx], g[BOND_INPUTS.wjy], g[BOND_INPUTS.wjz]
    lever_i, lever_j = g[BOND_INPUTS.lever_i], g[BOND_INPUTS.lever_j]
    onx, ony, onz = state[b, BOND_STATE.nx], state[b, BOND_STATE.ny], state[b, BOND_STATE.nz]
    if onx == 0.0 and ony == 0.0 and onz == 0.0:  # a new bond: no frame to carry from
        onx, ony, onz = nx, ny, nz
    spin = 0.5 * ((wix + wjx) * nx + (wiy + wjy) * ny + (wiz + wjz) * nz) * dt
    frame = contact_frame(onx, ony, onz, nx, ny, nz, spin)
    carry_with_frame(state, b, BOND_STATE.shear_x, frame)
    carry_with_frame(state, b, BOND_STATE.bending_x, frame)
    # relative velocity at the contact point
    sx = lever_i * wix + lever_j * wjx
    sy = lever_i * wiy + lever_j * wjy
    sz = lever_i * wiz + lever_j * wjz
    vcx = g[BOND_INPUTS.rvx] - (sy * nz - sz * ny)
    vcy = g[BOND_INPUTS.rvy] - (sz * nx - sx * nz)
    vcz = g[BOND_INPUTS.rvz] - (sx * ny - sy * nx)
    vcn = vcx * nx + vcy * ny + vcz * nz
    dwx, dwy, dwz = wix - wjx, wiy - wjy, wiz - wjz
    dwn = dwx * nx + dwy * ny + dwz * nz
    kn, ks = p[BOND_PARAMETERS.normal_stiffness], p[BOND_PARAMETERS.shear_stiffness]
    kb, kt = p[BOND_PARAMETERS.bending_stiffness], p[BOND_PARAMETERS.twisting_stiffness]
    fn = state[b, BOND_STATE.normal_force] + kn * vcn * dt
    fsx = state[b, BOND_STATE.shear_x] - ks * (vcx - vcn * nx) * dt
    fsy = state[b, BOND_STATE.shear_y] - ks * (vcy - vcn * ny) * dt
    fsz = state[b, BOND_STATE.shear_z] - ks * (vcz - vcn * nz) * dt
    mt = state[b, BOND_STATE.twisting_moment] - kt * dwn * dt
    mbx = state[b, BOND_STATE.bending_x] - kb * (dwx - dwn * nx) * dt
    mby = state[b, BOND_STATE.bending_y] - kb * (dwy - dwn * ny) * dt
    mbz = state[b, BOND_STATE.bending_z] - kb * (dwz - dwn * nz) * dt
    # the dashpots act beside the springs, on the relative motion (not stored, not in the stresses)
    cn, cs = p[BOND_PARAMETERS.normal_damping], p[BOND_PARAMETERS.shear_damping]
    cb, ct = p[BOND_PARAMETERS.bending_damping], p[BOND_PARAMETERS.twisting_damping]
    # stresses at the rim and failure
    area, radius, beta = p[BOND_PARAMETERS.area], p[BOND_PARAMETERS.bond_radius], p[BOND_PARAMETERS.moment_factor]
    sigma = fn / area + beta * math.sqrt(mbx * mbx + mby * mby + mbz * mbz) * radius / p[BOND_PARAMETERS.bending_inertia]
    tau = (math.sqrt(fsx * fsx + fsy * fsy + fsz * fsz) / area
           + beta * abs(mt) * radius / p[BOND_PARAMETERS.polar_inertia])
    mode = BOND_INTACT
    if sigma >= p[BOND_PARAMETERS.tensile_strength]:
        mode = BOND_BROKEN_TENSION
    elif tau >= p[BOND_PARAMETERS.cohesion] - fn / area * p[BOND_PARAMETERS.friction_tangent]:
        mode = BOND_BROKEN_SHEAR
    if mode != BOND_INTACT:
        fn = fsx = fsy = fsz = mt = mbx = mby = mbz = 0.0
    state[b, BOND_STATE.normal_force] = fn
    state[b, BOND_STATE.shear_x] = fsx
    state[b, BOND_STATE.shear_y] = fsy
    state[b, BOND_STATE.shear_z] = fsz
    state[b, BOND_STATE.twisting_moment] = mt
    state[b, BOND_STATE.bending_x] = mbx
    state[b, BOND_STATE.bending_y] = mby
    state[b, BOND_STATE.bending_z] = mbz
    state[b, BOND_STATE.nx] = nx
    state[b, BOND_STATE.ny] = ny
    state[b, BOND_STATE.nz] = nz
    if mode != BOND_INTACT:
        cn = cs = cb = ct = 0.0
    fn_total = fn + cn * vcn  # tension positive: opening (vcn > 0) pulls back harder
    fx = fsx - cs * (vcx - vcn * nx)
    fy = fsy - cs * (vcy - vcn * ny)
    fz = fsz - cs * (vcz - vcn * nz)
    mt_total = mt - ct * dwn
    mx = mbx - cb * (dwx - dwn * nx)
    my = mby - cb * (dwy - dwn * ny)
    mz = mbz - cb * (dwz - dwn * nz)
    # n x F_s: the shear force's lever torque
    cx = ny * fz - nz * fy
    cy = nz * fx - nx * fz
    cz = nx * fy - ny * fx
    return (-fn_total * nx + fx, -fn_total * ny + fy, -fn_total * nz + fz,
            -lever_i * cx + mt_total * nx + mx, -lever_i * cy + mt_total * ny + my,
            -lever_i * cz + mt_total * nz + mz,
            -lever_j * cx - mt_total * nx - mx, -lever_j * cy - mt_total * ny - my,
            -lever_j * cz - mt_total * nz - mz, mode)


@njit(cache=True)
def bond_energy(state, b, p):
    """The strain energy (J) of bond b: F_n^2/(2 K_n) + |F_s|^2/(2 K_s) + M_t^2/(2 K_t) + |M_b|^2/(2 K_b)."""
    s = state[b]
    return (s[BOND_STATE.normal_force] ** 2 / (2.0 * p[BOND_PARAMETERS.normal_stiffness])
            + (s[BOND_STATE.shear_x] ** 2 + s[BOND_STATE.shear_y] ** 2 + s[BOND_STATE.shear_z] ** 2)
            / (2.0 * p[BOND_PARAMETERS.shear_stiffness])
            + s[BOND_STATE.twisting_moment] ** 2 / (2.0 * p[BOND_PARAMETERS.twisting_stiffness])
            + (s[BOND_STATE.bending_x] ** 2 + s[BOND_STATE.bending_y] ** 2 + s[BOND_STATE.bending_z] ** 2)
            / (2.0 * p[BOND_PARAMETERS.bending_stiffness]))
