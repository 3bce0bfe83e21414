"""Simulation: the object users hold.

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), gravity=(0, 0, -9.81))
    sim.add_material(rd.Material("glass", 63e9, 0.24, 2500, friction=0.5, restitution=0.9))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="glass"))
    sim.add_particles([[0, 0, 0.01]], radius=0.005, material="glass")
    sim.run(0.5, observers=[rd.TimeSeries("out/series.csv", interval=1e-3)])
"""

from __future__ import annotations

import json
import math
import time as _time
import zipfile
from pathlib import Path

import numpy as np

from rollingdem.physics.contact.model import ContactModel
from rollingdem.engine.state import EngineState, periodic_box
from rollingdem.physics.records import BOND_PARAMETERS, BOND_STATE, ENERGY_CHANNELS, WALL_MESH
from rollingdem.engine.layout import I_FORCES_VALID
from rollingdem.engine.codegen import engine_module
from rollingdem.errors import ParameterError, SimulationError, check_finite, check_integer, check_positive, check_vector
from rollingdem.scene.materials import Material, MaterialTable
from rollingdem.physics.timestep import SPRING_FRACTION
from rollingdem.scene.mesh import MeshWall, TriangleMesh
from rollingdem.scene.walls import INACTIVE, Wall, wall_from_dict
from rollingdem.engine.backends import backend as find_backend, check_backend
from rollingdem.engine.schema import PER_PARTICLE, SCHEMA

def default_backend() -> str:
    """The backend of a Simulation not told one: ``ROLLINGDEM_BACKEND``, else ``"cpu"`` (how
    ``rollingdem validate --backend`` reaches the simulations of every case and worker)."""
    import os

    return check_backend(os.environ.get("ROLLINGDEM_BACKEND", "") or "cpu", "ROLLINGDEM_BACKEND")

__version__ = "0.1.0"
SOLID_SPHERE = 0.4  # I = 2/5 m R^2


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
                 periodic: dict | None = None, backend: str | None = None):
        self.contact = contact if contact is not None else ContactModel()
        if not isinstance(self.contact, ContactModel):
            raise ParameterError(f"contact = {contact!r} is not allowed: must be a rollingdem.ContactModel")
        self.materials = MaterialTable()
        self.gravity = gravity
        self._dt = None if dt is None else check_positive("dt", dt, "s")
        self._skin = None if skin is None else check_positive("skin", skin, "m")
        self.check_timestep = bool(check_timestep)
        self.track_energy = bool(track_energy)
        self._walls: list[Wall] = []
        self._outlets: list = []  # rollingdem.scene.boundaries.Outlet
        self._inflows: list = []  # rollingdem.scene.boundaries.Inflow
        self._engine_walls: list[Wall] = []  # the walls in place, in the engine's order
        self._state = EngineState(self.contact.history_size)
        self.backend = default_backend() if backend is None else backend
        self.periodic = self._check_periodic(periodic)
        self._state.contact_list.box = periodic_box(self.periodic)
        self.step = 0
        self.time = 0.0
        # (time, step) where the present dt took over: time = t0 + (step - s0) dt, one product, so
        # the clock does not depend on how the steps were cut into runs and kernel calls
        self._time_origin = (0.0, 0)
        self._pair_params = None
        self._dt_passed = None  # (scene key, fastest speeds) when dt last passed _check_dt
        self._modules = {}  # engine modules by (contact, track_energy, serial)
        self._stepped = set()  # ids of the engine modules this simulation has stepped with (compiled)
        # how a user turns a check off, as the refusal tells it; a case file names its own keys
        self.hints = {"check_timestep": "pass check_timestep=False to the Simulation",
                      "allow_overlap": "pass allow_overlap=True"}

    # --- scene ---------------------------------------------------------------------------------
    @property
    def backend(self) -> str:
        return self._state.backend.name

    @backend.setter
    def backend(self, value):
        self._state.backend = find_backend(value)

    @property
    def backend_info(self):
        """The backend itself (``rollingdem.engine.backends.Backend``): what it is and can do."""
        return self._state.backend

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
        self._time_origin = (self.time, self.step)

    @property
    def skin(self) -> float:
        if self._skin is not None:
            return self._skin
        radii = [float(self._state.radius.max())] if self.n_particles else []
        radii += [inflow.radius.max_radius for inflow in self._inflows]
        return 0.4 * max(radii) if radii else 1e-3

    def add_material(self, material: Material) -> int:
        self._pair_params = None
        return self.materials.add(material)

    def set_pair(self, a, b, **coefficients) -> None:
        """Override pair coefficients (friction, rolling_friction, restitution, rolling_damping)."""
        self.materials.set_pair(a, b, **coefficients)
        self._pair_params = None
        self._state.info[I_FORCES_VALID] = 0

    @property
    def n_particles(self) -> int:
        return self._state.n

    def add_particles(self, positions, radius, material, velocity=None, angular_velocity=None,
                      allow_overlap: bool = False, fixed: bool = False) -> np.ndarray:
        """Add spheres; returns their indices. ``radius`` is a number or one per sphere (m).

        Spheres that overlap each other or a wall are refused unless ``allow_overlap``. ``fixed``
        spheres never move (a rough base, an obstacle): they touch free spheres with their material
        and radius, as a partner of infinite mass and inertia, and neither walls nor each other
        (pairs of fixed spheres are left out of the neighbor list, so a base costs only its
        contacts with free spheres); ``forces`` holds the load the free spheres put on them.
        """
        try:
            x = np.array(positions, dtype=np.float64, ndmin=2)
        except (TypeError, ValueError):
            raise ParameterError(f"positions = {_short(positions)} is not allowed: must be N points of three "
                                 "numbers (m)") from None
        if x.ndim != 2 or x.shape[1] != 3:
            raise ParameterError(f"positions with shape {x.shape} are not allowed: must be N points of three "
                                 "numbers, shape (N, 3)")
        m = x.shape[0]
        bad = ~np.isfinite(x).all(axis=1)
        if bad.any():
            k = int(np.nonzero(bad)[0][0])
            raise ParameterError(f"position of particle {k} = {x[k].tolist()} is not allowed: must be finite")
        r = self._radii(radius, m)
        badr = ~(np.isfinite(r) & (r > 0))
        if badr.any():
            k = int(np.nonzero(badr)[0][0])
            raise ParameterError(f"radius of particle {k} = {r[k]:g} is not allowed: must be > 0 (m)")
        v = self._vectors("velocity", velocity, m)
        w = self._vectors("angular_velocity", angular_velocity, m)
        if not isinstance(fixed, (bool, np.bool_)):
            raise ParameterError(f"fixed = {_short(fixed)} is not allowed: must be True or False")
        if fixed and (v.any() or w.any()):
            raise ParameterError("velocity / angular_velocity of fixed particles is not allowed: a fixed particle "
                                 "never moves; leave them out (or add the particles with fixed=False)")
        mat_idx = (self.materials.index(material) if not isinstance(material, (list, tuple, np.ndarray))
                   else None)
        if mat_idx is None:
            if len(material) != m:
                raise ParameterError(f"material with {len(material)} entries is not allowed for {m} positions: "
                                     "must be one material or one per sphere")
            mats = np.array([self.materials.index(mm) for mm in material], dtype=np.int32)
        else:
            mats = np.full(m, mat_idx, dtype=np.int32)
        self._check_in_box(x)
        if not allow_overlap:
            self._check_no_overlap(x, r, walls=not fixed)  # walls never touch a fixed particle
        density = np.array([self.materials.materials[k].density for k in mats])
        mass = density * (4.0 / 3.0) * math.pi * r ** 3
        first = self.n_particles
        self._state.append_particles(x=x, v=v, w=w, radius=r, mass=mass, inertia=SOLID_SPHERE * mass * r ** 2,
                                     mat=mats, fixed=np.full(m, bool(fixed), dtype=np.uint8))
        self._pair_params = None
        return np.arange(first, first + m)

    @staticmethod
    def _radii(radius, m):
        """One radius per sphere from a number or a sequence of m numbers."""
        try:
            r = np.asarray(radius, dtype=np.float64)
        except (TypeError, ValueError):
            r = None
        if r is None or isinstance(radius, (str, bool)) or r.ndim > 1:
            raise ParameterError(f"radius = {_short(radius)} is not allowed: must be a number or one number per "
                                 "sphere (m)")
        if r.ndim == 1 and r.shape[0] != m:
            raise ParameterError(f"radius with {r.shape[0]} values is not allowed for {m} positions: must be one "
                                 f"radius or one per sphere ({m})")
        return np.broadcast_to(r, (m,)).copy()

    @staticmethod
    def _vectors(name, value, m):
        """(m, 3) vectors from one 3-vector or m of them."""
        if value is None:
            return np.zeros((m, 3))
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            arr = None
        if arr is None or isinstance(value, str) or not (arr.shape == (3,) or arr.shape == (m, 3)):
            raise ParameterError(f"{name} = {_short(value)} is not allowed: must be three numbers, or three "
                                 f"for each of the {m} spheres")
        arr = np.broadcast_to(arr, (m, 3)).copy()
        if not np.isfinite(arr).all():
            raise ParameterError(f"{name} = {_short(value)} is not allowed: components must be finite")
        return arr

    def _check_no_overlap(self, x, r, tolerance=1e-12, walls=True):
        from scipy.spatial import cKDTree

        first = self._state.n
        allx = np.concatenate([self._state.x, x])
        allr = np.concatenate([self._state.radius, r])
        imgx, imgr, source = self._with_images(allx, allr, 2.0 * float(allr.max()))
        tree = cKDTree(imgx)
        # each new sphere against every sphere (or periodic image) before it within its radius plus
        # the largest radius
        for k, near in enumerate(tree.query_ball_point(x, r + allr.max())):
            near = np.asarray(near, dtype=np.int64)
            i = first + k
            near = near[source[near] < i]
            if near.size == 0:
                continue
            gap = np.linalg.norm(imgx[near] - allx[i], axis=1) - imgr[near] - allr[i]
            bad = gap < -tolerance * (imgr[near] + allr[i])
            if bad.any():
                j = int(source[near[np.argmax(bad)]])
                j = int(self._state.ids[j]) if j < first else j  # as the user numbers them
                g = float(gap[np.argmax(bad)])
                raise ParameterError(f"particles {min(i, j)} and {max(i, j)} overlap by {-g:.3g} m at insertion: "
                                     f"positions must not overlap ({self.hints['allow_overlap']} to accept it)")
        for wl in self._walls if walls else ():
            if wl.kind == INACTIVE:
                continue
            ov = wl.overlap(x, r)
            k = int(np.argmax(ov)) if len(ov) else 0
            if len(ov) and ov[k] > tolerance * r[k]:
                raise ParameterError(f"particle {first + k} overlaps wall {self._wall_label(wl)} by {ov[k]:.3g} m "
                                     f"at insertion ({self.hints['allow_overlap']} to accept it)")

    def insert(self, region, count: int, radius, material, seed: int = 0, velocity=None,
               max_attempts: int = 200) -> np.ndarray:
        """Fill ``region`` (``BoxRegion`` / ``CylinderRegion``) with ``count`` non-overlapping spheres.

        ``radius`` is a number or a distribution (``rd.Uniform``, ``rd.Normal``, ``rd.Discrete``).
        Reproducible from ``seed``; raises when the region cannot hold them. The new spheres are
        numbered in Morton order of their positions (``rollingdem.engine.neighbors.spatial_order``).
        """
        from rollingdem.scene.insertion import fill_region
        from rollingdem.engine.neighbors import spatial_order

        for mat in (material if isinstance(material, (list, tuple, np.ndarray)) else [material]):
            self.materials.index(mat)  # an unknown material is refused before a long fill
        if velocity is not None:
            self._vectors("velocity", velocity, 1)
        x, r = fill_region(region, count, radius, seed=seed, existing_positions=self._state.x,
                           existing_radii=self._state.radius, walls=[w for w in self._walls if w.kind != INACTIVE],
                           max_attempts=max_attempts)
        order = spatial_order(x, 2.0 * float(r.max()))  # neighbors in space get nearby indices
        return self.add_particles(x[order], r[order], material, velocity=velocity)

    # --- periodic boundaries ------------------------------------------------------------------
    @staticmethod
    def _check_periodic(periodic) -> dict:
        """``{"x": (lo, hi), ...}`` checked: axes among x, y, z, each lo < hi finite."""
        if periodic is None:
            return {}
        if not isinstance(periodic, dict):
            raise ParameterError(f"periodic = {_short(periodic)} is not allowed: must be a mapping of axes to "
                                 "(min, max), e.g. {'x': (-0.05, 0.05)}")
        out = {}
        for axis, ends in periodic.items():
            if axis not in ("x", "y", "z"):
                raise ParameterError(f"periodic axis = {axis!r} is not allowed: must be 'x', 'y' or 'z'")
            try:
                lo, hi = (float(v) for v in ends)
            except (TypeError, ValueError):
                raise ParameterError(f"periodic {axis} = {_short(ends)} is not allowed: must be (min, max) in m") from None
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ParameterError(f"periodic {axis} = ({lo:g}, {hi:g}) is not allowed: must be finite with "
                                     "min < max (m)")
            out[axis] = (lo, hi)
        return {axis: out[axis] for axis in "xyz" if axis in out}

    def _check_periodic_length(self) -> None:
        """Each periodic length holds at least two neighbor-list cutoffs, 2 (2 R_max + skin): a pair
        within the cutoff then has one image within it, the one the minimum image finds."""
        if not self.periodic or not self.n_particles:
            return
        rmax = max([float(self._state.radius.max())] + [i.radius.max_radius for i in self._inflows])
        need = 2.0 * (2.0 * rmax + self.skin)
        for axis, (lo, hi) in self.periodic.items():
            if hi - lo < need:
                raise ParameterError(f"periodic {axis} length = {hi - lo:g} m is not allowed: must be at least "
                                     f"2 (2 R_max + skin) = {need:g} m (R_max = {rmax:g} m, skin = {self.skin:g} m), "
                                     "or a particle could touch two images of another")

    def _check_in_box(self, x: np.ndarray) -> None:
        for axis, (lo, hi) in self.periodic.items():
            a = "xyz".index(axis)
            bad = (x[:, a] < lo) | (x[:, a] >= hi)
            if bad.any():
                k = int(np.argmax(bad))
                raise ParameterError(f"position of particle {self.n_particles + k} = {x[k].tolist()} is not allowed: "
                                     f"{axis} must be in the periodic box [{lo:g}, {hi:g}) m")

    def _with_images(self, x: np.ndarray, r: np.ndarray, reach: float):
        """``x``, ``r`` and the periodic images of those within ``reach`` of a periodic end;
        returns (positions, radii, index of each one's original)."""
        source = np.arange(len(x))
        for axis, (lo, hi) in self.periodic.items():
            a, length = "xyz".index(axis), hi - lo
            low, high = x[:, a] < lo + reach, x[:, a] > hi - reach
            up, down = x[low].copy(), x[high].copy()
            up[:, a] += length
            down[:, a] -= length
            x = np.concatenate([x, up, down])
            r = np.concatenate([r, r[low], r[high]])
            source = np.concatenate([source, source[low], source[high]])
        return x, r, source

    @property
    def unwrapped_positions(self) -> np.ndarray:
        """Positions with the periodic lengths each particle crossed added back (``positions`` where
        no axis is periodic)."""
        st = self._state
        box = st.contact_list.box
        return st.by_id(st.x + st.image * box[3:6]) if len(box) else st.by_id(st.x).copy()

    # --- outlets and inflows ------------------------------------------------------------------
    def add_outlet(self, region, name: str | None = None, interval: float | None = None):
        """Take out every free particle whose centre enters ``region`` (``BoxRegion``,
        ``CylinderRegion``), every ``interval`` s (default 1e-3); the time series counts them and
        their mass, cumulative, per outlet (``outlet_{name}_count``, ``outlet_{name}_mass``). The
        other particles keep their contacts and history; their indices close up (``particle_ids``
        keeps each particle's number for good). Returns the ``Outlet``."""
        from rollingdem.scene.boundaries import Outlet

        outlet = Outlet(region, name, interval)
        self._check_boundary_name(outlet)
        free = ~self._state.is_fixed
        if free.sum() > 1 and outlet.inside(self._state.x[free]).all():
            raise ParameterError(f"outlet region {region!r} is not allowed: it contains every free particle (all "
                                 f"{int(free.sum())}), so it would empty the scene at once; must cover only the way out")
        for inflow in self._inflows:
            self._check_outlet_inflow(outlet, inflow)
        self._outlets.append(outlet)
        return outlet

    def add_inflow(self, region, radius, material, rate: float | None = None, mass_rate: float | None = None,
                   velocity=None, seed: int = 0, name: str | None = None, interval: float | None = None,
                   start: float | None = None):
        """Insert particles into ``region`` during the runs, at ``rate`` particles/s or ``mass_rate``
        kg/s from ``start`` (default now), every ``interval`` s (default 1e-3): at random places
        where they overlap neither a particle nor a wall, reproducibly from ``seed``, with
        ``velocity``. ``radius`` is a number or a distribution (``rd.Uniform`` ...). What finds no room
        waits for the next interval; a warning says so once, and the time series' ``inflow_{name}
        _shortfall`` counts it. Returns the ``Inflow``."""
        from rollingdem.scene.boundaries import Inflow

        self.materials.index(material)
        inflow = Inflow(region, radius, material, rate=rate, mass_rate=mass_rate, velocity=velocity, seed=seed,
                        name=name, interval=interval, start=self.time if start is None else start)
        self._check_boundary_name(inflow)
        lo, hi = inflow.region.bounds()
        for axis, (a_lo, a_hi) in self.periodic.items():
            a = "xyz".index(axis)
            if lo[a] < a_lo or hi[a] > a_hi:
                raise ParameterError(f"inflow region {inflow.region!r} is not allowed: along the periodic {axis} it "
                                     f"reaches [{lo[a]:g}, {hi[a]:g}], outside the box [{a_lo:g}, {a_hi:g}) m; must "
                                     "lie inside it")
        for outlet in self._outlets:
            self._check_outlet_inflow(outlet, inflow)
        self._inflows.append(inflow)
        return inflow

    def _check_boundary_name(self, new):
        if new.name is not None and any(b.name == new.name for b in self._outlets + self._inflows if b.kind == new.kind):
            raise ParameterError(f"{new.kind} name = {new.name!r} is not allowed: another {new.kind} has it; names "
                                 "must differ")

    @staticmethod
    def _check_outlet_inflow(outlet, inflow):
        lo, hi = inflow.region.bounds()
        corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
        if outlet.inside(corners).all():
            raise ParameterError(f"outlet region {outlet.region!r} is not allowed with inflow region {inflow.region!r}: "
                                 "it contains the whole inflow region, so every inserted particle would be taken "
                                 "out at once")

    @property
    def outlets(self) -> list:
        return list(self._outlets)

    @property
    def inflows(self) -> list:
        return list(self._inflows)

    def boundary_counts(self) -> dict:
        """The cumulative counts of each outlet and inflow, by time-series column."""
        out = {}
        for group in (self._outlets, self._inflows):
            for k, b in enumerate(group):
                out.update(zip(b.columns(b.name or f"#{k}"), b.values()))
        return out

    def _next_boundary_step(self) -> int | None:
        steps = [b.next_step(self.step, self.dt) for b in self._outlets + self._inflows]
        return min(steps) if steps else None

    def _apply_boundaries(self) -> None:
        """The outlets and inflows due at this step: removal first, then insertion."""
        st = self._state
        for outlet in self._outlets:
            if not outlet.due(self.step, self.dt) or st.n == 0:
                continue
            gone = outlet.inside(st.x) & ~st.is_fixed
            if gone.any():
                outlet.count += int(gone.sum())
                outlet.mass += float(st.mass[gone].sum())
                st.remove(gone)
        for inflow in self._inflows:
            if not inflow.due(self.step, self.dt) or self.time < inflow.start:
                continue
            density = self.materials[inflow.material].density
            radii = inflow.radii_due(self.time, density)
            walls = [w for w in self._walls if w.kind != INACTIVE]
            self.sync_walls_from_engine()
            reach = 2.0 * float(max(st.radius.max(initial=0.0), inflow.radius.max_radius))
            near_x, near_r, _ = self._with_images(st.x, st.radius, reach)
            x = inflow.place(radii, near_x, near_r, walls)
            placed = np.isfinite(x[:, 0])
            if placed.any():
                r = radii[placed]
                self.add_particles(x[placed], r, inflow.material, velocity=inflow.velocity, allow_overlap=True)
                inflow.count += int(placed.sum())
                inflow.mass += float((density * (4.0 / 3.0) * math.pi * r ** 3).sum())
            inflow.actions += 1
            inflow.note_shortfall(int((~placed).sum()), self.time)

    # --- walls ---------------------------------------------------------------------------------
    @property
    def walls(self) -> list[Wall]:
        return [w for w in self._walls if w.kind != INACTIVE]

    def add_wall(self, wall: Wall) -> Wall:
        if not isinstance(wall, Wall) or isinstance(wall, _Removed):
            raise ParameterError(f"wall = {wall!r} is not allowed: must be a rollingdem.Plane, Cylinder or MeshWall")
        if any(w is wall for w in self._walls):
            raise ParameterError(f"wall = {self._wall_label(wall)} is not allowed: it is part of this simulation "
                                 "already")
        if wall.material is None:
            if not len(self.materials):
                raise ParameterError("wall material = None is not allowed: add a material first or name one")
            wall.material = self.materials.materials[0].name
        self.materials.index(wall.material)
        if wall.kind == WALL_MESH:
            self._check_mesh_size(wall, self._state.radius)
        self._walls.append(wall)
        self._sync_walls()
        return wall

    @staticmethod
    def _check_mesh_size(wall, radius):
        """Refuse a mesh smaller than one particle: a file in mm read as m, or the reverse."""
        if not len(radius):
            return
        extent = float(np.ptp(wall.mesh.vertices, axis=0).max())
        diameter = 2.0 * float(radius.min())
        if extent < diameter:
            raise ParameterError(f"{wall.mesh.label}: the mesh is {extent:.3g} m across, smaller than one particle "
                                 f"(diameter {diameter:.3g} m): a unit mistake? give its scale (0.001 for a file "
                                 "in mm)")

    def remove_wall(self, wall: Wall | str) -> None:
        """Remove a wall (the object or its name); its contact history is dropped."""
        wall = self._own_wall(wall)
        slot = next(k for k, w in enumerate(self._walls) if w is wall)
        self._walls[slot] = _Removed(wall)
        self._sync_walls()

    def _own_wall(self, wall: Wall | str) -> Wall:
        """A wall in place in this simulation, given as the object or by name; else a ParameterError
        that names it and says why (removed already, never added, no such name)."""
        removed = [w.wall for w in self._walls if isinstance(w, _Removed) and w.wall is not None]
        if isinstance(wall, str):
            named = [w for w in self.walls if w.name == wall]
            if named:
                return named[0]
            if any(w.name == wall for w in removed):
                raise ParameterError(f"wall = {wall!r} is not allowed: it was removed already")
            names = ", ".join(repr(w.name) for w in self.walls if w.name) or "none"
            raise ParameterError(f"wall = {wall!r} is not allowed: no wall has that name; wall names are {names}")
        if not isinstance(wall, Wall) or isinstance(wall, _Removed):
            raise ParameterError(f"wall = {_short(wall)} is not allowed: must be a wall of this simulation (the "
                                 "rollingdem.Plane or Cylinder, or its name)")
        if any(w is wall for w in self._walls):
            return wall
        raise ParameterError(f"wall = {self._wall_label(wall)} is not allowed: "
                             + ("it was removed already" if any(w is wall for w in removed) else
                                "it is not part of this simulation (add it with add_wall)"))

    def set_wall_velocity(self, wall: Wall | str, velocity=None, angular_velocity=None, point=None) -> None:
        """Give a wall (the object or its name) a new prescribed velocity (m/s) and/or angular
        velocity (rad/s), from now on: a mesh turns about the axis through ``point`` (default: the
        point it turned about), a plane or cylinder turns its surface about its own axis."""
        wall = self._own_wall(wall)
        self.sync_walls_from_engine()
        if velocity is not None:
            wall.velocity = check_vector("wall velocity", velocity)
        if angular_velocity is not None:
            wall.set_angular_velocity(angular_velocity)
        if point is not None:
            if wall.kind != WALL_MESH:
                raise ParameterError(f"point = {point!r} is not allowed for wall {self._wall_label(wall)}: a plane or "
                                     "cylinder turns about its own point; only a mesh wall takes a rotation point")
            wall.point = check_vector("mesh point", point)
        self._sync_walls()

    def _wall_label(self, wall):
        if wall.name:
            return repr(wall.name)
        slot = next((k for k, w in enumerate(self._walls) if w is wall or getattr(w, "wall", None) is wall), None)
        kind = type(wall).__name__.lower()
        return f"#{slot} ({kind})" if slot is not None else f"({kind}, unnamed)"

    def _sync_walls(self):
        """Give the engine the walls in place. A removed wall keeps its place in ``_walls`` (labels
        and checkpoints number walls as the user added them) but not in the engine, whose
        per-sphere wall history would otherwise keep a row per sphere for it (72 B per sphere
        with EPSD) and whose gather would test it for every sphere at every step."""
        self.sync_walls_from_engine()  # a mesh's motion starts again from where it is now
        active = [wl for wl in self.walls if wl.kind != WALL_MESH]
        carry = [next((k for k, old in enumerate(self._engine_walls) if old is wl), -1) for wl in active]
        self._state.set_walls(carry, wall_kind=[wl.kind for wl in active], wall_geom=[wl.geometry() for wl in active],
                              wall_vel=[wl.velocity for wl in active], wall_omega=[wl.angular_velocity for wl in active],
                              wall_mat=[self.materials.index(wl.material) for wl in active])
        self._engine_walls = active
        meshes = [wl for wl in self.walls if wl.kind == WALL_MESH]
        carry = [next((k for k, old in enumerate(self._state.meshes.names) if old is wl), -1) for wl in meshes]
        self._state.set_meshes([wl.engine_mesh(self.materials.index(wl.material)) for wl in meshes], carry, meshes)
        self._pair_params = None

    # --- state access --------------------------------------------------------------------------
    # Per-particle arrays in the order the particles were added (index k is particle k for good);
    # the engine stores them re-sorted in space, so these are copies once it has sorted: write
    # through set_velocities, not into them.
    @property
    def positions(self) -> np.ndarray:
        return self._state.by_id(self._state.x)

    @property
    def velocities(self) -> np.ndarray:
        return self._state.by_id(self._state.v)

    @property
    def angular_velocities(self) -> np.ndarray:
        return self._state.by_id(self._state.w)

    @property
    def forces(self) -> np.ndarray:
        return self._state.by_id(self._state.f)

    @property
    def torques(self) -> np.ndarray:
        return self._state.by_id(self._state.t)

    @property
    def radii(self) -> np.ndarray:
        return self._state.by_id(self._state.radius)

    @property
    def masses(self) -> np.ndarray:
        return self._state.by_id(self._state.mass)

    @property
    def material_indices(self) -> np.ndarray:
        return self._state.by_id(self._state.mat)

    @property
    def particle_ids(self) -> np.ndarray:
        """Each particle's number for good, in the order of ``positions``: the index it had when it
        was added (equal to its index until an outlet takes particles out)."""
        return self._state.by_id(self._state.tags)

    @property
    def fixed(self) -> np.ndarray:
        """Whether each particle is fixed (``add_particles(..., fixed=True)``), bool."""
        return self._state.by_id(self._state.is_fixed)

    def particle_field(self, name: str) -> np.ndarray:
        """A per-particle field of the state's schema (``rollingdem.engine.schema``: ``radius``,
        ``contacts``, or one declared with ``SCHEMA.declare``), in the order of ``positions``."""
        return self._state.by_id(getattr(self._state, self._particle_field(name).name))

    def set_particle_field(self, name: str, indices, values) -> None:
        """Set a per-particle field of some particles (``values`` one for all, or one each)."""
        field = self._particle_field(name)
        if not field.settable:
            raise ParameterError(f"field = {name!r} is not allowed: the engine keeps it; settable are "
                                 + ", ".join(f.name for f in SCHEMA.of(PER_PARTICLE) if f.settable))
        idx = self._state.slots(self._indices(indices))
        array = getattr(self._state, field.name)
        if field.lazy and len(array) != self.n_particles:  # no rows yet: every particle at the fill
            array = field.rows(self.n_particles, self._state.history_size)
            setattr(self._state, field.name, array)
        try:
            array[idx] = np.asarray(values, dtype=field.dtype)
        except (TypeError, ValueError):
            raise ParameterError(f"values = {_short(values)} is not allowed for {name}: one value, or one for each "
                                 f"of the {len(idx)} particles") from None
        self._state.info[I_FORCES_VALID] = 0

    def _particle_field(self, name):
        fields = {f.name: f for f in SCHEMA.of(PER_PARTICLE)}
        if name not in fields:
            raise ParameterError(f"field = {name!r} is not allowed: the per-particle fields are {', '.join(fields)}")
        return fields[name]

    # --- bonds -------------------------------------------------------------------------------------
    def add_bonds(self, bond, pairs=None, gap=None) -> int:
        """Bond pairs of particles with ``bond`` (a ``rollingdem.ParallelBond``, docs/models.md §1.7):
        the ``pairs`` of particle indices given, or every pair whose surface gap is at most ``gap``
        (m; negative: overlapping by at least -gap), as PFC's bond gap. The bonds start unloaded at
        the pairs' present distance; the pair's contact acts beside its bond (PFC). Pairs across a
        periodic boundary are not found by ``gap``: give them as ``pairs``. Returns how many bonds
        were made."""
        from rollingdem.scene.bonds import ParallelBond

        if not isinstance(bond, ParallelBond):
            raise ParameterError(f"bond = {bond!r} is not allowed: must be a rollingdem.ParallelBond")
        if (pairs is None) == (gap is None):
            raise ParameterError(f"pairs = {pairs!r}, gap = {gap!r} is not allowed: give exactly one of pairs "
                                 "(particle index pairs) and gap (m)")
        st = self._state
        if pairs is None:
            from scipy.spatial import cKDTree

            gap = check_finite("gap", gap)
            x, r = self.positions, self.radii
            reach = 2.0 * float(r.max(initial=0.0)) + gap
            found = np.array(sorted(cKDTree(x).query_pairs(reach)) if len(x) > 1 and reach > 0 else [],
                             dtype=np.int64).reshape(-1, 2)
            if len(found):
                surface = np.linalg.norm(x[found[:, 0]] - x[found[:, 1]], axis=1) - r[found[:, 0]] - r[found[:, 1]]
                found = found[surface <= gap]
            ids = found
        else:
            try:
                ids = np.asarray(pairs)
                ok = ids.ndim == 2 and ids.shape[1] == 2 and (ids.size == 0 or np.issubdtype(ids.dtype, np.integer))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ParameterError(f"pairs = {pairs!r} is not allowed: must be a list of [i, j] particle index pairs")
            ids = ids.astype(np.int64)
            bad = (ids < 0) | (ids >= self.n_particles)
            if bad.any():
                raise ParameterError(f"pairs: particle {int(ids[bad][0])} is not allowed: the indices run from 0 to "
                                     f"{self.n_particles - 1}")
            same = ids[:, 0] == ids[:, 1]
            if same.any():
                raise ParameterError(f"pairs: [{ids[same][0, 0]}, {ids[same][0, 1]}] is not allowed: a bond between "
                                     "a particle and itself")
        slots = st.slots(ids.ravel()).reshape(-1, 2)
        key = np.sort(np.concatenate([st.bond_pairs, slots]), axis=1)
        if len(np.unique(key, axis=0)) < len(key):
            raise ParameterError("pairs: a pair is bonded twice (in the pairs given, or already): each pair takes one "
                                 "bond")
        fixed = st.is_fixed  # a fixed sphere is a partner of infinite mass and inertia
        mass = np.where(fixed, np.inf, st.mass)
        inertia = np.where(fixed, np.inf, st.inertia)
        rows = [bond.parameter_row(st.radius[i], st.radius[j], (mass[i], mass[j]), (inertia[i], inertia[j]))
                for i, j in slots]
        st.add_bonds(slots, np.array(rows).reshape(-1, len(BOND_PARAMETERS)))
        return len(slots)

    def bonds(self):
        """The bonds as a table (pandas): particles i and j, ``status`` (intact, tension, shear: the
        mode it broke in), the normal force F_n (N, tension positive), |F_s| (N), M_t and |M_b| (N m)."""
        import pandas as pd

        st = self._state
        ids = st.ids  # slot -> id
        s = st.bond_state
        names = np.array(["intact", "tension", "shear"])
        return pd.DataFrame({
            "i": ids[st.bond_pairs[:, 0]], "j": ids[st.bond_pairs[:, 1]], "status": names[st.bond_status],
            "normal_force": s[:, BOND_STATE.normal_force],
            "shear_force": np.linalg.norm(s[:, [BOND_STATE.shear_x, BOND_STATE.shear_y, BOND_STATE.shear_z]], axis=1),
            "twisting_moment": s[:, BOND_STATE.twisting_moment],
            "bending_moment": np.linalg.norm(s[:, [BOND_STATE.bending_x, BOND_STATE.bending_y, BOND_STATE.bending_z]],
                                             axis=1)})

    def bond_counts(self) -> dict[str, int]:
        """``bonds_intact``, ``bonds_broken_tension``, ``bonds_broken_shear``; empty without bonds."""
        st = self._state
        if not len(st.bond_pairs):
            return {}
        counts = np.bincount(st.bond_status, minlength=3)
        return {"bonds_intact": int(counts[0]), "bonds_broken_tension": int(counts[1]),
                "bonds_broken_shear": int(counts[2])}

    def bond_energy(self) -> float:
        """The strain energy (J) of the intact bonds (docs/models.md §1.7)."""
        from rollingdem.physics.bonds import bond_energy

        st = self._state
        return float(sum(bond_energy(st.bond_state, b, st.bond_parameters[b]) for b in range(len(st.bond_pairs))
                         if st.bond_status[b] == 0))

    def set_velocities(self, indices, velocity=None, angular_velocity=None) -> None:
        """Set translational (m/s) and/or angular (rad/s) velocities of some particles."""
        ids = self._indices(indices)
        idx = self._state.slots(ids)
        held = self._state.is_fixed[idx]
        if held.any() and any(np.any(vec) for vec in (velocity, angular_velocity) if vec is not None):
            raise ParameterError(f"indices = {_short(indices)} is not allowed with a nonzero velocity: particle "
                                 f"{int(ids[np.argmax(held)])} is fixed and never moves; leave the fixed particles "
                                 "out (sim.fixed says which they are)")
        if velocity is not None:
            self._state.v[idx] = self._vectors("velocity", velocity, len(idx))
        if angular_velocity is not None:
            self._state.w[idx] = self._vectors("angular_velocity", angular_velocity, len(idx))
        self._state.info[I_FORCES_VALID] = 0

    def _indices(self, indices, name="indices") -> np.ndarray:
        """Particle indices as int64, each in [0, n_particles)."""
        arr = np.atleast_1d(np.asarray(indices, dtype=object if isinstance(indices, str) else None))
        if arr.size and (arr.dtype.kind not in "iu" or arr.ndim != 1):
            raise ParameterError(f"{name} = {_short(indices)} is not allowed: must be particle indices (whole "
                                 f"numbers in [0, {self.n_particles - 1}])")
        arr = arr.astype(np.int64)
        bad = (arr < 0) | (arr >= self.n_particles)
        if bad.any():
            k = int(arr[np.argmax(bad)])
            allowed = f"must be in [0, {self.n_particles - 1}]" if self.n_particles else "there are no particles"
            raise ParameterError(f"{name} = {_short(indices)} is not allowed: particle {k} does not exist; {allowed}")
        return arr

    def kinetic_energy(self) -> tuple[float, float]:
        """(translational, rotational) kinetic energy (J)."""
        st = self._state
        trans = 0.5 * float(np.dot(st.mass, np.einsum("ij,ij->i", st.v, st.v)))
        rot = 0.5 * float(np.dot(st.inertia, np.einsum("ij,ij->i", st.w, st.w)))
        return trans, rot

    def engine_module(self):
        """The compiled engine module this simulation steps with (``rollingdem.engine.codegen``)."""
        st = self._state
        bonded_pairs = bool(len(st.bond_pairs))
        serial = st.backend.serial_step_loop(st)  # the CPU step loop to compile ahead, if the backend runs one
        key = (id(self.contact), self.track_energy, serial, bonded_pairs)
        held = self._modules.get(key)
        if held is None or held[0] is not self.contact:
            held = self._modules[key] = (self.contact, engine_module(self.contact, self.track_energy, serial=serial,
                                                                     bonded_pairs=bonded_pairs))
        return held[1]

    def phase_seconds(self, repeats: int = 20, rebuilds_per_step: float = 0.0) -> dict[str, float]:
        """Seconds per step of each phase of a step on the present state and backend (contact
        forces, walls, integration and gathering, neighbor search; a backend may add its own), each
        timed on its own, the fastest of 5 blocks of ``repeats`` calls; the neighbor search counts
        ``rebuilds_per_step`` times. The state is left as it was."""
        st = self._state
        return st.backend.phase_seconds(st, self.engine_module(), (self.dt, self.gravity, self.skin,
                                                                   self.pair_parameters()), repeats, rebuilds_per_step)

    def passes(self):
        """Each pass of the step as a call of its own on the present state (``engine.phases.Passes``,
        on the CPU), to time them one against another."""
        from rollingdem.engine.phases import Passes

        return Passes(self._state, self.engine_module(), self.dt, self.gravity, self.skin, self.pair_parameters())

    @property
    def device_memory_bytes(self) -> int:
        """The bytes the backend held on its device at the last run (0 on the CPU)."""
        return self._state.backend.device_bytes(self._state)

    def dissipated_energy(self) -> dict[str, float]:
        """Energy (J) dissipated while ``track_energy`` was on, by normal damping, sliding, rolling
        and twisting."""
        if not self.track_energy and not self._state.energy.any():
            raise ParameterError("dissipated_energy: track_energy = False, so no dissipated energy was summed; "
                                 "create the Simulation with track_energy=True (or set sim.track_energy = True "
                                 "before the run)")
        totals = self._state.energy.sum(axis=0)
        return {name: float(totals[k]) for k, name in enumerate(ENERGY_CHANNELS)}

    def number_of_contacts(self) -> int:
        return int(self._state.contacts.sum())

    # --- time step -----------------------------------------------------------------------------
    def time_step_limits(self) -> list[tuple[str, float]]:
        """Each criterion of docs/models.md §2 that applies: (description, largest allowed dt)."""
        st = self._state
        if st.n == 0 and not self._inflows:
            return []
        limits = []
        normal = self.contact.normal
        for k, mat in enumerate(self.materials.materials):
            sel = st.mat == k
            # the spheres an inflow will insert count as if they were there
            coming = [(i.radius.min_radius, float(np.linalg.norm(i.velocity))) for i in self._inflows
                      if self.materials.index(i.material) == k]
            if not sel.any() and not coming:
                continue
            rmin = min(([float(st.radius[sel].min())] if sel.any() else []) + [r for r, _ in coming])
            mmin = min(([float(st.mass[sel].min())] if sel.any() else [])
                       + [mat.density * (4.0 / 3.0) * math.pi * r ** 3 for r, _ in coming])
            pair = self.materials.pair(k, k)
            speed = np.sqrt((st.v[sel] ** 2).sum(axis=1))
            fastest = max([float(speed[np.isfinite(speed)].max(initial=0.0))] + [v for _, v in coming])
            impact = 2.0 * fastest  # a non-finite v is reported apart
            limits += normal.time_step_limits(mat, pair, rmin, mmin, impact)
            limits += self.contact.cohesion.time_step_limits(mat, pair, rmin, mmin)
            r_eff = 0.5 * rmin
            kn, kt, overlap = normal.reference_stiffness(pair, r_eff, 0.5 * mmin, rmin)
            inertia = SOLID_SPHERE * mmin * rmin ** 2
            for sub in (self.contact.rolling, self.contact.twisting):
                k_rot = sub.rotational_stiffness(kn, kt, r_eff, overlap, kn * overlap, pair)
                if k_rot > 0:
                    # worst case, centres held: omega^2 = k_rot (1/I_i + 1/I_j)
                    per = 2.0 * math.pi / math.sqrt(k_rot * 2.0 / inertia)
                    limits.append((f"{sub.slot} spring ({sub.name}) period {per:.4g} s / 10", SPRING_FRACTION * per))
        limits += self._bond_limits()
        return limits

    def _bond_limits(self) -> list[tuple[str, float]]:
        """The intact bonds' stiffest mode (docs/models.md §1.7): with K_n, K_s, K_b, K_t its springs,
        omega^2 = K_n (1/m_i + 1/m_j) (axial), K_s (1/m_i + 1/m_j + R_i^2/I_i + R_j^2/I_j) (shear with
        rotation), K_b (1/I_i + 1/I_j) (bending), K_t (1/I_i + 1/I_j) (twisting); a tenth of its period."""
        st = self._state
        live = st.bond_status == 0
        if not live.any():
            return []
        i, j = st.bond_pairs[live, 0], st.bond_pairs[live, 1]
        p = st.bond_parameters[live]
        free = (~st.is_fixed).astype(float)  # a fixed sphere: infinite mass and inertia
        inv_m = free[i] / st.mass[i] + free[j] / st.mass[j]
        inv_i = free[i] / st.inertia[i] + free[j] / st.inertia[j]
        lever = free[i] * st.radius[i] ** 2 / st.inertia[i] + free[j] * st.radius[j] ** 2 / st.inertia[j]
        omega2 = np.max([p[:, BOND_PARAMETERS.normal_stiffness] * inv_m,
                         p[:, BOND_PARAMETERS.shear_stiffness] * (inv_m + lever),
                         p[:, BOND_PARAMETERS.bending_stiffness] * inv_i,
                         p[:, BOND_PARAMETERS.twisting_stiffness] * inv_i])
        per = 2.0 * math.pi / math.sqrt(omega2)
        return [(f"bond period {per:.4g} s / 10", SPRING_FRACTION * per)]

    def stable_time_step(self) -> float:
        """The largest dt all criteria allow (s)."""
        limits = self.time_step_limits()
        if not limits:
            raise ParameterError("dt cannot be chosen automatically before particles are added: give dt")
        return min(v for _, v in limits)

    def check_time_step(self) -> None:
        """Refuse a dt above a stable limit (unless ``check_timestep`` is off), as ``run`` does."""
        self._check_dt()

    def _check_dt(self):
        if not self.check_timestep:
            return
        # Between runs of an unchanged scene only the speeds change, and the one limit that depends
        # on them (the Hertz time at the impact speed) falls as they rise: while no material's
        # fastest sphere is faster than when dt last passed, it still passes. A loop of short runs
        # (a trajectory sampled every 10 steps) then skips the full check, 1/3 of its time.
        speeds = self._fastest_per_material()
        key = (self.dt, self.n_particles, len(self._inflows), id(self.contact), self.pair_parameters())
        seen = self._dt_passed
        if seen is not None and seen[0][:4] == key[:4] and seen[0][4] is key[4] and (speeds <= seen[1]).all():
            return
        for label, limit in self.time_step_limits():
            if self.dt > limit * (1 + 1e-12):
                raise ParameterError(f"dt = {self.dt:.4g} s exceeds the stable limit {limit:.4g} s "
                                     f"({label}): choose dt <= {limit:.4g} s, or {self.hints['check_timestep']} "
                                     "to run anyway")
        self._dt_passed = (key, speeds)

    def _check_contact_reach(self):
        """A cohesion law whose contacts last past touching (``jkr``) needs the neighbor list to
        reach that far: refuse a skin shorter than the largest pair's separation limit."""
        cohesion = self.contact.cohesion
        st = self._state
        if cohesion.detach_slot is None or st.n == 0:
            return
        r_eff = 0.5 * float(st.radius.max())
        n = len(self.materials.materials)
        reach = max(cohesion.separation_limit(self.materials.pair(a, b), r_eff) for a in range(n) for b in range(n))
        if reach > self.skin:
            raise ParameterError(f"skin = {self.skin:.4g} m is not allowed with cohesion {cohesion.name!r}: its "
                                 f"contacts last until the spheres are {reach:.4g} m apart, and the neighbor list "
                                 f"must reach that far; give skin >= {reach:.4g} m")

    def _fastest_per_material(self) -> np.ndarray:
        """Each material's largest finite particle speed squared (0 without particles of it)."""
        st = self._state
        out = np.zeros(len(self.materials.materials))
        if st.n and len(out):
            speed2 = np.einsum("ij,ij->i", st.v, st.v)
            fastest = speed2.max()
            if len(out) == 1 and math.isfinite(fastest):
                out[0] = fastest
            else:
                np.maximum.at(out, st.mat, np.where(np.isfinite(speed2), speed2, 0.0))
        return out

    # --- running -------------------------------------------------------------------------------
    def pair_parameters(self) -> np.ndarray:
        if self._pair_params is None:
            self._pair_params = self.contact.pair_table(self.materials)
        return self._pair_params

    def run(self, duration: float | None = None, steps: int | None = None, observers=(),
            progress: bool = False, label: str = "run") -> None:
        """Advance the scene by ``duration`` seconds (rounded to whole steps) or by ``steps`` steps.

        Observers are called at their intervals; the progress bar shows simulated time, steps/s
        and time left. A run that goes unstable stops with ``SimulationError`` after the
        observers have written what they had.
        """
        if (duration is None) == (steps is None):
            raise ParameterError(f"duration = {duration!r}, steps = {steps!r} is not allowed: give exactly one of "
                                 "duration (s) and steps")
        if steps is None:
            duration = check_finite("duration", duration)
            if duration < 0:
                raise ParameterError(f"duration = {duration:g} is not allowed: must be >= 0 (s)")
            steps = int(round(duration / self.dt))
        else:
            steps = check_integer("steps", steps, low=0)
        observers = self._observers(observers)
        if not isinstance(label, str):
            raise ParameterError(f"label = {label!r} is not allowed: must be a string")
        self._check_finite_state()  # first: a non-finite state would make the dt check's message a riddle
        for wall in self.walls:
            if wall.kind == WALL_MESH:
                self._check_mesh_size(wall, self._state.radius)
        self._check_dt()
        self._check_contact_reach()
        self._check_periodic_length()
        for ob in observers:
            ob.check(self)  # all refusals before any observer writes
        bar = None
        end = self.step + steps
        for ob in observers:
            ob.start(self)
        failure = None
        try:
            kernel = self.engine_module()  # after the observers start: a TimeSeries turns on track_energy
            if progress:
                bar = _Progress(self, steps, label, warm=id(kernel) in self._stepped)
            for ob in observers:
                ob.maybe_observe(self, force=True)
            chunk = 64
            while self.step < end:
                boundary = self._next_boundary_step()
                nxt = min([end, self.step + chunk] + [ob.next_step(self) for ob in observers]
                          + ([boundary] if boundary is not None else []))
                todo = max(nxt - self.step, 1)
                tic = _time.perf_counter()
                done, problem = self._state.advance(kernel, todo, self.dt, self._gravity, self.skin,
                                                    self.pair_parameters())
                elapsed = _time.perf_counter() - tic
                self._stepped.add(id(kernel))
                self.step += done
                self.time = self._time_origin[0] + (self.step - self._time_origin[1]) * self.dt
                self._check_finite_state()
                if problem:
                    raise SimulationError(f"at t = {self.time:.6g} s (step {self.step}): {problem}")
                # aim at ~0.25 s of work per call so the progress bar and Ctrl-C stay responsive
                if elapsed > 0:
                    chunk = int(min(max(todo * 0.25 / elapsed, 1), 1_000_000))
                self._apply_boundaries()
                for ob in observers:
                    ob.maybe_observe(self)
                if bar:
                    bar.update(self, todo, elapsed)
        except SimulationError as err:
            failure = err
            raise
        finally:
            self.sync_walls_from_engine()
            for ob in observers:
                ob.finish(self, failure)
            if bar:
                bar.close()

    @staticmethod
    def _observers(observers) -> list:
        """The observers of a run: one observer or a sequence of them."""
        from rollingdem.scene.schedule import Observer

        if isinstance(observers, Observer):
            return [observers]
        try:
            observers = list(observers)
        except TypeError:
            observers = [observers]
        for k, ob in enumerate(observers):
            if not isinstance(ob, Observer):
                raise ParameterError(f"observers[{k}] = {ob!r} is not allowed: must be a rollingdem observer "
                                     "(TimeSeries, VTKSnapshots, Checkpoints, Callback)")
        return observers

    def _check_finite_state(self):
        st = self._state
        # the sum of the state is finite when every value is (a finite sum that overflows only leads
        # to the exact test): one pass, no temporaries; it runs after every call of the kernel, and
        # at 10^6 spheres the exact test costs 50 ms, a call ~0.25 s, the sums 3 ms
        if math.isfinite(float(st.x.sum()) + float(st.v.sum()) + float(st.w.sum())):
            return
        bad = ~(np.isfinite(st.x).all(axis=1) & np.isfinite(st.v).all(axis=1) & np.isfinite(st.w).all(axis=1))
        if bad.any():
            k = int(st.ids[np.nonzero(bad)[0][0]])
            raise SimulationError(f"the state became non-finite at t = {self.time:.6g} s (step {self.step}), "
                                  f"particle {k}: the run is unstable; reduce dt (now {self.dt:.4g} s, stable "
                                  f"estimate {self.stable_time_step():.4g} s) or check the input")

    # --- checkpoint ----------------------------------------------------------------------------
    def checkpoint(self, path) -> Path:
        """Write the complete state; ``Simulation.restore(path)`` continues bit for bit."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        meta = {
            "version": __version__,
            "contact": self.contact.to_dict(),
            "materials": self.materials.to_dict(),
            "gravity": list(self.gravity),
            "dt": self.dt,
            "skin": self._skin,
            "check_timestep": self.check_timestep,
            "track_energy": self.track_energy,
            "step": self.step,
            "time": self.time,
            "time_origin": list(self._time_origin),
            "walls": [None if wl.kind == INACTIVE else {**wl.describe(), "name": wl.name,
                                                          "material": self.materials[wl.material].name}
                      for wl in self._walls],
            "periodic": {axis: list(ends) for axis, ends in self.periodic.items()},
            "outlets": [o.describe() for o in self._outlets],
            "inflows": [i.describe() for i in self._inflows],
        }
        arrays = self._state.to_arrays()
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez(tmp, meta=np.array(json.dumps(meta)), **arrays)
        tmp.replace(path)
        return path

    @classmethod
    def restore(cls, path, backend: str | None = None) -> "Simulation":
        """The simulation a checkpoint (``Simulation.checkpoint``, ``Checkpoints``, a run's
        ``final.npz``) holds, to step on ``backend`` (a checkpoint does not depend on the backend
        that wrote it)."""
        path = Path(path)
        what = "must be a checkpoint .npz file written by Simulation.checkpoint"
        if not path.exists():
            raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it does not exist; {what}")
        if path.is_dir():
            raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it is a folder; {what}")
        try:
            with np.load(path, allow_pickle=False) as data:
                if not hasattr(data, "files") or "meta" not in data.files:
                    raise ValueError("no meta")
                meta = json.loads(str(data["meta"]))
                arrays = {k: data[k] for k in data.files if k != "meta"}
            for key in ("contact", "materials", "gravity", "dt", "walls", "step", "time"):
                meta[key]
        except OSError as err:
            raise ParameterError(f"checkpoint = {str(path)!r} cannot be read ({err.strerror or err}); {what}") from None
        except (ValueError, KeyError, TypeError, EOFError, zipfile.BadZipFile):  # not an .npz, or not rollingdem's
            raise ParameterError(f"checkpoint = {str(path)!r} is not allowed: it is not a rollingdem checkpoint; "
                                 f"{what}") from None
        contact = ContactModel.from_dict(meta["contact"])
        sim = cls(contact=contact, gravity=meta["gravity"], dt=meta["dt"], skin=meta["skin"],
                  check_timestep=meta["check_timestep"], track_energy=meta.get("track_energy", True),
                  periodic=meta.get("periodic"))
        sim.materials = MaterialTable.from_dict(meta["materials"])
        for wd in meta["walls"]:
            if wd is None:
                sim._walls.append(_Removed(None))
            elif wd["type"] == "mesh":  # its triangles are in the arrays, made into a wall below
                sim._walls.append(wd)
            else:
                wd = dict(wd)
                mat = wd.pop("material")
                sim._walls.append(wall_from_dict(wd, mat))
        sim._state = EngineState.from_arrays(arrays, contact.history_size)
        sim.backend = default_backend() if backend is None else backend
        st = sim._state
        in_place = np.flatnonzero(st.wall_kind != INACTIVE)
        if len(in_place) < len(st.wall_kind):  # a checkpoint of before 2026-12-02 keeps removed walls
            st.set_walls(in_place.tolist(), wall_kind=st.wall_kind[in_place], wall_geom=st.wall_geom[in_place],
                         wall_vel=st.wall_vel[in_place], wall_omega=st.wall_omega[in_place],
                         wall_mat=st.wall_mat[in_place])
        ms, m = st.meshes, 0
        for k, wd in enumerate(sim._walls):  # the meshes in the engine's order, their triangles from the arrays
            if isinstance(wd, dict):
                v0, v1 = ms.vertex_start[m], ms.vertex_start[m + 1]
                t0, t1 = ms.triangle_start[m], ms.triangle_start[m + 1]
                mesh = TriangleMesh(ms.vertices[v0:v1], ms.triangles[t0:t1] - v0, label=f"mesh {wd.get('name')!r}")
                sim._walls[k] = MeshWall.from_description(wd, wd["material"], mesh)
                m += 1
        sim._engine_walls = [wl for wl in sim.walls if wl.kind != WALL_MESH]
        for wl, g in zip(sim._engine_walls, sim._state.wall_geom):
            wl.update_from_geometry(g)
        ms.names = [wl for wl in sim.walls if wl.kind == WALL_MESH]
        sim.sync_walls_from_engine()
        from rollingdem.scene.boundaries import Inflow, Outlet

        sim._outlets = [Outlet.from_description(d) for d in meta.get("outlets", [])]
        sim._inflows = [Inflow.from_description(d) for d in meta.get("inflows", [])]
        sim.step = int(meta["step"])
        sim.time = float(meta["time"])
        origin = meta.get("time_origin", (sim.time, sim.step))  # absent in older checkpoints
        sim._time_origin = (float(origin[0]), int(origin[1]))
        return sim

    def sync_walls_from_engine(self):
        """Copy moved wall positions from the engine back to the Wall objects."""
        for wl, g in zip(self._engine_walls, self._state.wall_geom):
            wl.update_from_geometry(g)
        ms = self._state.meshes
        for m, wl in enumerate(ms.names):
            v0, v1 = ms.vertex_start[m], ms.vertex_start[m + 1]
            mo = ms.motion[m]
            wl.update_from_engine(ms.vertices[v0:v1], mo[6:9] + mo[0:3] * mo[9])

    def wall_loads(self, point=None) -> dict:
        """Force (N) and torque (N m) on each wall in place at the last step, by the wall's name (or
        '#k' for an unnamed one): {"force": (fx, fy, fz), "torque": (tx, ty, tz), "point": ...}, the
        torque about ``point`` if given, else about the wall's own ``torque_point`` (a mesh's
        centroid, moving with it; a plane's or cylinder's point)."""
        st = self._state
        out = {}
        planes = (st.wall_load.reshape(st.n, st.n_walls, -1).sum(axis=0) if st.n and st.n_walls
                  else np.zeros((st.n_walls, 6)))
        meshes = st.meshes.loads()
        rows = [(wl, planes[k]) for k, wl in enumerate(self._engine_walls)]
        rows += [(wl, meshes[k]) for k, wl in enumerate(st.meshes.names)]
        for wl, load in rows:
            about = np.array(wl.torque_point() if point is None else check_vector("torque point", point))
            force = load[0:3]
            torque = load[3:6] - np.cross(about, force)
            out[self._wall_key(wl)] = {"force": tuple(float(c) for c in force),
                                       "torque": tuple(float(c) for c in torque),
                                       "point": tuple(float(c) for c in about)}
        return out

    def mesh_walls(self) -> dict:
        """Each mesh wall in place, as its ``TriangleMesh`` where it is now, by a file-safe label
        (its name, else ``mesh{k}``)."""
        self.sync_walls_from_engine()
        out = {}
        for k, wl in enumerate(self._walls):
            if wl.kind == WALL_MESH:
                label = "".join(c if c.isalnum() or c in "-_" else "_" for c in wl.name) if wl.name else f"mesh{k}"
                out[label] = wl.mesh
        return out

    def _wall_key(self, wall) -> str:
        if wall.name:
            return wall.name
        return f"#{next(k for k, w in enumerate(self._walls) if w is wall)}"


class _Removed(Wall):
    """The place of a removed wall in ``Simulation._walls``; ``wall`` is the wall that was there."""

    kind = INACTIVE

    def __init__(self, wall=None):
        super().__init__(None)
        self.wall = wall

    def __repr__(self):
        return f"<removed wall {self.wall!r}>"


def _short(value, width: int = 60) -> str:
    """repr of a user's value, cut to ``width`` characters."""
    text = repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def _clock(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    m, sec = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


class _Progress:
    """tqdm bar over simulated time with steps/s and time left. Until the first chunk of steps is
    back it says "compiling" (the first call compiles the kernel, or loads it from Numba's cache),
    and the rate and the time left count only the chunks after it; ``warm``: the kernel has run
    before, so the first chunk counts too and nothing is said of compiling."""

    def __init__(self, sim, steps, label, warm=False):
        from tqdm import tqdm

        self.total_time = steps * sim.dt
        import sys

        self.label = label
        self.bar = tqdm(total=round(self.total_time, 12), desc=label if warm else f"{label} (compiling)", unit="s(sim)",
                        unit_scale=False, mininterval=0.5 if sys.stderr.isatty() else 10.0,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t={n:.4g}/{total:.4g} s [{elapsed}{postfix}]")
        self.dt = sim.dt
        self.total_steps = steps
        self.warm = warm
        self.done = 0
        self.steps = 0  # after the first chunk
        self.wall = 0.0

    def update(self, sim, todo, elapsed):
        self.done += todo
        if self.done == todo and not self.warm:  # the first chunk: compile time, not the stepping rate
            self.bar.set_description_str(self.label, refresh=False)
        else:
            self.steps += todo
            self.wall += elapsed
        if self.steps:
            rate = self.steps / max(self.wall, 1e-9)
            left = max(self.total_steps - self.done, 0) / rate
            self.bar.set_postfix_str(f"{rate:,.0f} steps/s, {_clock(left)} left", refresh=False)
        self.bar.update(min(todo * self.dt, self.bar.total - self.bar.n))

    def close(self):
        self.bar.close()
