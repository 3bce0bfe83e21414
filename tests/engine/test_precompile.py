"""A cold kernel compiles on two cores: a helper process fills Numba's cache with the scalar
contact law, the neighbor search and the gather while the run compiles the pair pass and the
drift (rollingdem.engine.precompile); only the step loop the run takes is compiled."""

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rollingdem as rd
from rollingdem.engine import precompile
from rollingdem.physics.contact.model import ContactModel
from rollingdem.engine.codegen import engine_module
from rollingdem.engine.precompile import is_cached, prepare


def test_no_helper_for_a_cached_step_loop_or_when_switched_off(monkeypatch):
    contact = ContactModel("hertz", rolling="cdt")
    sim = rd.Simulation(contact=contact, dt=1e-6)
    sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0))
    sim.add_particles([[0, 0, 0.01]], 0.01, "m")
    sim.run(steps=1)  # one sphere: the serial step loop
    kernel = sim.engine_module()  # the module for what the scene holds (no meshes, clumps, bonds, programs)
    assert is_cached(kernel, "gather_serial") and is_cached(kernel, "advance_serial")
    monkeypatch.setattr(precompile, "_PREPARED", set())
    assert not prepare(kernel, True)
    monkeypatch.setattr(precompile, "_PREPARED", set())
    monkeypatch.setenv("ROLLINGDEM_PRECOMPILE", "0")
    assert not prepare(kernel, False)


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="the helper runs only with a second core")
def test_a_failing_head_start_does_not_fail_the_run(monkeypatch):
    """The plan is only a head start: if it fails, the run compiles (here: loads) by itself, gives
    the same result, and the helper's lock is gone."""
    contact = ContactModel("hertz", rolling="cdt")

    def run():
        sim = rd.Simulation(contact=contact, dt=1e-6)
        sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0))
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
        sim.add_particles([[0, 0, 0.0099]], 0.01, "m", allow_overlap=True)
        sim.run(steps=20)
        return sim.positions.copy()

    before = run()
    kernel = engine_module(contact)

    def no_scene(*args, **kwargs):
        raise RuntimeError("no scene")

    monkeypatch.setattr(precompile, "_PREPARED", set())
    monkeypatch.setattr(precompile, "is_cached", lambda module, function="gather": False)
    monkeypatch.setattr(precompile, "signatures", no_scene)
    assert prepare(kernel, True)
    assert not list(Path(kernel.__file__).parent.glob(Path(kernel.__file__).stem + ".precompile.lock"))
    assert (run() == before).all()


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="the helper runs only with a second core")
def test_a_cold_kernel_compiles_on_two_processes_with_the_same_result(tmp_path):
    """Fresh caches, 600 spheres on 2 threads (the threaded step loop, as the default case): the
    run gives the same positions and spins, to the last bit, as with the helper switched off (on
    the suite's cache); the
    helper's lock is gone; both processes' functions are in the cache, and the serial step loop,
    which this run does not take, is not compiled."""
    script = ("import numpy as np, numba, rollingdem as rd\n"
              "from rollingdem.physics.contact.model import ContactModel\n"
              "numba.set_num_threads(2)\n"
              "sim = rd.Simulation(contact=ContactModel('hertz', rolling='epsd2'), dt=1e-6)\n"
              "sim.add_material(rd.Material('m', youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0))\n"
              "sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material='m'))\n"
              "g = np.arange(600)\n"
              "x = np.column_stack([0.0195 * (g % 30), 0.03 * (g // 30), np.full(600, 0.0099)])\n"
              "sim.add_particles(x, 0.01, 'm', allow_overlap=True)\n"
              "sim.set_velocities([0], velocity=(0.1, 0, 0), angular_velocity=(0, 3.0, 0))\n"
              "sim.run(steps=50)\n"
              "print(repr(float(sim.positions[:, 0].sum())), repr(float(sim.angular_velocities[:, 1].sum())))\n")
    out = {}
    for mode in ("1", "0"):
        env = dict(os.environ, ROLLINGDEM_PRECOMPILE=mode)
        if mode == "1":
            env.update(ROLLINGDEM_CACHE_DIR=str(tmp_path / "k1"), NUMBA_CACHE_DIR=str(tmp_path / "n1"))
        # The run without the helper takes the suite's own cache (compiled once there, shared with
        # the other tests): a cached kernel is the compiled one, so one cold compile suffices.
        res = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
        out[mode] = res.stdout.split()
    assert out["1"] == out["0"]
    deadline = time.time() + 120
    locks = list((tmp_path / "k1").glob("*.precompile.lock"))
    while locks and time.time() < deadline:
        time.sleep(0.5)
        locks = list((tmp_path / "k1").glob("*.precompile.lock"))
    assert not locks
    names = {p.name.split(".")[1].split("-")[0] for p in (tmp_path / "n1").rglob("*.nbi")}
    helper, main = precompile.plans(serial=False)
    # the module's rebuild is the package's list rebuild, cached under its own name (no mesh here)
    assert (set(helper) - {"rebuild"}) | set(main) | {"advance", "rebuild_lists_without_meshes"} <= names
    assert "advance_serial" not in names and "gather_serial" not in names


def test_a_second_process_waits_for_the_compile_in_progress_and_takes_over_a_dead_ones_marker(tmp_path):
    """The marker of a compile in progress holds its process's id: another process does not take it
    while that process lives, waits until it is gone (a test worker beside the one compiling loads
    the result instead of compiling it again), and takes over a marker whose process has died."""
    marker = tmp_path / "kernel.compiling0"
    assert precompile._take(marker) and marker.read_text() == str(os.getpid())
    assert not precompile._take(marker)  # held by a live process: this one
    marker.write_text("999999999")  # no such process
    assert precompile._take(marker) and marker.read_text() == str(os.getpid())
    holder = subprocess.Popen([sys.executable, "-c", f"import os, time; time.sleep(1.0); os.unlink({str(marker)!r})"])
    marker.write_text(str(holder.pid))
    tic = time.monotonic()
    precompile._wait_for(marker)
    waited = time.monotonic() - tic
    holder.wait()
    assert not marker.exists() and 0.5 < waited < 10.0
