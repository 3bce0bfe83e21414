"""The stress of a periodic box, and a pressure control on its lengths: what a shear cell measures
(``rollingdem.LeesEdwards``; docs/measurements.md, ``box_stress``).

The box's stress is the contacts' virial and the kinetic stress about the shear's affine profile
over its volume (``rollingdem.analysis.rheology.box_stress``): Lees & Edwards' (1972) pressure
tensor, compressive positive. ``BoxServo`` holds a normal stress at a pressure P by scaling the
box's lengths between runs of steps, as LAMMPS's ``fix press/berendsen`` does with its box.
"""

from __future__ import annotations

import math

import numpy as np

from rollingdem.analysis.rheology import box_stress
from rollingdem.errors import Declared, ParameterError, check_positive
from rollingdem.io.measurements import Measurement

#: the largest relative change of a box length at one move of the servo
MAX_STRAIN_PER_MOVE = 2e-3


def box_volume(sim) -> float:
    """The volume of a box periodic along x, y and z (m^3)."""
    return math.prod(hi - lo for lo, hi in sim.periodic.values())


def gradient_axis(sim) -> str:
    """The sheared box's gradient axis; z in a box that is not sheared."""
    return sim.shear.lees_edwards.gradient if sim.shear.active else "z"


def stress_now(sim, contacts=None) -> np.ndarray:
    """The box's stress (Pa, compressive positive), the kinetic part about the shear's affine profile
    v_x = shear rate (g - g_mid) along the gradient g (at rest in a box that is not sheared)."""
    c = sim.contact_forces() if contacts is None else contacts
    x = sim.positions
    streaming = np.zeros_like(x)
    if sim.shear.active:
        g = "xyz".index(gradient_axis(sim))
        lo, hi = sim.periodic["xyz"[g]]
        streaming[:, 0] = sim.shear.shear_rate * (x[:, g] - 0.5 * (lo + hi))
    return box_stress(c["force"], c["branch"], sim.masses, sim.velocities, box_volume(sim), streaming)


def effective_modulus(sim) -> float:
    """E* = E / (2 (1 - nu^2)) of two spheres of the scene's stiffest material (Hertz)."""
    return max(m.youngs_modulus / (2.0 * (1.0 - m.poisson_ratio ** 2)) for m in sim.materials.materials)


class BoxServo:
    """Holds the mean normal stress along ``axes`` of a periodic box at ``pressure`` P (Pa) by moving
    its lengths between runs of steps (``Simulation.shear.set_length``, affine): each move scales
    them by 1 + g (sigma - P) / P, at most ``MAX_STRAIN_PER_MOVE``, with the gain g = ``gain``
    (P / E*)^(2/3) (a Hertz packing's stiffness under P is of order (E* / P)^(2/3) P)."""

    def __init__(self, pressure: float, axes: str, effective_modulus: float, gain: float = 0.5):
        self.pressure, self.axes = pressure, axes
        self.gain = gain * (pressure / effective_modulus) ** (2.0 / 3.0)

    def move(self, sim, sigma: np.ndarray) -> float:
        """Scale ``sim``'s box lengths towards P, its stress being ``sigma``; returns the mean normal
        stress along the axes that was read."""
        normal = float(np.mean([sigma["xyz".index(a), "xyz".index(a)] for a in self.axes]))
        strain = float(np.clip(self.gain * (normal - self.pressure) / self.pressure, -MAX_STRAIN_PER_MOVE,
                               MAX_STRAIN_PER_MOVE))
        for a in self.axes:
            lo, hi = sim.periodic[a]
            sim.shear.set_length(a, (hi - lo) * (1.0 + strain))
        return normal


class BoxStress(Measurement):
    """The stress of a box periodic along x, y and z, and its shear: ``pressure`` p = tr(sigma)/3,
    the ``normal_stress`` sigma_gg and the ``shear_stress`` tau = -sigma_xg on the shear plane
    (g the gradient axis of a sheared box, else z), the ``friction`` tau / sigma_gg, the
    ``solid_fraction`` (the spheres' volume over the box's), the ``inertial_number``
    I = shear rate d / sqrt(sigma_gg / rho) (d the spheres' mean diameter, rho their mean density)
    and the ``box_length`` along g. With ``pressure_control`` P it also holds the normal stress
    along ``axes`` (default: the gradient axis of a sheared box, else all three) at P, moving the
    box's lengths at each sample (``BoxServo``): sample often, some hundreds of times per unit of
    strain, for the lengths to follow the flow's dilatancy."""

    kind = "box_stress"
    INTERVAL = 1e-3
    QUANTITIES = {"pressure": "Pa", "normal_stress": "Pa", "shear_stress": "Pa", "friction": "1",
                  "solid_fraction": "1", "inertial_number": "1", "box_length": "m"}
    declared = {**Measurement.declared,
                "pressure_control": Declared("hold the normal stress along `axes` at this pressure by moving the "
                                             "box's lengths at each sample", "Pa", low=0.0, low_open=True),
                "axes": Declared("the axes whose lengths the pressure control moves (x, y, z; default the "
                                 "gradient axis of a sheared box, else xyz)", kind="text")}

    def __init__(self, name: str = "box_stress", pressure_control: float | None = None, axes: str | None = None,
                 interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        self.pressure_control = None if pressure_control is None else check_positive("pressure_control",
                                                                                     pressure_control, "Pa")
        if axes is not None and (not isinstance(axes, str) or not axes or set(axes) - set("xyz")
                                 or len(set(axes)) != len(axes)):
            raise ParameterError(f"axes = {axes!r} is not allowed: must be some of x, y, z, each once (e.g. 'z')")
        self.axes = axes
        self.servo = None

    def describe(self):
        control = f", holding {self.pressure_control:g} Pa along {self.axes or 'the gradient'}" \
            if self.pressure_control else ""
        return f"the periodic box's stress and shear{control}"

    def check(self, sim) -> None:
        if set(sim.periodic) != set("xyz"):
            raise ParameterError(f"box_stress {self.name!r} is not allowed: the box must be periodic along x, y and "
                                 f"z (it is along {', '.join(sim.periodic) or 'no axis'}), so that its volume holds "
                                 "every sphere and contact")

    def start(self, sim) -> None:
        super().start(sim)
        if self.pressure_control is not None and self.servo is None:
            axes = self.axes or (gradient_axis(sim) if sim.shear.active else "xyz")
            self.servo = BoxServo(self.pressure_control, axes, effective_modulus(sim))

    def observe(self, sim) -> None:
        sigma = stress_now(sim)
        self._record(sim, self._row(sim, sigma))
        if self.servo is not None:  # after the sample: it reads the stress the box had
            self.servo.move(sim, sigma)

    def values(self, sim):
        return self._row(sim, stress_now(sim))

    def _row(self, sim, sigma: np.ndarray) -> list[float]:
        g = "xyz".index(gradient_axis(sim))
        normal, tau = float(sigma[g, g]), float(-sigma[0, g])
        r = sim.radii
        solid = float(np.sum(4.0 / 3.0 * math.pi * r ** 3))
        density = float(np.sum(sim.masses)) / solid if solid > 0.0 else math.nan
        rate = sim.shear.shear_rate if sim.shear.active else 0.0
        inertial = rate * 2.0 * float(np.mean(r)) / math.sqrt(normal / density) if normal > 0.0 else math.nan
        lo, hi = sim.periodic["xyz"[g]]
        return [float(np.trace(sigma)) / 3.0, normal, tau, tau / normal if normal > 0.0 else math.nan,
                solid / box_volume(sim), inertial, hi - lo]
