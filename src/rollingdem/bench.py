"""``rollingdem bench``: time standard scenes, report particle-steps per second and where the time goes.

The scenes (``column-collapse``, ``single-particle``, ``dense-bed``, ``slab``, ``scaling``,
``collapse-scaling``), what each measures and how the figures are taken (compilation timed apart,
each phase timed on its own): docs/performance.md, "rollingdem bench"; the scaling scenes:
docs/scaling.md."""

from __future__ import annotations

import json
import math
import platform
import resource
import time
import weakref
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numba
import numpy as np

from rollingdem import (
    BoxRegion,
    Clump,
    ContactModel,
    Cylinder,
    CylinderRegion,
    Material,
    MeshWall,
    Plane,
    Simulation,
    __version__,
    rough_base,
)
from rollingdem.engine.backends import BACKENDS
from rollingdem.engine.backends import backend as find_backend
from rollingdem.engine.codegen import kernel_cache_dir
from rollingdem.engine.layout import SERIAL_BELOW
from rollingdem.engine.schema import PER_CLUMP, SCHEMA
from rollingdem.errors import ParameterError, check_output_path
from rollingdem.experiments.coarse_graining import CoarseGraining, drum_parameters
from rollingdem.experiments.drum import RotatingDrum, drum_case
from rollingdem.experiments.single_sphere import sphere_on_wall, validation_models
from rollingdem.io.casefile import build_simulation, load_case
from rollingdem.scene.insertion import ROUGH_BASE_SPACING
from rollingdem.scene.mesh import SHAPES, hopper

SCENES = ("column-collapse", "single-particle", "dense-bed", "slab", "scaling", "collapse-scaling", "mesh-hopper",
          "rough-bed", "clumps", "coarse-graining")
GPU_SCENES = ("column-collapse", "slab")  # the scenes ``--backend cuda`` times
SCALING_SMALL = 20000
SCALING_LARGE = 1_000_000
SCALING_CHUNKS = 6
SLAB_LAYERS = 8
FORCE_PASS_ROUNDS = 25
FORCE_PASS_CALLS = 3
TABLE1 = dict(youngs_modulus=40e6, poisson_ratio=0.49, density=1056.0, friction=0.8, rolling_friction=0.2,
              restitution=0.5, rolling_damping=0.3)
RADIUS = 0.005
DT = 1e-5
SKIN = 0.002
COLUMN_RADIUS_20K = 0.125  # m, for 20,000 spheres (LIGGGHTS reference input)
FILL_HEIGHT = 0.80  # m, top of the insertion region (LIGGGHTS reference input)
SETTLE = 0.6  # s
SETTLE_CHECKPOINT = 0.05  # s of settling between checkpoints of a settle in progress
# the mesh-hopper scene: a conical hopper (frustum) of 100 x 50 x 2 = 10,000 triangles, spheres of
# radius 1.5 mm of Table 1's material dropped into it from a column and discharging through its
# open outlet; timed from HOPPER_FILL s after the drop
HOPPER = dict(top_radius=0.06, outlet_radius=0.012, height=0.08, segments=100, rings=50)
HOPPER_RADIUS = 0.0015  # m
HOPPER_DT = 4e-6  # s: the Hertz-time limit at the drop's impact speed (2.5 m/s) is 4.5e-6 s
HOPPER_SKIN = 0.0006  # m
HOPPER_REGION = (0.037, 0.045, 0.28)  # radius, z_min, z_max of the column the spheres start in (m)
HOPPER_FILL = 0.1  # s
# the rough-bed scene: free spheres settled on a rough base of half as many fixed ones (rd.rough_base,
# spacing 2.2 R), and the same number settled on the bare plate, in a square box of side planes
ROUGH_BED_SETTLE = 0.3  # s
ROUGH_BED_CHUNKS = 6
# the clumps scene: tetrahedra of four touching spheres of radius RADIUS settled in a square box, and
# as many spheres as they have members settled in the same box
CLUMP_BED_SETTLE = 1.0  # s
CLUMP_BED_CHUNKS = 6
# the coarse-graining scene: the coarse-graining study's drum (30 d in radius, a slice 10 d long, 9,346
# real particles) of the real particles and of parcels of CG_ALPHA, each settled and turned
# CG_SPIN_UP s at the same Froude number, timed over the same simulated time in chunks taken in turn
CG_ALPHA = 3.0
CG_SPIN_UP = 0.2  # s
CG_CHUNKS = 6
DENSE_BED_MODELS = ("none", "cdt", "epsd", "epsd2", "epsd3", "rrlinear", "sds", "displacement_damping",
                    "force_proportional", "viscous", "walton_braun", "walton", "sjkr", "jkr")
# the contact laws of dense-bed other than Hertz + history + a rolling model: each on Hertz-history
# without rolling resistance but for the law named, so that its cost reads against "none"
CONTACT_LAW_VARIANTS = {"walton_braun": {"normal": {"model": "walton_braun", "characteristic_velocity": 1.0}},
                        "walton": {"tangential": "walton"}, "sjkr": {"cohesion": "sjkr"}, "jkr": {"cohesion": "jkr"}}
# a weak cohesion, so that the bed's state stays near the others' (Bond number about 0.1)
VARIANT_COHESION = {"cohesion_energy_density": 1e4, "surface_energy": 0.01}


@dataclass
class BenchResult:
    scene: str
    model: str
    particles: int
    steps: int
    threads: int
    wall_s: float
    particle_steps_per_s: float
    compile_s: float
    contacts_per_particle: float
    neighbors_per_particle: float
    rebuilds: int
    split_s_per_step: dict = field(default_factory=dict)
    peak_rss_mb: float = math.nan
    state_bytes_per_particle: float = math.nan
    device_memory_bytes_per_particle: float = 0.0  # on the GPU: the arrays the step loop sends there
    note: str = ""

    def as_dict(self) -> dict:
        return asdict(self)


def _cache_dir() -> Path:
    return kernel_cache_dir().parent / "bench"


def bench_contact(rolling="epsd"):
    """The contact model of a bench label: a rolling model (or spec) on Hertz-history, or one of
    ``CONTACT_LAW_VARIANTS``."""
    if isinstance(rolling, str) and rolling in CONTACT_LAW_VARIANTS:
        return ContactModel(**{"normal": "hertz", **CONTACT_LAW_VARIANTS[rolling]})
    return ContactModel("hertz", rolling=rolling)


def _column_simulation(rolling: str = "epsd"):
    sim = Simulation(contact=bench_contact(rolling), dt=DT, skin=SKIN)
    cohesive = isinstance(rolling, str) and rolling in CONTACT_LAW_VARIANTS
    sim.add_material(Material("table1", **TABLE1, **(VARIANT_COHESION if cohesive else {})))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="table1", name="plate"))
    return sim


def column_radius(particles: int) -> float:
    return COLUMN_RADIUS_20K * math.sqrt(particles / 20000)


def settled_column(particles: int, seed: int = 1, rolling: str = "epsd", echo=print, backend: str = "cpu",
                   checkpoint_every: float | None = None):
    """The settled column (cylinder still in place), from the disk cache or built now, settling on
    ``backend``, and cached; a settle in progress is checkpointed every ``checkpoint_every``
    seconds of simulated time (``SETTLE_CHECKPOINT`` by default; none if ``SETTLE`` or more)."""
    path = _cache_dir() / f"column_{particles}_seed{seed}_{rolling}_v{__version__}.npz"
    if path.exists():
        sim = Simulation.restore(path)
        sim.track_energy = False  # the scene as a user runs it by default (and as the peers do)
        return sim
    # a long settle (2-3 h for 10^6 spheres on 2 cores) is checkpointed as it goes, and an
    # interrupted one resumes from its last checkpoint
    partial = path.with_name(path.stem + "_partial.npz")
    if partial.exists():
        sim = Simulation.restore(partial, backend=backend)
        echo(f"resuming the settling of {particles} spheres at t = {sim.time:.3f} of {SETTLE} s ({partial}) ...")
    else:
        echo(f"settling {particles} spheres for {SETTLE} s (cached afterwards in {path.parent}) ...")
        r_cyl = column_radius(particles)
        sim = _column_simulation(rolling)
        sim.backend = backend
        sim.add_wall(Cylinder(r_cyl, material="table1", name="cylinder"))
        sim.insert(CylinderRegion(r_cyl, 0.0, FILL_HEIGHT), particles, RADIUS, "table1", seed=seed,
                   velocity=(0.0, 0.0, -0.5))
    total = round(SETTLE / sim.dt)
    chunk = max(1, round((checkpoint_every or SETTLE_CHECKPOINT) / sim.dt))
    while sim.step < total:
        sim.run(steps=min(chunk, total - sim.step))
        if sim.step < total:
            sim.checkpoint(partial)
    sim.checkpoint(path)
    partial.unlink(missing_ok=True)
    return sim


def column_from_dump(path, rolling: str = "epsd"):
    """The settled state written by the LIGGGHTS reference input (``write_dump ... custom id type x y z
    vx vy vz radius``), with the cylinder of the matching radius in place."""
    data = _read_dump(path, ("x", "y", "z", "vx", "vy", "vz", "radius"))
    return _column_from_state(rolling, data[:, 0:3], data[:, 6], data[:, 3:6])


def _read_dump(path, names) -> np.ndarray:
    """The columns ``names`` of a LIGGGHTS/LAMMPS custom text dump, one row per atom, in file order."""
    path = Path(path)
    if not path.exists():
        raise ParameterError(f"from_dump = {str(path)!r} does not exist: give the dump written by "
                             "benchmarks/reference/liggghts_in.build (see benchmarks/reference/README.md)")
    if path.is_dir():
        raise ParameterError(f"from_dump = {str(path)!r} is not allowed: it is a folder; must be the dump file")
    lines = path.read_text().splitlines()
    try:
        start = next(k for k, line in enumerate(lines) if line.startswith("ITEM: ATOMS"))
        cols = lines[start].split()[2:]
        data = np.loadtxt(lines[start + 1:], ndmin=2)
        idx = [cols.index(c) for c in names]
    except (StopIteration, ValueError) as err:
        raise ParameterError(f"from_dump = {str(path)!r} is not a LIGGGHTS custom dump with columns "
                             f"{' '.join(names)} ({err})") from None
    return data[:, idx]


def rough_bed_half_width(free: int) -> float:
    """Half the side (m) of the rough-bed scene's square box for ``free`` free spheres."""
    return 0.5 * math.sqrt(0.5 * free * math.sqrt(3.0) / 2.0) * ROUGH_BASE_SPACING * RADIUS


def rough_bed_from_dump(path):
    """The rough-bed scene holding the spheres of a dump (``write_liggghts_dump`` with ``fixed``), as they
    are: those of type 2 fixed, the others free, each kind in the order of its ids, the fixed ones
    first (as ``rough_bed_simulation`` adds them); the box sized for the free count."""
    data = _read_dump(path, ("id", "type", "x", "y", "z", "vx", "vy", "vz", "radius"))
    data = data[np.argsort(data[:, 0], kind="stable")]
    base = data[:, 1] == 2
    sim = _box_simulation(rough_bed_half_width(int((~base).sum())))
    for rows, fixed in ((data[base], True), (data[~base], False)):
        if len(rows):
            sim.add_particles(rows[:, 2:5], rows[:, 8], "table1", velocity=rows[:, 5:8], allow_overlap=True,
                              fixed=fixed)
    return sim


def _column_from_state(rolling, positions, radii, velocities, angular_velocities=None):
    """A column scene (plate, cylinder scaled to the count) holding the given spheres as they are."""
    sim = _column_simulation(rolling)
    sim.add_wall(Cylinder(column_radius(len(positions)), material="table1", name="cylinder"))
    sim.add_particles(positions, radii, "table1", velocity=velocities, angular_velocity=angular_velocities,
                      allow_overlap=True)
    return sim


def _contacts_per_particle(sim) -> tuple[float, float]:
    """(contacts per particle, each pair counted for both and walls once; neighbors per particle)."""
    stats, n = sim.engine_statistics(), sim.n_particles
    return (2 * stats["pair_contacts"] + stats["wall_contacts"]) / n, 2 * stats["neighbor_pairs"] / n


def _force_pass_costs(sims: dict, rounds: int) -> dict:
    """Seconds per step of the contact-force and wall passes of each simulation, per round.

    The simulations take turns call by call (a pass is a few ms), so that the shared machine's
    slow spells, which last from milliseconds to seconds, fall on all of them alike. In a round
    each pass of each simulation is timed ``FORCE_PASS_CALLS`` times and its fastest call counts;
    the wall pass is a gather with the walls less one without them."""
    phases = {name: sim.passes() for name, sim in sims.items()}
    for ph in phases.values():  # one untimed call of each
        ph.pair(), ph.gather_walls(), ph.gather_plain()
    costs = {name: [] for name in sims}
    for _ in range(rounds):
        best = {name: [math.inf] * 3 for name in sims}
        for _ in range(FORCE_PASS_CALLS):
            for name, ph in phases.items():
                for p, fn in enumerate((ph.pair, ph.gather_walls, ph.gather_plain)):
                    tic = time.perf_counter()
                    fn()
                    best[name][p] = min(best[name][p], time.perf_counter() - tic)
        for name, (pair, walls, plain) in best.items():
            costs[name].append(pair + max(walls - plain, 0.0))
    for ph in phases.values():
        ph.restore()
    return costs


def compile_time(contact, spheres: int = 2, mesh: bool = False) -> float:
    """Seconds to compile (cold cache) or load (warm cache) the engine module of ``contact`` in this
    process, for the step loop a scene of ``spheres`` spheres takes (``advance_serial`` below
    ``SERIAL_BELOW`` spheres or on one thread, ``advance`` on threads otherwise): one step of 2
    (or ``SERIAL_BELOW``) spheres on a plate, two of them stacked (a pair contact and a wall
    contact); with ``mesh``, a mesh disk below the plate too (the module with the mesh passes)."""
    tic = time.perf_counter()
    sim = Simulation(contact=contact, dt=DT, skin=SKIN)
    sim.add_material(Material("table1", **TABLE1))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="table1"))
    if mesh:
        sim.add_wall(MeshWall(SHAPES["disk"](radius=0.1).moved(translation=(0, 0, -0.05)), material="table1"))
    spheres = 2 if spheres < SERIAL_BELOW else SERIAL_BELOW  # as many as the path needs
    row = np.arange(spheres - 2) + 1  # apart from the stack and each other, on the plate
    rest = np.column_stack([3 * RADIUS * (row % 64), 3 * RADIUS * (row // 64), np.full(len(row), RADIUS)])
    sim.add_particles(np.vstack([[[0, 0, RADIUS], [0, 0, 3 * RADIUS]], rest]), RADIUS, "table1")
    sim.run(steps=1)
    return time.perf_counter() - tic


_THREADS_FROM = weakref.WeakKeyDictionary()  # simulation -> its steps on each thread count when warmed up


def _warm_up(sim) -> None:
    """One untimed step (the list built, a large scene sorted in space); the steps on each thread
    count from here on are what ``_result`` reports."""
    sim.run(steps=1, progress=False)
    _THREADS_FROM[sim] = sim.engine_statistics()["steps_by_threads"]


def _timed_steps(sim, steps: int) -> tuple[float, int]:
    """(seconds, neighbor rebuilds) of ``steps`` steps."""
    before = sim.engine_statistics()["neighbor_rebuilds"]
    tic = time.perf_counter()
    sim.run(steps=steps, progress=False)
    wall = time.perf_counter() - tic
    return wall, sim.engine_statistics()["neighbor_rebuilds"] - before


def _time_run(sim, steps: int) -> tuple[float, int]:
    """(timed seconds, rebuilds during the timed steps), after one untimed step."""
    _warm_up(sim)
    return _timed_steps(sim, steps)


def _chunked(steps: int, chunks: int) -> np.ndarray:
    """``steps`` split into ``chunks`` near-equal whole chunks."""
    return np.array([steps * (c + 1) // chunks - steps * c // chunks for c in range(chunks)])


def _in_turn(sims, steps, chunks: int) -> tuple[np.ndarray, list[int]]:
    """Each scene warmed up, then ``steps`` steps of each (a number, or one per scene) in ``chunks``
    chunks taken in turn, so that they see the same moments of a shared machine's load: (seconds
    per scene and chunk, rebuilds per scene)."""
    for sim in sims:
        _warm_up(sim)
    todo = [_chunked(n, chunks) for n in np.broadcast_to(steps, len(sims))]
    walls = np.zeros((len(sims), chunks))
    rebuilds = [0] * len(sims)
    for c in range(chunks):
        for s, sim in enumerate(sims):
            walls[s, c], done = _timed_steps(sim, int(todo[s][c]))
            rebuilds[s] += done
    return walls, rebuilds


def _result(scene, model, sim, steps, compile_s, wall, rebuilds, threads, note="", split_repeats=20) -> BenchResult:
    n = sim.n_particles
    contacts, neighbors = _contacts_per_particle(sim)
    stats = sim.engine_statistics()
    state_bytes = stats["state_bytes"]
    since = _THREADS_FROM.get(sim, {})
    steps_on = {k: s - since.get(k, 0) for k, s in stats["steps_by_threads"].items() if s > since.get(k, 0)}
    if sim.backend_info.note():
        note = (note + "; " if note else "") + sim.backend_info.note()
    elif set(steps_on) - {threads}:  # the governor took threads away while other processes were busy
        shares = ", ".join(f"{k} thread{'s' if k > 1 else ''} for {s} steps"
                           for k, s in sorted(steps_on.items(), reverse=True))
        note = (note + "; " if note else "") + f"other processes were busy: {shares}"
    return BenchResult(scene=scene, model=model, particles=n, steps=steps, threads=threads, wall_s=wall,
                       particle_steps_per_s=n * steps / wall, compile_s=compile_s, contacts_per_particle=contacts,
                       neighbors_per_particle=neighbors, rebuilds=rebuilds,
                       split_s_per_step=sim.phase_seconds(split_repeats, rebuilds / max(steps, 1)),
                       peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                       state_bytes_per_particle=state_bytes / n, note=note,
                       device_memory_bytes_per_particle=sim.device_memory_bytes / n)


def _timed_on(sim, backend: str, steps: int, particles: int) -> tuple[float, float, int]:
    """(compile or load seconds, timed seconds, rebuilds) of ``steps`` steps of ``sim`` on
    ``backend``: on the GPU the kernels compile at the untimed first step, which is timed apart."""
    sim.backend = backend
    if sim.backend_info.on_host:
        compile_s = compile_time(ContactModel("hertz", rolling="epsd"), particles)
        return (compile_s, *_time_run(sim, steps))
    tic = time.perf_counter()
    _warm_up(sim)
    compile_s = time.perf_counter() - tic
    return (compile_s, *_timed_steps(sim, steps))


def column_collapse(particles=20000, steps=10000, threads=None, from_dump=None, echo=print,
                    backend="cpu") -> BenchResult:
    threads = threads or numba.get_num_threads()
    sim = _collapse(column_from_dump(from_dump) if from_dump else settled_column(particles, echo=echo,
                                                                                 backend=backend))
    compile_s, wall, rebuilds = _timed_on(sim, backend, steps, particles)
    note = f"settled state from {from_dump}" if from_dump else "settled state from the disk cache"
    return _result("column-collapse", "epsd", sim, steps, compile_s, wall, rebuilds, threads, note)


def hopper_simulation(particles: int, seed: int = 1, echo=print):
    """The mesh-hopper scene ``HOPPER_FILL`` s after the drop, from the disk cache or run now and
    cached; the hopper's STL is written beside it (for the LIGGGHTS input)."""
    path = _cache_dir() / f"hopper_{particles}_seed{seed}_v{__version__}.npz"
    if path.exists():
        sim = Simulation.restore(path)
        sim.track_energy = False
        return sim
    echo(f"dropping {particles} spheres into the hopper for {HOPPER_FILL} s (cached afterwards in {path.parent}) ...")
    sim = Simulation(contact=ContactModel("hertz", rolling="epsd"), dt=HOPPER_DT, skin=HOPPER_SKIN)
    sim.add_material(Material("table1", **TABLE1))
    mesh = hopper(**HOPPER)
    mesh.write(_cache_dir() / "hopper.stl")
    sim.add_wall(MeshWall(mesh, material="table1", name="hopper"))
    radius, z_min, z_max = HOPPER_REGION
    sim.insert(CylinderRegion(radius, z_min, z_max), particles, HOPPER_RADIUS, "table1", seed=seed)
    sim.run(HOPPER_FILL)
    sim.checkpoint(path)
    return sim


def mesh_hopper(particles=20000, steps=5000, threads=None, echo=print) -> BenchResult:
    """20,000 spheres discharging from a 10,000-triangle STL hopper (``HOPPER``)."""
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(ContactModel("hertz", rolling="epsd"), particles)
    sim = hopper_simulation(particles, echo=echo)
    wall, rebuilds = _time_run(sim, steps)
    return _result("mesh-hopper", "epsd", sim, steps, compile_s, wall, rebuilds, threads,
                   f"discharge from {HOPPER_FILL} s after the drop; hopper of {sim.walls[0].mesh.n_triangles} "
                   "triangles")


def single_particle(steps=150000, threads=None, echo=print) -> BenchResult:
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(ContactModel("hertz", rolling=validation_models()["epsd"]))
    sim = sphere_on_wall(validation_models()["epsd"])
    sim.set_velocities([0], velocity=(1.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0))
    wall, rebuilds = _time_run(sim, steps)
    return _result("single-particle", "epsd", sim, steps, compile_s, wall, rebuilds, threads,
                   "the seed report's case 1: one sphere rolling on a plane")


def dense_bed(particles=20000, steps=2000, threads=None, models=DENSE_BED_MODELS, echo=print) -> list[BenchResult]:
    """The settled column, cylinder kept, once per rolling model (and contact law of
    ``CONTACT_LAW_VARIANTS``) from the same positions and velocities.

    The cost of a model is measured on the identical state, one step in, before the runs part
    (without rolling resistance the bed rearranges and loses half its contacts within 2,000
    steps, which would flatter no rolling model): the contact-force and wall passes, the models
    taking turns call by call (``_force_pass_costs``, ``FORCE_PASS_ROUNDS`` rounds). The timed run
    that follows gives the particle-steps per second.
    """
    threads = threads or numba.get_num_threads()
    base = settled_column(particles, echo=echo)
    specs = validation_models()  # the models with the parameters the validation runs use (sds: k_roll)
    sims, compiles = {}, {}
    for model in models:
        spec = specs.get(model, model)
        compiles[model] = compile_time(bench_contact(spec), particles)
        sim = _column_from_state(spec, base.positions, base.radii, base.velocities, base.angular_velocities)
        sim.run(steps=1, progress=False)
        sims[model] = sim
    # a model's cost against none is the median of the rounds' ratios: a slow spell of the machine
    # that outlasts a round spoils one ratio, where it could spoil the minimum of one model alone
    rounds = _force_pass_costs(sims, FORCE_PASS_ROUNDS)
    force_pass = {model: min(times) for model, times in rounds.items()}
    results = []
    for model, sim in sims.items():
        contacts = _contacts_per_particle(sim)[0]
        wall, rebuilds = _time_run(sim, steps)
        r = _result("dense-bed", model, sim, steps, compiles[model], wall, rebuilds, threads)
        t = force_pass[model]
        r.note = f"identical state: contact forces + walls {t * 1e3:.3f} ms/step at {contacts:.2f} contacts/particle"
        if "none" in force_pass:
            ratios = np.array(rounds[model]) / np.array(rounds["none"])
            r.note += (f", {np.median(ratios):.3f}x no rolling model (median of {FORCE_PASS_ROUNDS} rounds, "
                       f"{ratios.min():.3f}-{ratios.max():.3f})")
        results.append(r)
    return results


def slab_state(particles: int) -> tuple[np.ndarray, np.ndarray]:
    """(positions, velocities) of the slab scene: a jittered cubic lattice of spacing 2.02 R,
    ``SLAB_LAYERS`` layers, just above the plate; velocities uniform in +-5 cm/s (seeded)."""
    side = max(1, math.ceil(math.sqrt(particles / SLAB_LAYERS)))  # enough lattice sites for every sphere
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side), np.arange(SLAB_LAYERS), indexing="ij"),
                    -1).reshape(-1, 3)[:particles]
    rng = np.random.default_rng(0)
    x = grid * 2.02 * RADIUS + (0.0, 0.0, 1.01 * RADIUS) + rng.uniform(-0.005, 0.005, grid.shape) * RADIUS
    return x, rng.uniform(-0.05, 0.05, x.shape)


def write_liggghts_dump(path, positions, velocities, radius: float, fixed=None) -> Path:
    """A LIGGGHTS/LAMMPS text dump (timestep 0; columns id type x y z vx vy vz radius) that the
    reference inputs read with ``read_dump``: the peers start from the identical state. ``fixed`` (a
    mask, optional): those spheres get type 2 (a rough base: ``rough_bed_from_dump``), the others 1."""
    path = Path(path)
    n = len(positions)
    types = np.ones(n) if fixed is None else np.where(np.asarray(fixed, dtype=bool), 2.0, 1.0)
    lo, hi = positions.min(axis=0) - 2 * radius, positions.max(axis=0) + 2 * radius
    with open(path, "w") as fh:
        fh.write(f"ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n{n}\nITEM: BOX BOUNDS ff ff ff\n")
        fh.write("".join(f"{a:.10g} {b:.10g}\n" for a, b in zip(lo, hi)))
        fh.write("ITEM: ATOMS id type x y z vx vy vz radius\n")
        np.savetxt(fh, np.column_stack([np.arange(1, n + 1), types, positions, velocities, np.full(n, radius)]),
                   fmt=["%d", "%d"] + ["%.10g"] * 7)
    return path


def slab(particles=20000, steps=1000, threads=None, echo=print, backend="cpu") -> BenchResult:
    threads = threads or numba.get_num_threads()
    sim = _slab_simulation(particles)
    compile_s, wall, rebuilds = _timed_on(sim, backend, steps, particles)
    return _result("slab", "epsd", sim, steps, compile_s, wall, rebuilds, threads,
                   f"{SLAB_LAYERS} lattice layers falling onto a plate")


def _slab_simulation(particles: int):
    x, v = slab_state(particles)
    sim = _column_simulation("epsd")
    sim.add_particles(x, RADIUS, "table1", velocity=v)
    return sim


def _collapse(sim):
    """``sim``, a settled column, with its cylinder removed: the collapse starts."""
    sim.remove_wall(next(w for w in sim.walls if w.name == "cylinder"))
    return sim


def scaling(particles=SCALING_LARGE, steps=300, threads=None, echo=print, scene="slab") -> list[BenchResult]:
    """The ``scene`` ("slab"; "column-collapse" from the settled columns of the disk cache; or
    "column-bed", the same columns at rest with their cylinder kept, ~4.2 contacts per sphere at
    both sizes) at ``SCALING_SMALL`` and at ``particles`` spheres, each timed over ``steps`` steps
    in ``SCALING_CHUNKS`` chunks taken in turn; the note of the second gives its cost per
    particle-step against the first, over the whole run and chunk by chunk."""
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(ContactModel("hertz", rolling="epsd"), particles)
    if scene == "slab":
        sims = [_slab_simulation(SCALING_SMALL), _slab_simulation(particles)]
        what = f"{SLAB_LAYERS} lattice layers falling onto a plate"
    elif scene == "column-collapse":
        sims = [_collapse(settled_column(n, echo=echo)) for n in (SCALING_SMALL, particles)]
        what = "the settled column's collapse (cylinder radius scaled with sqrt(N))"
    elif scene == "column-bed":
        sims = [settled_column(n, echo=echo) for n in (SCALING_SMALL, particles)]
        what = "the settled column at rest, cylinder kept (radius scaled with sqrt(N))"
    else:
        raise ParameterError(f"scene = {scene!r} is not a scaling scene: use 'slab', 'column-collapse' or "
                             "'column-bed'")
    walls, rebuilds = _in_turn(sims, steps, SCALING_CHUNKS)
    ratios = (walls[1] / sims[1].n_particles) / (walls[0] / sims[0].n_particles)
    whole = (walls[1].sum() / sims[1].n_particles) / (walls[0].sum() / sims[0].n_particles)
    results = [_result(scene, "epsd", sim, steps, compile_s, float(walls[s].sum()), rebuilds[s], threads,
                       f"{what}; in {SCALING_CHUNKS} chunks, in turn with the scene of {sims[1 - s].n_particles} "
                       "spheres")
               for s, sim in enumerate(sims)]
    results[1].note += (f": cost per particle-step {whole:.2f}x that at {SCALING_SMALL} (chunk by chunk "
                        f"{', '.join(f'{r:.2f}' for r in ratios)}; median {np.median(ratios):.2f}x)")
    return results


def rough_bed_simulation(particles: int, rough: bool, seed: int = 1, echo=print):
    """``particles`` spheres settled for ``ROUGH_BED_SETTLE`` s in a square box on a rough base of
    particles / 2 fixed spheres (``rough``) or on the bare plate; from the disk cache or built now."""
    path = _cache_dir() / f"roughbed_{particles}_{'rough' if rough else 'plate'}_seed{seed}_v{__version__}.npz"
    if path.exists():
        return _restored(path)
    echo(f"settling {particles} spheres on {'a rough base' if rough else 'the plate'} for {ROUGH_BED_SETTLE} s "
         f"(cached afterwards in {path.parent}) ...")
    half = rough_bed_half_width(particles)
    side = 2.0 * half
    sim = _box_simulation(half)
    floor = 0.0
    if rough:
        sim.add_particles(rough_base(RADIUS, ((-half, half), (-half, half)), seed=seed), RADIUS, "table1", fixed=True)
        floor = 2.0 * RADIUS
    height = particles * 4.0 / 3.0 * math.pi * RADIUS ** 3 / (0.3 * side * side)
    sim.insert(BoxRegion((-half, -half, floor), (half, half, floor + height)), particles, RADIUS, "table1", seed=seed)
    return _settled(sim, ROUGH_BED_SETTLE, path)


def _box_simulation(half: float):
    """The column's simulation (plate, Table 1) with four side planes at x, y = +-``half``."""
    sim = _column_simulation()
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            point, normal = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            point[axis], normal[axis] = sign * half, -sign
            sim.add_wall(Plane(point=point, normal=normal, material="table1"))
    return sim


def _restored(path):
    """A cached scene, as the bench times it (without the energy sums)."""
    sim = Simulation.restore(path)
    sim.track_energy = False
    return sim


def _settled(sim, seconds: float, path):
    """``sim`` run ``seconds`` and cached at ``path``, as the bench times it."""
    sim.run(seconds)
    sim.checkpoint(path)
    sim.track_energy = False
    return sim


def rough_bed(particles=20000, steps=2000, threads=None, echo=print) -> list[BenchResult]:
    """``particles`` free spheres at rest on ``particles`` / 2 fixed ones, against the same number on
    the bare plate: timed in ``ROUGH_BED_CHUNKS`` chunks taken in turn; the note of the first gives
    its cost per free particle-step against the second."""
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(ContactModel("hertz", rolling="epsd"), particles)
    sims = [rough_bed_simulation(particles, True, echo=echo), rough_bed_simulation(particles, False, echo=echo)]
    walls, rebuilds = _in_turn(sims, steps, ROUGH_BED_CHUNKS)
    ratios = walls[0] / walls[1]
    results = []
    for s, (sim, what) in enumerate(zip(sims, ("on a rough base", "on the plate"))):
        free = int((~sim.fixed).sum())
        r = _result("rough-bed", "epsd", sim, steps, compile_s, float(walls[s].sum()), rebuilds[s], threads,
                    f"{free} free spheres at rest {what}, in a square box; in {ROUGH_BED_CHUNKS} chunks in turn; "
                    f"{free * steps / walls[s].sum() / 1e6:.2f} M free particle-steps/s")
        results.append(r)
    results[0].note += (f": cost per free particle-step {walls[0].sum() / walls[1].sum():.3f}x that on the plate "
                        f"(chunk by chunk {', '.join(f'{r:.3f}' for r in ratios)}; median {np.median(ratios):.3f}x)")
    return results


def clump_bed_simulation(members: int, clumps: bool, seed: int = 1, echo=print):
    """``members`` // 4 tetrahedra of spheres of radius ``RADIUS`` (``clumps``), or as many spheres as
    they have members, poured into a square box and settled for ``CLUMP_BED_SETTLE`` s; from the disk
    cache or built now."""
    count = members // 4 if clumps else members // 4 * 4
    path = _cache_dir() / f"clumpbed_{count}_{'tetrahedra' if clumps else 'spheres'}_seed{seed}_v{__version__}.npz"
    if path.exists():
        return _restored(path)
    echo(f"settling {count} {'tetrahedra' if clumps else 'spheres'} in a box for {CLUMP_BED_SETTLE} s (cached "
         f"afterwards in {path.parent}) ...")
    tetrahedron = Clump.tetrahedron(RADIUS)
    reach = tetrahedron.reach() if clumps else RADIUS
    side = max(2.0 * column_radius(members), 10.0 * tetrahedron.reach())
    half = 0.5 * side
    sim = _box_simulation(half)
    height = count * 4.0 / 3.0 * math.pi * reach ** 3 / (0.25 * side * side)
    region = BoxRegion((-half, -half, 0.0), (half, half, height))
    if clumps:
        sim.insert(region, count, material="table1", clump=tetrahedron, seed=seed)
    else:
        sim.insert(region, count, RADIUS, "table1", seed=seed)
    return _settled(sim, CLUMP_BED_SETTLE, path)


def clump_bed(members=20000, steps=2000, threads=None, echo=print) -> list[BenchResult]:
    """Tetrahedral clumps at rest in a box against as many spheres as they have members in the same
    box, timed in ``CLUMP_BED_CHUNKS`` chunks taken in turn: clump-steps per second, the cost of a
    clump-step in sphere-steps (its members' pair and wall work plus the rigid-body pass: at most
    its members + 1, 5), the bytes a
    clump adds to its members' (its own fields, its members' clump index and offset, the index)."""
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(ContactModel("hertz", rolling="epsd"), members)
    sims = [clump_bed_simulation(members, True, echo=echo), clump_bed_simulation(members, False, echo=echo)]
    walls, rebuilds = _in_turn(sims, steps, CLUMP_BED_CHUNKS)
    st = sims[0].particle_set.state
    n_clumps = st.n_clumps
    extra = sum(getattr(st, f.name).nbytes for f in SCHEMA.of(PER_CLUMP)) + sum(
        getattr(st, name).nbytes for name in ("clump", "body_offset", "clump_start", "clump_members"))
    per_clump = (walls[0] / n_clumps) / (walls[1] / sims[1].n_particles)
    results = []
    for s, (sim, what) in enumerate(zip(sims, ("tetrahedra of 4 spheres", "spheres"))):
        bodies = n_clumps if s == 0 else sim.n_particles
        results.append(_result("clumps", "epsd", sim, steps, compile_s, float(walls[s].sum()), rebuilds[s], threads,
                               f"{bodies} {what} at rest in a box, {sim.n_particles} spheres in all; in "
                               f"{CLUMP_BED_CHUNKS} chunks in turn; {bodies * steps / walls[s].sum() / 1e6:.3f} M "
                               f"{'clump' if s == 0 else 'sphere'}-steps/s"))
    whole = (walls[0].sum() / n_clumps) / (walls[1].sum() / sims[1].n_particles)
    results[0].note += (f": a clump-step costs {whole:.2f} sphere-steps (target <= 5; chunk by chunk "
                        f"{', '.join(f'{r:.2f}' for r in per_clump)}, median {np.median(per_clump):.2f}); a clump "
                        f"adds {extra / n_clumps:.0f} B to its members'")
    return results


def coarse_graining_drum(alpha: float, seed: int = 1, echo=print, drum_diameters: float | None = None):
    """The coarse-graining study's drum (``experiments.coarse_graining.drum_parameters``; another
    radius in real diameters with ``drum_diameters``) of parcels of ``alpha``, settled (its case's
    settling stage) and turned ``CG_SPIN_UP`` s at the case's angular velocity; from the disk cache
    or built now."""
    size = CoarseGraining().sizes["full"]["drum"]
    if drum_diameters is not None:
        size = {**size, "drum_diameters": drum_diameters}
    params = drum_parameters("epsd", alpha, seed, size)
    data = drum_case(**RotatingDrum().drum_arguments(params))
    radius = f"{data['walls'][0]['radius']:.4g}m"
    path = _cache_dir() / f"cgdrum_{radius}_alpha{alpha:g}_seed{seed}_v{__version__}.npz"
    if path.exists():
        return _restored(path)
    echo(f"settling the drum of {'parcels of alpha ' + format(alpha, 'g') if alpha != 1.0 else 'real particles'} "
         f"and turning it for {CG_SPIN_UP} s (cached afterwards in {path.parent}) ...")
    sim = build_simulation(load_case(data))
    sim.run(data["stages"][0]["duration"])
    turn = data["stages"][1]["wall_motion"][0]
    sim.set_wall_velocity(turn["wall"], angular_velocity=[turn["rotate"]["angular_velocity"] * a
                                                           for a in turn["rotate"]["axis"]])
    return _settled(sim, CG_SPIN_UP, path)


def coarse_graining_bench(steps=12000, threads=None, echo=print, drum_diameters: float | None = None) -> list[BenchResult]:
    """The coarse-graining study's turning drum of real particles against parcels of ``CG_ALPHA``:
    ``steps`` steps of the real particles and as many of the parcels as take the same simulated time
    (their dt is alpha times longer), in ``CG_CHUNKS`` chunks taken in turn; the particles represented
    times the simulated time per second of wall time, and its ratio."""
    threads = threads or numba.get_num_threads()
    compile_s = compile_time(bench_contact("epsd"), 10000)
    sims = [coarse_graining_drum(a, echo=echo, drum_diameters=drum_diameters) for a in (1.0, CG_ALPHA)]
    counts = [steps, max(CG_CHUNKS, int(round(steps * sims[0].dt / sims[1].dt)))]
    walls, rebuilds = _in_turn(sims, counts, CG_CHUNKS)
    todo = np.array([_chunked(n, CG_CHUNKS) for n in counts])
    # particles represented x simulated seconds, per second of wall time: whole, and chunk by chunk
    represented = np.array([[sim.particles_represented * sim.dt] for sim in sims])
    rates = represented[:, 0] * todo.sum(axis=1) / walls.sum(axis=1)
    chunks = (represented * todo / walls)[1] / (represented * todo / walls)[0]
    drum = "the coarse-graining study's drum" if drum_diameters is None else f"a drum {drum_diameters:g} d in radius"
    results = []
    for s, (sim, what) in enumerate(zip(sims, ("real particles", f"parcels of alpha {CG_ALPHA:g}"))):
        results.append(_result("coarse-graining", "epsd", sim, counts[s], compile_s, float(walls[s].sum()), rebuilds[s],
                               threads, f"{drum} turning, {sim.n_particles} {what} standing for "
                               f"{sim.particles_represented:.0f} particles, dt {sim.dt:.3g} s, {counts[s]} steps "
                               f"({counts[s] * sim.dt:.3g} s simulated) in {CG_CHUNKS} chunks in turn; "
                               f"{rates[s]:.4g} particle-seconds simulated per second of wall time"))
    results[1].note += (f": {rates[1] / rates[0]:.3g}x the real particles' (chunk by chunk "
                        f"{', '.join(f'{r:.3g}' for r in chunks)}, median {np.median(chunks):.3g}x)")
    return results


def run_bench(scenes=SCENES, particles=None, steps=None, threads=None, from_dump=None, models=None,
              echo=print, backend="cpu") -> list[BenchResult]:
    unknown = [s for s in scenes if s not in SCENES]
    if unknown:
        raise ParameterError(f"scene = {', '.join(unknown)} is not known: allowed are {', '.join(SCENES)}")

    other = [s for s in scenes if s not in GPU_SCENES]
    if backend in BACKENDS and not BACKENDS[backend].on_host and other:
        raise ParameterError(f"scene = {', '.join(other)} is not timed on backend {backend!r}: allowed there are "
                             f"{', '.join(GPU_SCENES)}")
    find_backend(backend)
    if particles is not None and (isinstance(particles, bool) or not isinstance(particles, int) or particles < 1):
        raise ParameterError(f"particles = {particles!r} is not allowed: must be an integer >= 1")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int) or steps < 1):
        raise ParameterError(f"steps = {steps!r} is not allowed: must be an integer >= 1")
    if models is not None:
        bad = [m for m in models if m not in DENSE_BED_MODELS]
        if bad:
            raise ParameterError(f"model = {', '.join(bad)} is not known: allowed are {', '.join(DENSE_BED_MODELS)}")
    results = []
    for scene in scenes:
        if scene == "column-collapse":
            results.append(column_collapse(particles or 20000, steps or 10000, threads, from_dump, echo, backend))
        elif scene == "single-particle":
            results.append(single_particle(steps or 150000, threads, echo))
        elif scene == "mesh-hopper":
            results.append(mesh_hopper(particles or 20000, steps or 5000, threads, echo))
        elif scene == "slab":
            results.append(slab(particles or 20000, steps or 1000, threads, echo, backend))
        elif scene in ("rough-bed", "clumps"):
            pair = (rough_bed if scene == "rough-bed" else clump_bed)(particles or 20000, steps or 2000, threads, echo)
            echo(format_row(pair[0]))
            results += pair
        elif scene == "coarse-graining":
            pair = coarse_graining_bench(steps or 12000, threads, echo)
            echo(format_row(pair[0]))
            results += pair
        elif scene in ("scaling", "collapse-scaling"):
            pair = scaling(particles or SCALING_LARGE, steps or 300, threads, echo,
                           "slab" if scene == "scaling" else "column-collapse")
            echo(format_row(pair[0]))
            results += pair
        else:
            results += dense_bed(particles or 20000, steps or 2000, threads, models or DENSE_BED_MODELS, echo)
        echo(format_row(results[-1]))
    return results


def format_row(r: BenchResult) -> str:
    split = ", ".join(f"{k} {v * 1e3:.3g} ms" for k, v in r.split_s_per_step.items())
    return (f"{r.scene:16s} {r.model:20s} N={r.particles:<8d} steps={r.steps:<7d} threads={r.threads} "
            f"wall {r.wall_s:8.2f} s  {r.particle_steps_per_s / 1e6:7.2f} M particle-steps/s  "
            f"compile/load {r.compile_s:5.1f} s  contacts/p {r.contacts_per_particle:.2f}  "
            f"neighbors/p {r.neighbors_per_particle:.2f}  rebuilds {r.rebuilds}  "
            f"state {r.state_bytes_per_particle:.0f} B/p  peak RSS {r.peak_rss_mb:.0f} MB"
            + (f"  device {r.device_memory_bytes_per_particle:.0f} B/p" if r.device_memory_bytes_per_particle else "")
            + "\n"
            f"{'':17s}per step: {split}" + (f"\n{'':17s}{r.note}" if r.note else ""))


def write_json(results: list[BenchResult], path) -> Path:
    path = check_output_path("json", path, folder=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else []
    doc = {"version": __version__, "machine": platform.machine(), "processor": platform.processor(),
           "load_average": load, "results": [r.as_dict() for r in results]}
    path.write_text(json.dumps(doc, indent=2))
    return path
