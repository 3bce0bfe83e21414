"""Error types, parameter checks and parameter declarations shared by the whole package.

Every check names the parameter, the value it got and what is allowed, so a bad input is
refused at the door rather than crashing deep in the compiled step loop.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any


class ParameterError(ValueError):
    """A parameter has a value that is not allowed."""


class SimulationError(RuntimeError):
    """A run could not go on (instability, non-finite state, ...)."""


@dataclass(frozen=True)
class Declared:
    """What a constructor's parameter is, written once, in the class's ``declared`` beside its
    constructor: a description, the SI unit ("-" for a ratio, "" for a name or a switch), the kind
    of value ("number", "vector", "text", "flag", "numbers", "vectors", "pair") and the allowed
    interval (None: unbounded; each end closed unless ``low_open``/``high_open``). The case file's
    schema is made from it (``rollingdem schema`` carries the description, unit and bounds); the
    constructor's own checks refuse what lies outside, in one line."""

    description: str
    unit: str = ""
    kind: str = "number"
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False


def env_switch(name: str, default: bool = True) -> bool:
    """An on/off environment variable (``ROLLINGDEM_PRECOMPILE``, ...): "1" on, "0" off, unset
    ``default``; anything else is refused with the variable's name and value."""
    value = os.environ.get(name)
    if value is None:
        return default
    if value not in ("0", "1"):
        raise ParameterError(f"environment variable {name} = {value!r} is not allowed: must be 0 (off) or 1 (on)")
    return value == "1"


def short_repr(value: Any, width: int = 60) -> str:
    """repr of a user's value, cut to ``width`` characters (for refusals)."""
    text = repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def _fmt(value: Any) -> str:
    return repr(value) if not isinstance(value, float) else f"{value:g}"


def _is_bool(value: Any) -> bool:
    return isinstance(value, bool) or type(value).__name__ == "bool_"  # numpy's bool too


def check_finite(name: str, value: Any) -> float:
    if _is_bool(value) or isinstance(value, (str, bytes)):  # float(True) == 1.0, float("1") == 1.0: not numbers
        raise ParameterError(f"{name} = {value!r} is not allowed: must be a number")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} = {value!r} is not allowed: must be a number") from None
    if not math.isfinite(x):
        raise ParameterError(f"{name} = {_fmt(x)} is not allowed: must be a finite number")
    return x


def check_positive(name: str, value: Any, unit: str = "") -> float:
    x = check_finite(name, value)
    if x <= 0.0:
        u = f" ({unit})" if unit else ""
        raise ParameterError(f"{name} = {_fmt(x)} is not allowed: must be > 0{u}")
    return x


def check_non_negative(name: str, value: Any, unit: str = "") -> float:
    x = check_finite(name, value)
    if x < 0.0:
        u = f" ({unit})" if unit else ""
        raise ParameterError(f"{name} = {_fmt(x)} is not allowed: must be >= 0{u}")
    return x


def check_range(name: str, value: Any, low: float, high: float, *, low_open: bool = False,
                high_open: bool = False) -> float:
    x = check_finite(name, value)
    ok_low = x > low if low_open else x >= low
    ok_high = x < high if high_open else x <= high
    if not (ok_low and ok_high):
        lo = "(" if low_open else "["
        hi = ")" if high_open else "]"
        raise ParameterError(f"{name} = {_fmt(x)} is not allowed: must lie in {lo}{low:g}, {high:g}{hi}")
    return x


def check_choice(name: str, value: Any, allowed) -> str:
    try:
        known = value in allowed
    except TypeError:  # an unhashable value (a list, a mapping) is no name
        known = False
    if not known:
        raise ParameterError(f"{name} = {value!r} is not known: allowed are {', '.join(map(repr, sorted(allowed)))}")
    return value


def check_integer(name: str, value: Any, low: int | None = None) -> int:
    """A whole number (an int, or a float with no fractional part such as 1e4), at least ``low``."""
    if _is_bool(value) or isinstance(value, (str, bytes)):
        raise ParameterError(f"{name} = {value!r} is not allowed: must be a whole number")
    try:
        x = float(value)
        whole = math.isfinite(x) and x == int(x)
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole:
        raise ParameterError(f"{name} = {_fmt(value)} is not allowed: must be a whole number")
    n = int(x) if not hasattr(value, "__index__") else int(value)
    if low is not None and n < low:
        raise ParameterError(f"{name} = {n} is not allowed: must be a whole number >= {low}")
    return n


def check_vector(name: str, value: Any, *, unit: bool = False) -> tuple[float, float, float]:
    try:
        seq = [float(c) for c in value]
    except (TypeError, ValueError):
        raise ParameterError(f"{name} = {value!r} is not allowed: must be three numbers") from None
    if len(seq) != 3:
        raise ParameterError(f"{name} = {value!r} is not allowed: must be three numbers")
    if not all(math.isfinite(c) for c in seq):
        raise ParameterError(f"{name} = {value!r} is not allowed: components must be finite")
    if unit:
        norm = math.sqrt(sum(c * c for c in seq))
        if norm == 0.0:
            raise ParameterError(f"{name} = {value!r} is not allowed: must be a non-zero direction")
        seq = [c / norm for c in seq]
    return (seq[0], seq[1], seq[2])


def check_output_path(name: str, path, *, folder: bool = True):
    """Refuse, before anything runs, an output path that could not be written: one that is (or lies
    under) a file, a folder where a file is wanted, or under a folder without write permission.
    Returns the path as a ``Path``."""
    path = Path(path)
    if path.exists():
        if folder and not path.is_dir():
            raise ParameterError(f"{name} = {str(path)!r} is not allowed: it is a file; must be a folder")
        if not folder and path.is_dir():
            raise ParameterError(f"{name} = {str(path)!r} is not allowed: it is a folder; must be a file name")
    # the folders it goes in (an existing output file is overwritten)
    for above in ((path,) if folder else ()) + tuple(path.absolute().parents):
        if above.exists():
            if not above.is_dir():
                raise ParameterError(f"{name} = {str(path)!r} is not allowed: {above} is a file; must be a folder")
            if not os.access(above, os.W_OK | os.X_OK):
                raise ParameterError(f"{name} = {str(path)!r} is not allowed: {above} is not writable")
            break
    return path

