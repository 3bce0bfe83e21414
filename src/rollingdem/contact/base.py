"""The sub-model contract.

A sub-model is one small class plus one compiled function:

* the class validates and holds the parameters, says how many per-contact history slots it
  needs (``history_size``), and turns a material pair into a fixed row of floats
  (``pair_parameters``) that the kernel reads;
* ``kernel`` is a ``numba.njit`` function with the fixed signature of its slot (see
  ``rollingdem.contact.signatures``). It allocates nothing and calls no Python. Declare it
  ``@njit(cache=True, inline="always")``: it is inlined into the engine's per-contact function,
  which saves a call with array arguments per contact (about 30 ns each).

Subclasses register themselves by ``slot`` and ``name``: adding a model is adding a class, with no
edit to the engine.

Every pair-parameter row starts with the common slots below; each sub-model's own parameters
follow at an offset the contact model hands to its kernel.
"""

from __future__ import annotations

import inspect

from typing import ClassVar

from ..errors import ParameterError, check_choice

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
_REGISTRIES = {"normal": NORMAL_MODELS, "tangential": TANGENTIAL_MODELS, "rolling": ROLLING_MODELS,
               "twisting": TWISTING_MODELS}


class SubModel:
    """Base of all contact sub-models."""

    slot: ClassVar[str] = ""
    name: ClassVar[str] = ""
    history_size: ClassVar[int] = 0
    #: (module, function name) of the compiled kernel; the engine generator imports it from there.
    kernel: ClassVar[tuple[str, str]] = ("", "")

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.slot and cls.name:
            _REGISTRIES[cls.slot][cls.name] = cls

    def pair_parameters(self, pair) -> tuple[float, ...]:
        """Extra per-pair floats after the common slots (default: none)."""
        return ()

    def parameters(self) -> dict:
        """The constructor arguments, for case files and checkpoints."""
        return {}

    def kernel_modes(self) -> tuple[int, ...]:
        """Integer switches fixed when the kernel is compiled (default: none), passed to the
        rolling kernel as ``modes``; each distinct tuple is a kernel of its own."""
        return ()

    def rotational_stiffness(self, normal_stiffness, tangential_stiffness, r_eff, overlap, normal_force,
                             pair) -> float:
        """Stiffness (N m/rad) of this sub-model's rotational spring at the given contact state, for
        the time-step check (docs/models.md §2); 0 when it has none."""
        return 0.0

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.parameters().items())
        return f"{type(self).__name__}({args})"

    def __eq__(self, other):
        return type(self) is type(other) and self.parameters() == other.parameters()

    def __hash__(self):
        return hash((type(self), tuple(sorted(self.parameters().items()))))


def _describe_parameters(params) -> str:
    return ", ".join(f"{k} (required)" if p.default is p.empty else k for k, p in params.items()) or "none"


def _check_parameter_type(slot: str, name: str, key: str, value, default) -> None:
    """Refuse a value whose type cannot be that of the parameter's default (a number for a number,
    a name for a name): the sub-model's own checks then see only values of the right kind."""
    from numbers import Real

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
    registry = _REGISTRIES[slot]
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
