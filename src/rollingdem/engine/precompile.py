"""Compile a new engine module on two cores instead of one.

When the step loop a run takes is not yet in Numba's cache, a helper process compiles part of its
passes into the cache while this process compiles the rest (``prepare``, from
``codegen.engine_module``). The plan, its fallbacks and when the helper starts:
docs/architecture.md, "Compiling an engine module"; the time it saves: docs/performance.md."""

from __future__ import annotations

import importlib.util
import os
import selectors
import subprocess
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba.core.caching import FunctionCache

from rollingdem.engine.layout import KICK_CLOSE
from rollingdem.engine.state import EngineState
from rollingdem.errors import env_switch
from rollingdem.physics.records import N_INPUTS, WALL_GEOMETRY_SIZE, WALL_PLANE

LOCK_STALE_S = 600.0
HELPER_WAIT_S = 600.0  # the longest this process waits for the helper before compiling alone
_PREPARED: set[tuple[str, bool]] = set()


def plans(serial: bool) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(the helper's functions, this process's functions), each list in the order compiled."""
    sfx = "_serial" if serial else ""
    # about half the work each (docs/performance.md): the neighbor rebuild, which the step loop alone
    # calls, goes to the helper, which has it done while this process compiles the pair pass, the
    # gather and the drift passes
    helper = ("contact", "gather_rows", "rebuild")
    # the contact block first: it needs nothing of the helper's, which is still starting
    main = ("block_contacts", "pair_forces" + sfx, "gather" + sfx, "kick_drift" + sfx, "undo_drift")
    return helper, main


# main's function -> the helper's that it calls, which this process waits for
NEEDS = {"pair_forces": "contact", "pair_forces_serial": "contact", "gather": "gather_rows",
         "gather_serial": "gather_rows"}


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def is_cached(module, function: str = "gather") -> bool:
    """Whether Numba's cache holds ``module.function`` (its index file exists where Numba looks:
    the function may live in another module, as the neighbor search does)."""
    return Path(FunctionCache(getattr(module, function).py_func)._cache_file._index_path).exists()


def signatures(module) -> dict:
    """Argument types of every function the plans name, as the engine calls them (taken from an
    engine state of one sphere on a plate: types do not depend on sizes or values)."""
    st = EngineState(module.HISTORY_SIZE)
    st.set_walls([-1], wall_kind=[WALL_PLANE], wall_geom=[np.zeros(WALL_GEOMETRY_SIZE)])
    st.append_particles(x=np.array([[0.0, 0.0, 0.01]]), radius=np.array([0.01]), mass=np.array([1e-3]),
                        inertia=np.array([4e-8]))
    st.energy_for(module)
    dt, kick, half_skin, skin = 1e-6, KICK_CLOSE, 1e-3, 2e-3
    pp = np.zeros((1, 1, module.N_PARAMS))
    particles, walls, lists, scratch = st.records()
    gather = (dt, kick, np.zeros(3), pp, particles, walls, lists, scratch, half_skin)
    args = {
        "contact": (lists.pool, 0, (0.0,) * N_INPUTS, pp[0, 0], dt),
        "block_contacts": (scratch.blocks[0], pp[0, 0], dt),
        "rebuild_neighbor_list": (st.x, st.v, st.radius, skin, st.ids, st.fixed, st.clump, st.image, st.x_ref, lists),
        "rebuild": (particles, walls, lists, skin, st.info),
        "pair_forces": (dt, pp, particles, lists, scratch), "pair_forces_serial": (dt, pp, particles, lists, scratch),
        "gather_rows": (0, 1, dt, kick, np.zeros(3), particles, walls, lists, pp, half_skin),
        "gather": gather, "gather_serial": gather,
        "kick_drift": (dt, particles, half_skin), "kick_drift_serial": (dt, particles, half_skin),
        "undo_drift": (dt, particles),
    }
    return {name: tuple(numba.typeof(a) for a in values) for name, values in args.items()}


def compile_into_cache(module, name: str, sigs: dict) -> None:
    if not is_cached(module, name):
        getattr(module, name).compile(sigs[name])


def prepare(module, serial: bool) -> bool:
    """Compile the passes of ``module``'s step loop for ``serial`` on two cores (see above), if it
    would help, and return True; otherwise return False, and the first call compiles them on
    this core."""
    loop = "advance_serial" if serial else "advance"
    if (module.__name__, serial) in _PREPARED:
        return False
    _PREPARED.add((module.__name__, serial))
    if not env_switch("ROLLINGDEM_PRECOMPILE") or _cores() < 2 or is_cached(module, loop):
        return False
    # held for the whole compile: a second process that needs the same loop (a test worker beside
    # this one, a sweep's worker) waits for it and loads the result, instead of compiling it again
    busy = Path(module.__file__).with_suffix(f".compiling{int(serial)}")
    if not _take(busy):
        _wait_for(busy)
        return False
    try:
        return _prepare(module, serial)
    finally:
        busy.unlink(missing_ok=True)


def _take(marker: Path) -> bool:
    """Create ``marker`` holding this process's id; False where another live process holds it (one
    whose process is gone, or older than ``LOCK_STALE_S``, is taken over) or the folder is read-only."""
    for _ in range(2):
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if _holder_alive(marker):
                return False
            marker.unlink(missing_ok=True)
            continue
        except OSError:
            return False
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        return True
    return False


def _holder_alive(marker: Path) -> bool:
    try:
        age = time.time() - marker.stat().st_mtime
        text = marker.read_text()
        if age > LOCK_STALE_S:
            return False
        if not text:  # made, its id not written yet
            return age < 5.0
        os.kill(int(text), 0)
        return True
    except (OSError, ValueError):  # gone, or no such process
        return False


def _wait_for(marker: Path) -> None:
    """Until ``marker`` is gone or its holder has died, at most ``HELPER_WAIT_S``."""
    deadline = time.monotonic() + HELPER_WAIT_S
    while marker.exists() and _holder_alive(marker) and time.monotonic() < deadline:
        time.sleep(0.2)


def _prepare(module, serial: bool) -> bool:
    lock = Path(module.__file__).with_suffix(".precompile.lock")
    try:
        if lock.exists() and time.time() - lock.stat().st_mtime > LOCK_STALE_S:
            lock.unlink()
        os.close(os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except OSError:  # another process is preparing it, or the folder is read-only
        return False
    # the helper imports what this process imports (a sub-model defined in the user's own module)
    env = dict(os.environ, ROLLINGDEM_PRECOMPILE="0", PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    helper = subprocess.Popen([sys.executable, "-m", "rollingdem.engine.precompile", module.__file__, str(lock),
                               str(int(serial))], env=env, stdin=subprocess.DEVNULL,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, bufsize=0)
    progress = _Progress(helper)
    try:
        sigs = signatures(module)
        for name in plans(serial)[1]:
            if name in NEEDS:
                progress.wait(NEEDS[name])
            compile_into_cache(module, name, sigs)
        progress.wait(None)
    except Exception:  # only a head start: the run's first call compiles what is missing, and raises there
        pass
    finally:
        if helper.poll() is None:
            helper.kill()  # killed, it cannot remove its lock: this process does
        helper.wait()
        helper.stdout.close()
        lock.unlink(missing_ok=True)
    return True


class _Progress:
    """The names the helper has reported done, read from its unbuffered pipe (a buffered reader
    could hold a finished name back until the helper writes again)."""

    def __init__(self, helper):
        self.helper = helper
        self.done: set[str] = set()
        self._pending = b""

    def wait(self, name: str | None) -> None:
        """Until ``name`` is done (None: until the helper exits), at most ``HELPER_WAIT_S``."""
        deadline = time.monotonic() + HELPER_WAIT_S
        fd = self.helper.stdout.fileno()
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while name is None or name not in self.done:
                left = deadline - time.monotonic()
                if left <= 0 or not sel.select(left):
                    return
                chunk = os.read(fd, 4096)
                if not chunk:  # the helper exited
                    return
                *lines, self._pending = (self._pending + chunk).split(b"\n")
                self.done.update(line.decode().strip() for line in lines)


def _helper(path: str, serial: bool) -> None:
    """The helper's part of the plan for the generated engine module at ``path``, each name printed
    when it is in the cache."""
    name = Path(path).stem
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    sigs = signatures(module)
    for func in plans(serial)[0]:
        compile_into_cache(module, func, sigs)
        print(func, flush=True)


if __name__ == "__main__":
    try:
        _helper(sys.argv[1], sys.argv[3] == "1")
    finally:
        try:
            os.unlink(sys.argv[2])
        except OSError:
            pass
