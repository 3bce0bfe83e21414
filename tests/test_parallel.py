"""rollingdem.parallel: the runner that maps independent simulations over Dask workers."""

import math

import pytest

import rollingdem as rd
from rollingdem.parallel import runner


def _square_and_threads(x):
    import numba

    return x * x, numba.get_num_threads()


def test_serial_runner_keeps_order_and_limits_threads():
    with runner(workers=1) as run:
        out = list(run(_square_and_threads, [3, 1, 2]))
    assert [o[0] for o in out] == [9, 1, 4]
    assert all(o[1] == 1 for o in out)  # one Numba thread per task, as in the workers


def test_local_cluster_runs_every_item_once_in_order():
    items = list(range(8))
    with runner(workers=2) as run:
        out = list(run(_square_and_threads, items))
    assert [o[0] for o in out] == [i * i for i in items]
    assert all(o[1] == 1 for o in out)


@pytest.mark.parametrize("kwargs, name", [({"workers": 0}, "workers"), ({"workers": 1.5}, "workers"),
                                          ({"threads": 0}, "threads")])
def test_bad_arguments_are_refused(kwargs, name):
    with pytest.raises(rd.ParameterError, match=name):
        with runner(**kwargs):
            pass


def test_column_size_holds_the_spheres(table1):
    """column_size gives the tube of the pile cases; pile_run fills it by inserting the spheres at
    random into the tube up to height H PACKING / INSERT_PACKING (twice H) and lets them settle.
    Property: the quick case's 1000 spheres of R (1 +- 0.2) are placed there, all inside the tube
    (rho + r <= tube radius) and none overlapping another (random sequential insertion jams near a
    solid fraction of 0.38, here 0.30 is asked). The tube is also narrow enough that they would not
    fit at random into the settled height H alone (0.60 > 0.38): H is a packed height, not a loose one."""
    import numpy as np
    from scipy.spatial import cKDTree

    from rollingdem.cases.repose import INSERT_PACKING, PACKING, POLYDISPERSITY, column_size
    from rollingdem.cases.single_sphere import RADIUS

    n = 1000
    tube, height = column_size(n, RADIUS, POLYDISPERSITY)
    assert height == pytest.approx(2 * tube)  # aspect 1: as high as the tube is wide
    sizes = rd.Uniform(RADIUS * (1 - POLYDISPERSITY), RADIUS * (1 + POLYDISPERSITY))
    sim = rd.Simulation(contact=rd.ContactModel("hertz"), dt=1e-5)
    sim.add_material(table1())
    sim.insert(rd.CylinderRegion(tube, 0.0, height * PACKING / INSERT_PACKING), n, sizes, "m", seed=1)
    x, r = sim.positions, sim.radii
    assert len(x) == n
    assert np.all(np.hypot(x[:, 0], x[:, 1]) + r <= tube * (1 + 1e-9))
    assert np.all(x[:, 2] - r >= 0.0) and np.all(x[:, 2] + r <= 2 * height * (1 + 1e-9))
    pairs = cKDTree(x).query_pairs(2 * RADIUS * (1 + POLYDISPERSITY), output_type="ndarray")
    gaps = np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) - r[pairs[:, 0]] - r[pairs[:, 1]]
    assert gaps.min() >= 0.0
    # solid volume over the tube volume up to H: the settled solid fraction the size was made for
    assert np.sum(4 / 3 * math.pi * r ** 3) / (math.pi * tube ** 2 * height) == pytest.approx(PACKING, rel=0.05)
    with pytest.raises(rd.ParameterError, match="packing fraction"):
        sim.insert(rd.CylinderRegion(tube, 0.0, height), n, sizes, "m", seed=2)


@pytest.mark.slow
@pytest.mark.xfail(strict=True, raises=AssertionError, reason="the quick case's column settles 1.19 H high (solid fraction ~0.50, not "
                   "PACKING = 0.6): found in issue 25; when column_size is fixed, this test passes and strict "
                   "xfail fails, so remove the marker")
def test_settled_column_is_as_high_as_column_size_says(table1):
    """pile_run's settle (Table 1 material, dt = 1e-5 s, the quick case's 1000 spheres of R (1 +- 0.2)
    in the tube of column_size, run 2 sqrt(2 fill / g) + 0.1 s): the settled column should stand H
    high. For a column of uniform density 2 <z> = H (centres). A random packing of frictional
    spheres lies between random loose (0.55) and random close (0.64) packing, so if column_size's
    PACKING = 0.6 held to that range the height would be within 0.6/0.64 = 0.94 and 0.6/0.55 = 1.09
    of H. Measured 2 <z> / H = 1.19 (19 s of compute): the tube of 10.5 radii loosens the packing to
    about 0.50, and the quick case's column is 1.19 tube diameters high, not 1."""
    import numpy as np

    from rollingdem.cases.repose import INSERT_PACKING, PACKING, POLYDISPERSITY, column_size
    from rollingdem.cases.single_sphere import G, RADIUS, TABLE1

    n = 1000
    tube, height = column_size(n, RADIUS, POLYDISPERSITY)
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=1e-5)
    sim.add_material(rd.Material("m", **TABLE1))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_wall(rd.Cylinder(tube, extent=(0.0, 2 * height + 0.1), material="m"))
    fill = height * PACKING / INSERT_PACKING
    sim.insert(rd.CylinderRegion(tube, 0.0, fill), n,
               rd.Uniform(RADIUS * (1 - POLYDISPERSITY), RADIUS * (1 + POLYDISPERSITY)), "m", seed=1)
    sim.run(2.0 * math.sqrt(2.0 * fill / G) + 0.1)
    assert np.abs(sim.velocities).max() < 1e-3  # at rest
    assert 0.94 < 2 * sim.positions[:, 2].mean() / height < 1.09
