"""The GPU backend (``Simulation(backend="cuda")``, docs/gpu.md), checked without a GPU.

The kernels run on Numba's CUDA simulator, in a child process started with
``NUMBA_ENABLE_CUDASIM=1`` (the switch is read when ``numba.cuda`` is first imported), against the
CPU engine on the same scene. The GPU's pair pass takes every contact through the scalar contact
law, the CPU's through its vectorised blocks whose frame rotation uses a series for cos and sin
(docs/architecture.md): the two agree to round-off, not bit for bit, so each quantity is compared
at a relative 1e-9 of its scale. And every kernel compiles to PTX for compute capabilities 8.0 and
9.0 with NVIDIA's NVVM from PyPI, which needs no device: code the simulator runs but the real
compiler rejects fails here. The simulator's scenes are marked slow (below); the PTX check runs in
the default suite.
"""

import atexit
import json
import os
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

pytestmark = pytest.mark.cuda
# The simulator's scenes took over 15 minutes in a fresh-clone suite on 2 cores, the default suite's
# whole budget: they run with the slow tests (``pytest -m "slow and cuda"``), the PTX check by default.
simulator = pytest.mark.slow

SCENES = textwrap.dedent('''
    import json, sys
    import numpy as np
    import rollingdem as rd
    from numba import cuda  # a global: the simulator swaps it in a kernel's globals
    from rollingdem.engine.layout import I_REBUILDS

    def material(sim, mu_r):
        """Glass, twice under two names: spheres of two materials take the CPU's scalar pair path."""
        for name in ("glass", "glass 2"):
            sim.add_material(rd.Material(name, youngs_modulus=5e6, poisson_ratio=0.3, density=2500.0,
                                         restitution=0.5, friction=0.5, rolling_friction=mu_r))

    def pair(backend, materials=("glass", "glass 2")):
        """Two spheres colliding off-centre and spinning, then one bouncing on a floor."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend)
        material(sim, 0.2)
        sim.add_particles([[0, 0, 0.0012], [0.0003, 0, -0.0012]], radius=1e-3, material=list(materials),
                          velocity=[[0, 0, -0.5], [0, 0, 0.5]], angular_velocity=[[0, 3, 0], [1, 0, 0]])
        sim.add_wall(rd.Plane(point=(0, 0, -0.003), normal=(0, 0, 1)))
        sim.run(steps=600)
        return sim

    def rolling(backend, model, slope):
        """A sphere launched at 0.1 m/s on a floor tilted by ``slope`` rad (gravity turned)."""
        g = 9.81
        sim = rd.Simulation(contact=rd.ContactModel(rolling=model), gravity=(g * np.sin(slope), 0, -g * np.cos(slope)),
                            dt=5e-6, backend=backend)
        material(sim, 0.1)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
        sim.add_particles([[0, 0, 0.001 - 2e-7]], radius=1e-3, material="glass", velocity=[[0.1, 0, 0]],
                          angular_velocity=[[0, 100.0, 0]], allow_overlap=True)
        sim.run(steps=800)
        return sim

    def pile(backend):
        """27 spheres thrown down into a box of four planes and a floor, colliding with it and each other."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="cdt"), dt=2e-6, backend=backend)
        material(sim, 0.3)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
        for axis in (0, 1):
            for side in (-1, 1):
                n = [0, 0, 0]
                n[axis] = -side
                p = [0, 0, 0]
                p[axis] = side * 0.004
                sim.add_wall(rd.Plane(point=p, normal=n))
        grid = np.arange(3) * 0.0024 - 0.0024
        x = np.array([[a, b, 0.00105 + 0.0022 * c] for a in grid for b in grid for c in range(3)])
        x[:, :2] += 1e-4 * np.sin(np.arange(len(x)))[:, None]
        k = np.arange(len(x))
        sim.add_particles(x, radius=1e-3, material=["glass", "glass 2"] * 13 + ["glass"],
                          velocity=np.c_[0.05 * np.sin(k), 0.05 * np.cos(k), -0.2 - 0.1 * (k % 3)],
                          angular_velocity=np.c_[10 * np.cos(k), 10 * np.sin(k), 0 * k])
        sim.run(steps=1500)
        return sim

    def bonded(backend):
        """A periodic box along x over a moving triangle-mesh floor: two bonded pairs (one bond weak
        enough to break), a fixed sphere, and a sphere crossing the box's end."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend,
                            periodic={"x": (-0.004, 0.004)})
        material(sim, 0.2)
        floor = np.array([[-0.01, -0.01, 0], [0.01, -0.01, 0], [0.01, 0.01, 0], [-0.01, 0.01, 0]])
        sim.add_wall(rd.MeshWall(floor, [[0, 1, 2], [0, 2, 3]], material="glass", velocity=(0.02, 0, 0)))
        sim.add_particles([[-0.003, -0.005, 0.00102], [-0.001, -0.005, 0.00102], [-0.003, 0.0, 0.00102],
                           [-0.001, 0.0, 0.00102], [0.0034, 0.005, 0.00102]], radius=1e-3,
                          material=["glass", "glass 2", "glass", "glass 2", "glass"],
                          velocity=[[0, 0, -0.1], [0.1, 0, 0], [0, 0.05, 0], [0.3, 0, -0.2], [0.5, 0, 0]],
                          angular_velocity=[[5, 0, 0], [0, 0, 5], [0, 5, 0], [0, 0, 0], [0, 0, 0]])
        sim.add_particles([[0.0, 0.003, 0.0015]], radius=1e-3, material="glass", fixed=True)
        sim.add_bonds(rd.ParallelBond(youngs_modulus=5e6, tensile_strength=1e9, cohesion=1e9), pairs=[[0, 1]])
        sim.add_bonds(rd.ParallelBond(youngs_modulus=5e6, tensile_strength=2e3, cohesion=2e3), pairs=[[2, 3]])
        sim.run(steps=1500)
        if backend == "cpu":  # the scene does what it says: a bond breaks, a sphere crosses the end
            assert list(sim.bonds()["status"]) == ["intact", "tension"], list(sim.bonds()["status"])
            assert sim.unwrapped_positions[4, 0] > 0.004 > sim.positions[4, 0]
        return sim

    def programmed(backend):
        """Walls moved by programs: a floor shaken sideways, a mesh lid that a servo presses down on
        four spheres, a mesh plate turning by a table of times."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend)
        material(sim, 0.2)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), motion=rd.Oscillation(50.0, amplitude=(2e-4, 0, 0))))
        lid = np.array([[-0.004, -0.004, 0.002015], [0.004, -0.004, 0.002015], [0.004, 0.004, 0.002015],
                        [-0.004, 0.004, 0.002015]])
        sim.add_wall(rd.MeshWall(lid, [[0, 1, 2], [0, 2, 3]], material="glass",
                                 motion=rd.Servo((0, 0, -1), max_speed=0.5, force=0.01, gain=2.0)))
        plate = np.array([[0.006, -0.002, 0], [0.01, -0.002, 0], [0.01, 0.002, 0]])
        sim.add_wall(rd.MeshWall(plate, [[0, 1, 2]], material="glass", point=(0.008, 0, 0),
                                 motion=rd.MotionTable([0, 0.001, 0.002], [[0, 0, 0], [0, 0, 2e-4], [0, 0, 2e-4]],
                                                       [0, 0.3, 0.5], axis=(0, 0, 1))))
        sim.add_particles([[-0.0011, -0.0011, 0.00101], [0.0011, -0.0011, 0.00101], [0.0011, 0.0011, 0.00101],
                           [-0.0011, 0.0011, 0.00101], [0.008, 0, 0.0013]], radius=1e-3,
                          material=["glass", "glass 2", "glass", "glass 2", "glass"])
        sim.run(steps=600)
        if backend == "cpu":  # the servo lid has come down onto the spheres
            assert sim.wall_loads()["#1"]["force"][2] > 0.0
        return sim

    def bed(backend, timed=True):
        """32 touching spheres in a periodic x-y box on a floor, stirred: with a small skin the list
        is rebuilt on the device every few tens of steps while contacts last, so that each rebuild
        carries contact history over. Half way, the GPU's phases are timed for ``rollingdem
        bench`` (``timed``): on a copy of the state, so the run goes on as if it had not happened."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend, skin=1e-5,
                            periodic={"x": (-0.002, 0.002), "y": (-0.002, 0.002)})
        material(sim, 0.2)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
        g = (np.arange(4) - 1.5) * 0.000999
        x = np.array([[a, b, 0.0004995 + 0.000999 * c] for c in range(2) for a in g for b in g])
        k = np.arange(len(x))
        sim.add_particles(x, radius=5e-4, material=["glass", "glass 2"] * 16, allow_overlap=True,
                          velocity=np.c_[0.2 * np.sin(k), 0.2 * np.cos(1.3 * k), 0.1 * np.sin(2.1 * k)],
                          angular_velocity=np.c_[20 * np.cos(k), 20 * np.sin(k), 0 * k])
        sim.run(steps=150)
        if timed and backend == "cuda":
            out["phases"] = sim.phase_seconds(repeats=2, rebuilds_per_step=1.0)
        sim.run(steps=150)
        return sim

    def fine_floor(backend):
        """Three spheres rolling over a floor of 800 small triangles: each has about a hundred
        candidate triangles, more than the candidate arrays first hold, so they grow."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend)
        material(sim, 0.2)
        ticks = np.linspace(-0.0025, 0.0025, 21)
        vertices = np.array([[a, b, 0.0] for b in ticks for a in ticks])
        quads = [(r * 21 + c, r * 21 + c + 1, (r + 1) * 21 + c + 1, (r + 1) * 21 + c) for r in range(20)
                 for c in range(20)]
        sim.add_wall(rd.MeshWall(vertices, [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))],
                                 material="glass"))
        sim.add_particles([[-0.0012, -0.001, 0.00099], [0.0012, 0.0, 0.000995], [0.0, 0.0012, 0.00099]],
                          radius=1e-3, material=["glass", "glass 2", "glass"], allow_overlap=True,
                          velocity=[[0.2, 0, 0], [-0.1, 0.1, 0], [0, -0.2, 0]])
        sim.run(steps=300)
        return sim

    def clumps(backend):
        """Clumps (two dimers, two tetrahedra, two rings of four) turned at random, thrown onto a floor
        and onto each other spinning, with a sphere: the clump kernel's sums, kicks and turns, its
        members' contacts with walls, spheres and other clumps' members, and the list rebuilt as
        they move."""
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=backend)
        material(sim, 0.2)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
        shapes = (rd.Clump.dimer(1e-3, 1.5e-3), rd.Clump.tetrahedron(8e-4), rd.Clump.ring_prism(4, 6e-4))
        for k, shape in enumerate(shapes):
            sim.add_clumps(shape, [[0.004 * k - 0.004, 0, 0.0022], [0.004 * k - 0.0035, 0.0005, 0.0058]], "glass",
                           orientations=rd.random_orientations(np.random.default_rng(k), 2),
                           velocity=[[0.3 * (1 - k), 0, -0.3], [0, 0, -1.0]],
                           angular_velocity=[[0, 200, 50], [30, 0, 0]])
        sim.add_particles([[0.0005, -0.0035, 0.0015]], radius=1e-3, material="glass 2", velocity=[0.1, 0.3, 0])
        sim.run(steps=1500)
        return sim

    def handed_over(backend):
        """The pair's first 300 steps on the other backend, checkpointed, restored on ``backend``
        for the last 300: a checkpoint does not depend on the backend that wrote it."""
        import tempfile

        other = "cpu" if backend == "cuda" else "cuda"
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend=other)
        material(sim, 0.2)
        sim.add_particles([[0, 0, 0.0012], [0.0003, 0, -0.0012]], radius=1e-3, material=["glass", "glass 2"],
                          velocity=[[0, 0, -0.5], [0, 0, 0.5]], angular_velocity=[[0, 3, 0], [1, 0, 0]])
        sim.add_wall(rd.Plane(point=(0, 0, -0.003), normal=(0, 0, 1)))
        sim.run(steps=300)
        with tempfile.TemporaryDirectory() as folder:
            path = sim.checkpoint(folder + "/c.npz")
            sim = rd.Simulation.restore(path, backend=backend)
        assert sim.backend == backend
        sim.run(steps=300)
        return sim

    def bed_reversed(backend):
        """The bed with the counting sorts' slots taken in the opposite order of the threads: the
        list and the gather's order must not depend on which thread's atomic comes first."""
        if backend == "cpu":
            return bed(backend, timed=False)
        from rollingdem.engine.cuda import target as cuda_target, step_loop as gpu_engine

        def place_keys_reversed(sort, count):
            i = count - 1 - cuda.grid(1)
            if 0 <= i < count:
                slot = cuda.atomic.add(sort.start, sort.keys[i] + 1, 1)
                sort.items[slot] = i

        kernels = gpu_engine._KERNELS
        saved = {name: k["place_keys"] for name, k in kernels.items()}
        for k in kernels.values():
            k["place_keys"] = cuda_target.kernel(place_keys_reversed)
        try:
            return bed(backend, timed=False)
        finally:
            for name, k in kernels.items():
                k["place_keys"] = saved.get(name, k["place_keys"])

    out = {}
    for name, make in (("mesh, bonds, periodic", bonded), ("checkpoint handed over", handed_over), ("pair", pair), ("wall programs", programmed), ("clumps", clumps), ("pair of one material", lambda b: pair(b, ("glass", "glass"))),
                       ("rolling epsd flat", lambda b: rolling(b, "epsd", 0.0)),
                       ("rolling cdt flat", lambda b: rolling(b, "cdt", 0.0)),
                       ("rolling epsd slope", lambda b: rolling(b, "epsd", 0.05)),
                       ("rolling cdt slope", lambda b: rolling(b, "cdt", 0.05)), ("pile", pile), ("bed", bed),
                       ("bed, slots in reverse", bed_reversed), ("fine floor", fine_floor)):
        out[name] = {}
        for backend in ("cpu", "cuda"):
            sim = make(backend)
            out[name][backend] = dict(x=sim.positions.tolist(), v=sim.velocities.tolist(),
                                      w=sim.angular_velocities.tolist(), contacts=sim.number_of_contacts(),
                                      rebuilds=int(sim._state.info[I_REBUILDS]),
                                      candidates=int(sim._state.meshes.candidate_start[-1:].sum()))
    # a per-particle field declared at run time goes to the device in the particles' record, and back
    from unittest import mock
    from rollingdem.engine.cuda import step_loop as gpu_engine
    from rollingdem.engine.schema import SCHEMA, Field
    on_device, upload = [], gpu_engine.CudaStepLoop._upload

    def spy(self, host, history_size, copy=False):
        dev, rebuild = upload(self, host, history_size, copy)
        on_device.append(np.array(dev[0].temperature).tolist())
        return dev, rebuild

    with SCHEMA.declared(Field("temperature", fill=293.15, doc="K")), \
            mock.patch.object(gpu_engine.CudaStepLoop, "_upload", spy):
        sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=2e-6, backend="cuda")
        material(sim, 0.2)
        sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
        sim.add_particles([[0, 0, 0.0011], [0.003, 0, 0.0011], [0, 0.003, 0.0012]], radius=1e-3, material="glass")
        sim._state.temperature[:] = 300.0 + sim._state.tags
        sim.run(steps=20)
        out["declared field"] = dict(on_device=on_device[0], after=sim._state.temperature.tolist())
    import pathlib, tempfile
    from unittest import mock
    from rollingdem import bench
    with tempfile.TemporaryDirectory() as folder, mock.patch.object(bench, "_cache_dir", lambda: pathlib.Path(folder)), \
            mock.patch.object(bench, "SETTLE", 20 * bench.DT):
        column = bench.settled_column(200, echo=lambda *a: None, backend="cuda")
        out["column settled on"] = dict(backend=column.backend, steps=column.step, loops=len(column._state.backend_data["cuda"]))
    # the rebuild's prefix sum and counting sort at the device's chunk, 64 values a thread (the
    # scenes above take the simulator's 4): 5,000 values take three levels of chunk totals
    from rollingdem.engine.cuda import target as cuda_target, neighbors as gpu_neighbors
    from rollingdem.engine.codegen import engine_module
    with mock.patch.object(gpu_neighbors, "scan_chunk", lambda: 64):
        bodies = gpu_neighbors.kernel_bodies(engine_module(rd.ContactModel(rolling="epsd"), False, serial=None))
        rebuild = gpu_neighbors.DeviceRebuild.__new__(gpu_neighbors.DeviceRebuild)
        rebuild.k = {name: cuda_target.kernel(bodies[name])
                     for name in ("zero", "count_keys", "place_keys", "sort_groups", "chunk_sums", "chunk_scan")}
        rebuild.sums = rebuild._levels(5002, np.int32)
        rng = np.random.default_rng(7)
        values = rng.integers(0, 50, 5000).astype(np.int32)
        scanned = values.copy()
        rebuild.scan(scanned, len(scanned))
        keys = rng.integers(0, 300, 5000).astype(np.int32)
        start, items = np.zeros(302, dtype=np.int32), np.zeros(5000, dtype=np.int32)
        rebuild.counting_sort(keys, start, items, 5000, 300, True)
    out["device chunk"] = dict(levels=len(rebuild.sums), scan=bool(np.array_equal(scanned, np.cumsum(values))),
                               start=bool(np.array_equal(start[:301], np.r_[0, np.cumsum(np.bincount(keys, minlength=300))])),
                               items=bool(np.array_equal(items, np.argsort(keys, kind="stable"))))
    json.dump(out, sys.stdout)
''')


PTX = textwrap.dedent('''
    import numpy as np
    from numba import typeof
    import rollingdem as rd
    from rollingdem.engine.cuda import target as cuda_target, step_loop as gpu_engine
    from rollingdem.engine.cuda.step_loop import StepInputs
    from rollingdem.engine.cuda.neighbors import CountingSort, RebuildArrays, Scan
    from rollingdem.engine.codegen import engine_module

    sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"))
    sim.add_material(rd.Material("m", youngs_modulus=1e7, poisson_ratio=0.3, density=2500.0))
    sim.add_particles([[0, 0, 0.0011], [0, 0, -0.0011]], radius=1e-3, material="m")
    sim.add_bonds(rd.ParallelBond(youngs_modulus=1e7, tensile_strength=1e6, cohesion=1e6), gap=1e-3)
    sim.add_wall(rd.Plane(point=(0, 0, -0.01), normal=(0, 0, 1)))
    # the module, not its CPU step loop: nothing is compiled for the CPU here
    module = engine_module(sim.contact, sim.track_energy, bonded_pairs=True)
    particles, walls, lists, _ = sim._state.records()
    step = StepInputs(np.zeros(3), sim.pair_parameters(), np.zeros(2, dtype=np.int64))
    rebuild = RebuildArrays(np.zeros(7), np.zeros(9), np.zeros(4, dtype=np.int64), np.zeros((16, module.HISTORY_SIZE)))
    scan, sort = Scan(lists.counts, lists.counts), CountingSort(lists.cell_of, lists.cell_start, lists.cell_items)
    args = dict(pairs=(1e-6, particles, lists, step), bonds=(1e-6, particles, lists),
                gather=(1e-6, 2.0, 1e-4, particles, walls, lists, step), drift=(1e-6, 1e-4, particles, step),
                clumps=(1e-6, 2.0, 1e-4, particles, lists, step),
                walls_move=(1e-6, 1e-4, walls, step, True),
                prepare=(particles, lists, rebuild), bounds=(particles, rebuild), grid=(1e-4, 64, lists, rebuild),
                bin_particles=(particles, lists, rebuild), count_rows=(1e-4, particles, lists, rebuild, 1),
                count_contacts=(particles, lists), mesh_grid=(1e-4, walls, rebuild),
                mesh_rows=(1e-4, particles, walls, rebuild, 1), report=(particles, walls, lists, rebuild), carry_out=(particles, lists, rebuild),
                new_starts=(particles, lists), carry_in=(particles, lists, rebuild), zero=(scan, 1),
                count_keys=(sort, 1), place_keys=(sort, 1), sort_groups=(sort, 1), chunk_sums=(scan, 1),
                chunk_scan=(scan, 1))
    bodies = gpu_engine.kernel_bodies(module)
    assert sorted(bodies) == sorted(args)
    for cc in cuda_target.PTX_TARGETS:
        for name, body in bodies.items():
            ptx = cuda_target.compile_ptx(body, tuple(typeof(a) for a in args[name]), cc)
            assert f".target sm_{cc[0]}{cc[1]}" in ptx, name
            print(name, cc, len(ptx))
    ''')


class Children:
    """The simulator's scenes and the PTX check, each in a child process (the simulator's switch is
    read when ``numba.cuda`` is first imported, and the PTX check must not see it), one after the
    other (side by side they were slower: each starts compile helpers of its own, on 2 cores). They
    start as soon as the session has collected tests of this module (``conftest.py``), so that they
    run while the rest of the suite does; a result waits for its child."""

    def __init__(self):
        cpu_only = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
        self.jobs = {"simulated": (SCENES, dict(os.environ, NUMBA_ENABLE_CUDASIM="1")), "ptx": (PTX, cpu_only)}
        self.results = {}
        self.finished = {name: threading.Event() for name in self.jobs}
        self.queued = []
        self.lock = threading.Lock()
        self.thread = None
        self.running = None
        atexit.register(self._stop)

    def start(self, names):
        """Queue the jobs ``names`` not queued yet; they run in the background, one after the other,
        in the order of ``jobs``."""
        with self.lock:
            self.queued += [n for n in self.jobs if n in names and n not in self.queued]
            if self.thread is None or not self.thread.is_alive():
                self.thread = threading.Thread(target=self._run, daemon=True)
                self.thread.start()

    def _next(self):
        with self.lock:
            pending = [n for n in self.queued if not self.finished[n].is_set()]
            if not pending:
                self.thread = None
            return pending[0] if pending else None

    def _run(self):
        while (name := self._next()) is not None:
            code, env = self.jobs[name]
            try:
                self.running = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                                                stderr=subprocess.PIPE, text=True, env=env)
                stdout, stderr = self.running.communicate(timeout=900)
                self.results[name] = (self.running.returncode, stdout, stderr)
            except Exception as error:  # a timeout, or the process could not start
                self._stop()
                self.results[name] = (-1, "", repr(error))
            self.finished[name].set()

    def _stop(self):
        if self.running is not None and self.running.poll() is None:
            self.running.kill()

    def result(self, name):
        self.start([name])
        self.finished[name].wait()
        return self.results[name]


CHILDREN = Children()


@pytest.fixture(scope="module")
def ptx():
    """The PTX check's child process: (return code, stdout, stderr)."""
    return CHILDREN.result("ptx")


@pytest.fixture(scope="module")
def simulated():
    """Every scene run on the CPU engine and on the CUDA simulator, in one child process."""
    returncode, stdout, stderr = CHILDREN.result("simulated")
    assert returncode == 0, stderr[-3000:]
    return json.loads(stdout)


@simulator
@pytest.mark.parametrize("scene", ["pair", "rolling epsd flat", "rolling cdt flat", "rolling epsd slope",
                                   "rolling cdt slope", "pile", "bed", "bed, slots in reverse", "fine floor", "mesh, bonds, periodic", "checkpoint handed over",
                                   "wall programs", "clumps"])
def test_the_simulated_gpu_steps_bit_for_bit_as_the_cpu_engine(simulated, scene):
    """Positions, velocities and spins after the run equal the CPU engine's bit for bit, and so do
    the contact counts: the GPU's kernels run the same compiled functions in the same order (each
    particle's force summed by one thread, in list order), and the list rebuilt on the device is
    the CPU's. The scenes take every kernel: pairs, walls, the kicks and the drift, neighbor-list
    rebuilds (the pile's spheres move more than skin/2; the bed's list is rebuilt every ~20 steps
    with contacts to carry over, its phases timed for the bench half way, and again with the
    counting sorts' atomic slots taken in the opposite order of the threads), EPSD and CDT rolling
    on a flat and a sloped floor, and bonds (one breaking), a moving triangle mesh, a fine mesh
    whose candidate arrays grow, a fixed sphere and a periodic box, and walls moved by programs (a
    floor shaken sideways, a servo lid, a mesh turned by a table of times), and clumps (rigid bodies of
    spheres) landing on the floor and on each other. A checkpoint written on one
    backend restores on the other and goes on as the run on that backend would. Their spheres are of two
    materials (the same glass), so that the CPU too takes the scalar pair path; the pile, 27
    spheres thrown into a box, amplifies a difference of one unit in the last place to 1e-7 m
    within 1000 steps, so it would show any."""
    cpu, gpu = simulated[scene]["cpu"], simulated[scene]["cuda"]
    for key in ("x", "v", "w"):
        assert np.array_equal(np.asarray(gpu[key]), np.asarray(cpu[key])), f"{scene}: {key}"
    assert gpu["contacts"] == cpu["contacts"]


@simulator
def test_a_declared_particle_field_goes_to_the_device_and_back(simulated):
    """A per-particle field declared in the state's schema at run time (``temperature``, set to
    300 K + the particle's tag) is in the particles' record the GPU backend uploads, with each
    particle's value, and holds the same values after the run comes back."""
    field = simulated["declared field"]
    assert field["on_device"] == [300.0, 301.0, 302.0]
    assert field["after"] == [300.0, 301.0, 302.0]


@simulator
def test_spheres_of_one_material_agree_to_round_off(simulated):
    """Spheres of one material take the CPU's vectorised pair path, whose frame rotation uses a
    series for cos and sin (docs/architecture.md), the GPU the scalar one: the colliding pair ends
    within a relative 1e-9 of each quantity's largest value (round-off, about 1e-16 per step, over
    600 steps of a two-body impact, which does not amplify it much)."""
    cpu, gpu = simulated["pair of one material"]["cpu"], simulated["pair of one material"]["cuda"]
    for key in ("x", "v", "w"):
        a, b = np.asarray(cpu[key]), np.asarray(gpu[key])
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9 * np.abs(a).max(), err_msg=key)


@simulator
def test_the_scenes_exercise_what_they_claim(simulated):
    """Guards on the scenes themselves, from the CPU engine: the pair collides (its spheres leave
    slower than they came), the flat rollers slow down under rolling resistance, the pile's
    spheres hit the floor and each other (some move up at the end), and the clumps touch."""
    pair = simulated["pair"]["cpu"]
    assert np.abs(np.asarray(pair["v"])[:, 2]).max() < 0.5
    for model in ("epsd", "cdt"):
        assert np.asarray(simulated[f"rolling {model} flat"]["cpu"]["v"])[0, 0] < 0.1
    assert np.asarray(simulated["pile"]["cpu"]["v"])[:, 2].max() > 0
    # the bed's list is rebuilt often, with contacts to carry over: 32 spheres of a 4 x 4 x 2 stack
    # on a floor touch in about 40 pairs and walls
    assert simulated["bed"]["cpu"]["rebuilds"] >= 10 and simulated["bed"]["cpu"]["contacts"] >= 20
    assert simulated["bed"]["cuda"]["rebuilds"] == simulated["bed"]["cpu"]["rebuilds"]
    # the fine floor's spheres have more candidate triangles than the arrays first held (4 per sphere)
    for backend in ("cpu", "cuda"):
        assert simulated["fine floor"][backend]["candidates"] > 4 * 3
    # the clumps land on the floor and on each other: they touch at the end (7 contacts on the CPU)
    assert simulated["clumps"]["cpu"]["contacts"] >= 4 and simulated["clumps"]["cpu"]["rebuilds"] >= 5
    # the hand-over's two halves are the pair's 600 steps: its CPU half started on the GPU
    for key in ("x", "v", "w"):
        assert np.array_equal(simulated["checkpoint handed over"]["cpu"][key], simulated["pair"]["cpu"][key])


@simulator
def test_bench_times_each_gpu_phase_apart(simulated):
    """``rollingdem bench --backend cuda`` splits a step as on the CPU (contact forces, walls,
    integration and gathering, neighbor search) plus the host's share (its launches, which the
    device's work overlaps, and the step's synchronisation), each timed on a copy of the state on
    the device: the run it interrupts goes on bit for bit (the "bed" scene, timed half way)."""
    split = simulated["phases"]
    assert set(split) == {"contact forces", "walls", "integration and gathering", "neighbor search",
                          "host launches (overlapped)", "flag read (synchronisation)"}
    assert all(np.isfinite(v) and v >= 0 for v in split.values()), split
    assert min(split["contact forces"], split["integration and gathering"], split["neighbor search"],
               split["host launches (overlapped)"]) > 0, split


@simulator
def test_the_bench_column_settles_on_the_gpu(simulated):
    """``rollingdem bench --backend cuda -s column-collapse`` settles a column it lacks on the GPU
    (hours for 10^6 spheres on two cores): its steps ran through the GPU's step loop."""
    assert simulated["column settled on"] == dict(backend="cuda", steps=20, loops=1)


@simulator
def test_the_prefix_sum_and_counting_sort_at_the_devices_chunk(simulated):
    """The rebuild's prefix sum and counting sort take 64 values a thread on a device (4 in the
    simulator's scenes): at 64, the sum of 5,000 values through three levels of chunk totals is
    NumPy's cumsum, and 5,000 keys sorted into 300 groups give NumPy's group starts and its stable
    argsort, exactly (integers)."""
    assert simulated["device chunk"] == dict(levels=3, scan=True, start=True, items=True)


def test_every_kernel_compiles_to_ptx_without_a_device(ptx):
    """Each CUDA kernel, typed for a scene with pairs, walls and bonds (the clumps' kernel typed for
    the same records: their arrays have the clumps' types with no rows), compiles to PTX for compute
    capabilities 8.0 and 9.0 with NVIDIA's NVVM (the ``nvidia-cuda-nvcc-cu12`` package): no GPU or
    driver is needed, and what the simulator accepts but the real compiler rejects fails here."""
    pytest.importorskip("numba_cuda", reason="numba-cuda is in the test extra")
    returncode, stdout, stderr = ptx
    assert returncode == 0, stderr[-3000:]
    assert stdout.count("\n") == 2 * 24  # 24 kernels (the clumps' one of them), for each of the 2 targets


def test_a_missing_gpu_is_one_clear_line():
    """Without a CUDA driver (this machine's case in CI), ``backend="cuda"`` is refused when the
    simulation is made, with one line that names what is missing; an unknown backend is refused
    naming the allowed ones."""
    import rollingdem as rd
    from rollingdem.errors import ParameterError

    with pytest.raises(ParameterError, match=r"backend = 'gpu' is not allowed: must be one of cpu, cuda"):
        rd.Simulation(backend="gpu")
    if os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0"):
        pytest.skip("the simulator stands in for a device here")
    try:
        from numba import cuda
        if cuda.is_available():
            pytest.skip("a GPU is present")
    except Exception:
        pass
    with pytest.raises(ParameterError, match=r"backend 'cuda' (has no GPU|found no usable CUDA driver|needs numba-cuda)"):
        rd.Simulation(backend="cuda")


@pytest.mark.parametrize("features", [{}, dict(bonded_pairs=True, meshes=True, clumps=True, programs=True)])
def test_the_gpu_binds_every_phase_of_the_cpus_step_control(features):
    """The GPU's step loop runs the engine module's ``advance`` as Python on the host: every
    function its body calls is one the GPU binds to launches on the device (a pass called there
    directly would run on the host's records, not the device's). Checked on the module with no
    feature switch and with all of them (the generated module is read, not compiled)."""
    import rollingdem as rd
    from rollingdem.engine.codegen import engine_module
    from rollingdem.engine.cuda.step_loop import PHASES

    module = engine_module(rd.ContactModel(rolling="epsd"), **features)
    code = module.advance.py_func.__code__
    called = {name for name in code.co_names if hasattr(getattr(module, name, None), "py_func")}
    assert called == set(PHASES)
