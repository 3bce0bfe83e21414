"""ContactModel: composes normal, tangential, rolling and twisting sub-models into one kernel.

The engine template (``rollingdem/engine_kernel.py``) calls four functions by slot name. For each
combination of sub-models a copy of the template is written to the kernel cache directory with
those imports, parameter offsets and history slots filled in, and imported; Numba's on-disk cache
then works as for any module (closures over jitted functions would defeat it). The file name carries a hash of every source it depends on, so an edited sub-model
never runs with a stale kernel.

The step loop is written once, for the parallel passes; each function tagged ``@@SERIAL_COPY`` is
written a second time with the ``*_serial`` passes (``advance_serial``). Two step loops, not one
with a ``serial`` flag: Numba types and compiles every function a loop can call, so one loop would
compile both sets of passes for a run that takes one (a cold compile 4-5 s longer).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

from .base import N_COMMON, SubModel, make_submodel

HISTORY_FRAME = 3  # the previous contact normal, kept by the engine for every contact

SERIAL_PASSES = ("advance", "pair_forces", "gather", "kick_drift")  # name -> name_serial
_SERIAL_NAME = re.compile(r"\b(" + "|".join(SERIAL_PASSES) + r")\(")

_LOADED: dict[str, object] = {}
_BY_CLASSES: dict[tuple, object] = {}


def kernel_cache_dir() -> Path:
    """Where generated kernels live: $ROLLINGDEM_CACHE_DIR, else ~/.cache/rollingdem/kernels."""
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


class ContactModel:
    """The contact law: normal + tangential + rolling + twisting sub-models.

    Parameters
    ----------
    normal: "hertz" (default), "hooke", "linear", or a sub-model instance / {"model": name, ...}.
    tangential: "history" (default).
    rolling: "none" (default), "cdt", ... (``rollingdem.contact.ROLLING_MODELS``).
    twisting: "none" (default).

    Particle-particle and particle-wall contacts use the same sub-model functions.
    """

    def __init__(self, normal="hertz", tangential="history", rolling="none", twisting="none"):
        self.normal = make_submodel("normal", normal)
        self.tangential = make_submodel("tangential", tangential)
        self.rolling = make_submodel("rolling", rolling)
        self.twisting = make_submodel("twisting", twisting)

    @property
    def submodels(self) -> tuple[SubModel, SubModel, SubModel, SubModel]:
        return (self.normal, self.tangential, self.rolling, self.twisting)

    # --- layout -----------------------------------------------------------------------------
    def offsets(self) -> dict[str, int]:
        """Parameter offsets and history slots of each sub-model, as the kernel sees them."""
        out = {}
        off = N_COMMON
        hist = HISTORY_FRAME
        dummy = _DummyPair()
        for sub in self.submodels:
            key = sub.slot.upper()
            out["OFF_" + key] = off
            out["H_" + key] = hist
            off += len(sub.pair_parameters(dummy))
            hist += sub.history_size
        out["N_PARAMS"] = off
        out["HISTORY_SIZE"] = hist
        return out

    @property
    def history_size(self) -> int:
        return self.offsets()["HISTORY_SIZE"]

    def pair_table(self, materials) -> np.ndarray:
        """The (n_materials, n_materials, n_params) table of per-pair parameters."""
        nmat = len(materials)
        lay = self.offsets()
        table = np.zeros((nmat, nmat, lay["N_PARAMS"]))
        for a in range(nmat):
            for b in range(nmat):
                pair = materials.pair(a, b)
                row = [pair.effective_youngs_modulus, pair.effective_shear_modulus, pair.friction,
                       pair.rolling_friction, pair.rolling_damping, pair.restitution]
                for sub in self.submodels:
                    row.extend(float(x) for x in sub.pair_parameters(pair))
                table[a, b, :] = row
        return table

    # --- kernel -----------------------------------------------------------------------------
    def kernel_source(self, track_energy: bool = False) -> str:
        from .. import engine_kernel

        template = Path(engine_kernel.__file__).read_text()
        lay = self.offsets()
        out = []
        for line in template.splitlines():
            tag = line.rsplit("# @@", 1)[1].strip() if "# @@" in line else ""
            if tag and tag.isupper() and tag != "SERIAL_COPY":
                if tag in ("NORMAL", "TANGENTIAL", "ROLLING", "TWISTING"):
                    sub = getattr(self, tag.lower())
                    module, func = sub.kernel
                    alias = {"NORMAL": "normal_force", "TANGENTIAL": "tangential_force",
                             "ROLLING": "rolling_moment", "TWISTING": "twisting_moment"}[tag]
                    line = f"from {module} import {func} as {alias}"
                elif tag == "TRACK_ENERGY":
                    line = f"TRACK_ENERGY = {int(bool(track_energy))}"
                elif tag == "ROLLING_MODES":
                    line = f"ROLLING_MODES = {tuple(int(m) for m in self.rolling.kernel_modes())!r}"
                else:
                    line = f"{tag} = {lay[tag]}"
            out.append(line)
        return "\n".join(out + _serial_copies(out)) + "\n"

    def _dependency_hash(self, source: str) -> str:
        import numba

        from .. import neighbors
        from . import frame

        h = hashlib.sha256(source.encode())
        modules = {sys.modules[sub.kernel[0]] if sub.kernel[0] in sys.modules
                   else importlib.import_module(sub.kernel[0]) for sub in self.submodels}
        for mod in sorted(modules | {neighbors, frame}, key=lambda m: m.__name__):
            h.update(inspect.getsource(mod).encode())
        h.update(numba.__version__.encode())
        return h.hexdigest()[:16]

    def kernel(self, track_energy: bool = False, serial: bool | None = None):
        """The compiled engine module for this combination (generated and imported once); with
        ``track_energy`` the one that also sums the dissipated energies. With ``serial`` (the step
        loop the run takes: ``advance_serial`` if True, ``advance`` if False) a step loop not yet
        in the cache is compiled on two cores now (``rollingdem.contact.precompile``)."""
        # the generated code depends on the sub-model classes and the rolling model's compile-time
        # switches only, never on parameter values
        key = (tuple((type(sub), sub.kernel) for sub in self.submodels) + (bool(track_energy),)
               + tuple(self.rolling.kernel_modes()))
        module = _BY_CLASSES.get(key)
        if module is None:
            _BY_CLASSES[key] = module = self._load_kernel(bool(track_energy))
        if serial is not None:
            from .precompile import prepare

            prepare(self, module, bool(track_energy), bool(serial))
        return module

    def _load_kernel(self, track_energy: bool):
        source = self.kernel_source(track_energy)
        digest = self._dependency_hash(source)
        names = "_".join(sub.kernel[1] for sub in self.submodels)  # models sharing a kernel share the file
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

    # --- (de)serialisation ----------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {sub.slot: {"model": sub.name, **sub.parameters()} for sub in self.submodels}

    @classmethod
    def from_dict(cls, data: dict) -> "ContactModel":
        return cls(**data)

    def __repr__(self):
        return (f"ContactModel(normal={self.normal!r}, tangential={self.tangential!r}, "
                f"rolling={self.rolling!r}, twisting={self.twisting!r})")


class _DummyPair:
    """A stand-in material pair used only to count each sub-model's parameters."""

    effective_youngs_modulus = 1e7
    effective_shear_modulus = 4e6
    friction = 0.5
    rolling_friction = 0.1
    restitution = 0.5
    rolling_damping = 0.0


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
