"""Simulation: the object users hold, a façade over the scene's collections and its schedule.

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), gravity=(0, 0, -9.81))
    sim.add_material(rd.Material("glass", 63e9, 0.24, 2500, friction=0.5, restitution=0.9))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="glass"))
    sim.add_particles([[0, 0, 0.01]], radius=0.005, material="glass")
    sim.run(0.5, observers=[rd.TimeSeries("out/series.csv", interval=1e-3)])

What it holds, each in its own module: the spheres (``scene.particles.Particles``), the walls
(``scene.wall_set.WallSet``), the bonds (``scene.bonds.BondSet``), the outlets and inflows
(``scene.boundaries.Boundaries``), everything that acts between steps (``scene.schedule.Schedule``),
the time-step policy (``scene.timestep``) and checkpoints (``scene.checkpoint``); its engine state
(``engine.state.EngineState``) the arrays the step loop reads and writes.
"""

from __future__ import annotations

import numpy as np

from rollingdem.engine.backends import backend as find_backend, default_backend
from rollingdem.engine.codegen import EngineModules
from rollingdem.engine.layout import I_FORCES_VALID
from rollingdem.engine.phases import Passes
from rollingdem.engine.state import EngineState
from rollingdem.errors import ParameterError, check_positive, check_vector
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene import checkpoint, periodic as periodic_box_checks
from rollingdem.scene.bonds import BondSet
from rollingdem.scene.boundaries import Boundaries
from rollingdem.scene.checkpoint import VERSION as __version__  # noqa: F401
from rollingdem.scene.conditions import as_conditions
from rollingdem.scene.materials import Material, MaterialTable
from rollingdem.scene.particles import Particles
from rollingdem.scene.rigid_bodies import ClumpSet
from rollingdem.scene.schedule import Schedule, as_observers, steps_of
from rollingdem.scene.timestep import TimeStepPolicy
from rollingdem.scene.wall_set import WallSet
from rollingdem.scene.walls import Wall


def _particle_view(name: str, doc: str):
    """A read-only property: the state's per-particle array ``name`` in the order the particles
    were added (a copy once the engine has sorted them: write through the setters)."""
    return property(lambda self: self.particle_set.by_id(name), doc=doc)


class Simulation:
    """A DEM scene of spheres and walls, and its time integration.

    Parameters
    ----------
    contact: the contact law (``ContactModel``); default Hertz-Mindlin, history spring, no rolling.
    gravity: gravitational acceleration (m/s^2), a 3-vector; may be changed between runs.
    dt: time step (s); default: the largest step the checks allow (0.2 x Rayleigh time, ...).
    skin: neighbor-list skin (m); default 0.4 x the largest radius.
    check_timestep: refuse a run whose dt exceeds the stable limit (docs/models.md §2).
    periodic: periodic boundaries, ``{"x": (x_min, x_max), ...}`` for any of x, y, z (m): a particle
        that leaves at one end comes back at the other, and pairs across the ends are ordinary
        contacts (the minimum image); each length must be at least 2 (2 R_max + skin). Walls may
        coexist (a chute floor under an x-periodic flow). ``positions`` are put back into the box
        at each neighbor-list build; ``unwrapped_positions`` count the lengths crossed.
    lees_edwards: ``rd.LeesEdwards(shear_rate=..., gradient="z")``: the periodic box sheared (flow
        along x); ``shear`` reads and sets its rate and shift (``rollingdem.scene.periodic``).
    track_energy: sum the energy dissipated in the contacts (``dissipated_energy``), by normal
        damping, sliding, rolling and twisting. Off by default, as in LIGGGHTS and LAMMPS: the
        bookkeeping costs about 12 % of the contact forces. A ``TimeSeries`` observer turns it on
        (its columns hold the dissipated energies); it may be switched at any time and counts from then.
    backend: where the steps run: ``"cpu"`` (Numba threads) or ``"cuda"`` (an NVIDIA GPU through
        numba-cuda, docs/gpu.md); default: the environment variable ``ROLLINGDEM_BACKEND``, else
        ``"cpu"``. It may be changed between runs, and a checkpoint of either restores on either.
    """

    def __init__(self, contact: ContactModel | None = None, gravity=(0.0, 0.0, -9.81), dt: float | None = None,
                 skin: float | None = None, check_timestep: bool = True, track_energy: bool = False,
                 periodic: dict | None = None, backend: str | None = None, lees_edwards=None):
        self._contact = contact if contact is not None else ContactModel()
        if not isinstance(self._contact, ContactModel):
            raise ParameterError(f"contact = {contact!r} is not allowed: must be a rollingdem.ContactModel")
        self.materials = MaterialTable()
        self.gravity = gravity
        self._dt = None if dt is None else check_positive("dt", dt, "s")
        self.dt_automatic = dt is None  # chosen by the checks, and lowered by them when a run's speeds need it
        self.given_skin = None if skin is None else check_positive("skin", skin, "m")  # None: from the radii
        self.check_timestep = bool(check_timestep)
        self.track_energy = bool(track_energy)
        self._state = EngineState(self._contact.history_size)
        self.backend = default_backend() if backend is None else backend
        self.periodic = periodic_box_checks.check_periodic(periodic)
        self.shear = periodic_box_checks.ShearedBox(self._state, self.periodic, lees_edwards)
        # how a user turns a check off, as the refusal tells it; a case file names its own keys
        self.hints = {"check_timestep": "pass check_timestep=False to the Simulation",
                      "allow_overlap": "pass allow_overlap=True"}
        state, changed = self._state, self._scene_changed  # each collection gets what it needs (docs/architecture.md)
        self.schedule = Schedule(state)
        self.wall_set = WallSet(state, self.materials, self.schedule, changed)
        self.particle_set = Particles(state, self.materials, self.periodic, self.hints, self.wall_set, changed)
        self.clump_set = ClumpSet(state, self.materials, self.periodic, self.particle_set, self.wall_set, changed)
        self.bond_set = BondSet(state, self.particle_set)
        self.boundary_set = Boundaries(state, self.schedule, self.materials, self.periodic, self.wall_set)
        self.time_step_policy = TimeStepPolicy(state, self._contact, self.materials, self.wall_set,
                                               self.boundary_set, self.bond_set)
        self.step, self.time = 0, 0.0
        # (time, step) where dt took over: time = t0 + (step - s0) dt, however the steps were cut
        self.time_origin, self._pair_params, self._modules = (0.0, 0), None, EngineModules()

    def _scene_changed(self) -> None:  # particles, walls or coefficients changed: a new pair table
        self._pair_params = None
    # --- settings --------------------------------------------------------------------------------
    def _refuse_contact(self, value):
        raise ParameterError(f"contact = {value!r} is not allowed after the Simulation is made: pass it as "
                             "Simulation(contact=...)")

    contact = property(lambda self: self._contact, _refuse_contact,
                       doc="The contact law, fixed when the simulation is made (its history is laid out for it).")

    @property
    def backend(self) -> str:
        return self._state.backend.name

    @backend.setter
    def backend(self, value):
        self._state.backend = find_backend(value)

    backend_info = property(lambda self: self._state.backend,
                            doc="The backend itself (``rollingdem.engine.backends.Backend``): what it is and can do.")

    @property
    def gravity(self) -> tuple[float, float, float]:
        return tuple(self._gravity)

    @gravity.setter
    def gravity(self, value):
        self._gravity = np.array(check_vector("gravity", value))
        if hasattr(self, "_state"):
            self._state.info[I_FORCES_VALID] = 0

    @property
    def dt(self) -> float:
        if self._dt is None:
            self._dt = self.stable_time_step()
        return self._dt

    @dt.setter
    def dt(self, value):
        self._dt = check_positive("dt", value, "s")
        self.time_origin, self.dt_automatic = (self.time, self.step), False

    @property
    def skin(self) -> float:
        radius = None if self.given_skin is not None else self.particle_set.largest_radius(self.inflows)
        return self.given_skin if radius is None else 0.4 * radius if radius > 0 else 1e-3

    def add_material(self, material: Material) -> int:
        self._scene_changed()
        return self.materials.add(material, self.contact)

    def set_material(self, material: Material) -> None:  # contact properties anew (MaterialTable.replace)
        if self.materials.replace(material):
            self._scene_changed()
            self._state.info[I_FORCES_VALID] = 0

    def set_pair(self, a, b, **coefficients) -> None:
        """Override pair coefficients (friction, rolling_friction, restitution, rolling_damping)."""
        self.materials.set_pair(a, b, **coefficients)
        self._scene_changed()
        self._state.info[I_FORCES_VALID] = 0

    def pair_parameters(self) -> np.ndarray:
        if self._pair_params is None:
            self._pair_params = self.contact.pair_table(self.materials.pairs())
        return self._pair_params

    # --- particles -------------------------------------------------------------------------------
    n_particles = property(lambda self: self._state.n, doc="The number of particles.")

    def add_particles(self, positions, radius, material, velocity=None, angular_velocity=None,
                      allow_overlap: bool = False, fixed: bool = False) -> np.ndarray:
        """Add spheres; returns their indices. ``radius`` is a number or one per sphere (m). Spheres that overlap each
        other or a wall are refused unless ``allow_overlap``. ``fixed`` spheres never move (a rough base, an obstacle):
        they touch free spheres with their material and radius, as a partner of infinite mass and inertia, and neither
        walls nor each other (pairs of fixed spheres are left out of the neighbor list, so a base costs only its
        contacts with free spheres); ``forces`` holds the load the free spheres put on them."""
        return self.particle_set.add(positions, radius, material, velocity, angular_velocity, allow_overlap, fixed)

    def insert(self, region, count: int | None = None, radius=None, material=None, seed: int = 0, velocity=None,
               max_attempts: int = 200, mass: float | None = None, fraction: float | None = None, clump=None) -> np.ndarray:
        """Fill ``region`` (``BoxRegion``, ``CylinderRegion``, ``MeshRegion``) with ``count`` non-overlapping spheres,
        or of ``mass`` (kg) or a ``fraction`` of its volume; ``radius``: a number or a distribution (``rd.Uniform``,
        ``Normal``, ``Discrete``, ``MassFractions``, ``SieveCurve``); with ``clump`` (``rd.Clump``) clumps at random
        orientations. Reproducible from ``seed``. Returns the new spheres' (in Morton order) or clumps' indices."""
        if clump is not None:
            return self.clump_set.insert(region, count, clump, material, seed, velocity, max_attempts, mass, fraction, radius)
        return self.particle_set.insert(region, count, radius, material, seed, velocity, max_attempts, mass, fraction)

    def add_clumps(self, clump, positions, material, orientations=None, velocity=None, angular_velocity=None,
                   fixed: bool = False, allow_overlap: bool = False) -> np.ndarray:
        """Add rigid bodies of ``clump`` (``rd.Clump``) at ``positions`` (centres of mass), turned by ``orientations``
        (unit quaternions w, x, y, z); returns their indices in ``clumps``; members are particles (models.md §17)."""
        return self.clump_set.add(clump, positions, material, orientations, velocity, angular_velocity, fixed,
                                  allow_overlap)

    clumps = property(lambda self: self.clump_set.table(), doc="Each clump's centre, velocity, angular_velocity, "
                      "orientation (of its principal frame), axes (columns), mass, moments, angular_momentum, by row.")

    positions = _particle_view("x", "Positions (m), (N, 3), in the order the particles were added.")
    velocities = _particle_view("v", "Velocities (m/s), (N, 3).")
    angular_velocities = _particle_view("w", "Angular velocities (rad/s), (N, 3).")
    forces = _particle_view("f", "Forces (N) at the last step, (N, 3).")
    torques = _particle_view("t", "Torques (N m) at the last step, (N, 3).")
    radii = _particle_view("radius", "Radii (m).")
    masses = _particle_view("mass", "Masses (kg).")
    material_indices = _particle_view("mat", "Each particle's material index.")
    particle_ids = _particle_view("tags", "Each particle's number for good: the index it had when it was added "
                                          "(equal to its index until an outlet takes particles out).")
    fixed = _particle_view("is_fixed", "Whether each particle is fixed (add_particles(..., fixed=True)), bool.")
    particles_represented = property(lambda self: self.particle_set.represented(), doc="The real particles the "
                                     "spheres stand for: alpha^3 a parcel of coarse_graining alpha (docs/models.md §18).")

    @property
    def unwrapped_positions(self) -> np.ndarray:
        """Positions with the periodic lengths each particle crossed added back (``positions`` where
        no axis is periodic)."""
        return self.particle_set.unwrapped_positions()

    def particle_field(self, name: str) -> np.ndarray:
        """A per-particle field of the state's schema (``engine.schema``: ``radius``, ``clump``, ...), by ``positions``."""
        return self.particle_set.by_id(self.particle_set.field(name).name)

    def set_particle_field(self, name: str, indices, values) -> None:
        """Set a per-particle field of some particles (``values`` one for all, or one each)."""
        self.particle_set.set_field(name, indices, values)

    def set_velocities(self, indices, velocity=None, angular_velocity=None) -> None:  # m/s, rad/s
        self.particle_set.set_velocities(indices, velocity, angular_velocity)

    def set_clump_velocities(self, indices, velocity=None, angular_velocity=None) -> None:  # of clumps, as above
        self.clump_set.set_velocities(indices, velocity, angular_velocity)

    def kinetic_energy(self) -> tuple[float, float]:  # (translational, rotational) kinetic energy (J)
        return self.particle_set.kinetic_energy(self.clump_set)

    # --- outlets and inflows ---------------------------------------------------------------------
    def add_outlet(self, region, name: str | None = None, interval: float | None = None, refill=None, seed: int = 0):
        """Take out every free particle whose centre enters ``region`` (``BoxRegion``,
        ``CylinderRegion``), every ``interval`` s (default 1e-3); the time series counts them and
        their mass, cumulative, per outlet (``outlet_{name}_count``, ``outlet_{name}_mass``). The
        others keep their contacts and history (``particle_ids`` keeps each one's number for good).
        With a ``refill`` region each one is put back there at once (``boundaries.Outlet``)."""
        return self.boundary_set.add_outlet(region, name, interval, refill, seed)

    def add_inflow(self, region, radius, material, rate: float | None = None, mass_rate: float | None = None,
                   velocity=None, seed: int = 0, name: str | None = None, interval: float | None = None,
                   start: float | None = None):
        """Insert particles into ``region`` during the runs, at ``rate`` particles/s or ``mass_rate``
        kg/s from ``start`` (default now), every ``interval`` s (default 1e-3): at random places
        where they overlap neither a particle nor a wall, reproducibly from ``seed``, with
        ``velocity``. ``radius`` is a number or a distribution (``rd.Uniform`` ...). What finds no room
        waits for the next interval; a warning says so once, and the time series' ``inflow_{name}
        _shortfall`` counts it. Returns the ``Inflow``."""
        return self.boundary_set.add_inflow(region, radius, material, rate, mass_rate, velocity, seed, name,
                                            interval, self.time if start is None else start)

    outlets = property(lambda self: self.boundary_set.outlets, doc="The outlets (``Outlet``), in the order added.")
    inflows = property(lambda self: self.boundary_set.inflows, doc="The inflows (``Inflow``), in the order added.")

    def boundary_counts(self) -> dict:  # the cumulative counts of each outlet and inflow, by time-series column
        return self.boundary_set.counts()

    # --- walls -----------------------------------------------------------------------------------
    walls = property(lambda self: self.wall_set.in_place(), doc="The walls in place, in the order they were added.")

    def add_wall(self, wall: Wall) -> Wall:
        """Add a ``Plane``, ``Cylinder`` or ``MeshWall`` (material default: the first material)."""
        return self.wall_set.add(wall)

    def remove_wall(self, wall: Wall | str) -> None:
        """Remove a wall (the object or its name); its contact history is dropped."""
        self.wall_set.remove(wall)

    def set_wall_velocity(self, wall: Wall | str, velocity=None, angular_velocity=None, point=None) -> None:
        """A wall's (the object or its name) new steady velocity (m/s) and/or angular velocity (rad/s) from
        now on, about ``point`` for a mesh (default: its own); a plane or cylinder turns its surface."""
        self.wall_set.set_velocity(wall, velocity, angular_velocity, point)

    def set_wall_motion(self, wall: Wall | str, motion) -> None:
        """A wall's program from now on (``Oscillation``, ``MotionTable``, ``Servo``; None: none), from where it is."""
        self.wall_set.set_motion(wall, motion)

    def wall_loads(self, point=None) -> dict:
        """Force (N) and torque (N m) on each wall in place at the last step, by the wall's name (or
        '#k' for an unnamed one): {"force": (fx, fy, fz), "torque": (tx, ty, tz), "point": ...}, the
        torque about ``point`` if given, else about the wall's own ``torque_point`` (a mesh's
        centroid, moving with it; a plane's or cylinder's point)."""
        return self.wall_set.loads(point)

    def mesh_walls(self) -> dict:
        """Each mesh wall in place, as its ``TriangleMesh`` where it is now, by a file-safe label
        (its name, else ``mesh{k}``)."""
        return self.wall_set.meshes()

    # --- bonds -----------------------------------------------------------------------------------
    def add_bonds(self, bond, pairs=None, gap=None) -> int:
        """Bond pairs of particles with ``bond`` (a ``rollingdem.ParallelBond``, docs/models.md §1.7):
        the ``pairs`` of particle indices given, or every pair whose surface gap is at most ``gap``
        (m; negative: overlapping by at least -gap), as PFC's bond gap. The bonds start unloaded at
        the pairs' present distance; the pair's contact acts beside its bond (PFC). Pairs across a
        periodic boundary are not found by ``gap``: give them as ``pairs``. Returns how many bonds
        were made."""
        return self.bond_set.add(bond, pairs, gap)

    def bonds(self):
        """The bonds as a table (pandas): particles i and j, ``status`` (intact, tension, shear: the
        mode it broke in), the normal force F_n (N, tension positive), |F_s| (N), M_t and |M_b| (N m)."""
        return self.bond_set.table()

    def bond_counts(self) -> dict[str, int]:
        """``bonds_intact``, ``bonds_broken_tension``, ``bonds_broken_shear``; empty without bonds."""
        return self.bond_set.counts()

    def bond_energy(self) -> float:  # the strain energy (J) of the intact bonds (docs/models.md §1.7)
        return self.bond_set.energy()

    # --- engine ----------------------------------------------------------------------------------
    def engine_module(self):
        """The compiled engine module this simulation steps with (``rollingdem.engine.codegen``)."""
        return self._modules.module(self.contact, self.track_energy, self._state)

    def phase_seconds(self, repeats: int = 20, rebuilds_per_step: float = 0.0) -> dict[str, float]:
        """Seconds per step of each phase of a step on the present state and backend (contact forces, walls,
        integration and gathering, neighbor search; a backend may add its own), each timed on its own, the fastest of
        5 blocks of ``repeats`` calls; the neighbor search counts ``rebuilds_per_step`` times. The state stays."""
        st = self._state
        return st.backend.phase_seconds(st, self.engine_module(), (self.dt, self.gravity, self.skin,
                                                                   self.pair_parameters()), repeats, rebuilds_per_step)

    def passes(self):  # each pass of the step as a call on the present state (engine.phases.Passes, CPU), to time
        return Passes(self._state, self.engine_module(), self.dt, self.gravity, self.skin, self.pair_parameters())

    device_memory_bytes = property(lambda self: self._state.backend.device_bytes(self._state),
                                   doc="The bytes the backend held on its device at the last run (0 on the CPU).")

    def dissipated_energy(self) -> dict[str, float]:
        """Energy (J) dissipated while ``track_energy`` was on (normal damping, sliding, rolling, twisting), over the
        run: what the particles an outlet took out had dissipated stays in it."""
        return self.particle_set.dissipated_energy(self.track_energy)

    def number_of_contacts(self) -> int:
        return int(self._state.contacts.sum())

    def contact_forces(self) -> dict:  # the last step's contacts: i, j (-1: a wall), force on i (N), branch j to i (m)
        return self._state.contact_forces()

    def engine_statistics(self) -> dict:
        """What the engine counts (``EngineState.statistics``): neighbor-list rebuilds, steps on each
        thread count, bytes of the state, pair and wall contacts, neighbor pairs."""
        return self._state.statistics()

    # --- time step -------------------------------------------------------------------------------
    def time_step_limits(self) -> list[tuple[str, float]]:  # each criterion of models.md §2 that applies: (what, dt)
        return self.time_step_policy.limits()

    def stable_time_step(self) -> float:  # the largest dt all criteria allow (s)
        return self.time_step_policy.stable()

    def check_time_step(self) -> None:  # refuse a dt above a stable limit (unless check_timestep is off), as run does
        if self.check_timestep:
            dt = self.time_step_policy.check(self.dt, self.dt_automatic, self.pair_parameters(), self.time,
                                             self.hints["check_timestep"])
            if dt != self.dt:  # an automatic dt, lowered: it stays automatic
                self.dt, self.dt_automatic = dt, True

    def choose_time_step(self) -> None:  # an automatic dt anew: the stable step now, raised or lowered; a given one stays
        if self.dt_automatic and self.n_particles:
            self.dt, self.dt_automatic = self.time_step_policy.stable(), True

    # --- running ---------------------------------------------------------------------------------
    def check_before_run(self) -> None:
        """What ``run`` refuses first: a non-finite state, mesh walls, inflows' room, dt, cohesion reach, periodic box."""
        self.schedule.check_finite_state(self)
        self.wall_set.check_scene()
        self.boundary_set.check_room()
        self.check_time_step()
        self.time_step_policy.check_contact_reach(self.skin)
        periodic_box_checks.check_scene(self)

    def run(self, duration: float | None = None, steps: int | None = None, observers=(),
            progress: bool = False, label: str = "run", until=None) -> str | None:
        """Advance the scene by ``duration`` seconds (rounded to whole steps) or by ``steps`` steps,
        at most: with ``until`` (conditions, ``rollingdem.scene.conditions``) it ends at the first
        check that finds one met and returns what ended it, in words (None: the time ran out).

        Observers are called at their intervals and at the last step; the progress bar shows
        simulated time, steps/s and time left. A run that goes unstable stops with
        ``SimulationError`` after the observers have written what they had.
        """
        steps_of(duration, steps, self.dt)
        observers, conditions = as_observers(observers), as_conditions(until)
        if not isinstance(label, str):
            raise ParameterError(f"label = {label!r} is not allowed: must be a string")
        self.check_before_run()  # (it may lower an automatic dt: the duration is counted in its steps)
        return self.schedule.run(self, steps_of(duration, steps, self.dt), observers, progress, label, conditions)

    # --- checkpoint ------------------------------------------------------------------------------
    def checkpoint(self, path):
        """Write the complete state; ``Simulation.restore(path)`` continues bit for bit."""
        return checkpoint.write(self, path, self._state)

    @classmethod
    def restore(cls, path, backend: str | None = None) -> "Simulation":
        """The simulation a checkpoint (``Simulation.checkpoint``, ``Checkpoints``, a run's ``final.npz``) holds,
        to step on ``backend`` (a checkpoint does not depend on the backend that wrote it)."""
        return checkpoint.restore(cls, path, backend)
