"""Each pass of a step as a call of its own on a state's present arrays, and the seconds per step
of each phase of the step on the CPU (what ``rollingdem bench`` reports as the split of a step)."""

from __future__ import annotations

import math
import time

import numpy as np

from rollingdem.engine.layout import DRIFT_SHARE, KICK_NONE, PERIODIC_BOX_SIZE, SHEARED_DRIFT_SHARE
from rollingdem.engine.mesh_passes import build_mesh_candidates
from rollingdem.engine.neighbors import rebuild_neighbor_list

#: the phases of a step, as every backend names them
PHASES = ("contact forces", "walls", "integration and gathering", "neighbor search")


class Passes:
    """Each pass of the step as a call on the present arrays of ``state`` (the timings overwrite the
    contacts' rows, the forces and, for the neighbor search, the list: ``restore`` puts them back).
    The paths are those the engine takes for this state (serial or threaded)."""

    def __init__(self, state, module, dt, gravity, skin, pair_params):
        st = self.state = state
        st.energy_for(module)
        gravity = np.asarray(gravity, dtype=np.float64)
        pp = pair_params
        particles, walls, lists, scratch = st.records()
        self.saved = [(owner, name, getattr(owner, name).copy())
                      for owner, names in ((st, ("whist", "wtouch", "wall_load", "energy", "f", "t", "contacts",
                                                 "x_ref", "x", "v", "w", "clump_f", "clump_t", "image")),
                                           (st.meshes, ("slot_triangle", "history", "load", "candidate_start",
                                                        "candidates", "candidate_gap", "built")),
                                           (st.contact_list, ("pool", "contact_row", "groups", "start", "j", "i",
                                                              "tr_start", "tr_k", "box")))
                      for name in names]
        serial = st.serial()
        pair_forces = module.pair_forces_serial if serial else module.pair_forces
        gather = module.gather_serial if serial else module.gather
        kick_drift = module.kick_drift_serial if serial else module.kick_drift
        no_walls = walls._make(a[:0] for a in walls)

        self.pair = lambda: pair_forces(dt, pp, particles, lists, scratch)
        half = skin * (DRIFT_SHARE if lists.box.shape[0] <= PERIODIC_BOX_SIZE else SHEARED_DRIFT_SHARE)
        self.gather_walls = lambda: gather(dt, KICK_NONE, gravity, pp, particles, walls, lists, scratch, half)
        self.gather_plain = lambda: gather(dt, KICK_NONE, gravity, pp, particles, no_walls, lists, scratch, half)
        self.kick = lambda: kick_drift(0.0, particles, half)
        clump_pass = module.clump_pass_serial if serial else module.clump_pass
        self.clumps = lambda: clump_pass(dt, KICK_NONE, gravity, particles, lists.box, half)
        self.rebuild = lambda: rebuild_neighbor_list(st.x, st.v, st.radius, skin, st.ids, st.fixed, st.clump, st.image, st.x_ref, lists)
        self.mesh_candidates = lambda: build_mesh_candidates(st.x, st.radius, skin, walls)

    def restore(self) -> None:
        for owner, name, arr in self.saved:
            getattr(owner, name)[...] = arr


def seconds_per_call(fn, repeats: int, blocks: int = 5) -> float:
    """The fastest of ``blocks`` blocks of ``repeats`` calls, per call (on a shared machine the
    fastest block is the one least disturbed by other work), after one call untimed."""
    fn()
    best = math.inf
    for _ in range(blocks):
        tic = time.perf_counter()
        for _ in range(repeats):
            fn()
        best = min(best, (time.perf_counter() - tic) / repeats)
    return best


def cpu_phase_seconds(passes: Passes, repeats: int, rebuilds_per_step: float) -> dict:
    """Seconds per step of each of ``PHASES``, each pass timed on its own on the present state: the
    walls are a gather with them less one without (and the mesh candidates, built with each
    neighbor list); the list's build counts ``rebuilds_per_step`` times."""
    split = {"contact forces": seconds_per_call(passes.pair, repeats)}
    gather_walls = seconds_per_call(passes.gather_walls, repeats)
    gather_plain = seconds_per_call(passes.gather_plain, repeats)
    split["walls"] = max(gather_walls - gather_plain, 0.0)
    if passes.state.meshes.n_triangles:
        split["walls"] += seconds_per_call(passes.mesh_candidates, repeats) * rebuilds_per_step
    split["integration and gathering"] = gather_plain + seconds_per_call(passes.kick, repeats)
    if passes.state.n_clumps:
        split["integration and gathering"] += seconds_per_call(passes.clumps, repeats)
    split["neighbor search"] = seconds_per_call(passes.rebuild, repeats) * rebuilds_per_step
    passes.restore()  # the timing calls must leave the state as it was
    return split
