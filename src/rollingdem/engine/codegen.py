"""The compiled engine of a contact law: the step loop's template (``rollingdem.engine.template``,
its parts in order) with the law's compiled functions and row layout filled in, written to the
engine-module cache and imported.

One module per combination of sub-models, rolling ``kernel_modes`` and energy switch, named by a
hash of its sources, with a serial copy of the step loop (``advance_serial``): docs/architecture.md,
"The step loop and its contract" and "Compiling an engine module"."""

from __future__ import annotations

import ast
import hashlib
import importlib
import importlib.util
import inspect
import os
import re
import sys
import tempfile
from pathlib import Path

import numba

from rollingdem.engine import template
from rollingdem.engine.precompile import prepare

SERIAL_PASSES = ("advance", "open_step", "close_step", "pair_forces", "gather", "kick_drift", "clump_pass")  # name -> name_serial
_SERIAL_NAME = re.compile(r"\b(" + "|".join(SERIAL_PASSES) + r")\(")
_ALIASES = {"NORMAL": "normal_force", "TANGENTIAL": "tangential_force", "ROLLING": "rolling_moment",
            "TWISTING": "twisting_moment", "COHESION": "cohesion_force"}

_LOADED: dict[str, object] = {}
_BY_CLASSES: dict[tuple, object] = {}


def kernel_cache_dir() -> Path:
    """Where generated engine modules live: $ROLLINGDEM_CACHE_DIR, else ~/.cache/rollingdem/kernels."""
    env = os.environ.get("ROLLINGDEM_CACHE_DIR")
    base = Path(env) if env else Path.home() / ".cache" / "rollingdem" / "kernels"
    try:
        base.mkdir(parents=True, exist_ok=True)
        probe = base / ".write-test"
        probe.write_text("")
        probe.unlink()
        return base
    except OSError:
        fallback = Path(tempfile.gettempdir()) / "rollingdem-kernels"
        fallback.mkdir(parents=True, exist_ok=True)
        return fallback


def engine_source(contact, track_energy: bool = False, bonded_pairs: bool = False, meshes: bool = True,
                  clumps: bool = True, programs: bool = True) -> str:
    """The template's parts, in order, with ``contact``'s functions, layout and switches filled in
    and the imports between parts left out (the module defines their names itself)."""
    layout = contact.layout()
    out = []
    for line in "".join(part.read_text() for part in template_files()).splitlines():
        tag = line.rsplit("# @@", 1)[1].strip() if "# @@" in line else ""
        if tag == "PART":
            continue
        if tag and tag.isupper() and tag != "SERIAL_COPY":
            if tag in _ALIASES:
                module, func = getattr(contact, tag.lower()).compiled_function()
                line = f"from {module} import {func} as {_ALIASES[tag]}"
            elif tag == "TRACK_ENERGY":
                line = f"TRACK_ENERGY = {int(bool(track_energy))}"
            elif tag == "BONDED_PAIRS":
                line = f"BONDED_PAIRS = {int(bool(bonded_pairs))}"
            elif tag == "MESHES":
                line = f"MESHES = {int(bool(meshes))}"
            elif tag == "CLUMPS":
                line = f"CLUMPS = {int(bool(clumps))}"
            elif tag == "PROGRAMS":
                line = f"PROGRAMS = {int(bool(programs))}"
            elif tag == "ROLLING_MODES":
                line = f"ROLLING_MODES = {tuple(int(m) for m in contact.rolling.kernel_modes())!r}"
            else:
                line = f"{tag} = {layout[tag]}"
        out.append(line)
    return "\n".join(out + _serial_copies(out)) + "\n"


def template_files() -> list[Path]:
    """The files of the step loop's template, in the order the engine module takes them."""
    return [Path(template.__file__).with_name(f"{part}.py") for part in template.PARTS]


def template_modules() -> set[str]:
    """The template's parts as module names."""
    return {f"rollingdem.engine.template.{part}" for part in template.PARTS}


def engine_module(contact, track_energy: bool = False, serial: bool | None = None, bonded_pairs: bool = False,
                  meshes: bool = True, clumps: bool = True, programs: bool = True):
    """The compiled engine module for ``contact`` (generated and imported once per process); with
    ``track_energy`` the one that also sums the dissipated energies, with ``bonded_pairs`` the one
    that checks each contact for an intact bond (an exclusive one keeps the contact off, a parallel
    one its rolling and twisting moments) and has the bonds' passes; without ``meshes``, ``clumps``,
    ``programs`` one whose step loop has no pass for triangle meshes, clumps, walls' motion
    programs (a scene without them compiles less: docs/performance.md). With ``serial`` (the step loop
    the run takes: ``advance_serial`` if True, ``advance`` if False) a step loop not yet in the
    cache is compiled on two cores now (``rollingdem.engine.precompile``)."""
    # the generated code depends on the sub-model classes and the rolling model's compile-time
    # switches only, never on parameter values
    key = (tuple((type(sub), sub.compiled_function()) for sub in contact.submodels) + (bool(track_energy),)
           + tuple(contact.rolling.kernel_modes()) + (bool(bonded_pairs), bool(meshes), bool(clumps), bool(programs)))
    module = _BY_CLASSES.get(key)
    if module is None:
        _BY_CLASSES[key] = module = _load(contact, bool(track_energy), bool(bonded_pairs), bool(meshes),
                                                     bool(clumps), bool(programs))
    if serial is not None:
        prepare(module, bool(serial))
    return module


def _dependency_hash(contact, source: str) -> str:
    """A hash of the generated source, the sources of every package module it compiles in (the
    template's imports and theirs, the laws' modules and theirs) and Numba's version: Numba's own
    cache checks only the generated file, so a change in any module it inlines must rename it."""
    h = hashlib.sha256(source.encode())
    names = {sub.compiled_function()[0] for sub in contact.submodels} | template_modules()
    for name in sorted(_package_imports(names)):
        module = sys.modules[name] if name in sys.modules else importlib.import_module(name)
        h.update(inspect.getsource(module).encode())
    h.update(numba.__version__.encode())
    return h.hexdigest()[:16]


def _package_imports(names: set[str]) -> set[str]:
    """``names`` and the package modules they import, transitively (from their source)."""
    seen, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name in seen or not name.startswith("rollingdem"):
            continue
        seen.add(name)
        module = sys.modules[name] if name in sys.modules else importlib.import_module(name)
        package = name if hasattr(module, "__path__") else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(inspect.getsource(module))):
            if isinstance(node, ast.ImportFrom):
                base = importlib.util.resolve_name("." * node.level + (node.module or ""), package) \
                    if node.level else node.module
                if not base.startswith("rollingdem"):
                    continue
                todo.append(base)
                if hasattr(importlib.import_module(base), "__path__"):  # ``from package import module``
                    todo.extend(f"{base}.{a.name}" for a in node.names
                                if importlib.util.find_spec(f"{base}.{a.name}") is not None)
            elif isinstance(node, ast.Import):
                todo.extend(a.name for a in node.names)
    return seen


def _load(contact, track_energy: bool, bonded_pairs: bool = False, meshes: bool = True, clumps: bool = True,
          programs: bool = True):
    source = engine_source(contact, track_energy, bonded_pairs, meshes, clumps, programs)
    digest = _dependency_hash(contact, source)
    names = "_".join(sub.compiled_function()[1] for sub in contact.submodels)  # laws sharing a function share the file
    modname = f"rollingdem_kernel_{names}_{digest}"
    if modname in _LOADED:
        return _LOADED[modname]
    path = kernel_cache_dir() / f"{modname}.py"
    if not path.exists() or path.read_text() != source:
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)  # atomic: concurrent processes never import half a file
    spec = importlib.util.spec_from_file_location(modname, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[modname] = module
    spec.loader.exec_module(module)
    _LOADED[modname] = module
    return module


def _serial_copies(lines: list[str]) -> list[str]:
    """The functions tagged ``@@SERIAL_COPY`` again, calling the ``*_serial`` passes."""
    copies, inside = [], False
    for line in lines:
        if line.rstrip().endswith("# @@SERIAL_COPY"):
            inside = True
            copies += ["", ""]
        elif inside and line and not line[0].isspace() and not line.startswith(("def ", ")")):
            inside = False
        if inside:
            copies.append(_SERIAL_NAME.sub(r"\1_serial(", line.replace("  # @@SERIAL_COPY", "")))
    return copies


class EngineModules:
    """The engine modules one simulation steps with, made once each: by (contact law, whether
    energy is tracked, the CPU step loop its backend compiles ahead, whether it has bonds,
    triangle meshes, clumps, walls' motion programs)."""

    def __init__(self):
        self.held = {}

    def module(self, contact, track_energy: bool, state):
        bonded_pairs, meshes, clumps, programs = state.features()
        serial = state.backend.serial_step_loop(state)  # the CPU step loop to compile ahead, if the backend runs one
        key = (id(contact), track_energy, serial, bonded_pairs, meshes, clumps, programs)
        held = self.held.get(key)
        if held is None or held[0] is not contact:
            held = self.held[key] = (contact, engine_module(contact, track_energy, serial=serial,
                                                            bonded_pairs=bonded_pairs, meshes=meshes, clumps=clumps,
                                                            programs=programs))
        return held[1]
