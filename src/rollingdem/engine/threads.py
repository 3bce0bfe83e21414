"""How many threads a run steps on: all it was given on a quiet machine, fewer while other
processes keep cores busy.

A run not given a fixed thread count steps in segments of about ``SEGMENT_S`` seconds, each on the
cores that other processes left free in the last (:class:`ThreadGovernor`); results are the same
bit for bit. Why and when: docs/architecture.md, "Threads"; measured: docs/performance.md."""

from __future__ import annotations

import os
import time

import numba

from rollingdem.errors import env_switch

SEGMENT_S = 0.5  # seconds per segment: a call of the step loop costs ~0.1 ms
DECIDE_S = 0.2  # shortest segment that decides: /proc/stat counts in ticks of 10 ms per core
FIRST_SEGMENT = 20  # steps, to measure the rate
_fixed = not env_switch("ROLLINGDEM_ADAPTIVE_THREADS")


def fix_threads(threads: int) -> None:
    """Step on exactly ``threads`` Numba threads from now on, whatever the load (``--threads``)."""
    global _fixed
    numba.set_num_threads(threads)
    _fixed = True


def _cpu_ticks(cpus) -> int | None:
    """Busy clock ticks (user, nice, system, irq, softirq; not idle, iowait or steal) of ``cpus``
    since boot, from /proc/stat; None where it cannot be read."""
    try:
        with open("/proc/stat") as fh:
            lines = fh.readlines()
    except OSError:
        return None
    total = 0
    for line in lines:
        name, _, rest = line.partition(" ")
        if name.startswith("cpu") and name[3:].isdigit() and int(name[3:]) in cpus:
            fields = rest.split()
            total += sum(int(fields[k]) for k in (0, 1, 2, 5, 6))
    return total


def threads_for(cores: int, others: float, given: int) -> int:
    """Threads to step on: the cores that other processes leave free (``others``: the cores'
    worth of CPU time they took), rounded, at least 1 and at most ``given``."""
    return max(1, min(given, int(cores - others + 0.5)))


class ThreadGovernor:
    """Chooses each segment's length and thread count (docs/architecture.md, "Threads"). One per
    engine state, kept across ``EngineState.advance`` calls so that short output intervals still
    add up to a measurement. ``given`` is the Numba thread count when a call begins; it is set
    back when the call ends."""

    def __init__(self, clock=time.perf_counter, ticks=None, own_cpu=None):
        try:
            self.cpus = set(os.sched_getaffinity(0))
        except AttributeError:  # not Linux
            self.cpus = set(range(os.cpu_count() or 1))
        self.hz = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
        self.clock = clock
        self.ticks = ticks or (lambda: _cpu_ticks(self.cpus))
        self.own_cpu = own_cpu or (lambda: sum(os.times()[:2]))
        self.readable = self.ticks() is not None
        self.given = self.threads = None
        self.active = False
        self.rate = None  # steps per second of the last segment
        self.steps_on = {}  # steps made on each thread count, while active
        self._window = None  # (wall, busy ticks, own CPU seconds) where the measurement began
        self._start = 0.0

    def begin(self, given: int, parallel: bool) -> None:
        """A call of ``EngineState.advance`` begins, with ``given`` Numba threads, on the
        threaded step loop if ``parallel``."""
        if given != self.given:  # the user's setting changed: start again from it
            self.given = self.threads = given
            self._window = None
        self.active = parallel and given > 1 and not _fixed and self.readable

    def segment(self, remaining: int) -> int:
        """Steps of the next call of the step loop (all that remain unless active); its thread count is set."""
        if not self.active:
            return remaining

        numba.set_num_threads(self.threads)
        self._start = self.clock()
        if self._window is None:
            self._window = (self._start, self.ticks(), self.own_cpu())
        if self.rate is None:
            return min(remaining, FIRST_SEGMENT)
        return min(remaining, max(1, int(self.rate * SEGMENT_S)))

    def done(self, steps: int) -> None:
        """After a call of the step loop of ``steps`` steps: once ``DECIDE_S`` seconds are measured, the
        thread count of the segments to come."""
        if not self.active or self._window is None:
            return
        now = self.clock()
        self.steps_on[self.threads] = self.steps_on.get(self.threads, 0) + steps
        if steps > 0 and now > self._start:
            self.rate = steps / (now - self._start)
        wall0, ticks0, own0 = self._window
        wall = now - wall0
        if wall < DECIDE_S or wall <= 0.0:
            return
        ticks = self.ticks()
        self._window = None
        if ticks is None:
            return
        others = max(0.0, (ticks - ticks0) / self.hz - (self.own_cpu() - own0)) / wall
        self.threads = threads_for(len(self.cpus), others, self.given)

    def close(self) -> None:
        """The call ends: the Numba thread count is the user's again."""
        if self.active:
            numba.set_num_threads(self.given)
