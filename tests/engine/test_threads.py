"""rollingdem.engine.threads: a run steps on the cores that other processes leave free."""

import time

import numba
import numpy as np
import pytest

import rollingdem.engine.layout as ek
import rollingdem.engine.threads as th
from helpers import cluster


class FakeMachine:
    """A clock and /proc/stat busy ticks (100 per second per core) of a 2-core machine on which
    this process uses ``own`` cores and other processes ``others`` cores."""

    def __init__(self, others=0.0, own=2.0):
        self.t, self.busy, self.mine = 0.0, 0.0, 0.0
        self.others, self.own = others, own

    def clock(self):
        return self.t

    def ticks(self):
        return int(self.busy)

    def own_cpu(self):
        return self.mine

    def run(self, seconds):
        self.t += seconds
        self.mine += self.own * seconds
        self.busy += 100 * (self.own + self.others) * seconds


def governor(machine, cores=2):
    g = th.ThreadGovernor(clock=machine.clock, ticks=machine.ticks, own_cpu=machine.own_cpu)
    g.cpus, g.hz = set(range(cores)), 100
    return g


@pytest.mark.parametrize("cores, others, given, expected", [
    (2, 0.0, 2, 2),  # quiet: all it was given
    (2, 0.3, 2, 2),  # a light background load is not worth a core
    (2, 1.0, 2, 1),  # a process busy on one core
    (2, 2.0, 2, 1),  # never fewer than one
    (8, 3.0, 8, 5),
    (8, 0.0, 4, 4),  # never more than given
])
def test_threads_for_the_free_cores(cores, others, given, expected):
    assert th.threads_for(cores, others, given) == expected


def test_governor_follows_the_load_and_gives_the_threads_back(monkeypatch):
    """Segments of ~SEGMENT_S seconds; a decision once DECIDE_S seconds are measured, from the busy
    ticks other processes added (the ticks minus this process's CPU time). The user's thread count
    is set back at the end of each call."""
    monkeypatch.setattr(th, "_fixed", False)
    monkeypatch.setattr(numba, "set_num_threads", lambda k: None)
    m = FakeMachine(others=0.0, own=2.0)
    g = governor(m)
    g.begin(2, parallel=True)
    assert g.active
    assert g.segment(10_000) == th.FIRST_SEGMENT
    m.run(0.01)  # 20 steps in 10 ms: 2000 steps/s
    g.done(th.FIRST_SEGMENT)
    assert g.threads == 2  # too short a window to decide
    steps = g.segment(10_000)
    assert steps == int(2000 * th.SEGMENT_S)
    m.others, m.own = 1.0, 1.2  # another process takes a core: ours share the other
    m.run(0.5)
    g.done(steps)
    assert g.threads == 1
    m.others, m.own = 0.0, 1.0  # it ends
    g.segment(10_000)
    m.run(0.5)
    g.done(steps)
    assert g.threads == 2
    assert g.steps_on == {2: th.FIRST_SEGMENT + steps, 1: steps}  # what the bench reports
    g.close()
    # one thread given, the serial loop, or --threads: all steps in one call
    for given, parallel, fixed in ((1, True, False), (2, False, False), (2, True, True)):
        monkeypatch.setattr(th, "_fixed", fixed)
        g.begin(given, parallel)
        assert not g.active and g.segment(12_345) == 12_345


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 Numba threads")
def test_run_on_changing_threads_is_bit_identical(table1, monkeypatch):
    """Each particle's terms are summed in a fixed order, so a run whose segments step on 2, 1, 2,
    ... threads (the governor seeing the machine busy every other decision) ends exactly where the
    same run on 2 threads in one call ends."""
    monkeypatch.setattr(ek, "SERIAL_BELOW", 0)  # the threaded loop for this small scene
    monkeypatch.setattr(th, "_fixed", True)
    numba.set_num_threads(2)
    ref = cluster(table1, n_side=6)
    ref.run(steps=400)
    assert ref.number_of_contacts() > 50

    monkeypatch.setattr(th, "_fixed", False)
    monkeypatch.setattr(th, "DECIDE_S", 0.0)  # decide after every segment
    monkeypatch.setattr(th, "SEGMENT_S", 1e-9)  # segments of one step after the first
    sim = cluster(table1, n_side=6)
    m = FakeMachine()
    g = governor(m)
    used = []

    def ticks():  # another process on one core at every other reading
        used.append(numba.get_num_threads())
        m.busy += 0 if len(used) % 4 < 2 else 1e9
        return int(m.busy)
    g.ticks, g.readable, g.clock = ticks, True, time.perf_counter
    sim._state._governor = g
    try:
        sim.run(steps=400)
    finally:
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert {1, 2} <= set(used)
    assert numba.get_num_threads() == numba.config.NUMBA_NUM_THREADS
    for name in ("positions", "velocities", "angular_velocities"):
        np.testing.assert_array_equal(getattr(sim, name), getattr(ref, name), err_msg=name)


def test_on_off_environment_variables_refuse_other_values(monkeypatch):
    """"1" on, "0" off, unset the default; a value such as "yes" is refused, naming the variable
    and its value, rather than read silently as on: at import for ROLLINGDEM_ADAPTIVE_THREADS."""
    import subprocess
    import sys

    from rollingdem.errors import ParameterError, env_switch

    name = "ROLLINGDEM_PRECOMPILE"
    monkeypatch.delenv(name, raising=False)
    assert env_switch(name) is True and env_switch(name, default=False) is False
    for value, on in (("1", True), ("0", False)):
        monkeypatch.setenv(name, value)
        assert env_switch(name) is on
    monkeypatch.setenv(name, "no")
    with pytest.raises(ParameterError, match=f"{name} = 'no' is not allowed: must be 0"):
        env_switch(name)
    monkeypatch.setenv("ROLLINGDEM_ADAPTIVE_THREADS", "yes")
    out = subprocess.run([sys.executable, "-c", "import rollingdem"], capture_output=True, text=True)
    assert out.returncode != 0
    assert "ROLLINGDEM_ADAPTIVE_THREADS = 'yes' is not allowed" in out.stderr
