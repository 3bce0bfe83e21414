"""What ends a run before its maximum duration: ``Simulation.run(max_duration, until=...)``.

A condition is checked every ``every`` seconds of simulated time (rounded to whole steps), after
the outlets, inflows and observers have acted at that step; the run ends at the first check that
finds it met, and ``Simulation.run`` returns what ended it, in words. Several conditions: the first
met ends the run.
"""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_finite, check_positive
from rollingdem.scene.schedule import OBSERVE, Operation


class Condition(Operation):
    """Base class: ``met(sim)`` says whether the run should end now; ``describe()`` says why."""

    order = OBSERVE + 1  # after every observer has seen the step

    def __init__(self, every: float = 1e-3):
        self.every = check_positive("until every", every, "s")
        self._steps = None
        self._next = None

    def start(self, sim) -> None:
        self._steps = max(1, int(round(self.every / sim.dt)))
        self._next = sim.step + self._steps

    def next_step(self, sim) -> int:
        return self._next

    def update(self, sim) -> None:
        pass  # checked by the schedule, which stops the run

    def due(self, sim) -> bool:
        if sim.step < self._next:
            return False
        self._next = sim.step + self._steps
        return True

    def met(self, sim) -> bool:
        raise NotImplementedError

    def describe(self) -> str:
        raise NotImplementedError


class Settled(Condition):
    """Settled: the translational kinetic energy per free particle has stayed below
    ``kinetic_energy`` (J) for ``hold`` seconds, at every check. Default threshold: 1e-6 m g d for
    the free particles' mean mass m and mean diameter d (a particle of mean mass moving at
    1.4e-3 sqrt(g d)). With ``rotation``, the rotational energy counts too; it is left out by
    default because a sphere spinning about its contact normal, undamped without a twisting law,
    keeps its energy in a bed that no longer moves."""

    declared = {"kinetic_energy": Declared("threshold of the translational kinetic energy per free particle "
                                           "(default 1e-6 m g d, m and d the free particles' mean mass and "
                                           "diameter)", "J", low=0.0, low_open=True),
                "hold": Declared("how long the energy must stay below the threshold", "s", low=0.0),
                "every": Declared("time between checks", "s", low=0.0, low_open=True),
                "rotation": Declared("count the rotational kinetic energy too", kind="flag")}

    def __init__(self, kinetic_energy: float | None = None, hold: float = 0.05, every: float = 1e-3,
                 rotation: bool = False):
        super().__init__(every)
        if not isinstance(rotation, bool):
            raise ParameterError(f"settled rotation = {rotation!r} is not allowed: must be true or false")
        self.rotation = rotation
        self.kinetic_energy = None if kinetic_energy is None else check_positive("settled kinetic_energy",
                                                                                 kinetic_energy, "J")
        self.hold = check_finite("settled hold", hold)
        if self.hold < 0:
            raise ParameterError(f"settled hold = {hold:g} is not allowed: must be >= 0 (s)")
        self._below_since = None
        self._threshold = None

    def threshold(self, sim) -> float:
        if self.kinetic_energy is not None:
            return self.kinetic_energy
        free = ~sim.fixed
        if not free.any():
            return math.inf
        g = float(np.linalg.norm(sim.gravity)) or 9.81
        return 1e-6 * float(sim.masses[free].mean()) * g * 2.0 * float(sim.radii[free].mean())

    def start(self, sim):
        super().start(sim)
        self._below_since = None
        self._threshold = self.threshold(sim)

    def per_particle(self, sim) -> float:
        n = int((~sim.fixed).sum())
        translational, rotational = sim.kinetic_energy()
        return (translational + (rotational if self.rotation else 0.0)) / n if n else 0.0

    def met(self, sim):
        if self.per_particle(sim) >= self._threshold:
            self._below_since = None
            return False
        if self._below_since is None:
            self._below_since = sim.time
        return sim.time - self._below_since >= self.hold - 0.5 * sim.dt

    def describe(self):
        what = "kinetic energy" if self.rotation else "translational kinetic energy"
        return (f"settled: {what} per particle below {self._threshold:.3g} J for {self.hold:g} s")


class Reaches(Condition):
    """A measurement's quantity reaches a value: ``value(sim, quantity) >= above`` or ``<= below``
    (any object with that method: ``rollingdem.io.measurements``), at every check for ``hold``
    seconds (0: at one check). With a rate ``below`` a small value and a hold, "the flow has
    stopped": a trickle that sends one sphere through within the hold keeps the stage going."""

    def __init__(self, measurement, quantity: str, above: float | None = None, below: float | None = None,
                 every: float = 1e-3, hold: float = 0.0):
        super().__init__(every)
        self.hold = check_finite("until hold", hold)
        if self.hold < 0:
            raise ParameterError(f"until hold = {hold:g} is not allowed: must be >= 0 (s)")
        self._since = None
        if (above is None) == (below is None):
            raise ParameterError(f"until {getattr(measurement, 'name', measurement)}.{quantity}: above = {above!r}, "
                                 f"below = {below!r} is not allowed: give exactly one of above and below")
        if not hasattr(measurement, "value"):
            raise ParameterError(f"until measurement = {measurement!r} is not allowed: must be a measurement "
                                 "(rollingdem.io.measurements)")
        quantities = getattr(measurement, "QUANTITIES", None)
        if quantities is not None and quantity not in quantities:
            raise ParameterError(f"until {measurement.name}.{quantity} is not allowed: {measurement.name!r} measures "
                                 f"{', '.join(quantities)}")
        self.measurement, self.quantity = measurement, quantity
        self.above = None if above is None else check_finite("until above", above)
        self.below = None if below is None else check_finite("until below", below)
        self.last = math.nan

    def start(self, sim):
        super().start(sim)
        self._since = None

    def met(self, sim):
        self.last = v = self.measurement.value(sim, self.quantity)
        if not (v >= self.above if self.above is not None else v <= self.below):
            self._since = None
            return False
        if self._since is None:
            self._since = sim.time
        return sim.time - self._since >= self.hold - 0.5 * sim.dt

    def describe(self):
        how = f">= {self.above:g}" if self.above is not None else f"<= {self.below:g}"
        held = f" for {self.hold:g} s" if self.hold > 0 else ""
        return f"{self.measurement.name}.{self.quantity} {how}{held} (it is {self.last:.6g})"


#: Student's t at 97.5 % for the batch means' degrees of freedom (``io.measurements.BATCHES`` - 1 = 9)
T_975_BATCHES = 2.262157162798205


class Known(Condition):
    """A measurement's quantity known to within ``within`` (its unit): the 95 % interval of its mean
    over the samples since the run (the stage) began and inside its window, from the batch means
    of ``rollingdem.io.measurements`` (t with 9 degrees of freedom times the standard error), is
    +- ``within`` or narrower, over ``min_samples`` samples at least (20 at the least: two per
    batch). A rate's interval is that of its slope. The rotating drum's ``angle_within`` ends its
    measuring turn on it, so that the angle is sampled until it is known, not for a fixed turn."""

    def __init__(self, measurement, quantity: str, within: float, every: float = 1e-3, min_samples: int = 20):
        super().__init__(every)
        self.within = check_positive("until known_within", within)
        if isinstance(min_samples, bool) or not isinstance(min_samples, int) or min_samples < 20:
            raise ParameterError(f"until min_samples = {min_samples!r} is not allowed: must be an integer >= 20 (two "
                                 "samples in each of the 10 batches)")
        self.min_samples = min_samples
        if not hasattr(measurement, "estimate"):
            raise ParameterError(f"until measurement = {measurement!r} is not allowed: must be a measurement "
                                 "(rollingdem.io.measurements)")
        self.measurement, self.quantity = measurement, quantity
        self._check_quantity()  # a Function's quantities are known at its first sample: checked again at the start
        self.mean = self.half_width = math.nan
        self.samples = 0
        self._since = 0.0

    def _check_quantity(self):
        m, q = self.measurement, self.quantity
        if m.QUANTITIES is not None and q not in m.QUANTITIES:
            raise ParameterError(f"until {m.name}.{q} is not allowed: {m.name!r} measures {', '.join(m.QUANTITIES)}")
        if q in m.CUMULATIVE:
            raise ParameterError(f"until {m.name}.{q} known_within is not allowed: its value is the last sample's (a "
                                 "cumulative or end-state quantity), not a mean over samples")

    def start(self, sim):
        super().start(sim)
        self._check_quantity()
        self._since = sim.time

    def met(self, sim):
        mean, err, n = self.measurement.estimate(self.quantity, self._since)
        self.mean, self.half_width, self.samples = mean, T_975_BATCHES * err, n
        return n >= self.min_samples and self.half_width <= self.within

    def describe(self):
        return (f"{self.measurement.name}.{self.quantity} known to +- {self.within:g} (95 %): {self.mean:.6g} "
                f"+- {self.half_width:.3g} over {self.samples} samples")


class Empty(Condition):
    """No free particle is left (the outlets took them all)."""

    def met(self, sim):
        return not (~sim.fixed).any()

    def describe(self):
        return "empty: no free particle left"


def as_conditions(until) -> list[Condition]:
    """The conditions of a run: none, one, or a sequence of them; anything else refused."""
    if until is None:
        return []
    items = [until] if isinstance(until, Condition) else list(until) if isinstance(until, (list, tuple)) else [until]
    for k, c in enumerate(items):
        if not isinstance(c, Condition):
            raise ParameterError(f"until = {c!r} is not allowed: must be a condition (Settled, Reaches, Known, Empty) or a "
                                 "list of them")
    return items


__all__ = ["Condition", "Empty", "Known", "Reaches", "Settled", "as_conditions"]
