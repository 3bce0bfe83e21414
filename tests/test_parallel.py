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


def test_column_size_holds_the_spheres():
    """Tube radius r and height H = 2 aspect r hold N spheres at solid fraction 0.6:
    0.6 pi r^2 H = N (4/3) pi R^3 (1 + p^2), <r^3> of radii uniform in R (1 +- p)."""
    from rollingdem.cases.repose import PACKING, column_size

    r, h = column_size(3000, 0.005, 0.2, aspect=1.5)
    assert h == pytest.approx(2 * 1.5 * r)
    assert PACKING * math.pi * r * r * h == pytest.approx(3000 * 4 / 3 * math.pi * 0.005 ** 3 * 1.04)
