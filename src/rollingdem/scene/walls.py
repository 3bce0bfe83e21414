"""Walls: infinite plane and cylinder (a thin shell; particles are placed inside).

A wall is a contact partner of infinite radius and mass with a prescribed velocity
(docs/models.md §0: R* = R_i, m* = m_i). It can move with a constant velocity, its surface can move
with an angular velocity (a rotating drum: surface velocity v + omega x (c - point)), follow a motion
program on top (``rollingdem.scene.motion``: an oscillation, a table of times, a servo), and it can be
removed or given a new motion between runs.
"""

from __future__ import annotations

import math

import numpy as np

from rollingdem.engine.layout import MESH_MOTION as MO
from rollingdem.errors import Declared, ParameterError, check_positive, check_vector
from rollingdem.physics.records import WALL_CYLINDER as CYLINDER
from rollingdem.physics.records import WALL_GEOMETRY_SIZE as GEOMETRY_SIZE
from rollingdem.physics.records import WALL_INACTIVE as INACTIVE
from rollingdem.physics.records import WALL_PLANE as PLANE
from rollingdem.scene.motion import check_program, program_from_dict


def surface_speed(velocity, angular_velocity, motion, reach: float) -> float:
    """The fastest a wall surface moves ``reach`` (m) from its spin axis (m/s): |v| + |omega| reach
    plus its program's peak there (``motion``: a program or None)."""
    speed = float(np.linalg.norm(velocity)) + float(np.linalg.norm(angular_velocity)) * reach
    return speed + (motion.peak_speed(reach) if motion is not None else 0.0)


class Wall:
    """Base class of walls; see ``Plane`` and ``Cylinder``."""

    kind: int = INACTIVE

    def __init__(self, material, velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0), name=None):
        self.material = material
        self.velocity = check_vector("wall velocity", velocity)
        self.angular_velocity = check_vector("wall angular_velocity", angular_velocity)
        self.name = name
        self.motion = None
        # the engine's motion row (and a mesh's vertices where it began) at the last refresh, carried
        # to the engine again unless the motion changed since (``WallSet.hand_over``)
        self.engine_motion_row = self.engine_motion_reference = None
        self.restart_motion = True

    def set_motion(self, motion) -> None:
        """Set the wall's program (``rollingdem.scene.motion``: ``Oscillation``, ``MotionTable``,
        ``Servo``; None for none), added to its steady motion; it starts from where the wall is when
        it goes to the engine."""
        if isinstance(motion, dict):
            motion = program_from_dict(motion)
        check_program(self, motion, repr(self.name) if self.name else f"({type(self).__name__.lower()})")
        self.motion = motion
        self.restart_motion = True

    def reach(self, x: np.ndarray) -> float:
        """The farthest a point of ``x`` (m, particle centres) lies from the wall's spin axis (m)."""
        if not len(x):
            return 0.0
        axis = np.asarray(getattr(self, self.spin_axis_name), float)
        d = x - np.asarray(self.point, float)
        return float(np.linalg.norm(d - np.outer(d @ axis, axis), axis=1).max())

    def peak_speed(self, x: np.ndarray) -> float:
        """The fastest the wall's surface can move where particles (centres ``x``) meet it (m/s): its
        velocity, its turn at the farthest reach, and its program's peak (the dt check's wall speed)."""
        return surface_speed(self.velocity, self.angular_velocity, self.motion, self.reach(x))

    def present_velocity(self) -> tuple:
        """The velocity (m/s) and angular velocity (rad/s) of the wall's last step (a program's
        included), as the engine moved it; the steady ones before it has moved."""
        row = self.engine_motion_row
        if self.motion is None or row is None:
            return np.asarray(self.velocity, float), np.asarray(self.angular_velocity, float)
        return row[[MO.tvx, MO.tvy, MO.tvz]], row[[MO.twx, MO.twy, MO.twz]]

    def describe_motion(self) -> dict:
        return {"motion": None if self.motion is None else self.motion.describe()}

    #: the direction a plane's or cylinder's angular velocity must lie along: its surface turns in
    #: itself (a turntable, a drum), its geometry stays; a mesh turns as a whole instead
    spin_axis_name = None

    def set_angular_velocity(self, angular_velocity):
        """Set the angular velocity (rad/s); a plane's must lie along its normal, a cylinder's along
        its axis (else its surface would move out of itself while it stays: use a MeshWall)."""
        omega = check_vector("wall angular_velocity", angular_velocity)
        if self.spin_axis_name is not None:
            axis = np.asarray(getattr(self, self.spin_axis_name))
            w = np.asarray(omega)
            off = np.linalg.norm(w - (w @ axis) * axis)
            if off > 1e-12 * max(np.linalg.norm(w), 1e-300):
                raise ParameterError(f"wall angular_velocity = {list(omega)} is not allowed for a {type(self).__name__.lower()}: "
                                     f"it must lie along its {self.spin_axis_name} {list(axis)} (its surface turns in "
                                     "itself); to turn the wall as a whole, use a MeshWall")
        self.angular_velocity = omega

    def geometry(self) -> np.ndarray:
        raise NotImplementedError

    def torque_point(self) -> tuple:
        """The point the wall's torque is reported about (``Simulation.wall_loads``): its ``point``."""
        return tuple(self.point)

    def overlap(self, x: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Overlap (m) of spheres (centres x, radii r) with this wall; > 0 where they overlap."""
        return wall_overlap(self.geometry(), self.kind, x, r)

    def describe(self) -> dict:
        raise NotImplementedError

    def __repr__(self):
        try:
            d = self.describe()
        except NotImplementedError:
            return f"{type(self).__name__}(name={self.name!r})"
        d.pop("type", None)
        args = {"name": d.pop("name", None), "material": self.material, **d}
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in args.items())})"


#: what the walls' common constructor parameters are (``Declared``)
WALL_DECLARED = {
    "material": Declared("the wall's material (a name, or a Material)", kind="text"),
    "velocity": Declared("steady velocity of the wall", "m/s", "vector"),
    "angular_velocity": Declared("steady angular velocity of the wall's surface about its own point and axis", "rad/s",
                                 "vector"),
    "name": Declared("label of the wall in loads and outputs", kind="text"),
    "motion": Declared("a motion program added to the steady motion (Oscillation, MotionTable, Servo)", kind="program"),
}


class Plane(Wall):
    """Infinite plane through ``point`` with unit ``normal`` pointing to the particles' side.

    A particle touches it when its centre is closer than its radius to the plane (or behind it):
    overlap = R - (x - point) . normal.
    """

    kind = PLANE
    spin_axis_name = "normal"
    declared = {"point": Declared("a point of the plane", "m", "vector"),
                "normal": Declared("normal towards the particles' side (made unit length)", "-", "vector"),
                **WALL_DECLARED}

    def __init__(self, point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), material=None, velocity=(0.0, 0.0, 0.0),
                 angular_velocity=(0.0, 0.0, 0.0), name=None, motion=None):
        super().__init__(material, velocity, (0.0, 0.0, 0.0), name)
        self.point = check_vector("plane point", point)
        self.normal = check_vector("plane normal", normal, unit=True)
        self.set_angular_velocity(angular_velocity)
        self.set_motion(motion)

    def geometry(self) -> np.ndarray:
        g = np.zeros(GEOMETRY_SIZE)
        g[0:3] = self.point
        g[3:6] = self.normal
        return g

    def update_from_geometry(self, g):
        self.point = tuple(float(c) for c in g[0:3])

    def describe(self) -> dict:
        return {"type": "plane", "point": list(self.point), "normal": list(self.normal),
                "velocity": list(self.velocity), "angular_velocity": list(self.angular_velocity), "name": self.name,
                **self.describe_motion()}


class Cylinder(Wall):
    """Cylinder of ``radius`` about the axis through ``point`` along ``axis``: a thin shell that
    holds particles inside and pushes those outside away, with rounded rims at its ends
    (docs/models.md §0); insertion and placement fill it inside.

    ``extent`` = (s_min, s_max) limits it along the axis (axial coordinate s = (x - point) . axis,
    m); None means infinite. There are no end caps: add planes for those.
    """

    kind = CYLINDER
    spin_axis_name = "axis"
    declared = {"radius": Declared("radius of the shell", "m", low=0.0, low_open=True),
                "point": Declared("a point of the axis, where s = 0", "m", "vector"),
                "axis": Declared("direction of the axis (made unit length)", "-", "vector"),
                "extent": Declared("(s_min, s_max): where the shell ends along the axis, s = (x - point) . axis; "
                                   "none: infinite", "m", "pair"),
                **WALL_DECLARED}

    def __init__(self, radius, point=(0.0, 0.0, 0.0), axis=(0.0, 0.0, 1.0), extent=None, material=None,
                 velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0), name=None, motion=None):
        super().__init__(material, velocity, (0.0, 0.0, 0.0), name)
        self.radius = check_positive("cylinder radius", radius, "m")
        self.point = check_vector("cylinder point", point)
        self.axis = check_vector("cylinder axis", axis, unit=True)
        self.set_angular_velocity(angular_velocity)
        self.set_motion(motion)
        if extent is None:
            self.extent = (-math.inf, math.inf)
        else:
            try:
                lo, hi = (float(extent[0]), float(extent[1]))
            except (TypeError, ValueError, IndexError):
                raise ParameterError(f"cylinder extent = {extent!r} is not allowed: must be (s_min, s_max)") from None
            if not lo < hi:
                raise ParameterError(f"cylinder extent = {extent!r} is not allowed: need s_min < s_max")
            self.extent = (lo, hi)

    def geometry(self) -> np.ndarray:
        g = np.zeros(GEOMETRY_SIZE)
        g[0:3] = self.point
        g[3:6] = self.axis
        g[6] = self.radius
        g[7], g[8] = self.extent
        return g

    def update_from_geometry(self, g):
        self.point = tuple(float(c) for c in g[0:3])

    def describe(self) -> dict:
        return {"type": "cylinder", "radius": self.radius, "point": list(self.point), "axis": list(self.axis),
                "extent": [self.extent[0], self.extent[1]], "velocity": list(self.velocity),
                "angular_velocity": list(self.angular_velocity), "name": self.name, **self.describe_motion()}


def wall_overlap(geometry: np.ndarray, kind: int, x: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Overlap (m) of spheres (centres x, radii r) with a wall; > 0 means they overlap.

    The rule for placing spheres: a plane is a half-space, a cylinder holds particles inside within
    its axial extent (a sphere outside it there counts as in the wall, so a drum or tube is filled
    inside; in contact it is a thin shell, docs/models.md §0).
    """
    if kind == PLANE:
        return r - (x - geometry[0:3]) @ geometry[3:6]
    if kind != CYLINDER:
        return np.full(len(r), -1.0)
    d = x - geometry[0:3]
    s = d @ geometry[3:6]
    q = d - s[:, None] * geometry[3:6]
    ov = np.linalg.norm(q, axis=1) + r - geometry[6]
    ov[(s < geometry[7]) | (s > geometry[8])] = -1.0
    return ov


def wall_from_dict(d: dict, material) -> Wall:
    d = dict(d)
    kind = d.pop("type")
    if kind == "plane":
        return Plane(material=material, **d)
    if kind == "cylinder":
        ext = d.pop("extent", None)
        if ext is not None and ext[0] == -math.inf and ext[1] == math.inf:
            ext = None
        return Cylinder(material=material, extent=ext, **d)
    raise ParameterError(f"wall type = {kind!r} is not known: allowed are 'plane', 'cylinder', 'mesh'")


