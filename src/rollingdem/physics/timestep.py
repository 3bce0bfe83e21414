"""Time-step criteria (docs/models.md §2).

* Rayleigh time: dt_R = pi R_min sqrt(rho / G) / (0.1631 nu + 0.8766), G = E / (2 (1 + nu))
  (LIGGGHTS ``fix check/timestep/gran``).
* Hertz collision time: t_H = 2.87 (m*^2 / (R* E*^2 v_max))^(1/5).
* Linear springs: period 2 pi / omega, omega = sqrt(k / m_eff).

The project's rule: dt <= 0.2 dt_R, dt <= t_H / 20 and dt <= period / 10 for every linear spring.
"""

from __future__ import annotations

import math

from rollingdem.errors import check_positive, check_range

RAYLEIGH_FRACTION = 0.2
HERTZ_FRACTION = 1.0 / 20.0
SPRING_FRACTION = 1.0 / 10.0


def rayleigh_time_step(radius: float, density: float, youngs_modulus: float, poisson_ratio: float) -> float:
    """Rayleigh time dt_R (s) of the smallest sphere, radius (m), density (kg/m^3), E (Pa), nu."""
    radius = check_positive("radius", radius, "m")
    density = check_positive("density", density, "kg/m^3")
    youngs_modulus = check_positive("youngs_modulus", youngs_modulus, "Pa")
    nu = check_range("poisson_ratio", poisson_ratio, -1.0, 0.5, low_open=True, high_open=True)
    shear = youngs_modulus / (2.0 * (1.0 + nu))
    return math.pi * radius * math.sqrt(density / shear) / (0.1631 * nu + 0.8766)


def hertz_contact_time(effective_mass: float, effective_radius: float, effective_youngs_modulus: float,
                       impact_speed: float) -> float:
    """Hertz collision time t_H = 2.87 (m*^2 / (R* E*^2 v))^(1/5) (s)."""
    return 2.87 * (effective_mass ** 2 / (effective_radius * effective_youngs_modulus ** 2 * impact_speed)) ** 0.2


def spring_period(stiffness: float, effective_mass: float) -> float:
    """Undamped period 2 pi sqrt(m / k) (s) of a linear spring."""
    return 2.0 * math.pi * math.sqrt(effective_mass / stiffness)
