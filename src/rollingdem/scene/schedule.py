"""What acts between calls of the compiled step loop: the schedule of a simulation.

Everything that happens between steps is an ``Operation``: the scene's outlets and inflows (for
good, saved in checkpoints) and a run's observers (the writers of ``rollingdem.io.observers``, a
user's ``Callback``; for that run). ``Simulation.run`` steps to the next step any operation is due
at, then lets each act, in the order of their ``order`` (taking out, then putting in, then
observing) and, within one order, in the order they were added, as HOOMD-blue's ``Operations``
runs updaters before writers. No operation ever runs inside the step loop.
"""

from __future__ import annotations

import math
import time as _time

import numpy as np

from rollingdem.errors import ParameterError, SimulationError, check_finite, check_integer, check_positive
from rollingdem.scene.progress import Progress

REMOVE, INSERT, OBSERVE = 0, 1, 2
"""The order operations act in at one step: what takes particles out, what puts them in, what
looks at the result."""


class Operation:
    """Base class of what acts between steps: ``next_step`` says when it is due next, ``update``
    acts if it is due now."""

    order = OBSERVE

    def next_step(self, sim) -> int:
        """The first step, after ``sim.step``, at which this operation is due."""
        raise NotImplementedError

    def update(self, sim) -> None:
        """Act if due at ``sim.step``."""
        raise NotImplementedError


class Observer(Operation):
    """Base class of what a run calls at an interval of simulated time (rounded to whole steps),
    at its start and at its end: override ``observe`` (and ``start`` / ``finish`` if needed)."""

    def __init__(self, interval: float):
        self.interval = check_positive("observer interval", interval, "s")
        self._every = None
        self._next = None
        self._last_step = None

    def check(self, sim) -> None:
        """Refuse what ``start`` would refuse for ``sim``, without writing anything (default: nothing)."""

    def start(self, sim) -> None:
        self._every = max(1, int(round(self.interval / sim.dt)))
        self._next = sim.step

    def next_step(self, sim) -> int:
        return self._next

    def position(self) -> tuple:
        """Where the observer stands: (the next step it observes at, the last step it observed)."""
        return self._next, getattr(self, "_last_step", None)

    def resume_at(self, position: tuple) -> None:
        """Go on from ``position`` (``position``), as if the run had not stopped."""
        self._next, self._last_step = position

    def update(self, sim) -> None:
        self.maybe_observe(sim)

    def maybe_observe(self, sim, force: bool = False) -> None:
        """Observe now if due (or if ``force``), once per step even over consecutive runs."""
        if (force or sim.step >= self._next) and getattr(self, "_last_step", None) != sim.step:
            self.observe(sim)
            self._last_step = sim.step
        if sim.step >= self._next:
            self._next = sim.step + self._every

    def observe(self, sim) -> None:
        raise NotImplementedError

    def finish(self, sim, failure=None) -> None:
        pass

    def __getstate__(self):
        """Everything but open files: a run's checkpoint keeps its observers (``rollingdem.io.runner``)."""
        return {k: (None if k in ("_file", "_writer") else v) for k, v in self.__dict__.items()}


class Callback(Observer):
    """Calls ``function(sim)`` at every interval (e.g. to record something of your own)."""

    def __init__(self, function, interval: float):
        super().__init__(interval)
        if not callable(function):
            raise ParameterError(f"callback function = {function!r} is not allowed: must be callable, function(sim)")
        self.function = function

    def observe(self, sim):
        self.function(sim)


def steps_of(duration, steps, dt) -> int:
    """The steps of a run given exactly one of ``duration`` (s, rounded to whole steps) and ``steps``."""
    if (duration is None) == (steps is None):
        raise ParameterError(f"duration = {duration!r}, steps = {steps!r} is not allowed: give exactly one of "
                             "duration (s) and steps")
    if steps is not None:
        return check_integer("steps", steps, low=0)
    duration = check_finite("duration", duration)
    if duration < 0:
        raise ParameterError(f"duration = {duration:g} is not allowed: must be >= 0 (s)")
    return int(round(duration / dt))


def as_observers(observers) -> list:
    """The observers of a run: one observer or a sequence of them; anything else refused."""
    if isinstance(observers, Observer):
        return [observers]
    try:
        observers = list(observers)
    except TypeError:
        observers = [observers]
    for k, ob in enumerate(observers):
        if not isinstance(ob, Observer):
            raise ParameterError(f"observers[{k}] = {ob!r} is not allowed: must be a rollingdem observer "
                                 "(TimeSeries, VTKSnapshots, Checkpoints, Callback)")
    return observers


class Schedule:
    """The operations of a simulation, kept for good (outlets, inflows), and those of one run
    (``during``: its observers); ``run`` alternates calls of the step loop with them."""

    def __init__(self, state):
        self.state = state  # the engine state the step loop advances
        self.stepped: set[int] = set()  # ids of the engine modules it has stepped with (compiled)
        self.operations: list[Operation] = []

    def add(self, operation: Operation) -> Operation:
        self.operations.append(operation)
        return operation

    def of(self, kind) -> list:
        """The operations kept that are instances of ``kind``, in the order they were added."""
        return [op for op in self.operations if isinstance(op, kind)]

    def during(self, observers=()) -> list[Operation]:
        """Every operation of a run with ``observers``, in the order they act at a step."""
        return sorted(self.operations + list(observers), key=lambda op: op.order)

    @staticmethod
    def next_step(sim, operations) -> int | None:
        """The first step after ``sim.step`` at which one of ``operations`` is due (None: none)."""
        steps = [op.next_step(sim) for op in operations]
        return min(steps) if steps else None

    @staticmethod
    def update(sim, operations) -> None:
        for op in operations:
            op.update(sim)

    def run(self, sim, steps: int, observers: list, progress: bool = False, label: str = "run",
            conditions=(), continuing: bool = False) -> str | None:
        """``Simulation.run`` after its checks: ``steps`` steps of ``sim``, each call of the step loop
        ending at the next step an operation is due at (or after ~0.25 s of work, so the progress
        bar and Ctrl-C stay responsive), or fewer where one of ``conditions`` is met first (then
        its words are returned; None when the steps ran out). The observers see the last step. A
        run that goes unstable stops with ``SimulationError`` after the observers have written
        what they had. ``continuing``: the observers and conditions go on from where a restored
        run left them (``rollingdem.io.runner.resume_case``), as if it had never stopped."""
        for ob in observers:
            ob.check(sim)  # all refusals before any observer writes
        bar, end, failure = None, sim.step + steps, None
        for ob in observers:
            kept = ob.position() if continuing else None
            ob.start(sim)
            if kept:
                ob.resume_at(kept)
        for c in () if continuing else conditions:
            c.start(sim)
        operations = self.during([*observers, *conditions])
        ended = None
        try:
            module = sim.engine_module()  # after the observers start: a TimeSeries turns on track_energy
            if progress:
                bar = Progress(sim, steps, label, warm=id(module) in self.stepped)
            for ob in () if continuing else observers:
                ob.maybe_observe(sim, force=True)
            chunk = 64
            while True:
                ended = next((c.describe() for c in conditions if c.due(sim) and c.met(sim)), None)
                if ended or sim.step >= end:
                    break
                due = self.next_step(sim, operations)
                todo = max(min(end, sim.step + chunk, *(() if due is None else (due,))) - sim.step, 1)
                tic = _time.perf_counter()
                gravity = np.asarray(sim.gravity, dtype=np.float64)
                done, problem = self.state.advance(module, todo, sim.dt, gravity, sim.skin, sim.pair_parameters())
                sim.wall_set.refresh()  # the one place the engine moves walls: their objects follow at once
                elapsed = _time.perf_counter() - tic
                self.stepped.add(id(module))
                sim.step += done
                sim.time = sim.time_origin[0] + (sim.step - sim.time_origin[1]) * sim.dt
                self.check_finite_state(sim)
                if problem:
                    raise SimulationError(f"at t = {sim.time:.6g} s (step {sim.step}): {problem}")
                if elapsed > 0:
                    chunk = int(min(max(todo * 0.25 / elapsed, 1), 1_000_000))
                self.update(sim, operations)
                # an operation may have added what the module has no pass for (an inflow's first
                # clumps): the module the scene now takes (the same one, nearly always)
                module = sim.engine_module()
                if bar:
                    bar.update(sim, todo, elapsed)
            for ob in observers:
                ob.maybe_observe(sim, force=True)  # the run's last step, once
        except SimulationError as err:
            failure = err
            raise
        finally:
            sim.wall_set.refresh()  # a run stopped by an interrupt between a call and its refresh
            for ob in observers:
                ob.finish(sim, failure)
            if bar:
                bar.close()
        return ended

    def check_finite_state(self, sim) -> None:
        """Stop with ``SimulationError`` naming the first particle whose state is not finite."""
        st = self.state
        # the sum of the state is finite when every value is (a finite sum that overflows only leads
        # to the exact test): one pass, no temporaries, after every call of the step loop
        if math.isfinite(float(st.x.sum()) + float(st.v.sum()) + float(st.w.sum())):
            return
        bad = ~(np.isfinite(st.x).all(axis=1) & np.isfinite(st.v).all(axis=1) & np.isfinite(st.w).all(axis=1))
        if bad.any():
            k = int(st.ids[np.nonzero(bad)[0][0]])
            raise SimulationError(f"the state became non-finite at t = {sim.time:.6g} s (step {sim.step}), "
                                  f"particle {k}: the run is unstable; reduce dt (now {sim.dt:.4g} s, stable "
                                  f"estimate {sim.stable_time_step():.4g} s) or check the input")
