"""The seed report's case 3 pile: spheres settled in a tube on a plate (or a rough base), the tube
lifted or removed, the pile's angle measured once it is at rest.

:class:`PileMaterial`, :class:`PileSetup` and :class:`Collapse` say what the pile is made of, how
it is built and how the tube leaves; :func:`pile_case` writes it as a case file; :func:`pile_run`
runs it and measures the angle (:func:`rollingdem.analysis.repose.repose_angle`). The experiments
on it: :mod:`rollingdem.experiments.repose`.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rollingdem.analysis.repose import ReposeAngle, default_max_speed, repose_angle, touching
from rollingdem.errors import ParameterError, check_choice
from rollingdem.experiments.case_file import stage_keys
from rollingdem.experiments.single_sphere import DT, RADIUS, TABLE1, G
from rollingdem.io.casefile import build_simulation, load_case, take_materials
from rollingdem.io.mapping_file import read_mapping
from rollingdem.scene.checkpoint import read
from rollingdem.scene.materials import Material
from rollingdem.scene.simulation import Simulation

POLYDISPERSITY = 0.2  # radii uniform in R (1 +- 0.2)
MOVING_FRACTION = 0.005  # of the spheres: a pile with fewer still moving counts as settled
PACKING = 0.6  # nominal solid fraction of the settled column, used to size the tube
INSERT_PACKING = 0.3  # solid fraction of the random insertion (it tops out near 0.35)
ROUGH_BASE_EXTENT = 12.0  # tube radii: the side of the square rough base under a pile


def column_size(count, radius=RADIUS, polydispersity=0.0, aspect=1.0) -> tuple[float, float]:
    """(tube radius, nominal column height) in m for ``count`` spheres: the height the column has at
    solid fraction ``PACKING`` is ``aspect`` tube diameters.

    Solid volume N (4/3) pi <r^3>, with <r^3> = R^3 (1 + p^2) for radii uniform in R (1 +- p). A
    narrow tube packs looser than that: 1000 spheres of R (1 +- 0.2) in the tube of 10.5 R settle at
    a solid fraction of about 0.50, 1.19 times the nominal height.
    """
    solid = count * 4.0 / 3.0 * math.pi * radius ** 3 * (1.0 + polydispersity ** 2)
    tube = (solid / (PACKING * math.pi * 2.0 * aspect)) ** (1.0 / 3.0)
    return tube, 2.0 * aspect * tube


@dataclass
class PileRun:
    """One collapse: kinetic energies (J) sampled after the tube is removed or lifted, and the final pile."""

    label: str
    t: np.ndarray
    translational: np.ndarray
    rotational: np.ndarray
    spin_vertical: np.ndarray
    positions: np.ndarray
    radii: np.ndarray
    velocities: np.ndarray
    angle: ReposeAngle | None
    angle_error: str = ""
    settled_at: float = math.nan
    wall_time: float = math.nan
    settle_seconds_saved: float = 0.0  # wall time of a shared settling the run started from


@dataclass(frozen=True)
class PileMaterial:
    """The pile's material where it may differ from Table 1 (whose Poisson ratio 0.49 and density
    1056 kg/m^3 it keeps): sliding and rolling friction coefficients, Young's modulus (Pa),
    coefficient of restitution and rolling viscous damping ratio; the cohesion law (``cohesion``:
    "none", "sjkr", "jkr", docs/models.md §1.6) and its parameters, the work of adhesion
    ``surface_energy`` (J/m^2) and the ``cohesion_energy_density`` (J/m^3); ``coarse_graining`` alpha,
    parcels alpha times the radii given (docs/models.md §18; the walls' material keeps 1). Checked by
    :class:`rollingdem.Material` and :class:`rollingdem.ContactModel` when the pile is built."""

    friction: float = TABLE1["friction"]
    rolling_friction: float = TABLE1["rolling_friction"]
    youngs_modulus: float = TABLE1["youngs_modulus"]
    restitution: float = TABLE1["restitution"]
    rolling_damping: float = TABLE1["rolling_damping"]
    poisson_ratio: float = TABLE1["poisson_ratio"]
    density: float = TABLE1["density"]
    cohesion: str = "none"
    surface_energy: float = 0.0
    cohesion_energy_density: float = 0.0
    coarse_graining: float = 1.0

    @classmethod
    def from_parameters(cls, p: dict) -> "PileMaterial":
        """The material of an experiment's parameters (``mu``, ``mur``, ``youngs_modulus``, ``e``,
        ``eta_r``, and where given ``poisson_ratio``, ``density`` and the cohesion parameters;
        Table 1's otherwise)."""
        extra = {k: p[k] for k in ("poisson_ratio", "density", "cohesion", "surface_energy", "cohesion_energy_density",
                                   "coarse_graining") if k in p}
        return cls(friction=p["mu"], rolling_friction=p["mur"], youngs_modulus=p["youngs_modulus"],
                   restitution=p["e"], rolling_damping=p["eta_r"], **extra)

    def as_material(self, name: str) -> Material:
        """Table 1 with these values, as a :class:`rollingdem.Material` called ``name``."""
        return Material(name, youngs_modulus=self.youngs_modulus, poisson_ratio=self.poisson_ratio,
                        density=self.density, friction=self.friction, rolling_friction=self.rolling_friction,
                        restitution=self.restitution, rolling_damping=self.rolling_damping,
                        surface_energy=self.surface_energy, cohesion_energy_density=self.cohesion_energy_density,
                        coarse_graining=self.coarse_graining)

    def wall_material(self, name: str) -> Material:
        """The walls' material: the spheres', without cohesion (the spheres stick to each other, not
        to the tube, the plate or the drum); ``Simulation.set_pair`` must zero the pair's too."""
        return replace(self, surface_energy=0.0, cohesion_energy_density=0.0, coarse_graining=1.0).as_material(name)


@dataclass(frozen=True)
class Collapse:
    """How the tube leaves and how long the pile collapses: the tube is removed at once or, with
    ``lift_speed`` (m/s), lifted; the collapse runs at least ``min_time`` s and then on, in steps
    of ``sample`` s, until the pile is settled or ``max_time`` s have passed."""

    min_time: float = 1.0
    max_time: float = 3.0
    sample: float = 0.01
    lift_speed: float | None = None


@dataclass(frozen=True)
class PileSetup:
    """Where the column stands: its height in tube diameters (``aspect``), the tube (with
    ``tube_segments``, a triangle mesh of that many flat sides through the cylinder's radius, else
    the cylinder) and the floor (``base``: "plate", the bare plate; "rough", a rough base of fixed
    spheres of the mean radius on it, ``rollingdem.rough_base``, over a square ``ROUGH_BASE_EXTENT``
    tube radii wide, as the PFC and LIGGGHTS repose studies glue one to the floor: on the bare
    plate, spheres with little rolling resistance roll away and no pile forms). The sizes: the
    spheres' mean ``radius`` (m); ``tube_radius`` (m; None: sized for ``aspect`` by
    :func:`column_size`); the base spheres' ``base_radius`` (None: the mean radius), ``base_spacing``
    and ``base_jitter`` (None: ``rollingdem.rough_base``'s defaults); ``clearance``, how far (m;
    None: two mean radii) the tube's lower edge rises above the settled column's top before the
    lifted tube is removed. ``shared``: (a folder, a reference ``PileMaterial``): the column settles
    once per reference material and is kept there, and each run starts from it with its own
    (:func:`settled_column`); None: each run settles its own."""

    aspect: float = 1.0
    tube_segments: int | None = None
    base: str = "plate"
    radius: float = RADIUS
    tube_radius: float | None = None
    base_radius: float | None = None
    base_spacing: float | None = None
    base_jitter: float | None = None
    clearance: float | None = None
    shared: tuple | None = None


def tube_clearing_time(floor: float, height: float, radius: float, clearance: float, lift_speed: float) -> float:
    """Time (s) for the lifted tube's lower edge, rising from the plate (z = 0) at ``lift_speed``,
    to stand ``clearance`` above the settled column's top: the floor (the rough base's top, 0 on
    the plate), the column's nominal ``height`` and 2 radii more (a narrow column stands higher,
    :func:`column_size`)."""
    return (floor + height + 2.0 * radius + clearance) / lift_speed


SHIPPED = Path(__file__).parent / "cases" / "repose-rough-base.yaml"
"""The rough-base pile's case file (``rollingdem experiments show repose-rough-base``)."""


def pile_case(rolling="epsd", twisting="none", count=3000, seed=1, material: PileMaterial = PileMaterial(),
              collapse: Collapse = Collapse(), normal="hertz", polydispersity=POLYDISPERSITY, dt=DT,
              setup: PileSetup = PileSetup()) -> dict:
    """The pile of :func:`pile_run` as a case file's data (the shipped ``repose-rough-base`` file,
    sized): the scene, and as stages the settling, the lift (or the tube's removal) and the
    collapse until settled, which ``rollingdem run`` runs with its kinetic-energy criterion."""
    for what, value, kind in (("material", material, PileMaterial), ("collapse", collapse, Collapse),
                              ("setup", setup, PileSetup)):
        if not isinstance(value, kind):
            raise ParameterError(f"{what} = {value!r} is not allowed: must be a "
                                 f"rollingdem.experiments.pile.{kind.__name__}")
    check_choice("base", setup.base, ("plate", "rough"))
    radius = setup.radius
    tube_radius, height = column_size(count, radius, polydispersity, setup.aspect)
    if setup.tube_radius is not None:  # the same column volume in the tube given
        tube_radius, height = setup.tube_radius, height * (tube_radius / setup.tube_radius) ** 2
    data, _ = read_mapping(SHIPPED)
    data["dt"] = dt
    data["materials"] = [material.as_material("beads").to_dict()]
    walls = "beads"
    data["pairs"] = []
    if material.cohesion != "none":  # cohesive spheres, not cohesive to the plate and the tube
        walls = "wall"
        data["materials"].append(material.wall_material("wall").to_dict())
        data["pairs"] = [{"materials": ["beads", "wall"], "surface_energy": 0.0, "cohesion_energy_density": 0.0}]
    data["contact"] = {"normal": normal, "rolling": rolling, "twisting": twisting, "cohesion": material.cohesion}
    plate = {"type": "plane", "name": "plate", "material": walls, "point": [0, 0, 0], "normal": [0, 0, 1]}
    if setup.tube_segments is None:
        tube = {"type": "cylinder", "name": "tube", "material": walls, "radius": tube_radius,
                "extent": [0.0, 2.0 * height + 0.1]}
    else:
        tube = {"type": "mesh", "name": "tube", "material": walls, "shape": "drum",
                "size": {"radius": tube_radius, "length": 2.0 * height + 0.1, "segments": setup.tube_segments,
                         "caps": False}}
    data["walls"] = [plate, tube]
    floor, particles = 0.0, []
    if setup.base == "rough":
        half = 0.5 * ROUGH_BASE_EXTENT * tube_radius
        base_radius = setup.base_radius or radius
        particles.append({"rough_base": {"radius": base_radius, "extent": [[-half, half], [-half, half]],
                                         "spacing": setup.base_spacing, "jitter": setup.base_jitter, "seed": seed},
                          "material": "beads"})
        floor = 2.0 * base_radius * material.coarse_graining  # the base of parcels is alpha times taller
    fill = height * PACKING / INSERT_PACKING
    particles.append({"insert": {"type": "cylinder", "radius": tube_radius, "z_min": floor, "z_max": floor + fill},
                      "count": count, "material": "beads", "seed": seed,
                      "radius": {"distribution": "uniform", "low": radius * (1 - polydispersity),
                                 "high": radius * (1 + polydispersity)} if polydispersity else radius})
    data["particles"] = particles
    # free fall from the top of the fill, then as long again to come to rest
    stages = [{"name": "settle", "duration": 2.0 * math.sqrt(2.0 * fill / G) + 0.1}]
    sample = collapse.sample
    if collapse.lift_speed:
        clearance = setup.clearance if setup.clearance is not None else 2.0 * radius
        lift = tube_clearing_time(floor, height, radius, clearance, collapse.lift_speed)
        lift = math.ceil(lift / sample - 1e-9) * sample  # the tube goes at the first sample after it clears
        stages.append({"name": "lift", "duration": lift,
                       "wall_motion": [{"wall": "tube", "velocity": [0.0, 0.0, collapse.lift_speed]}]})
        stages.append({"name": "rest", "remove_walls": ["tube"], "until": "settled",
                       "max_duration": max(collapse.max_time - lift, sample)})
    else:
        stages.append({"name": "collapse", "remove_walls": ["tube"], "until": "settled",
                       "max_duration": collapse.max_time})
    data["stages"] = stages
    return data


#: s of wall time between a resumable pile's checkpoints (``pile_run``'s ``checkpoint``)
PILE_CHECKPOINT_SECONDS = 600.0


class PileProgress:
    """Where a resumable pile run stands, in two slots (``.a`` and ``.b`` beside ``path``), each a
    ``Simulation.checkpoint`` and a JSON of the collapse's time, kinetic energies so far and wall
    time, written in that order: a kill while one slot is written leaves the other whole, and the
    slot whose JSON names its checkpoint's step is read."""

    def __init__(self, path, every: float | None = None):
        self.path = Path(path)
        self.every = PILE_CHECKPOINT_SECONDS if every is None else every
        self.saved_at = time.perf_counter()
        self.slot = 0

    def _files(self, slot: int) -> tuple[Path, Path]:
        stem = f"{self.path.name}.{'ab'[slot]}"
        return self.path.with_name(stem + ".npz"), self.path.with_name(stem + ".json")

    def load(self):
        """(simulation, t, kinetic energies, wall time so far) of the latest whole slot, or None."""
        best = None
        for slot in (0, 1):
            npz, meta = self._files(slot)
            if not (npz.exists() and meta.exists()):
                continue
            state = json.loads(meta.read_text())
            if read(npz)[0]["step"] == state["step"] and (best is None or state["step"] > best[1]["step"]):
                best = (slot, state)
        if best is None:
            return None
        self.slot = 1 - best[0]  # the next save goes into the other slot
        state = best[1]
        return (Simulation.restore(self._files(best[0])[0]), state["t"], [tuple(k) for k in state["ke"]],
                state["wall_time"])

    def save(self, sim, t: float, ke: list, wall_time: float, force: bool = False) -> None:
        """Write the next slot if ``every`` s of wall time have passed since the last (or ``force``)."""
        if not force and time.perf_counter() - self.saved_at < self.every:
            return
        npz, meta = self._files(self.slot)
        sim.checkpoint(npz)
        tmp = meta.with_name(meta.name + ".tmp")
        tmp.write_text(json.dumps({"step": sim.step, "t": t, "ke": ke, "wall_time": wall_time}))
        tmp.replace(meta)
        self.slot, self.saved_at = 1 - self.slot, time.perf_counter()

    def remove(self) -> None:
        for slot in (0, 1):
            for f in self._files(slot):
                f.unlink(missing_ok=True)


def settled_column(data: dict, reference: dict | None, folder) -> tuple:
    """(the simulation of the case ``data`` after its first stage, the wall-clock seconds a shared
    settling saved). With ``reference`` (the case's data with the free parameters at reference
    values) and a ``folder``, the first stage runs once per reference case, its end is kept in
    ``folder`` with the wall time of its stepping, and every run starts from it with its own
    materials (``take_materials``): the column's packing is then the reference material's.
    Without, the stage runs here."""
    duration = data["stages"][0]["duration"]
    if reference is None or folder is None:
        sim = build_simulation(load_case(data))
        sim.run(duration)
        return sim, 0.0
    key = stage_keys(reference)[0]
    folder = Path(folder)
    path, meta = folder / f"settled-{key}.npz", folder / f"settled-{key}.json"
    if path.exists() and meta.exists():
        sim, saved = Simulation.restore(path), json.loads(meta.read_text())["wall_seconds"]
    else:
        sim = build_simulation(load_case(reference))
        sim.engine_module()  # compiled or loaded first: the time kept is the settling's own
        tic = time.perf_counter()
        sim.run(duration)
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f".settled-{key}.{time.time_ns()}.npz"  # a concurrent worker may write it too
        sim.checkpoint(tmp)
        tmp.replace(path)
        tmp = meta.with_name(f".{meta.name}.{time.time_ns()}")
        tmp.write_text(json.dumps({"wall_seconds": time.perf_counter() - tic}))
        tmp.replace(meta)
        saved = 0.0
    take_materials(sim, load_case(data))
    return sim, float(saved)


def pile_run(rolling="epsd", twisting="none", count=3000, seed=1, material: PileMaterial = PileMaterial(),
             collapse: Collapse = Collapse(), normal="hertz", polydispersity=POLYDISPERSITY, dt=DT,
             setup: PileSetup = PileSetup(), edit=None, checkpoint=None) -> PileRun:
    """The report's case 3 at ``count`` spheres (mean R = 5 mm, Table 1 material, dt = 1e-5 s).

    Spheres of radius uniform in R (1 +- ``polydispersity``) fall from a random insertion into a
    tube on a plate and settle into a column ``setup.aspect`` diameters high (a monodisperse column
    orders into layers on a flat plate and then spreads into a monolayer); ``material`` sets what
    may differ from Table 1. Then the tube is removed at once (the report's case 3) or, with
    ``collapse.lift_speed`` (m/s), lifted as in the PFC example. The collapse runs at least
    ``collapse.min_time`` s and then on, in ``collapse.sample`` steps, until the pile is settled or
    ``collapse.max_time`` s have passed. Settled: of the spheres that touch another
    (:func:`rollingdem.analysis.repose.touching`), at most ``MOVING_FRACTION`` (0.5 %) move faster than
    1e-3 sqrt(g d) (:func:`rollingdem.analysis.repose.default_max_speed`). A sphere rolling alone over the
    plate (with little rolling resistance it may roll for seconds) and a few rattlers caged in
    the pile do not change its surface. Then the angle is measured. ``setup``: the tube and the
    floor (``PileSetup``). The scene and the stages' times are :func:`pile_case`'s; ``edit``, a
    function of the case's data, may change it before it is built (the clumps' study puts clumps in
    the column, ``experiments.clump_stand_in``). With ``checkpoint`` (a path), the collapse is saved
    beside it every ``PILE_CHECKPOINT_SECONDS`` of wall time (``PileProgress``) and a run started
    again with the same path goes on from the last save, bit for bit; the saves are removed when
    the run ends. With ``setup.shared`` = (folder, reference ``PileMaterial``), the column settles
    once per reference material and every run starts from it with its own (:func:`settled_column`).
    """
    data = pile_case(rolling, twisting, count, seed, material, collapse, normal, polydispersity, dt, setup)
    if edit is not None:
        data = edit(data)
    reference, folder = None, None
    if setup.shared is not None:
        folder, ref_material = setup.shared
        reference = pile_case(rolling, twisting, count, seed, ref_material, collapse, normal, polydispersity, dt, setup)
        if edit is not None:
            reference = edit(reference)
    lift_speed, sample, max_collapse = collapse.lift_speed, collapse.sample, collapse.max_time
    tic = time.perf_counter()
    rest = data["stages"][1:]
    lift_time = rest[0]["duration"] if lift_speed else 0.0
    progress = None if checkpoint is None else PileProgress(checkpoint)
    resumed = None if progress is None else progress.load()
    saved = 0.0
    if resumed is None:
        sim, saved = settled_column(data, reference, folder)
        tube = next(w for w in sim.walls if w.name == "tube")
        if lift_speed:
            sim.set_wall_velocity(tube, velocity=(0.0, 0.0, lift_speed))
        else:
            sim.remove_wall(tube)
        ke, t, earlier = [], 0.0, 0.0
        if progress is not None:
            progress.save(sim, t, ke, time.perf_counter() - tic, force=True)
    else:
        sim, t, ke, earlier = resumed
        tube = next((w for w in sim.walls if w.name == "tube"), None)
    free = ~sim.fixed
    inertia = 0.4 * sim.masses[free] * sim.radii[free] ** 2
    limit = default_max_speed(sim.radii[free])
    settled_at = math.nan
    while t < max_collapse - 1e-9:
        sim.run(sample)
        t += sample
        if lift_speed and t >= lift_time - 1e-9 and tube in sim.walls:
            sim.remove_wall(tube)  # clear of the pile
        trans, rot = sim.kinetic_energy()
        ke.append((t, trans, rot, 0.5 * float(np.dot(inertia, sim.angular_velocities[free, 2] ** 2))))
        if progress is not None:
            progress.save(sim, t, ke, earlier + time.perf_counter() - tic)
        if t >= collapse.min_time - 1e-9 and tube not in sim.walls:
            pile = touching(sim.positions[free], sim.radii[free])
            speed = np.linalg.norm(sim.velocities[free][pile], axis=1)
            if np.count_nonzero(speed >= limit) <= MOVING_FRACTION * np.count_nonzero(free):
                settled_at = t
                break
    ke = np.array(ke)
    angle, error = None, ""
    if math.isnan(settled_at):
        error = f"the pile did not settle within {max_collapse} s"
    else:
        try:
            angle = repose_angle(sim.positions[free], sim.radii[free])
        except ValueError as err:  # too flat or too small to fit a cone: say so
            error = str(err)
    if progress is not None:
        progress.remove()
    return PileRun(str(rolling), ke[:, 0], ke[:, 1], ke[:, 2], ke[:, 3], sim.positions[free].copy(),
                   sim.radii[free].copy(), sim.velocities[free].copy(), angle, error, settled_at,
                   earlier + time.perf_counter() - tic, saved)
