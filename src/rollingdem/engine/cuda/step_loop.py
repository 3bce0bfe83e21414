"""The step loop on a CUDA GPU (``Simulation(backend="cuda")``, docs/gpu.md).

The CPU engine's own step control: the host runs the engine module's ``advance``
(``rollingdem.engine.template.loop``) as Python, its phases (``rebuild``, ``open_step``,
``close_step``, ``take_back_drift``) bound to launches of CUDA kernels around the very functions
the CPU compiles from the same generated module: the contact laws, the pair row, the gather, the
walls, the bonds, the integrator. One physics source and one control; only the driving differs:

- pair pass: one thread per list row, through the scalar ``pair_row`` (``pair_rows_scalar``); the
  list goes to the device without pool groups, which makes entry k's contact keep pool row k (the
  CPU's rows share their group's rows, which one thread must own). The history goes to that
  layout on the way to the device and back to the CPU's on the way home;
- bonds: one thread per bond (``bond_forces``), each writing its own row;
- gather: one thread per particle (``gather_rows`` on one particle): its own row's sum, the
  entries where it is the second partner in list order, walls, gravity, the kicks and the drift;
- clumps: one thread per clump (``clump_rows``), summing its members in their order and moving them;
- neighbor list: rebuilt on the device (``rollingdem.engine.cuda.neighbors``), the same list as the CPU's.

No force is summed with atomics: every particle's force is written by one thread in a fixed order,
so runs are deterministic. Atomics add up the step's two flag counts and the rebuild's counting
sorts (integers), and take the bounding box (float min and max): none of them makes the result
depend on the threads' order. One synchronisation per step: the host reads the flag counts after
the gather (and the walls' motion, which the device skips when a particle is too fast).
"""

from __future__ import annotations

import collections
import math
import time
import types

import numpy as np

from rollingdem.engine.cuda import target as cuda_target
from rollingdem.engine.cuda import neighbors as gpu_neighbors
from rollingdem.engine.layout import KICK_CLOSE_AND_DRIFT
from rollingdem.engine.neighbors import index_list, put_entry_history
from rollingdem.engine.rigid_body import KICK_OPEN

#: what a kernel needs besides the records; the flags count particles past skin/2 and too fast
StepInputs = collections.namedtuple("StepInputs", ("gravity", "pair_params", "flags"))
EXCEED, FAST = 0, 1
#: the engine module's functions that its ``advance`` calls, each bound to launches on the device
PHASES = ("rebuild", "open_step", "close_step", "take_back_drift")

_KERNELS = {}
# ``numba.cuda``, from ``cuda_target`` when the first kernels are made: a global of this module, as
# the kernels use it (the simulator swaps such a global for its own while they run)
cuda = None


def kernel_bodies(module) -> dict:
    """The Python bodies of the CUDA kernels of an engine module (``rollingdem.engine.codegen``), by name:
    what ``cuda_kernels`` compiles, and what the PTX check compiles without a device."""
    global cuda
    cuda = cuda_target.cuda_module()
    pair_rows_scalar, gather_rows, bond_forces = module.pair_rows_scalar, module.gather_rows, module.bond_forces
    kick_drift_range, move_walls, move_meshes = module.kick_drift_range, module.move_walls, module.move_meshes
    clump_rows = module.clump_rows

    def pairs(dt, particles, lists, step):
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            pair_rows_scalar(i, i + 1, dt, particles, lists, step.pair_params)

    def bonds(dt, particles, lists):
        b = cuda.grid(1)
        if b < particles.bond_pairs.shape[0]:
            bond_forces(b, b + 1, dt, particles, lists.box)

    def gather(dt, kick, half_skin, particles, walls, lists, step):
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            exceed, fast = gather_rows(i, i + 1, dt, kick, step.gravity, particles, walls, lists, step.pair_params,
                                       half_skin)
            if exceed:
                cuda.atomic.add(step.flags, EXCEED, exceed)
            if fast:
                cuda.atomic.add(step.flags, FAST, fast)

    def clumps(dt, kick, half_skin, particles, lists, step):
        """One thread per clump (``clump_rows``): after the gather, or for the opening half alone."""
        c = cuda.grid(1)
        if c < particles.clump_mass.shape[0]:
            exceed, fast = clump_rows(c, c + 1, dt, kick, step.gravity, particles, lists.box, half_skin)
            if exceed:
                cuda.atomic.add(step.flags, EXCEED, exceed)
            if fast:
                cuda.atomic.add(step.flags, FAST, fast)

    def drift(dt, half_skin, particles, step):
        i = cuda.grid(1)
        if i < particles.x.shape[0]:
            exceed = kick_drift_range(i, i + 1, dt, particles, half_skin)
            if exceed:
                cuda.atomic.add(step.flags, EXCEED, exceed)

    def walls_move(dt, half_skin, walls, step, unless_fast):
        """The walls' and meshes' motion; none (``unless_fast``) after a gather that found a
        particle too fast, whose drift the host undoes."""
        if cuda.grid(1) == 0 and not (unless_fast and step.flags[FAST] != 0):
            move_walls(dt, walls)
            step.flags[EXCEED] += move_meshes(dt, walls, half_skin)

    return dict(pairs=pairs, bonds=bonds, gather=gather, clumps=clumps, drift=drift, walls_move=walls_move,
                **gpu_neighbors.kernel_bodies(module))


def cuda_kernels(module) -> dict:
    """The CUDA kernels of an engine module, by name, made once (each compiled at its first launch)."""
    kernels = _KERNELS.get(module.__name__)
    if kernels is None:
        cuda_target.require()
        kernels = _KERNELS[module.__name__] = {name: cuda_target.kernel(body)
                                               for name, body in kernel_bodies(module).items()}
    return kernels


class CudaStepLoop:
    """A drop-in for the engine module's ``advance``: the same arguments (host records), the same
    ``info`` bookkeeping, the steps on the GPU. The records go to the device at the call's start and
    come back at its end (or when the host must grow an array)."""

    def __init__(self, module):
        self.module = module
        self.kernels = cuda_kernels(module)
        self.device_bytes = 0  # the arrays of the last upload

    def __call__(self, nsteps, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info):
        m, k = self.module, self.kernels
        n = particles.x.shape[0]
        host = self._host(gravity, pair_params, particles, walls, lists)
        n_bonds, n_clumps = particles.bond_pairs.shape[0], particles.clump_mass.shape[0]
        dev, rebuild = self._upload(host, m.HISTORY_SIZE)
        self._counted = 0  # particles past skin/2 counted on the device so far (``_flags``)
        self.device_bytes = sum(a.nbytes for record in (*dev[:3], rebuild.arrays) for a in record) + \
            sum(a.nbytes for a in (*rebuild.sums, *rebuild.sums64))
        on_host = []  # the records came back before the call's end (a drift taken back)

        def rebuild_lists(particles, walls, lists, skin, info):
            return rebuild(skin, dev[0], dev[1], dev[2], info)

        def open_step(dt, gravity, particles, walls, lists, half_skin):
            return self._flags(dev, lambda: (
                cuda_target.launch(k["drift"], n, dt, half_skin, dev[0], dev[3]),
                cuda_target.launch(k["clumps"], n_clumps, dt, KICK_OPEN, half_skin, dev[0], dev[2], dev[3]),
                cuda_target.launch(k["walls_move"], 1, dt, half_skin, dev[1], dev[3], False)))[0]

        def close_step(dt, dt_bonds, kick, gravity, pair_params, particles, walls, lists, scratch, half_skin):
            """One synchronisation: the walls' move that goes with the next drift is launched
            with the rest, and the device skips it when a particle is too fast."""
            def launches():
                cuda_target.launch(k["pairs"], n, dt, dev[0], dev[2], dev[3])
                cuda_target.launch(k["bonds"], n_bonds, dt_bonds, dev[0], dev[2])  # none without bonds
                cuda_target.launch(k["gather"], n, dt, kick, half_skin, *dev)
                cuda_target.launch(k["clumps"], n_clumps, dt, kick, half_skin, dev[0], dev[2], dev[3])  # none without
                if kick == KICK_CLOSE_AND_DRIFT:
                    cuda_target.launch(k["walls_move"], 1, dt, half_skin, dev[1], dev[3], True)
            return self._flags(dev, launches)

        def take_back_drift(dt, particles, lists):
            self._download(dev, host, m.HISTORY_SIZE)
            on_host.append(True)
            m.take_back_drift(dt, particles, lists)

        bound = dict(zip(PHASES, (rebuild_lists, open_step, close_step, take_back_drift)))
        control = types.FunctionType(m.advance.py_func.__code__, {**vars(m), **bound})
        try:
            control(nsteps, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info)
        finally:
            if not on_host:
                self._download(dev, host, m.HISTORY_SIZE)

    def _flags(self, dev, launch):
        """Run ``launch`` and read the flag counts back (a synchronisation): what it added to them.
        The counts only grow on the device (uploaded as zeros), so that no step zeroes them; a too
        fast particle ends the call, so the count of those stays 0 until the launch that finds one."""
        launch()
        counts = cuda_target.array_to_host(dev[3].flags)
        added = int(counts[EXCEED]) - self._counted, int(counts[FAST])
        self._counted = int(counts[EXCEED])
        return added

    def phase_seconds(self, repeats, dt, gravity, skin, pair_params, particles, walls, lists, scratch, info):
        """Seconds per call of each pass of a step, timed on a copy of the present state on the
        device (the host's records stay as they are): ``repeats`` calls launched one after the
        other, then one synchronisation; the same arguments as a call of the loop.

        ``pairs`` (with the bonds), ``gather`` (with the walls and their motion), ``gather without
        walls``, ``rebuild`` (the neighbor list, with its one read-back; NaN if its arrays are
        short): the device's time. ``launch``: the host's time to launch a step's kernels, which
        the device's work overlaps. ``flag read``: a read of the flag counts from an idle device,
        the step's synchronisation."""
        k, m = self.kernels, self.module
        n, n_bonds, half_skin = particles.x.shape[0], particles.bond_pairs.shape[0], 0.5 * skin
        host = self._host(gravity, pair_params, particles, walls, lists)
        dev, rebuild = self._upload(host, m.HISTORY_SIZE, copy=True)
        no_walls = cuda_target.to_device(walls._make(a[:0] for a in walls), copy=True)
        launch = cuda_target.launch

        def timed(launches):
            """(device seconds, host seconds) per call of ``launches``."""
            launches()  # compiled, and the device warm
            cuda_target.synchronize()
            tic = time.perf_counter()
            for _ in range(repeats):
                launches()
            launched = time.perf_counter() - tic
            cuda_target.synchronize()
            return (time.perf_counter() - tic) / repeats, launched / repeats

        def pairs():
            launch(k["pairs"], n, dt, dev[0], dev[2], dev[3])
            launch(k["bonds"], n_bonds, dt, dev[0], dev[2])

        def gather(walls_now):
            launch(k["gather"], n, dt, 0.0, half_skin, dev[0], walls_now, dev[2], dev[3])
            launch(k["clumps"], particles.clump_mass.shape[0], dt, 0.0, half_skin, dev[0], dev[2], dev[3])
            launch(k["walls_move"], 1, dt, half_skin, walls_now, dev[3], True)

        (pair_s, pair_host), (gather_s, gather_host) = timed(pairs), timed(lambda: gather(dev[1]))
        seconds = dict(pairs=pair_s, gather=gather_s, launch=pair_host + gather_host)
        seconds["gather without walls"] = timed(lambda: gather(no_walls))[0]
        seconds["flag read"] = timed(lambda: cuda_target.array_to_host(dev[3].flags))[0]
        spare = info.copy()  # the rebuild's count and status are the copy's
        seconds["rebuild"] = math.nan  # unless the list's arrays are long enough
        if rebuild(skin, dev[0], dev[1], dev[2], spare):
            seconds["rebuild"] = timed(lambda: rebuild(skin, dev[0], dev[1], dev[2], spare))[0]
        return seconds

    @staticmethod
    def _host(gravity, pair_params, particles, walls, lists) -> tuple:
        """The host's records of a call: the engine's three and the step's inputs, with flag counts
        at zero."""
        return (particles, walls, lists, StepInputs(np.asarray(gravity, dtype=np.float64), pair_params,
                                                    np.zeros(2, dtype=np.int64)))

    def _upload(self, host, history_size, copy=False):
        """The records on the device and the rebuild for them. The list's contacts move to a pool
        row per entry (a list without pool groups); ``cell_start`` and ``tr_start`` are one longer
        there (``gpu_neighbors.DeviceRebuild``). ``copy``: arrays the host does not share, also on
        the simulator (``cuda_target.to_device``)."""
        particles, walls, lists, step = host
        total = int(lists.start[-1]) if lists.start.size else 0
        rows = lists.contact_row[:total]
        touching = np.nonzero(rows >= 0)[0]
        pool = np.zeros_like(lists.pool)
        pool[touching, :history_size] = lists.pool[rows[touching], :history_size]
        contact_row = np.full_like(lists.contact_row, -1)
        contact_row[touching] = touching
        by_entry = lists._replace(pool=pool, contact_row=contact_row, groups=lists.groups[:0],
                                  cell_start=np.zeros(lists.cell_start.shape[0] + 1, dtype=lists.cell_start.dtype),
                                  tr_start=np.append(lists.tr_start, lists.tr_start[-1]))
        # the device does not make the walls' candidates with its lists: every wall is near (and
        # so it is on the host after the run, until the host builds its lists)
        walls = walls._replace(near=np.ones_like(walls.near))
        dev = tuple(cuda_target.to_device(r, copy) for r in (particles, walls, by_entry, step))
        return dev, gpu_neighbors.DeviceRebuild(self.kernels, dev[0], dev[1], dev[2], history_size, len(touching))

    @staticmethod
    def _download(dev, host, history_size):
        """The particles and walls back in place; the list back, its contacts in the CPU's pool
        layout."""
        for d, h in zip(dev[:2], host[:2]):
            cuda_target.to_host(d, h)
        lists, device_lists = host[2], dev[2]
        lists.start[:] = cuda_target.array_to_host(device_lists.start)
        total = int(lists.start[-1]) if lists.start.size else 0
        lists.j[:total] = cuda_target.array_to_host(device_lists.j)[:total]
        index_list(lists)
        pool = cuda_target.array_to_host(device_lists.pool)
        contact_row = cuda_target.array_to_host(device_lists.contact_row)
        hist = np.where((contact_row[:total] >= 0)[:, None], pool[:total, :history_size], 0.0)
        put_entry_history(lists, hist, history_size)
