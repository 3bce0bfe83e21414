"""Reading a YAML or TOML file (or a mapping given as is) into a dict, with one-line errors.

Shared by case files (:mod:`rollingdem.io.casefile`) and sweep files (:mod:`rollingdem.studies.sweep`).
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from rollingdem.errors import ParameterError

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli is the same parser, before it joined the library
    import tomli as tomllib

__all__ = ["read_mapping"]


class _YAMLLoader(yaml.SafeLoader):
    """PyYAML reads YAML 1.1, where 1.0e4 (no exponent sign) is a string; read it as the float
    every user means (YAML 1.2 rule)."""


_YAMLLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                |[-+]?\.(?:inf|Inf|INF)
                |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def read_mapping(path_or_dict, what: str = "case file") -> tuple[dict, str]:
    """(data, source name) of a YAML file, a TOML file (by extension) or a mapping.

    A file that is missing, a folder, unreadable, not text, not YAML / TOML, empty or not a
    mapping is a ParameterError of one line that names the file."""
    if isinstance(path_or_dict, dict):
        return path_or_dict, "<dict>"
    path = Path(path_or_dict)
    source = str(path)
    if not path.exists():
        raise ParameterError(f"{what} {source} does not exist")
    if path.is_dir():
        raise ParameterError(f"{what} {source} is a folder: must be a YAML or TOML file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ParameterError(f"{what} {source} is not a text file: must be a YAML or TOML file") from None
    except OSError as err:
        raise ParameterError(f"{what} {source} cannot be read: {err.strerror or err}") from None
    if path.suffix.lower() == ".toml":
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise ParameterError(f"{what} {source} is not valid TOML: {err}") from None
    else:
        try:
            data = yaml.load(text, Loader=_YAMLLoader)
        except yaml.YAMLError as err:
            raise ParameterError(f"{what} {source} is not valid YAML: {_yaml_problem(err)}") from None
    if data is None:
        raise ParameterError(f"{what} {source} is empty: must hold a mapping of keys")
    if not isinstance(data, dict):
        raise ParameterError(f"{what} {source} must hold a mapping of keys, got {type(data).__name__}")
    return data, source


def _yaml_problem(err) -> str:
    """A YAML parse error in one line: what and where (line, column as an editor counts them)."""
    problem = getattr(err, "problem", None) or str(err).splitlines()[0]
    mark = getattr(err, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    context = getattr(err, "context", None)
    return f"{problem}{where}" + (f" ({context})" if context else "")
