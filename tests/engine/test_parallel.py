"""rollingdem.studies.parallel: the runner that maps independent simulations over Dask workers."""

import math

import pytest

import rollingdem as rd
from rollingdem.studies.parallel import runner


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

    from rollingdem.experiments.pile import INSERT_PACKING, PACKING, POLYDISPERSITY, column_size
    from rollingdem.experiments.single_sphere import RADIUS

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

