"""The experiments: each a class (``rollingdem.experiments.registry.Experiment``) in the module of
its scene, all in one registry, ``EXPERIMENTS``, that ``rollingdem validate``, ``sweep`` and
``calibrate`` read.

- ``validation``: the seed report's single-sphere cases 0-2 (inclined wall, rolling on a flat,
  rolling up a slope), on the scenes of ``single_sphere``;
- ``repose``: the seed report's angle-of-repose pile and the pile on a rough base;
- ``drum``: the rotating drum; ``silo``: silo discharge;
- ``contact_laws``: the contact laws against their closed forms; ``chung_ooi``: Chung & Ooi's eight
  impact benchmarks;
- ``clumps``: clumps against rigid-body statics and dynamics; ``clump_stand_in``: a pile of clumps
  against one of the spheres with the mu_r that stands in for them; ``coarse_graining``: parcels
  against the real particles they stand for; ``simple_shear``: steady simple shear between
  Lees-Edwards boundaries, mu(I) and phi(I) with and without rolling resistance;
  ``inclined_plane``: a layer flowing steadily down a rough incline, against the same mu(I).

Importing this package defines, and so registers, every one. The PFC repose-angle study, a sweep
of the pile, is a study (``rollingdem.studies.repose_study``); ``default.yaml`` is the case file
``rollingdem run`` uses without one.
"""

# each module registers its experiments; this order is the registry's, and the report's
from rollingdem.experiments import validation  # noqa: F401, I001
from rollingdem.experiments import contact_laws  # noqa: F401
from rollingdem.experiments import repose  # noqa: F401
from rollingdem.experiments import drum  # noqa: F401
from rollingdem.experiments import silo  # noqa: F401
from rollingdem.experiments import clumps  # noqa: F401
from rollingdem.experiments import clump_stand_in  # noqa: F401
from rollingdem.experiments import coarse_graining  # noqa: F401
from rollingdem.experiments import chung_ooi  # noqa: F401
from rollingdem.experiments import simple_shear  # noqa: F401
from rollingdem.experiments import inclined_plane  # noqa: F401
from rollingdem.experiments import case_file  # noqa: F401  (get_experiment takes a case file's path)
from rollingdem.experiments.registry import EXPERIMENTS, Experiment, Parameter, get_experiment
from rollingdem.experiments.results import ValidationResult, Check
from rollingdem.experiments.validation import inclined_wall, rolling_flat, rolling_slope

__all__ = ["EXPERIMENTS", "ValidationResult", "Check", "Experiment", "Parameter", "get_experiment", "inclined_wall",
           "rolling_flat", "rolling_slope"]
