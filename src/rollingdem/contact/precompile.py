"""Compile a new engine kernel on two cores instead of one.

A kernel that is not yet in the on-disk cache costs about 22 s of Numba compilation, one function
after the other: the neighbor search (5 s), the serial contact and gather loops, then the parallel
ones, then the step loop. While this process compiles the first of them, a helper process
compiles the parallel gather (with the wall contacts, 4.7 s plus the contact law it needs), the
parallel drift and the parallel pair loop, and stores them in Numba's cache; when this process
reaches them it loads them from there. Numba writes its cache files atomically (a temporary file,
then ``os.replace``), so two processes compiling the same function at once only duplicate work.

The helper starts only when the kernel's gather is not cached, more than one core is available,
no other helper is compiling this kernel (a lock file, stale after 10 minutes) and
``ROLLINGDEM_PRECOMPILE`` is not ``0``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

HELPER_FUNCTIONS = ("block_contacts", "gather", "kick_drift", "pair_forces")  # the step loop types them last
LOCK_STALE_S = 600.0


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def is_cached(module, function: str = "gather") -> bool:
    """Whether Numba's cache holds ``module.function`` (its index file exists)."""
    path = Path(module.__file__)
    pattern = f"{path.stem}.{function}-*.nbi"
    places = [path.parent / "__pycache__"]
    if os.environ.get("NUMBA_CACHE_DIR"):
        places.append(Path(os.environ["NUMBA_CACHE_DIR"]))
    return any(next(iter(p.rglob(pattern)), None) is not None for p in places if p.exists())


def start_helper(contact, module, track_energy: bool = False):
    """Start the helper for ``module`` (the kernel of ``contact``) if it would help; returns the
    process or None."""
    if os.environ.get("ROLLINGDEM_PRECOMPILE", "1") == "0" or _cores() < 2 or is_cached(module):
        return None
    lock = Path(module.__file__).with_suffix(".precompile.lock")
    try:
        if lock.exists() and time.time() - lock.stat().st_mtime > LOCK_STALE_S:
            lock.unlink()
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        os.close(fd)
    except OSError:  # another helper is at it, or the folder is read-only
        return None
    env = dict(os.environ, ROLLINGDEM_PRECOMPILE="0")
    return subprocess.Popen([sys.executable, "-m", "rollingdem.contact.precompile", json.dumps(contact.to_dict()),
                             str(lock), str(int(track_energy))], env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def _compile(contact_dict: dict, track_energy: bool = False) -> None:
    """Type the helper's functions on a one-sphere state and compile them into the cache."""
    import numba

    from ..materials import Material
    from ..simulation import Simulation
    from ..walls import Plane
    from .model import ContactModel

    sim = Simulation(contact=ContactModel.from_dict(contact_dict), dt=1e-6, track_energy=track_energy)
    sim.add_material(Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=1000.0, friction=0.5,
                              rolling_friction=0.1, restitution=0.5, rolling_damping=0.1))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0.0, 0.0, 0.01]], 0.01, "m")
    st, kernel = sim._state, sim.kernel()
    dt, kick, half_skin = 1e-6, 1.0, 1e-3
    pp = sim.pair_parameters()
    args = {
        "block_contacts": (st.contact_blocks()[0][0], pp[0, 0], dt),
        "gather": (dt, kick, sim._gravity, st.x, st.v, st.w, st.f, st.t, st.radius, st.mass, st.inertia, st.mat, pp,
                   st.tr_start, st.tr_k, st.touch, st.pair_force, st.pair_torque_j, st.wall_kind, st.wall_geom,
                   st.wall_vel, st.wall_omega, st.wall_mat, st.whist, st.wtouch, st.energy, st.contacts, st.x_ref,
                   half_skin),
        "kick_drift": (dt, st.x, st.v, st.w, st.f, st.t, st.mass, st.inertia, st.x_ref, half_skin),
        "pair_forces": (dt, st.x, st.v, st.w, st.f, st.t, st.radius, st.mass, st.mat, pp, st.nl_start, st.nl_j,
                        st.hist, st.touch, st.pair_force, st.pair_torque_j, st.energy, st.contacts,
                        *st.contact_blocks()),
    }
    for name in HELPER_FUNCTIONS:
        if not is_cached(kernel, name):
            getattr(kernel, name).compile(tuple(numba.typeof(a) for a in args[name]))


if __name__ == "__main__":
    try:
        _compile(json.loads(sys.argv[1]), len(sys.argv) > 3 and sys.argv[3] == "1")
    finally:
        try:
            os.unlink(sys.argv[2])
        except OSError:
            pass
