"""rollingdem: discrete element simulation of spheres, built around rolling resistance."""

import os as _os

import numba as _numba

# TBB stalls on an oversubscribed 2-core machine, and its fork/join costs
# ~190 us per parallel region on 2 cores against ~1 us for OpenMP; the workqueue costs ~80 us.
_numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
# OpenMP threads spin 30,000 times before they sleep (GNU default: 300,000 with OMP_WAIT_POLICY
# unset). Measured on 2 cores, column-collapse 20,000 spheres, 2 threads: quiet 8.9-10.3 M
# particle-steps/s (3,000: 7.5-8.7 M; 300,000: 9.5-9.8 M); with a busy process on one core
# 2.8-2.9 M (3,000: 3.7-3.8 M), which is why a run that was not given --threads steps on the
# cores other processes leave free (rollingdem.engine.threads). A user's own setting wins; set before
# libgomp is loaded.
_os.environ.setdefault("GOMP_SPINCOUNT", "30000")

from rollingdem.physics import contact as _contact  # noqa: E402
from rollingdem.scene import convert  # noqa: E402
from rollingdem.scene.bonds import ParallelBond  # noqa: E402
from rollingdem.physics.contact import ContactModel  # noqa: E402
from rollingdem.errors import ParameterError, SimulationError  # noqa: E402
from rollingdem.scene.insertion import BoxRegion, CylinderRegion, Discrete, Normal, Uniform, rough_base  # noqa: E402
from rollingdem.scene.materials import Material, MaterialTable  # noqa: E402
from rollingdem.scene.mesh import MeshWall, TriangleMesh  # noqa: E402
from rollingdem.io.observers import Checkpoints, TimeSeries, VTKSnapshots  # noqa: E402
from rollingdem.scene.schedule import Callback, Observer  # noqa: E402
from rollingdem.scene.simulation import Simulation, __version__  # noqa: E402
from rollingdem.physics.timestep import hertz_contact_time, rayleigh_time_step  # noqa: E402
from rollingdem.scene.walls import Cylinder, Plane  # noqa: E402

globals().update(_contact.SUBMODELS)  # every contact sub-model class by name (rd.EPSD, rd.Hertz, ...)

__all__ = [
    "convert", "Simulation", "ContactModel", "ParallelBond", "Material", "MaterialTable", "Plane", "Cylinder", "MeshWall", "TriangleMesh", "TimeSeries",
    "VTKSnapshots", "Checkpoints", "Callback", "Observer", "BoxRegion", "CylinderRegion", "Uniform", "Normal",
    "Discrete", "rough_base", "ParameterError", "SimulationError", "rayleigh_time_step", "hertz_contact_time", "__version__",
    *_contact.SUBMODELS,
]
