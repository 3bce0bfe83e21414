"""The step loop's template, its first part: the contact law's compiled functions and row layout
(the lines tagged ``# @@``, filled in per law), and one contact through the law.

``rollingdem.engine.codegen`` writes one module per contact law from the parts of
``rollingdem.engine.template`` in order; as it stands each part is a valid module (Hertz, history,
no rolling, no twisting). The step loop takes four records of arrays (``rollingdem.engine.schema``,
``rollingdem.engine.layout``), allocates nothing and calls no Python. The step and the contract:
docs/architecture.md; what each choice is worth: docs/performance.md.
"""

from numba import njit

from rollingdem.physics.records import CONTACT_INPUTS as IN, N_INPUTS, N_RESULTS
from rollingdem.physics.contact.frame import contact_frame, spin_angle
from rollingdem.physics.contact.normal import hertz_normal as normal_force  # @@NORMAL
from rollingdem.physics.contact.tangential import history_spring as tangential_force  # @@TANGENTIAL
from rollingdem.physics.contact.rolling import no_rolling as rolling_moment  # @@ROLLING
from rollingdem.physics.contact.twisting import no_twisting as twisting_moment  # @@TWISTING
from rollingdem.physics.contact.cohesion import no_cohesion as cohesion_force  # @@COHESION

NORMAL_PARAMS = 6  # @@NORMAL_PARAMS
TANGENTIAL_PARAMS = 8  # @@TANGENTIAL_PARAMS
ROLLING_PARAMS = 8  # @@ROLLING_PARAMS
TWISTING_PARAMS = 8  # @@TWISTING_PARAMS
COHESION_PARAMS = 8  # @@COHESION_PARAMS
NORMAL_HISTORY = 3  # @@NORMAL_HISTORY
TANGENTIAL_HISTORY = 3  # @@TANGENTIAL_HISTORY
ROLLING_HISTORY = 6  # @@ROLLING_HISTORY
TWISTING_HISTORY = 6  # @@TWISTING_HISTORY
COHESION_HISTORY = 6  # @@COHESION_HISTORY
DETACH_AT = -1  # @@DETACH_AT
TRACK_ENERGY = 1  # @@TRACK_ENERGY
# whether the scene holds bonds: an engine module of its own, as the per-entry bond check (an exclusive bond
# keeps its pair's contact off, a parallel one its rolling and twisting moments) costs the pair pass
# of every other scene a third
BONDED_PAIRS = 0  # @@BONDED_PAIRS
# whether the scene holds triangle meshes, clumps: without them the step loop compiles none of their
# passes (a module of its own, as for BONDED_PAIRS; the bond pass and the bond gather likewise
# follow BONDED_PAIRS). A module made for a scene without them must not step one with them
# (``EngineState.advance`` checks)
MESHES = 1  # @@MESHES
CLUMPS = 1  # @@CLUMPS
# whether a plane or cylinder follows a motion program (``engine.wall_motion``): without one the
# step loop moves the walls at their velocity alone and compiles no program
PROGRAMS = 1  # @@PROGRAMS
ROLLING_MODES = ()  # @@ROLLING_MODES
HISTORY_SIZE = 6  # @@HISTORY_SIZE
N_PARAMS = 8  # @@N_PARAMS

# Indices in the hot loops are unsigned (``uint64(k)``): Numba gives a signed index Python's
# wraparound for negative values, a compare and a select per index (40 % of the candidate loop).

B_IN = HISTORY_SIZE  # block buffer columns: history, inputs, results, the scalar contact's results
B_OUT = B_IN + N_INPUTS
B_SCALAR = B_OUT + N_RESULTS
BLOCK_COLUMNS = B_SCALAR + N_RESULTS
CANDIDATE_SLACK = 1.0 + 1e-12
GATHER_RUN = 256  # particles per call of gather_rows: the call is negligible, the threads stay balanced
INERTIA_R_FACTOR = 1.4  # I + m R^2 = 1.4 m R^2 for a solid sphere (seed report eq. 12)


@njit(cache=True, inline="always")
def contact_of(hist, k, g, p, dt, moments):
    """One contact, its inputs ``g`` (``CONTACT_INPUTS``): the ``CONTACT_RESULTS`` (force on i,
    torque on i, torque on j, dissipated energies). (rvx, rvy, rvz) is the velocity of i's centre
    relative to j's centre (for a wall: relative to the wall's surface velocity at the contact,
    with lever_j = 0). Without ``moments`` (a compile-time constant) no rolling or twisting moment."""
    nx, ny, nz = g[IN.nx], g[IN.ny], g[IN.nz]
    onx = hist[k, 0]
    ony = hist[k, 1]
    onz = hist[k, 2]
    # ``stored_normal`` with a branch: its selects give the same values, but move the compiler's
    # fused multiply-adds, and the scalar path would change at round-off
    if onx == 0.0 and ony == 0.0 and onz == 0.0:
        onx = nx
        ony = ny
        onz = nz
    frame = contact_frame(onx, ony, onz, nx, ny, nz, spin_angle(nx, ny, nz, g[IN.wix], g[IN.wiy], g[IN.wiz], g[IN.wjx],
                                                                g[IN.wjy], g[IN.wjz], dt))
    return contact_in_frame(hist, k, frame, g, p, dt, moments)


# ``no_cpython_wrapper``: a function only compiled code calls has no Python entry (its Python entry
# costs compile time; called from Python, such a function crashes: the CUDA simulator's kernels call
# ``gather_rows`` and ``pair_rows_scalar`` from Python, so those keep theirs)
@njit(cache=True, no_cpython_wrapper=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def contact(hist, k, g, p, dt):
    """``contact_of`` with every moment."""
    return contact_of(hist, k, g, p, dt, True)


@njit(cache=True, no_cpython_wrapper=True, _nrt=False, error_model="numpy", fastmath={"contract"})
def bonded_contact(hist, k, g, p, dt):
    """The contact of a pair held by an intact ``parallel`` bond: no rolling or twisting moment (the
    bond's bending and twisting springs resist that motion, docs/models.md §1.7), and their
    history stays zero, so that they start fresh at the break."""
    return contact_of(hist, k, g, p, dt, False)


@njit(cache=True, inline="always")
def contact_in_frame(hist, k, frame, g, p, dt, moments):
    """The body of ``contact`` once the frame change is known."""
    (nx, ny, nz, overlap, rvx, rvy, rvz, wix, wiy, wiz, wjx, wjy, wjz, lever_i, lever_j, r_eff, m_eff,
     inertia_r) = g
    vn = rvx * nx + rvy * ny + rvz * nz
    # slip velocity at the contact point: v_c = (v_i - v_j) - (R'_i w_i + R'_j w_j) x n
    sx = lever_i * wix + lever_j * wjx
    sy = lever_i * wiy + lever_j * wjy
    sz = lever_i * wiz + lever_j * wjz
    vcx = rvx - (sy * nz - sz * ny)
    vcy = rvy - (sz * nx - sx * nz)
    vcz = rvz - (sx * ny - sy * nx)
    vcn = vcx * nx + vcy * ny + vcz * nz
    vtx = vcx - vcn * nx
    vty = vcy - vcn * ny
    vtz = vcz - vcn * nz

    # a contact kept past touching (DETACH_AT >= 0) reaches the normal law at zero overlap
    f_el, f_damp, kn, kt, gamma_t, e_n = normal_force(hist, k, NORMAL_HISTORY, max(overlap, 0.0) if DETACH_AT >= 0
                                                      else overlap, vn, r_eff, m_eff, p, NORMAL_PARAMS)
    fn = f_el + f_damp
    normal = (f_el, fn, kn, kt, gamma_t)  # NORMAL_RESULT
    f_coh, e_coh = cohesion_force(hist, k, COHESION_HISTORY, g, normal, p, COHESION_PARAMS)
    fn += f_coh
    ftx, fty, ftz, e_t = tangential_force(hist, k, TANGENTIAL_HISTORY, g, frame, (vtx, vty, vtz), normal, dt, p,
                                          TANGENTIAL_PARAMS)
    mix = miy = miz = mjx = mjy = mjz = e_r = m_tw = e_tw = 0.0
    if moments:
        mix, miy, miz, mjx, mjy, mjz, e_r = rolling_moment(hist, k, ROLLING_HISTORY, g, frame, normal, dt, p,
                                                           ROLLING_PARAMS, ROLLING_MODES)
        m_tw, e_tw = twisting_moment(hist, k, TWISTING_HISTORY, g, normal, dt, p, TWISTING_PARAMS)
    hist[k, 0] = nx
    hist[k, 1] = ny
    hist[k, 2] = nz

    # torque of F_t at the contact point: -R'_i n x F_t on i, -R'_j n x F_t on j
    cx = ny * ftz - nz * fty
    cy = nz * ftx - nx * ftz
    cz = nx * fty - ny * ftx
    return (fn * nx + ftx, fn * ny + fty, fn * nz + ftz,
            -lever_i * cx - mix - m_tw * nx, -lever_i * cy - miy - m_tw * ny, -lever_i * cz - miz - m_tw * nz,
            -lever_j * cx + mjx + m_tw * nx, -lever_j * cy + mjy + m_tw * ny, -lever_j * cz + mjz + m_tw * nz,
            e_n + e_coh - f_damp * vn * dt if TRACK_ENERGY else 0.0, e_t if TRACK_ENERGY else 0.0,
            e_r if TRACK_ENERGY else 0.0, e_tw if TRACK_ENERGY else 0.0)


#: the sums of no contact: force and torque on i, the four dissipated energies, the count
NO_CONTACT = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0)


@njit(cache=True, inline="always")
def add_contact(sums, res):
    """``sums`` (as ``NO_CONTACT``) with one contact's ``CONTACT_RESULTS`` added: its force and
    torque on i, its dissipated energies, one contact more."""
    return (sums[0] + res[0], sums[1] + res[1], sums[2] + res[2], sums[3] + res[3], sums[4] + res[4],
            sums[5] + res[5], sums[6] + res[9], sums[7] + res[10], sums[8] + res[11], sums[9] + res[12],
            sums[10] + 1)


@njit(cache=True, inline="always")
def add_energies_and_count(i, particles, sums):
    """Particle i's dissipated energies and contact count with those of ``sums`` (as
    ``NO_CONTACT``) added."""
    if TRACK_ENERGY:
        particles.energy[i, 0] += sums[6]
        particles.energy[i, 1] += sums[7]
        particles.energy[i, 2] += sums[8]
        particles.energy[i, 3] += sums[9]
    particles.contacts[i] += sums[10]
