"""The experiments: one class each, one registry that ``validate``, ``sweep`` and ``calibrate`` read.

An experiment (``Experiment``) is a protocol run on a scene: its parameters, each with a default,
limits and a unit (``Parameter``), what it observes (``observables``, with units and meaning),
its quick and full sizes, ``observe(params) -> observables`` (one run at one point: what sweeps and
calibration call) and ``validate(...) -> ValidationResult`` (its runs over several points, checked
against theory: what ``rollingdem validate`` calls). Defining a subclass with a ``name`` registers
it in ``EXPERIMENTS``; ``rollingdem.experiments`` imports every built-in one. The experiments, their
observables and their theory: docs/studies.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rollingdem.errors import ParameterError, check_choice, check_finite
from rollingdem.experiments.single_sphere import validation_models
from rollingdem.physics.contact import ROLLING_MODELS
from rollingdem.physics.contact.base import REGISTRIES, make_submodel

EXPERIMENTS: dict[str, "Experiment"] = {}
"""Every experiment by name, in the order they were defined."""

CASE_FILE_SUFFIXES = (".yaml", ".yml", ".toml")
FILE_EXPERIMENT: list = []
"""The function that makes the experiment of a case file's path (``case_file.case_experiment``,
which puts itself here when imported: this module does not import the one built on it)."""


@dataclass(frozen=True)
class Parameter:
    """A named parameter of an experiment: default, allowed interval (``low``/``high``, open or
    closed) or choices, unit, and the range calibration searches by default."""

    name: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    integer: bool = False
    choice: str = ""  # "rolling", "twisting" or "cohesion": a model name
    calibration_range: tuple[float, float] | None = None

    def check(self, value: Any) -> Any:
        """The value as the experiment uses it, or ParameterError naming the parameter and what is allowed."""
        if self.choice:
            if not isinstance(value, str):
                raise ParameterError(f"{self.name} = {value!r} is not allowed: must be a {self.choice} model name")
            if self.choice == "rolling":
                resolve_rolling(value, self.name)
            else:
                check_choice(self.name, value, REGISTRIES[self.choice])
                try:
                    make_submodel(self.choice, value)
                except ParameterError as err:  # a model that needs parameters of its own (sds)
                    raise ParameterError(f"{self.name} = {value!r} is not allowed: {err}") from None
            return value
        if self.integer:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or float(value) != int(value):
                raise ParameterError(f"{self.name} = {value!r} is not allowed: must be an integer")
            value = int(value)
        else:
            if isinstance(value, bool):
                raise ParameterError(f"{self.name} = {value!r} is not a number")
            value = check_finite(self.name, value)
        bad_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        bad_high = self.high is not None and value > self.high
        if bad_low or bad_high:
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            unit = f" {self.unit}" if self.unit else ""
            raise ParameterError(f"{self.name} = {value!r} is not allowed: must lie in "
                                 f"{'(' if self.low_open or self.low is None else '['}{lo}, {hi}"
                                 f"{']' if self.high is not None else ')'}{unit}")
        return value


class Experiment:
    """Base class of the experiments. A subclass sets:

    - ``name``, ``description``;
    - ``parameters`` (a tuple of ``Parameter``), ``observables`` (name -> unit and meaning),
      ``default_observable``, ``stochastic`` (does the seed change the result?) and ``targets``
      (observable -> the (low, high) it can reach: what calibration may ask of it), and overrides
      ``observe``: an experiment without parameters is validated only, never swept;
    - ``sizes``: ``{"quick": {...}, "full": {...}}``, what ``validate(quick=...)`` runs;
    - ``model_keyword`` ("models": ``validate`` takes a list; "model": one; None: no choice) and
      ``models()``, the names ``rollingdem validate --model`` may give it; and overrides
      ``validate``.
    """

    name: str = ""
    description: str = ""
    parameters: tuple[Parameter, ...] = ()
    observables: dict[str, str] = {}
    default_observable: str = ""
    stochastic: bool = False
    targets: dict[str, tuple[float, float]] = {}
    sizes: dict[str, dict] = {"quick": {}, "full": {}}
    model_keyword: str | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.name:
            EXPERIMENTS[cls.name] = cls()

    @property
    def by_name(self) -> dict[str, Parameter]:
        return {p.name: p for p in self.parameters}

    @property
    def observable(self) -> bool:
        """Whether it runs at one point of its parameters (``observe``): what sweeps need."""
        return type(self).observe is not Experiment.observe

    def resolve(self, params: dict) -> dict:
        """Defaults filled in and every value checked; unknown names refused."""
        by_name = self.by_name
        unknown = [k for k in params if k not in by_name]
        if unknown:
            raise ParameterError(f"parameter = {unknown[0]!r} is not known for experiment {self.name!r}: allowed are "
                                 f"{', '.join(by_name)}")
        return {p.name: p.check(params[p.name]) if p.name in params else p.default for p in self.parameters}

    def observe(self, params: dict) -> dict:
        """One run at ``params`` (checked by ``resolve``): {observable: value}."""
        raise NotImplementedError

    def check(self, params: dict) -> None:
        """Refuse, without running, a point whose scene cannot be built (a ParameterError); an
        experiment whose scene depends on its parameters in ways ``resolve`` cannot see overrides it
        (the silo: parcels larger than its orifice)."""

    def validate(self, quick=False, outdir=None, progress=None, runner=map, **models):
        """Its runs over several points, checked against theory: a ``ValidationResult``."""
        raise NotImplementedError

    def models(self) -> list[str]:
        """The model names ``validate`` takes through ``model_keyword``."""
        return []

    def __repr__(self):
        return f"<experiment {self.name!r}>"


class BedExperiment(Experiment):
    """An experiment on a random bed of spheres: the seed changes what it observes, and
    ``validate`` runs one rolling model (``model``), any of ``rolling_models()``."""

    stochastic = True
    model_keyword = "model"

    def models(self) -> list[str]:
        return rolling_models()


def get_experiment(name: str, observable: bool = False, what: str = "experiment") -> Experiment:
    """The experiment ``name`` (a built-in one, or a case file's path: ``case_file.CaseExperiment``;
    with ``observable``: one that ``observe`` runs at a point, as a sweep or calibration needs), or
    ParameterError naming it as ``what`` (the key or option the
    user gave it with) and listing the allowed ones."""
    if isinstance(name, str) and name.lower().endswith(CASE_FILE_SUFFIXES) and FILE_EXPERIMENT:
        return FILE_EXPERIMENT[0](name)
    allowed = [n for n, e in EXPERIMENTS.items()
               if (e.observable or not observable) and not n.lower().endswith(CASE_FILE_SUFFIXES)]
    if name not in allowed:
        why = "has no parameters to vary" if name in EXPERIMENTS else "is not known"
        raise ParameterError(f"{what} = {name!r} {why}: allowed are {', '.join(allowed)}")
    return EXPERIMENTS[name]


def resolve_rolling(name: str, what: str = "model"):
    """A rolling model by name: a key of ``rollingdem.physics.contact.ROLLING_MODELS`` ("epsd", "cdt", ...)
    or a label of the validation tables ("epsd (liggghts)", "cdt (limiter 0.08)", ...)."""
    labels = validation_models()
    if name in labels:
        return labels[name]
    check_choice(what, name, set(ROLLING_MODELS) | set(labels))
    return name


def rolling_models() -> list[str]:
    """Every rolling model name and validation label: what ``--model`` may give an experiment that
    runs one rolling model."""
    labels = list(validation_models())
    return sorted(ROLLING_MODELS) + [m for m in labels if m not in ROLLING_MODELS]


# --- parameters several experiments share ---------------------------------------------------------
def common_parameters(mu=0.8, mur=0.2, mur_range=(0.02, 1.0), mur_low_open=False) -> tuple[Parameter, ...]:
    """The rolling model, the contact coefficients and the seed."""
    return (Parameter("model", "epsd", "rolling resistance model (rollingdem.physics.contact.ROLLING_MODELS or a "
                                       "validation label such as 'epsd (liggghts)')", choice="rolling"),
            Parameter("mu", mu, "sliding friction coefficient", low=0.0, low_open=True, calibration_range=(0.1, 1.0)),
            Parameter("mur", mur, "rolling friction coefficient", low=0.0, low_open=mur_low_open,
                      calibration_range=mur_range),
            Parameter("eta_r", 0.3, "rolling viscous damping ratio", low=0.0, high=1.0, calibration_range=(0.0, 1.0)),
            Parameter("e", 0.5, "coefficient of restitution", low=0.0, high=1.0, low_open=True,
                      calibration_range=(0.1, 0.9)),
            Parameter("seed", 1, "random seed (insertion)", low=0, integer=True))


def cohesion_parameters() -> tuple[Parameter, ...]:
    """The cohesion law and its two material parameters (docs/models.md §1.6), which calibration can
    fit as it fits mu_r."""
    return (Parameter("cohesion", "none", "cohesion law (rollingdem.physics.contact.COHESION_MODELS): none, sjkr, jkr",
                      choice="cohesion"),
            Parameter("surface_energy", 0.0, "work of adhesion w of the spheres (cohesion jkr)", "J/m^2", low=0.0,
                      calibration_range=(0.0, 0.5)),
            Parameter("cohesion_energy_density", 0.0, "cohesion energy density k_c of the spheres (cohesion sjkr)",
                      "J/m^3", low=0.0, calibration_range=(0.0, 2e5)))


def twisting_parameter() -> Parameter:
    return Parameter("twisting", "none", "twisting model (rollingdem.physics.contact.TWISTING_MODELS)",
                     choice="twisting")


def granular_parameters() -> tuple[Parameter, ...]:
    """The parameters of an experiment with a bed of spheres: the common ones, the twisting model,
    the spheres' size and stiffness, the time step, cohesion."""
    return (common_parameters(mu=0.5, mur=0.2, mur_range=(0.0, 0.6))
            + (twisting_parameter(),
               Parameter("radius", 0.005, "mean sphere radius R", "m", low=0.0, low_open=True),
               Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p)", low=0.0, high=0.9),
               Parameter("youngs_modulus", 5e6, "Young's modulus", "Pa", low=0.0, low_open=True),
               Parameter("dt", 2.5e-5, "time step", "s", low=0.0, low_open=True), coarse_graining_parameter())
            + cohesion_parameters())


def coarse_graining_parameter() -> Parameter:
    """alpha: the spheres are parcels alpha times the radius given, each standing for alpha^3 of them
    (docs/models.md §18); the scene's sizes and counts stay the real particles'."""
    return Parameter("coarse_graining", 1.0, "coarse-graining factor alpha: parcels alpha times the radius, each standing "
                                             "for alpha^3 spheres (counts and sizes are the real spheres')", low=1.0)


UNBOUNDED = (0.0, math.inf)
"""The targets of an observable that can be any positive number."""
