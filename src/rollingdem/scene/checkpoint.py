"""Checkpoints: a simulation's complete state in one ``.npz`` file, and the simulation it holds.

The engine's arrays go in as the state schema lists them (``EngineState.to_arrays``); the rest of
the scene (contact law, materials, walls, outlets and inflows, the clock) goes in as JSON under
``meta``. A checkpoint does not depend on the backend that wrote it: ``restore`` continues it bit
for bit on either."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from rollingdem.engine.state import EngineState
from rollingdem.errors import ParameterError
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene.periodic import LeesEdwards

VERSION = "0.1.0"
"""The package version a checkpoint records."""

FORMAT = 2
"""The checkpoint layout this code writes; it reads every earlier one (a field an older checkpoint
lacks gets its new rows) and refuses a later one. 1: checkpoints that record no format."""

WHAT = "must be a checkpoint .npz file written by Simulation.checkpoint"


def write(sim, path, state) -> Path:
    """``Simulation.checkpoint``: written to a temporary file first, so a kill leaves the last
    whole checkpoint in place."""
    path = Path(path)
    meta = {
        "version": VERSION,
        "format": FORMAT,
        "contact": sim.contact.to_dict(),
        "materials": sim.materials.to_dict(),
        "gravity": list(sim.gravity),
        "dt": sim.dt,
        "dt_automatic": sim.dt_automatic,
        "skin": sim.given_skin,
        "check_timestep": sim.check_timestep,
        "track_energy": sim.track_energy,
        "step": sim.step,
        "time": sim.time,
        "time_origin": list(sim.time_origin),
        "walls": sim.wall_set.describe(),
        "periodic": {axis: list(ends) for axis, ends in sim.periodic.items()},
        "lees_edwards": sim.shear.lees_edwards.to_dict() if sim.shear.active else None,
        **sim.boundary_set.describe(),
    }
    arrays = state.to_arrays()
    tmp = path.with_name(path.name + ".tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, meta=np.array(json.dumps(meta)), **arrays)
        tmp.replace(path)
    except OSError as err:
        if tmp.parent.is_dir():
            tmp.unlink(missing_ok=True)
        raise ParameterError(f"checkpoint = {str(path)!r} cannot be written ({err.strerror or err}): give a path "
                             "in a folder that exists or can be made, and that this user may write to") from None
    return path


def read(path) -> tuple[dict, dict]:
    """(meta, arrays) of a checkpoint file; a ParameterError for anything else."""
    path = Path(path)
    if not path.exists():
        raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it does not exist; {WHAT}")
    if path.is_dir():
        raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it is a folder; {WHAT}")
    try:
        with np.load(path, allow_pickle=False) as data:
            if not hasattr(data, "files") or "meta" not in data.files:
                raise ValueError("no meta")
            meta = json.loads(str(data["meta"]))
            arrays = {k: data[k] for k in data.files if k != "meta"}
        for key in ("contact", "materials", "gravity", "dt", "walls", "step", "time"):
            meta[key]
    except OSError as err:
        raise ParameterError(f"checkpoint = {str(path)!r} cannot be read ({err.strerror or err}); {WHAT}") from None
    except (ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):  # not an .npz, or not rollingdem's
        raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it is not a rollingdem checkpoint; "
                             f"{WHAT}") from None
    written = meta.get("format", 1)
    if not isinstance(written, int) or written > FORMAT:
        raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it is of format {written!r}, written by "
                             f"rollingdem {meta.get('version', '?')}, and this rollingdem ({VERSION}) reads formats up "
                             f"to {FORMAT}; restore it with the rollingdem that wrote it, or a newer one")
    return meta, arrays


def restore(simulation_class, path, backend: str | None = None):
    """``Simulation.restore``: a ``simulation_class`` made from the checkpoint at ``path``."""
    meta, arrays = read(path)
    contact = ContactModel.from_dict(meta["contact"])
    sim = simulation_class(contact=contact, gravity=meta["gravity"], dt=meta["dt"], skin=meta["skin"],
                           check_timestep=meta["check_timestep"], track_energy=meta.get("track_energy", True),
                           periodic=meta.get("periodic"), backend=backend,
                           lees_edwards=LeesEdwards(**meta["lees_edwards"]) if meta.get("lees_edwards") else None)
    sim.materials.load(meta["materials"])
    try:
        sim.particle_set.state.take_over(EngineState.from_arrays(arrays, contact.history_size))
    except KeyError as err:
        raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: its array {err.args[0]!r} is missing "
                             f"(the file was cut or edited); {WHAT}") from None
    sim.wall_set.restore(meta["walls"])
    sim.boundary_set.restore(meta)
    sim.step = int(meta["step"])
    sim.time = float(meta["time"])
    origin = meta.get("time_origin", (sim.time, sim.step))  # absent in older checkpoints
    sim.time_origin = (float(origin[0]), int(origin[1]))
    sim.dt_automatic = bool(meta.get("dt_automatic", False))
    return sim
