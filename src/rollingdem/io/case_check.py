"""``check_case``: everything a run of a case file would refuse before its first step, refused
without running or writing anything (``rollingdem check``, and ``rollingdem run`` before it starts)."""

from __future__ import annotations

import numpy as np

from rollingdem.engine.layout import I_FORCES_VALID
from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_positive, check_vector
from rollingdem.io.case_errors import InCase
from rollingdem.io.case_schema import CaseSpec, StageWindowSpec
from rollingdem.io.casefile import (build_measurements, build_simulation, motion_of, stage_conditions, stage_duration,
                                    stage_time_steps)
from rollingdem.scene.motion import check_program
from rollingdem.scene.periodic import check_scene


def check_case(case: CaseSpec, sim=None):
    """Everything ``run_case`` would refuse before its first step, refused now, without running or
    writing anything: the scene (``build_simulation``), each stage (duration, gravity, walls it
    removes, velocities it sets), the outputs, and dt against the stable limit at the start of
    the first stage. ``rollingdem check`` and ``rollingdem run`` both call it; returns the
    simulation (``sim`` if given, else a new one)."""
    sim = build_simulation(case) if sim is None else sim
    with InCase("periodic"):
        check_scene(sim)
    n = sim.n_particles
    in_place = {w.name for w in sim.walls if w.name}
    removed: set[str] = set()
    first_velocities = None
    measurements = build_measurements(case, sim)
    for k, stage in enumerate(case.stages):
        where = f"stage {stage.name!r}"
        stage_conditions(stage, measurements)
        check_non_negative(f"{where}: " + ("duration" if stage.until is None else "max_duration"),
                           stage_duration(stage), "s")
        if stage.gravity is not None:
            check_vector(f"{where}: gravity", stage.gravity)
        if stage.shear_rate is not None:
            check_finite(f"{where}: shear_rate", stage.shear_rate)
            if not sim.shear.active:
                raise ParameterError(f"{where}: shear_rate = {stage.shear_rate!r} is not allowed: the box is not "
                                     "sheared; give the periodic block a shear_rate (0 to start at rest) and a "
                                     "gradient")
        for name in stage.remove_walls:
            if name in removed:
                raise ParameterError(f"{where}: remove_walls = {name!r} is not allowed: an earlier stage removed "
                                     "that wall already")
            if name not in in_place:
                raise ParameterError(f"{where}: remove_walls = {name!r} is not allowed: no wall has that name; "
                                     f"wall names are {', '.join(map(repr, sorted(in_place))) or 'none'}")
            in_place.discard(name)
            removed.add(name)
        for m in stage.wall_motion:
            if m.wall not in in_place:
                raise ParameterError(f"{where}: wall_motion wall = {m.wall!r} is not allowed: no wall in place has "
                                     f"that name; wall names are {', '.join(map(repr, sorted(in_place))) or 'none'}")
            try:
                motion = motion_of(m, base=case.base_directory)
                wall = next(w for w in sim.walls if w.name == m.wall)
                check_program(wall, motion["motion"], repr(m.wall), motion.get("angular_velocity", (0.0, 0.0, 0.0)))
            except ParameterError as err:
                raise ParameterError(f"{where}: wall_motion {m.wall!r}: {err}") from None
            mesh = next(w.type == "mesh" for w in case.walls if w.name == m.wall)
            if m.rotate is not None and m.rotate.point is not None and not mesh:
                raise ParameterError(f"{where}: wall_motion {m.wall!r}: rotate point = {list(m.rotate.point)} is not "
                                     "allowed: a plane or cylinder turns about its own point; only a mesh wall takes a "
                                     "rotation point")
        sv = stage.set_velocity
        if sv is not None:
            if sv.velocity is None and sv.angular_velocity is None:
                raise ParameterError(f"{where}: set_velocity = {sv.model_dump(exclude_none=True)} is not allowed: "
                                     "give velocity and/or angular_velocity")
            for key in ("velocity", "angular_velocity"):
                if getattr(sv, key) is not None:
                    check_vector(f"{where}: set_velocity {key}", getattr(sv, key))
            if sv.particles != "all":
                bad = [i for i in sv.particles if not 0 <= i < n]
                if bad:
                    raise ParameterError(f"{where}: set_velocity particles = {bad[0]} is not allowed: must be in "
                                         f"[0, {n - 1}] (the case has {n} particles)")
            if k == 0:
                first_velocities = sv
        if stage.bonds is not None:
            b = stage.bonds
            if (b.gap is None) == (b.pairs is None):
                raise ParameterError(f"{where}: bonds is not allowed without exactly one of gap (m) and pairs")
            try:
                b.parallel_bond()
            except ParameterError as err:
                raise ParameterError(f"{where}: bonds: {err}") from None
            for i, j in b.pairs or ():
                if not (0 <= i < n and 0 <= j < n) or i == j:
                    raise ParameterError(f"{where}: bonds pairs = [{i}, {j}] is not allowed: must be two different "
                                         f"particles in [0, {n - 1}]")
    check_windows(case)
    stage_time_steps(case, sim)  # a given dt against each stage's wall motion
    out = case.output
    for key in ("time_series", "snapshots", "checkpoint"):
        block = getattr(out, key)
        if block is not None:
            check_positive(f"output.{key}.interval", block.interval, "s")
    if out.time_series is not None:
        bad = [i for i in out.time_series.particles if not 0 <= i < n]
        if bad:
            raise ParameterError(f"output.time_series.particles = {bad[0]} is not allowed: must be in [0, {n - 1}] "
                                 f"(the case has {n} particles)")
    _check_first_time_step(sim, first_velocities)
    with InCase("contact"):
        sim.time_step_policy.check_contact_reach(sim.skin)
    try:
        sim.boundary_set.check_room()
    except ParameterError as err:  # an inflow's region, or an outlet's refill region
        raise ParameterError(f"{'outlets' if str(err).startswith('outlet') else 'inflows'}: {err}") from None
    return sim


def check_windows(case: CaseSpec) -> None:
    """Refuse a measurement window that no run of the case reaches: an absolute one starting at or
    after the longest the stages can last, a stage's one naming no stage, starting before it or at
    or after its longest, or of no length."""
    ends = np.cumsum([stage_duration(s) for s in case.stages])
    lengths = {s.name: stage_duration(s) for s in case.stages}
    for k, m in enumerate(case.measurements):
        w, where = m.window, f"measurements.{k}: window"
        if w is None:
            continue
        if isinstance(w, StageWindowSpec):
            if w.stage not in lengths:
                raise ParameterError(f"{where} stage = {w.stage!r} is not allowed: no stage has that name; the stages "
                                     f"are {', '.join(repr(n) for n in lengths)}")
            if not 0 <= w.start < lengths[w.stage]:
                raise ParameterError(f"{where} start = {w.start:g} is not allowed: must be in [0, {lengths[w.stage]:g}) s, "
                                     f"within stage {w.stage!r}")
            if w.duration is not None and not w.duration > 0:
                raise ParameterError(f"{where} duration = {w.duration:g} is not allowed: must be > 0 (s)")
        elif len(ends) and w[0] >= ends[-1]:
            raise ParameterError(f"{where} = [{w[0]:g}, {w[1]:g}] is not allowed: it starts after the run, which lasts "
                                 f"at most {ends[-1]:g} s; give times within it, or a window from a stage's start "
                                 "({stage: NAME, start: S, duration: D})")


def _check_first_time_step(sim, sv) -> None:
    """dt against the stable limit as the first stage's run will see it (after its set_velocity);
    the velocities are put back afterwards."""
    st = sim.particle_set.state
    saved = (st.v.copy(), st.w.copy(), int(st.info[I_FORCES_VALID]))
    try:
        if sv is not None:
            idx = np.flatnonzero(~sim.fixed) if sv.particles == "all" else sv.particles
            sim.set_velocities(idx, sv.velocity, sv.angular_velocity)
        sim.check_time_step()
    finally:
        st.v[...] = saved[0]
        st.w[...] = saved[1]
        st.info[I_FORCES_VALID] = saved[2]
