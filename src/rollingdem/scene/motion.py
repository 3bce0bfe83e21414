"""Programmed wall motion: an oscillation, a table of times, a servo (docs/models.md, "Wall motion").

A wall (``Plane``, ``Cylinder``, ``MeshWall``) takes one program as ``motion=``, added to its steady
velocity and angular velocity; ``Simulation.set_wall_motion`` sets or removes it between runs. The
step loop moves the wall (``rollingdem.engine.wall_motion``); a checkpoint keeps where the program
is, and a run resumed from it goes on bit for bit. A plane or cylinder moves only by translation
(its geometry does not turn): a program that turns belongs to a ``MeshWall``.
"""

from __future__ import annotations

import math

import numpy as np

from rollingdem.engine.layout import MESH_MOTION as MO, MESH_MOTION_SIZE, MOTION_OSCILLATION, MOTION_SERVO, \
    MOTION_TABLE
from rollingdem.errors import Declared, ParameterError, check_finite, check_positive, check_vector, short_repr


class Oscillation:
    """A sinusoidal motion about where the wall is when it starts (a vibrating feeder, a shaking
    table; LIGGGHTS ``wiggle`` and ``riggle``): displacement A (sin(2 pi f t + phi) - sin phi) and,
    for a ``MeshWall``, a turn by alpha (sin(2 pi f t + phi) - sin phi) about ``axis`` through the
    wall's point. ``frequency`` f (Hz), ``amplitude`` A (m, a vector), ``angle`` alpha (rad),
    ``phase`` phi (rad)."""

    kind = MOTION_OSCILLATION
    declared = {"frequency": Declared("frequency f", "Hz", low=0.0, low_open=True),
                "amplitude": Declared("amplitude A of the displacement", "m", "vector"),
                "angle": Declared("amplitude alpha of the turn about axis (a mesh wall only)", "rad"),
                "axis": Declared("axis of the turn, through the wall's point (made unit length)", "-", "vector"),
                "phase": Declared("phase phi", "rad")}

    def __init__(self, frequency, amplitude=(0.0, 0.0, 0.0), angle=0.0, axis=None, phase=0.0):
        self.frequency = check_positive("oscillation frequency", frequency, "Hz")
        self.amplitude = check_vector("oscillation amplitude", amplitude)
        self.angle = check_finite("oscillation angle", angle)
        self.phase = check_finite("oscillation phase", phase)
        if self.angle != 0.0 and axis is None:
            raise ParameterError(f"oscillation axis = None is not allowed with angle = {self.angle:g} rad: give the "
                                 "axis it turns about")
        self.axis = None if axis is None else check_vector("oscillation axis", axis, unit=True)
        if self.angle == 0.0 and not any(self.amplitude):
            raise ParameterError("oscillation amplitude = (0, 0, 0) is not allowed with angle = 0: give the amplitude "
                                 "(m) and/or the angle (rad) it swings by")

    @property
    def turns(self) -> bool:
        return self.angle != 0.0

    def fill(self, row: np.ndarray) -> None:
        row[[MO.ax, MO.ay, MO.az]] = self.amplitude
        row[MO.angle] = self.angle
        row[MO.omega] = 2.0 * math.pi * self.frequency
        row[MO.phase] = self.phase
        if self.turns:
            row[[MO.ux, MO.uy, MO.uz]] = self.axis

    def table_rows(self):
        return None

    def peak_speed(self, reach: float) -> float:
        """The fastest the program moves a point ``reach`` (m) from its axis (m/s)."""
        omega = 2.0 * math.pi * self.frequency
        return omega * (float(np.linalg.norm(self.amplitude)) + abs(self.angle) * reach)

    def position(self, t: float) -> tuple:
        """The displacement (m) and angle (rad) t seconds after the program began (the steady motion
        not included)."""
        s = math.sin(2.0 * math.pi * self.frequency * t + self.phase) - math.sin(self.phase)
        return tuple(a * s for a in self.amplitude), self.angle * s

    def describe(self) -> dict:
        return {"type": "oscillation", "frequency": self.frequency, "amplitude": list(self.amplitude),
                "angle": self.angle, "axis": None if self.axis is None else list(self.axis), "phase": self.phase}


class MotionTable:
    """A motion from a table of times (kinematics exported from CAD): displacement and angle about
    ``axis`` (rad; a ``MeshWall`` only) at each time, interpolated linearly between rows, less the
    first row's (the wall starts where it is). ``times`` (s) increasing, the program's time counted
    from the first; after the last row the wall holds there, or with ``repeat`` starts the table
    again (its last row must then equal its first)."""

    kind = MOTION_TABLE
    declared = {"times": Declared("times of the rows, increasing; the program's time counts from the first", "s",
                                  "numbers"),
                "displacements": Declared("displacement at each time", "m", "vectors"),
                "angles": Declared("angle about axis at each time (a mesh wall only)", "rad", "numbers"),
                "axis": Declared("axis of the turn, through the wall's point (made unit length)", "-", "vector"),
                "repeat": Declared("start the table again at its end (its last row must equal its first)",
                                   kind="flag")}

    def __init__(self, times, displacements=None, angles=None, axis=None, repeat: bool = False):
        try:
            t = np.asarray(times, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ParameterError(f"motion table times = {times!r} is not allowed: must be numbers") from None
        if len(t) < 2 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
            raise ParameterError(f"motion table times = {_short(t)} is not allowed: need at least two finite times, "
                                 "each later than the one before")
        self.times = t
        self.displacements = self._column("displacements", displacements, (len(t), 3))
        self.angles = self._column("angles", angles, (len(t),))
        if angles is not None and axis is None:
            raise ParameterError("motion table axis = None is not allowed with angles: give the axis they turn about")
        self.axis = None if axis is None else check_vector("motion table axis", axis, unit=True)
        if displacements is None and angles is None:
            raise ParameterError("motion table displacements = None is not allowed with angles = None: give the "
                                 "displacements (m) and/or the angles (rad)")
        self.repeat = bool(repeat)
        if self.repeat:
            jump = max(float(np.abs(self.displacements[-1] - self.displacements[0]).max()),
                       float(abs(self.angles[-1] - self.angles[0])))
            if jump > 1e-12 * max(1.0, float(np.abs(self.displacements).max()), float(np.abs(self.angles).max())):
                raise ParameterError(f"motion table repeat = True is not allowed: the last row differs from the first "
                                     f"by {jump:.3g} (the wall would jump at each repeat); end the table where it "
                                     "began")

    def _column(self, name, values, shape):
        if values is None:
            return np.zeros(shape)
        try:
            a = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"motion table {name} = {_short(values)} is not allowed: must be numbers") from None
        if a.shape != shape or not np.all(np.isfinite(a)):
            what = "three numbers (x, y, z) per time" if len(shape) == 2 else "one number per time"
            raise ParameterError(f"motion table {name} = {_short(a)} is not allowed: must be finite, {what} "
                                 f"({shape[0]} times)")
        return a

    @property
    def turns(self) -> bool:
        return self.axis is not None

    def fill(self, row: np.ndarray) -> None:
        row[MO.period] = self.times[-1] - self.times[0] if self.repeat else 0.0
        if self.turns:
            row[[MO.ux, MO.uy, MO.uz]] = self.axis

    def table_rows(self) -> np.ndarray:
        return np.column_stack([self.times, self.displacements, self.angles])

    def peak_speed(self, reach: float) -> float:
        step = np.linalg.norm(np.diff(self.displacements, axis=0), axis=1) + np.abs(np.diff(self.angles)) * reach
        return float((step / np.diff(self.times)).max())

    def position(self, t: float) -> tuple:
        if self.repeat:
            t = t % (self.times[-1] - self.times[0])
        t = self.times[0] + t
        d = [float(np.interp(t, self.times, self.displacements[:, k]) - self.displacements[0, k]) for k in range(3)]
        return tuple(d), float(np.interp(t, self.times, self.angles) - self.angles[0])

    def describe(self) -> dict:
        return {"type": "table", "times": self.times.tolist(), "displacements": self.displacements.tolist(),
                "angles": self.angles.tolist() if self.turns else None,
                "axis": None if self.axis is None else list(self.axis), "repeat": self.repeat}


class Servo:
    """A wall that holds a load (PFC's servo, LIGGGHTS ``servo``; compression and shear-box tests):
    it moves along the unit ``direction`` at s' = G (F* - F), within +-``max_speed`` (m/s), F the
    force the particles put on it against ``direction`` at the last step, F* the target ``force``
    (N) or ``pressure`` (Pa) times ``area`` (m^2). ``gain`` G (m/s per N; default max_speed / F*:
    full speed with no load). A move changes F through the contacts' stiffness k (N/m, summed) over
    the step and at once through their damping c (N s/m): the loop is stable when G c < 1 and
    G (k dt + 2 c) < 2 (docs/models.md §16); an unstable one chatters at +-max_speed."""

    kind = MOTION_SERVO
    turns = False
    declared = {"direction": Declared("direction the wall moves along, against the particles' force (made unit "
                                      "length)", "-", "vector"),
                "max_speed": Declared("the fastest the wall moves", "m/s", low=0.0, low_open=True),
                "force": Declared("target force F* (or pressure with area)", "N", low=0.0, low_open=True),
                "pressure": Declared("target pressure, with area", "Pa", low=0.0, low_open=True),
                "area": Declared("area the pressure acts on", "m^2", low=0.0, low_open=True),
                "gain": Declared("gain G (default max_speed / F*: full speed with no load)", "m/s per N", low=0.0,
                                 low_open=True)}

    def __init__(self, direction, max_speed, force=None, pressure=None, area=None, gain=None):
        self.direction = check_vector("servo direction", direction, unit=True)
        self.max_speed = check_positive("servo max_speed", max_speed, "m/s")
        if (force is None) == (pressure is None):
            raise ParameterError("servo force = None is not allowed with pressure = None: give one of force (N) and "
                                 "pressure (Pa) with area (m^2)" if force is None else
                                 f"servo force = {force!r} is not allowed with pressure = {pressure!r}: give one")
        if pressure is not None:
            if area is None:
                raise ParameterError(f"servo area = None is not allowed with pressure = {pressure!r}: give the area "
                                     "(m^2) the pressure acts on")
            self.pressure = check_positive("servo pressure", pressure, "Pa")
            self.area = check_positive("servo area", area, "m^2")
            self.force = self.pressure * self.area
        else:
            if area is not None:
                raise ParameterError(f"servo area = {area!r} is not allowed with force: area goes with pressure")
            self.force = check_positive("servo force", force, "N")
            self.pressure = self.area = None
        self.gain = self.max_speed / self.force if gain is None else check_positive("servo gain", gain, "m/s per N")

    def fill(self, row: np.ndarray) -> None:
        row[[MO.ax, MO.ay, MO.az]] = self.direction
        row[MO.target] = self.force
        row[MO.gain] = self.gain
        row[MO.max_speed] = self.max_speed

    def table_rows(self):
        return None

    def peak_speed(self, reach: float) -> float:
        return self.max_speed

    def describe(self) -> dict:
        return {"type": "servo", "direction": list(self.direction), "max_speed": self.max_speed,
                "force": None if self.pressure is not None else self.force, "pressure": self.pressure,
                "area": self.area, "gain": self.gain}


PROGRAMS = {"oscillation": Oscillation, "table": MotionTable, "servo": Servo}


def _short(value) -> str:
    """``short_repr`` of a value, an array as its list."""
    return short_repr(np.asarray(value).tolist() if isinstance(value, np.ndarray) else value)


def program_from_dict(d: dict | None):
    """The program ``describe`` described (checkpoints)."""
    if d is None:
        return None
    d = dict(d)
    return PROGRAMS[d.pop("type")](**d)


def check_program(wall, motion, label: str, angular_velocity=None) -> None:
    """Refuse a program the wall cannot follow: a turn for a plane or cylinder, a turn about another
    axis than the wall's steady angular velocity (``angular_velocity``, default the wall's own)."""
    if motion is None:
        return
    if not isinstance(motion, (Oscillation, MotionTable, Servo)):
        raise ParameterError(f"wall {label} motion = {motion!r} is not allowed: must be a rollingdem.Oscillation, "
                             "MotionTable or Servo (or None)")
    if not motion.turns:
        return
    if wall.spin_axis_name is not None:
        what = "an oscillation" if isinstance(motion, Oscillation) else "a motion table"
        raise ParameterError(f"wall {label} motion: {what} with an angle is not allowed for a "
                             f"{type(wall).__name__.lower()} (it moves only by translation; its angular_velocity "
                             "turns its surface in itself): turn a MeshWall")
    w = np.asarray(wall.angular_velocity if angular_velocity is None else angular_velocity, dtype=float)
    u = np.asarray(motion.axis)
    if np.linalg.norm(w - (w @ u) * u) > 1e-12 * max(np.linalg.norm(w), 1e-300):
        raise ParameterError(f"wall {label} motion axis = {list(motion.axis)} is not allowed: the wall turns steadily "
                             f"about {list(w)}; a program may turn it only about that axis")


def motion_row(wall, point) -> np.ndarray:
    """A fresh motion row (``engine.layout.MESH_MOTION``) for a wall starting its motion at ``point``:
    its steady velocity and angular velocity, its program's parameters (table rows filled in by the
    caller), the step's velocity as the steady one."""
    row = np.zeros(MESH_MOTION_SIZE)
    row[[MO.vx, MO.vy, MO.vz]] = wall.velocity
    row[[MO.wx, MO.wy, MO.wz]] = wall.angular_velocity
    row[[MO.px, MO.py, MO.pz]] = point
    row[[MO.tvx, MO.tvy, MO.tvz]] = wall.velocity
    row[[MO.twx, MO.twy, MO.twz]] = wall.angular_velocity
    row[[MO.ox, MO.oy, MO.oz]] = point
    if wall.motion is not None:
        row[MO.program] = wall.motion.kind
        wall.motion.fill(row)
    return row
