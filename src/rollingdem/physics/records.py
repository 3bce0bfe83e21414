"""The records the contact laws, the bond law and the wall geometry share with the engine: named
indices (``slots``) of a contact's inputs and results, what the normal law hands the other
sub-models, a bond's state, parameters and load, the wall kinds and a wall contact's load, and the
channels of dissipated energy. The physics functions read their rows by these names; the engine
allocates the rows."""

from __future__ import annotations

import collections


def slots(*names: str) -> tuple:
    """Named indices 0, 1, ... (a namedtuple instance): ``IN = slots("nx", "ny")``, then
    ``row[IN.ny]``; in a compiled function the index is a constant, folded when compiled."""
    return collections.namedtuple("Slots", names)(*range(len(names)))


# wall kinds (``walls.Wall.kind``) and the length of a wall's geometry row
WALL_INACTIVE = -1
WALL_PLANE = 0
WALL_CYLINDER = 1
WALL_MESH = 2  # a triangle mesh: its triangles are in the mesh arrays of ``WallArrays``, not a geometry row
WALL_GEOMETRY_SIZE = 9
#: a wall contact's load row (``WallArrays.load``, ``mesh_load``): the force on the wall (N) and its
#: moment about the origin (N m), c x F + the contact's torque on the wall (rolling, twisting), at the
#: last step; a wall's force and its torque about any point P (M - P x F) are summed from these
#: between calls of the step loop
WALL_LOAD = slots("fx", "fy", "fz", "mx", "my", "mz")
WALL_LOAD_SIZE = len(WALL_LOAD)

ENERGY_CHANNELS = ("normal_damping", "sliding", "rolling", "twisting")  # columns of the dissipated energy
# The contact's stored normal of the last step, ``hist[k, 0:3]``, before the sub-models' history.
HISTORY_FRAME = 3

# a contact's inputs, as the engine hands them to the sub-models, and its results
CONTACT_INPUTS = slots("nx", "ny", "nz", "overlap", "rvx", "rvy", "rvz", "wix", "wiy", "wiz", "wjx", "wjy", "wjz",
                       "lever_i", "lever_j", "r_eff", "m_eff", "inertia_r")
CONTACT_RESULTS = slots("fx", "fy", "fz", "tix", "tiy", "tiz", "tjx", "tjy", "tjz", "e_normal", "e_sliding", "e_rolling",
                        "e_twisting")
# what the normal law gives the other three sub-models (``normal``: force_total = elastic + damping)
NORMAL_RESULT = slots("force_elastic", "force_total", "normal_stiffness", "tangential_stiffness", "tangential_damping")
N_INPUTS = len(CONTACT_INPUTS)
N_RESULTS = len(CONTACT_RESULTS)


def contact_inputs(normal=(0.0, 0.0, 1.0), overlap=0.0, relative_velocity=(0.0, 0.0, 0.0), omega_i=(0.0, 0.0, 0.0),
                   omega_j=(0.0, 0.0, 0.0), lever_i=0.0, lever_j=0.0, r_eff=0.0, m_eff=0.0, inertia_r=0.0) -> tuple:
    """A contact's ``CONTACT_INPUTS`` tuple, as the step loop hands it to the sub-models (to call a
    sub-model's compiled function on its own, in tests)."""
    values = (*normal, overlap, *relative_velocity, *omega_i, *omega_j, lever_i, lever_j, r_eff, m_eff, inertia_r)
    return tuple(float(v) for v in values)


#: a bond's row of load and frame: F_n (N, tension positive), F_s (N, on i), M_t (N m, about n,
#: on i), M_b (N m, on i), the bond normal of the last step (j to i)
BOND_STATE = slots("normal_force", "shear_x", "shear_y", "shear_z", "twisting_moment", "bending_x", "bending_y",
                   "bending_z", "nx", "ny", "nz")
#: a bond's parameter row: its stiffnesses K_n = k_n A, K_s = k_s A (N/m), K_b = k_n I, K_t = k_s J
#: (N m/rad), section A (m^2), I, J (m^4) and radius R (m), strengths (Pa), tan(friction angle),
#: moment-contribution factor, 1.0 if the pair's contact is off while the bond holds, and the
#: dashpots' coefficients (N s/m, N m s/rad)
BOND_PARAMETERS = slots("normal_stiffness", "shear_stiffness", "bending_stiffness", "twisting_stiffness", "area",
                        "bending_inertia", "polar_inertia", "bond_radius", "tensile_strength", "cohesion",
                        "friction_tangent", "moment_factor", "exclusive", "normal_damping", "shear_damping",
                        "bending_damping", "twisting_damping")
#: a bond's load row (``ParticleArrays.bond_load``): the force on i, the torques on i and on j (the
#: force on j is minus that on i)
BOND_LOAD = slots("fx", "fy", "fz", "tix", "tiy", "tiz", "tjx", "tjy", "tjz")
BOND_LOAD_SIZE = len(BOND_LOAD)
