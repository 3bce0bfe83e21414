import numpy as np
import pytest

import rollingdem as rd

# The seed report's Table 1 material (R = 5 mm spheres): E = 40 MPa, nu = 0.49, rho = 1056 kg/m^3.
TABLE1 = dict(youngs_modulus=40e6, poisson_ratio=0.49, density=1056.0)
R = 0.005
G = 9.81


def pytest_collection_finish(session):
    """Start the GPU backend's child processes (tests/engine/test_cuda.py) that the selected tests of that
    module take, so that they run beside the rest of the suite instead of before its own tests. Not in
    a pytest-xdist worker: each collects every test, and the one that gets the module starts them."""
    if hasattr(session.config, "workerinput"):
        return
    started, needed = None, set()
    for item in session.items:
        children = getattr(getattr(item, "module", None), "CHILDREN", None)
        if children is not None:
            started = children
            needed.update(name for name in children.jobs if name in item.fixturenames)
    if needed:
        started.start(needed)  # only the children whose tests were selected


@pytest.fixture(autouse=True)
def _experiments_as_they_were():
    """A case file swept or calibrated is registered as an experiment under its path
    (``case_experiment``): each test leaves the registry as it found it, so that one that counts the
    built-in experiments does not see another's case files."""
    from rollingdem.experiments import EXPERIMENTS

    before = dict(EXPERIMENTS)
    yield
    EXPERIMENTS.clear()
    EXPERIMENTS.update(before)


@pytest.fixture
def table1():
    def make(name="m", **kw):
        params = dict(TABLE1, friction=0.8, rolling_friction=0.2, restitution=0.5, rolling_damping=0.3)
        params.update(kw)
        return rd.Material(name, **params)
    return make


def sphere_mass(radius=R, density=TABLE1["density"]):
    return density * 4.0 / 3.0 * np.pi * radius ** 3
