"""Built-in cases: the seed report's test cases, each one scene built, run and measured.

Each validation case is a function returning a :class:`CaseResult` (table, checks, figures):
:func:`inclined_wall`, :func:`rolling_flat`, :func:`rolling_slope` (single sphere, every rolling
model); the pile case lives in :mod:`rollingdem.experiments.repose`. The cases sit below the sweep
machinery and never import it; the PFC repose-angle study, a sweep of the pile, is
:mod:`rollingdem.studies.repose_study`. ``default.yaml`` is the case ``rollingdem run`` uses without a file.
"""

from rollingdem.experiments.results import CaseResult, Check
from rollingdem.experiments.validation import inclined_wall, rolling_flat, rolling_slope

__all__ = ["CaseResult", "Check", "inclined_wall", "rolling_flat", "rolling_slope"]
