"""What runs between steps: ``Observer``, the base of everything a run calls at an interval of
simulated time (the writers of ``rollingdem.io.observers``, a user's ``Callback``).

``Simulation.run`` calls each observer between calls of the compiled step loop, never inside it:
at the run's start, at every interval (rounded to whole steps), and at its end.
"""

from __future__ import annotations

from rollingdem.errors import ParameterError, check_positive


class Observer:
    """Base class: override ``observe`` (and ``start`` / ``finish`` if needed)."""

    def __init__(self, interval: float):
        self.interval = check_positive("observer interval", interval, "s")
        self._every = None
        self._next = None

    def check(self, sim) -> None:
        """Refuse what ``start`` would refuse for ``sim``, without writing anything (default: nothing)."""

    def start(self, sim) -> None:
        self._every = max(1, int(round(self.interval / sim.dt)))
        self._next = sim.step

    def next_step(self, sim) -> int:
        return self._next

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


class Callback(Observer):
    """Calls ``function(sim)`` at every interval (e.g. to record something of your own)."""

    def __init__(self, function, interval: float):
        super().__init__(interval)
        if not callable(function):
            raise ParameterError(f"callback function = {function!r} is not allowed: must be callable, function(sim)")
        self.function = function

    def observe(self, sim):
        self.function(sim)
