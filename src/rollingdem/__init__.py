"""rollingdem: discrete element simulation of spheres, built around rolling resistance."""

import os as _os

import numba as _numba

# TBB stalls on an oversubscribed 2-core machine, and its fork/join costs
# ~190 us per parallel region on 2 cores against ~1 us for OpenMP; the workqueue costs ~80 us.
_numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]
# OpenMP threads spin 30,000 times before they sleep (GNU's default is 300,000): about as fast on
# quiet cores, and a spinning thread gives its core back sooner to another process (the figures:
# docs/performance.md). A user's own setting wins; set before libgomp is loaded.
_os.environ.setdefault("GOMP_SPINCOUNT", "30000")
# the inliner's copy of a callee made once, not once per block: about a tenth of an engine module's
# compile (rollingdem.engine.numba_inlining)
from rollingdem.engine import numba_inlining as _numba_inlining  # noqa: E402,F401

from rollingdem.physics import contact as _contact  # noqa: E402
from rollingdem.scene import convert  # noqa: E402
from rollingdem.scene.bonds import ParallelBond  # noqa: E402
from rollingdem.physics.contact import ContactModel  # noqa: E402
from rollingdem.errors import ParameterError, SimulationError  # noqa: E402
from rollingdem.scene.insertion import rough_base  # noqa: E402
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, MeshFace, Rectangle  # noqa: E402
from rollingdem.scene.size_distributions import Discrete, MassFractions, Normal, SieveCurve, Uniform  # noqa: E402
from rollingdem.scene.materials import Material, MaterialTable  # noqa: E402
from rollingdem.scene.mesh import MeshRegion, MeshWall, TriangleMesh  # noqa: E402
from rollingdem.io.observers import Checkpoints, TimeSeries, VTKSnapshots  # noqa: E402
from rollingdem.io.measurements import Function, MassFlow, MeshFlow, OutletTotals, Probe, WallLoad  # noqa: E402
from rollingdem.io.rig_measurements import DrumAngle, DrumFlow, PileAngle, SurfaceProfile  # noqa: E402
from rollingdem.io.field_measurements import ContinuumFields  # noqa: E402
from rollingdem.io.box_measurements import BoxStress  # noqa: E402
from rollingdem.scene.conditions import Empty, Known, Reaches, Settled  # noqa: E402
from rollingdem.scene.schedule import Callback, Observer  # noqa: E402
from rollingdem.scene.simulation import Simulation, __version__  # noqa: E402
from rollingdem.physics.timestep import hertz_contact_time, rayleigh_time_step  # noqa: E402
from rollingdem.scene.walls import Cylinder, Plane  # noqa: E402
from rollingdem.scene.periodic import LeesEdwards  # noqa: E402
from rollingdem.scene.motion import MotionTable, Oscillation, Servo  # noqa: E402
from rollingdem.scene.clumps import Clump, equivalent_rolling_friction, onset_angle, random_orientations, stand_in_rolling_friction  # noqa: E402

globals().update(_contact.SUBMODELS)  # every contact sub-model class by name (rd.EPSD, rd.Hertz, ...)

__all__ = [
    "convert", "Simulation", "LeesEdwards", "ContactModel", "ParallelBond", "Material", "MaterialTable", "Plane", "Cylinder", "MeshWall", "Oscillation", "MotionTable", "Servo", "Clump", "equivalent_rolling_friction", "onset_angle", "random_orientations", "stand_in_rolling_friction", "MeshRegion", "TriangleMesh", "TimeSeries",
    "VTKSnapshots", "Checkpoints", "Callback", "Observer", "MassFlow", "MeshFlow", "Probe", "ContinuumFields", "BoxStress", "OutletTotals", "WallLoad",
    "PileAngle", "DrumAngle", "DrumFlow", "SurfaceProfile", "Function", "Settled", "Reaches", "Known", "Empty", "BoxRegion", "CylinderRegion", "Uniform", "Normal", "MassFractions", "SieveCurve", "Disk", "Rectangle", "MeshFace",
    "Discrete", "rough_base", "ParameterError", "SimulationError", "rayleigh_time_step", "hertz_contact_time", "__version__",
    *_contact.SUBMODELS,
]
