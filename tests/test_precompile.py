"""A cold kernel compiles on two cores: a helper process fills Numba's cache with the parallel
gather, drift and pair loop while the engine compiles the rest (rollingdem.contact.precompile)."""

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rollingdem as rd
from rollingdem.contact.model import ContactModel
from rollingdem.contact.precompile import is_cached, start_helper


def _ready_kernel():
    contact = ContactModel("hertz", rolling="cdt")
    sim = rd.Simulation(contact=contact, dt=1e-6)
    sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0))
    sim.add_particles([[0, 0, 0.01]], 0.01, "m")
    sim.run(steps=1)
    return contact, contact.kernel()


def test_no_helper_for_a_cached_kernel_or_when_switched_off(monkeypatch):
    contact, kernel = _ready_kernel()
    assert is_cached(kernel, "gather") and is_cached(kernel, "advance")
    assert start_helper(contact, kernel) is None
    monkeypatch.setenv("ROLLINGDEM_PRECOMPILE", "0")
    assert start_helper(contact, kernel) is None


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="the helper runs only with a second core")
def test_a_cold_kernel_gets_its_gather_from_the_helper(tmp_path):
    """Fresh caches: the run compiles; the helper's three functions are in the cache, its lock is
    gone, and the one-step result is the same as with the helper switched off."""
    script = ("import rollingdem as rd, sys\n"
              "from rollingdem.contact.model import ContactModel\n"
              "sim = rd.Simulation(contact=ContactModel('hertz', rolling='epsd2'), dt=1e-6)\n"
              "sim.add_material(rd.Material('m', youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0))\n"
              "sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material='m'))\n"
              "sim.add_particles([[0, 0, 0.0099], [0.0195, 0, 0.0099]], 0.01, 'm', allow_overlap=True)\n"
              "sim.set_velocities([0], velocity=(0.1, 0, 0), angular_velocity=(0, 3.0, 0))\n"
              "sim.run(steps=50)\n"
              "print(repr(float(sim.positions[0, 0])), repr(float(sim.angular_velocities[1, 1])))\n")
    out = {}
    for mode in ("1", "0"):
        env = dict(os.environ, ROLLINGDEM_PRECOMPILE=mode, ROLLINGDEM_CACHE_DIR=str(tmp_path / f"k{mode}"),
                   NUMBA_CACHE_DIR=str(tmp_path / f"n{mode}"))
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
    assert {"gather", "kick_drift", "pair_forces", "advance"} <= names
