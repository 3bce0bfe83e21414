"""The sub-model contract: a contact law is one class and one compiled function.

The class declares its per-pair parameters (``parameters``) and per-contact history
(``history``) by name, once, with ``slots``; the contact model places them in the step loop's rows
and the offsets follow. ``function`` is the compiled law, with its slot's signature (module
docstrings of ``normal``, ``tangential``, ``rolling``, ``twisting``). Subclasses register by
``slot`` and ``name``. How to add one: docs/architecture.md.
"""

from __future__ import annotations

import inspect
from numbers import Real
from typing import ClassVar

from rollingdem.errors import ParameterError, check_choice
from rollingdem.physics.contact.properties import declare
from rollingdem.physics.records import slots

# Common pair-parameter slots, shared by every sub-model.
P_YOUNG = 0            # E* (Pa)
P_SHEAR = 1            # G* (Pa)
P_FRICTION = 2         # mu
P_ROLLING_FRICTION = 3  # mu_r
P_ROLLING_DAMPING = 4  # eta_r
P_RESTITUTION = 5      # e
N_COMMON = 6

NORMAL_MODELS: dict[str, type] = {}
TANGENTIAL_MODELS: dict[str, type] = {}
ROLLING_MODELS: dict[str, type] = {}
TWISTING_MODELS: dict[str, type] = {}
COHESION_MODELS: dict[str, type] = {}
#: each slot's sub-models by name (defining a class registers it): what ``make_submodel``, the case
#: file's contact block and the experiments' choices take
REGISTRIES = {"normal": NORMAL_MODELS, "tangential": TANGENTIAL_MODELS, "rolling": ROLLING_MODELS,
              "twisting": TWISTING_MODELS, "cohesion": COHESION_MODELS}


NO_SLOTS = slots()


class SubModel:
    """Base of all contact sub-models.

    Class attributes: ``slot`` ("normal", "tangential", "rolling", "twisting", "cohesion"), ``name`` (as
    case files give it), ``parameters`` and ``history`` (``slots``: the per-pair floats after the
    common ones, and the per-contact history), ``function`` (the compiled law, as a
    ``staticmethod``), ``material_properties`` (what it reads of the materials, each with its
    pair-mixing rule). ``history_size`` and ``n_parameters`` follow from the declarations.
    """

    slot: ClassVar[str] = ""
    name: ClassVar[str] = ""
    parameters: ClassVar[tuple] = NO_SLOTS
    history: ClassVar[tuple] = NO_SLOTS
    function: ClassVar = None
    #: the material properties the law reads (``properties.MaterialProperty``); defining the class
    #: registers them, so ``Material`` takes them and the material table mixes them per pair
    material_properties: ClassVar[tuple] = ()
    #: label -> constructor arguments of the variants the validation experiments run (rolling
    #: models; ``experiments.single_sphere.validation_models``); by default the model with its defaults
    validation_presets: ClassVar[dict | None] = None
    history_size: ClassVar[int] = 0
    n_parameters: ClassVar[int] = 0

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.history_size = len(cls.history)
        cls.n_parameters = len(cls.parameters)
        declare(cls.__name__, cls.material_properties)
        if cls.name and "validation_presets" not in cls.__dict__:
            cls.validation_presets = {cls.name: {}}
        if cls.slot and cls.name:
            if cls.function is None:
                raise TypeError(f"{cls.__name__}: a {cls.slot} sub-model needs its compiled function "
                                "(function = staticmethod(...))")
            REGISTRIES[cls.slot][cls.name] = cls

    @classmethod
    def compiled_function(cls) -> tuple[str, str]:
        """(module, name) of the compiled law, as the engine generator imports it."""
        func = getattr(cls.function, "py_func", cls.function)
        return func.__module__, func.__name__

    def pair_values(self, pair) -> tuple[float, ...]:
        """The declared ``parameters`` of a material pair, in their order (default: none)."""
        return ()

    def coarse_graining_exponents(self) -> tuple[float, ...] | None:
        """The power of alpha by which each declared parameter is multiplied for parcels alpha times the
        real particle's size, so that contact forces scale as alpha^2 and moments as alpha^3
        (stress similarity, docs/models.md §18); None: no rule is known, and coarse graining is
        refused with this sub-model. Every parameter of a built-in model that is a ratio, a modulus,
        a velocity or a switch keeps its value (exponent 0)."""
        return None

    def check_coarse_graining(self, alpha: float) -> None:
        """Refuse coarse graining (``alpha`` > 1) with a sub-model that declares no rule for it."""
        if alpha != 1.0 and self.coarse_graining_exponents() is None:
            known = ", ".join(sorted(k for k, c in REGISTRIES[self.slot].items() if _has_rule(c)))
            raise ParameterError(f"coarse_graining = {alpha:g} is not allowed with {self.slot} model {self.name!r}: "
                                 f"how its parameters scale with the parcel is not known; {self.slot} models with a "
                                 f"rule are {known}")

    def pair_row(self, pair) -> tuple[float, ...]:
        """``pair_values`` as floats, checked against the declaration, each multiplied by the pair's
        coarse-graining factor to its declared power (``coarse_graining_exponents``)."""
        values = tuple(float(x) for x in self.pair_values(pair))
        if len(values) != self.n_parameters:
            raise TypeError(f"{type(self).__name__}.pair_values gave {len(values)} values for its "
                            f"{self.n_parameters} declared parameters {self.parameters._fields}")
        alpha = getattr(pair, "coarse_graining", 1.0)
        if alpha == 1.0:
            return values
        self.check_coarse_graining(alpha)
        return tuple(v * alpha ** e if e else v for v, e in zip(values, self.coarse_graining_exponents()))

    def settings(self) -> dict:
        """The constructor arguments, for case files and checkpoints."""
        return {}

    def kernel_modes(self) -> tuple[int, ...]:
        """Integer switches fixed when the engine module is compiled (default: none), passed to the
        rolling function as ``modes``; each distinct tuple compiles an engine module of its own."""
        return ()

    def rotational_stiffness(self, normal_stiffness, tangential_stiffness, r_eff, overlap, normal_force,
                             pair) -> float:
        """Stiffness (N m/rad) of this sub-model's rotational spring at the given contact state, for
        the time-step check (docs/models.md §2); 0 when it has none."""
        return 0.0

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.settings().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other):
        return type(self) is type(other) and self.settings() == other.settings()

    def __hash__(self):
        return hash((type(self), tuple(sorted(self.settings().items()))))


def nothing_to_scale(self) -> tuple:
    """``coarse_graining_exponents`` of a sub-model without parameters of its own: its law sees only
    the pair's moduli and coefficients and the contact's geometry, which scale by themselves."""
    return ()


def _has_rule(cls) -> bool:
    """Whether a sub-model class declares how it scales with coarse graining (its defaults, or any
    instance: a declared rule does not depend on whether it can be built without arguments)."""
    return cls.coarse_graining_exponents is not SubModel.coarse_graining_exponents


def _describe_parameters(params) -> str:
    return ", ".join(f"{k} (required)" if p.default is p.empty else k for k, p in params.items()) or "none"


def _check_parameter_type(slot: str, name: str, key: str, value, default) -> None:
    """Refuse a value whose type cannot be that of the parameter's default (a number for a number,
    a name for a name): the sub-model's own checks then see only values of the right kind."""
    if default is None or default is inspect.Parameter.empty:
        return  # no default to go by: the sub-model's own check names what is allowed
    if isinstance(default, bool):
        ok, what = isinstance(value, bool), "true or false"
    elif isinstance(default, Real):
        ok, what = isinstance(value, Real) and not isinstance(value, bool), "a number"
    elif isinstance(default, str):
        ok, what = isinstance(value, str), "a name (a string)"
    else:
        return
    if not ok:
        raise ParameterError(f"{slot} model {name!r}: parameter {key} = {value!r} is not allowed: must be {what}")


def make_submodel(slot: str, spec) -> SubModel:
    """Turn a name, a ``{"model": name, ...}`` mapping or an instance into a sub-model instance.

    Every mistake is a ``ParameterError`` naming the slot, the model and the parameter: an unknown
    model or parameter, a required parameter left out, a value of the wrong kind.
    """
    registry = REGISTRIES[slot]
    if isinstance(spec, SubModel):
        if spec.slot != slot:
            raise ParameterError(f"{slot} model = {spec!r} is not allowed: it is a {spec.slot} model")
        return spec
    if isinstance(spec, dict):
        spec = dict(spec)
        if "model" not in spec:
            raise ParameterError(f"{slot} model = {spec!r} is not allowed: a mapping must name its model, "
                                 f"{{model: NAME, ...}}; models are {', '.join(map(repr, sorted(registry)))}")
        name = spec.pop("model")
    elif isinstance(spec, str):
        name, spec = spec, {}
    else:
        raise ParameterError(f"{slot} model = {spec!r} is not allowed: must be a model name, a mapping "
                             f"{{model: NAME, parameter: value, ...}} or a {slot} sub-model instance")
    check_choice(f"{slot} model", name, registry)
    cls = registry[name]
    params = {k: p for k, p in inspect.signature(cls).parameters.items()
              if k != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    for key, value in spec.items():
        if key not in params:
            raise ParameterError(f"{slot} model {name!r}: parameter {key} = {value!r} is not known: "
                                 f"allowed are {', '.join(params) or 'none'}")
        _check_parameter_type(slot, name, key, value, params[key].default)
    missing = [k for k, p in params.items() if p.default is p.empty and k not in spec]
    if missing:
        raise ParameterError(f"{slot} model {name!r}: parameter {missing[0]} is missing: it is required; give "
                             f"{{model: {name}, {missing[0]}: VALUE}} (parameters: {_describe_parameters(params)})")
    return cls(**spec)
