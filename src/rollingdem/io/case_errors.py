"""A case file's faults in words: a pydantic validation error as one line per key at fault (the
key's path as the file has it, the value, what is allowed), and ``InCase``, which prefixes an
error raised while a block is built with the block's key."""

from __future__ import annotations

import difflib
import json
import re
from typing import Annotated, Optional, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from rollingdem.errors import ParameterError
from rollingdem.io.case_schema import CaseSpec, ClumpSpec, InsertSpec, ListSpec, RoughBaseSpec, particle_kind


_KIND_OF_INPUT = {
    "float_type": "a number", "float_parsing": "a number", "finite_number": "a finite number",
    "int_type": "a whole number", "int_parsing": "a whole number", "int_from_float": "a whole number",
    "bool_type": "true or false", "bool_parsing": "true or false", "string_type": "a string",
    "list_type": "a list", "tuple_type": "a list", "dict_type": "a mapping of keys",
    "model_type": "a mapping of keys", "model_attributes_type": "a mapping of keys",
}
_NOT_A_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TYPE_NAMES = {"float", "int", "str", "bool", "dict", "list", "tuple", "number"}


def _key_path(loc) -> tuple:
    """The case-file keys of a pydantic error location (union members and tags dropped)."""
    keep = []
    for p in loc:
        if isinstance(p, int):
            keep.append(p)
        elif (_NOT_A_KEY.match(p) and p not in _TYPE_NAMES and not p.endswith("Spec")
              and not (keep and p in ("insert", "list") and isinstance(keep[-1], int) and keep[:1] == ["particles"]
                       and len(keep) == 2)):
            keep.append(p)
    return tuple(keep)


def _spec_at(path, data=None) -> Optional[type]:
    """The model class of the mapping at ``path`` (None where it cannot be told), to list its keys."""
    def model_of(tp, key_hint=None):
        origin = get_origin(tp)
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            return tp
        if origin is Annotated:
            return model_of(get_args(tp)[0], key_hint)
        if origin in (Union, list, tuple, Optional) or (origin is not None and str(origin).endswith("UnionType")):
            found = [m for m in (model_of(a, key_hint) for a in get_args(tp)) if m is not None]
            if key_hint is not None:
                found = [m for m in found if key_hint(m)] or found
            return found[0] if len(found) == 1 else None
        return None

    def tagged(value):
        """A hint that keeps the union members whose tag (``type``, ``distribution``) is the value's."""
        if not isinstance(value, dict):
            return None

        def hint(m):
            particle = {InsertSpec: "insert", RoughBaseSpec: "rough_base", ListSpec: "list", ClumpSpec: "clump"}.get(m)
            if particle is not None:
                return particle == particle_kind(value)
            for key in ("type", "distribution"):
                field = m.model_fields.get(key)
                if key in value and field is not None and value[key] not in get_args(field.annotation):
                    return False
            return True
        return hint

    spec, node = CaseSpec, data
    for k, part in enumerate(path):
        if isinstance(part, int):
            continue
        field = spec.model_fields.get(part) if spec is not None else None
        if field is None:
            return None
        node = _value_at(node, (part,) + tuple(p for p in path[k + 1:k + 2] if isinstance(p, int)))
        spec = model_of(field.annotation, tagged(node))
    return spec


def _data_path(loc, data, missing: bool) -> tuple:
    """The keys of a pydantic error location as the file has them: each step kept where the file has
    that key (or index) there, union members and tags (``cylinder``, ``float``, ...) left out; a
    missing key is kept at the end."""
    keep, tag_seen = [], False
    for k, part in enumerate(loc):
        last = k == len(loc) - 1
        if (isinstance(data, dict) and not last and not tag_seen
                and part in (data.get("type"), data.get("distribution"), particle_kind(data))):
            tag_seen = True  # the union's tag for this mapping (once), not one of its keys
            continue
        if isinstance(data, list) and isinstance(part, int) and 0 <= part < len(data):
            keep.append(part)
            data, tag_seen = data[part], False
        elif isinstance(data, dict) and part in data:
            keep.append(part)
            data, tag_seen = data[part], False
        elif last and missing and (isinstance(part, int) or _NOT_A_KEY.match(part)):
            keep.append(part)
    return tuple(keep)


def _describe_error(e: dict, data) -> tuple[tuple, str]:
    """(key path, what is wrong) of one pydantic error, in the words of the house style."""
    path = (_data_path(e["loc"], data, e["type"] == "missing") if isinstance(data, dict)
            else _key_path(e["loc"]))
    kind = e["type"]
    ctx = e.get("ctx") or {}
    if kind == "extra_forbidden":
        parent = _spec_at(path[:-1], data)
        if parent is None:
            return path, "not a known key (misspelled?)"
        near = difflib.get_close_matches(str(path[-1]), list(parent.model_fields), n=1, cutoff=0.75) if path else []
        allowed = f"allowed are {', '.join(parent.model_fields)}"
        return path, (f"not a known key: did you mean {near[0]!r}? ({allowed})" if near
                      else f"not a known key (misspelled?): {allowed}")
    if kind == "missing":
        return path, "missing (required)"
    if kind in _KIND_OF_INPUT:
        return path, f"must be {_KIND_OF_INPUT[kind]}"
    if kind == "literal_error":
        return path, f"must be {ctx.get('expected')}"
    if kind == "union_tag_invalid":
        key = str(ctx.get("discriminator", "")).strip("'")
        return path + ((key,) if key and key != "<function>" else ()), f"must be one of {ctx.get('expected_tags')}"
    if kind == "union_tag_not_found":
        key = str(ctx.get("discriminator", "")).strip("'")
        return path + (key,), "missing (required)"
    if kind in ("too_short", "too_long"):
        if ctx.get("field_type") == "Tuple":
            return path, f"must be {ctx.get('max_length', ctx.get('min_length'))} numbers"
        return path, (f"must have at least {ctx.get('min_length')} entries" if kind == "too_short"
                      else f"must have at most {ctx.get('max_length')} entries")
    if kind == "radius_kind":
        return path, e["msg"]
    return path, e["msg"].removeprefix("Value error, ")


def _value_at(data, path):
    for part in path:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data


def format_validation_error(err: ValidationError, source: str, data=None) -> str:
    """One line per key at fault (branches of a union that all failed are one line); a single
    fault is one line with the file's name."""
    problems: dict[tuple, list[str]] = {}
    kinds: dict[tuple, str] = {}
    for e in err.errors():
        path, what = _describe_error(e, data)
        kind = e["type"]
        if kind == "missing" and len(e["loc"]) > 1 and isinstance(e["loc"][-1], int):
            path, what, kind = path[:-1], "must be three numbers", "too_short"  # a vector with too few numbers
        kinds.setdefault(path, kind)
        if what not in problems.setdefault(path, []):
            problems[path].append(what)
    # a misspelled key is one problem, not two: the line of the unknown key names the one the file lacks
    for path in [p for p, k in kinds.items() if k == "extra_forbidden" and p]:
        meant = re.search(r"did you mean '([^']+)'", problems[path][0])
        if meant and path[:-1] + (meant.group(1),) in problems and kinds[path[:-1] + (meant.group(1),)] == "missing":
            del problems[path[:-1] + (meant.group(1),)]
    lines = []
    for path, whats in problems.items():
        key = ".".join(str(p) for p in path) or "(top level)"
        if kinds[path] in ("missing", "extra_forbidden", "union_tag_not_found"):
            lines.append(f"key {key!r}: {whats[0]}")
            continue
        shown = json.dumps(_value_at(data, path), default=str)
        if len(shown) > 80:
            shown = shown[:77] + "..."
        musts = [w.removeprefix("must be ") for w in whats if w.startswith("must be ")]
        what = ("must be " + " or ".join(musts)) if len(musts) == len(whats) else "; ".join(whats)
        lines.append(f"key {key!r} = {shown} is not allowed: {what}")
    if len(lines) == 1:
        return f"case file {source}: {lines[0]}"
    return "\n".join([f"case file {source} is not valid ({len(lines)} problems):"] + [f"  {x}" for x in lines])


class InCase:
    """Prefix a ParameterError raised while a case block is built with the block's key."""

    def __init__(self, key: str):
        self.key = key

    def __enter__(self):
        return self

    def __exit__(self, kind, err, tb):
        if kind is not None and issubclass(kind, ParameterError):
            raise ParameterError(f"{self.key}: {err}") from None
        return False
