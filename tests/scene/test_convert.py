"""rd.convert: other codes' rolling parameters give the same trajectory as the rollingdem model
they are claimed to equal (docs/models.md §12, §13 T6(f)).

Every comparison uses the linear contact (constant k_s), so that EPSD2's k_r = k_s R*^2 is a
constant and the two runs differ only in how the same numbers are computed: they must agree to
round-off. A deliberately wrong conversion (a factor 2 in mu_r or 4 in k_r) must not agree, so
that the comparisons can fail.
"""

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.scene import convert
from conftest import R, TABLE1

KN = 2e4
KS = 2.0 / 7.0 * KN
MU, MU_R = 0.8, 0.2
# Round-off: k_r computed as k_s R*^2 or as (alpha k_s R1 R2 / R*^2) R*^2 differs in the last bits;
# over a few thousand steps of a stable (non-chaotic) run this stays far below 1e-9 relative.
ROUND_OFF = 1e-9


def contact(rolling):
    return rd.ContactModel(rd.Linear(KN, KS), rolling=rolling)


def model_and_material(params, rolling, material, restitution):
    """The rolling model and the Table-1 material, from a conversion result or given directly."""
    model = params.model if params is not None else rolling
    kw = dict(friction=MU, restitution=restitution, **(params.material_kwargs() if params is not None else material))
    return model, rd.Material("m", **TABLE1, **kw)


def on_flat(params: convert.RollingParameters | None = None, rolling=None, **material):
    """T2 on a flat wall: launched at 0.5 m/s with omega = 0; slides, rolls, stops. Returns the
    position and angular velocity history (every 100 steps)."""
    model, mat = model_and_material(params, rolling, material, restitution=0.5)
    sim = rd.Simulation(contact=contact(model), dt=2e-5)
    sim.add_material(mat)
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R]], R, "m")
    sim.run(0.05)
    sim.set_velocities([0], velocity=(0.5, 0, 0), angular_velocity=(0, 0, 0))
    out = []
    for _ in range(60):
        sim.run(steps=100)
        out.append(np.concatenate([sim.positions[0], sim.angular_velocities[0]]))
    return np.array(out)


def pair_collisions(params: convert.RollingParameters | None = None, rolling=None, **material):
    """Three equal spheres in zero gravity: oblique collisions with spin (pair contacts only)."""
    model, mat = model_and_material(params, rolling, material, restitution=0.7)
    sim = rd.Simulation(contact=contact(model), gravity=(0, 0, 0), dt=2e-5)
    sim.add_material(mat)
    sim.add_particles([[0, 0, 0], [3 * R, 0.8 * R, 0.2 * R], [-3 * R, -0.5 * R, 0]], R, "m",
                      velocity=[[0, 0, 0], [-0.3, 0, 0], [0.25, 0.05, 0]],
                      angular_velocity=[[0, 0, 0], [0, 40, -30], [20, 0, 50]])
    out = []
    for _ in range(40):
        sim.run(steps=100)
        out.append(np.concatenate([sim.positions.ravel(), sim.angular_velocities.ravel()]))
    return np.array(out)


def assert_same(a, b):
    scale = np.abs(a).max(axis=0) + 1e-30
    assert (np.abs(a - b) / scale).max() < ROUND_OFF


def assert_differs(a, b):
    scale = np.abs(a).max(axis=0) + 1e-30
    assert (np.abs(a - b) / scale).max() > 1e-4


def test_lammps_sds_with_k_roll_equal_k_t_is_epsd2():
    """T6(f): LAMMPS sds with k_roll = k_t and no damping is EPSD2 (n constant on a flat)."""
    reference = on_flat(rolling=rd.EPSD2(), rolling_friction=MU_R)
    k_roll = convert.lammps_sds_equivalent_of_epsd2(KS)
    assert_same(on_flat(convert.from_lammps_sds(k_roll, 0.0, MU_R, parity=False)), reference)
    assert_differs(on_flat(convert.from_lammps_sds(4 * k_roll, 0.0, MU_R, parity=False)), reference)


def test_mercury_torque_conventions():
    """Mercury's pseudo-force at lever 2 R*: k^M = k_t / 4 and mu^M = mu_r / 2 give EPSD2."""
    reference = on_flat(rolling=rd.EPSD2(), rolling_friction=MU_R)
    assert_same(on_flat(convert.from_mercury(KS / 4, 0.0, MU_R / 2, parity=False)), reference)
    assert_differs(on_flat(convert.from_mercury(KS / 4, 0.0, MU_R, parity=False)), reference)


def test_pfc_rrlinear_is_epsd2_with_the_linear_contact():
    reference = on_flat(rolling=rd.EPSD2(), rolling_friction=MU_R)
    assert_same(on_flat(convert.from_pfc_rrlinear(MU_R)), reference)


def test_yade_radius_product_and_smaller_radius_limit():
    """Yade: k_r = alphaKr k_s R1 R2 and limit etaRoll min(R1, R2) F_n. For equal spheres
    (R* = R/2) alphaKr = 1/4 and etaRoll = mu_r / 2 are EPSD2 with mu_r."""
    reference = pair_collisions(rolling=rd.EPSD2(), rolling_friction=MU_R)
    assert_same(pair_collisions(convert.from_yade_cohfrict(0.25, MU_R / 2, KS, R, R)), reference)
    assert_differs(pair_collisions(convert.from_yade_cohfrict(1.0, MU_R / 2, KS, R, R)), reference)


def test_liggghts_names_map_to_parity_presets():
    p = convert.from_liggghts("epsd", 0.3, 0.2)
    assert isinstance(p.model, rd.EPSD) and p.model.parity == "liggghts"
    assert p.material_kwargs() == {"rolling_friction": 0.3, "rolling_damping": 0.2}
    p = convert.from_liggghts("epsd3", 0.3, 0.2, rolling_stiffness_coefficient=3.0, parity=False)
    assert p.model.parity is None and p.model.stiffness_coefficient() == 3.0
    assert convert.from_liggghts("cdt", 0.1).model.parity == "liggghts"
    with pytest.raises(rd.ParameterError, match="liggghts rolling model = 'epsd4' is not known"):
        convert.from_liggghts("epsd4", 0.1)
    with pytest.raises(rd.ParameterError, match="yade alphaKr = -1"):
        convert.from_yade_cohfrict(-1, 0.1, KS, R, R)
