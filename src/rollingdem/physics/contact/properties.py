"""Material properties the contact laws read: each declared once, beside the sub-model that reads
it, with its unit, its bounds, its default and how a pair of materials mixes it.

A sub-model lists what it reads in ``material_properties`` (``MaterialProperty`` instances);
defining the class registers them here (``MATERIAL_PROPERTIES``), so that ``Material`` takes
them as keywords, checks them against the declared bounds, and the material table mixes them
per pair by the declared rule (``MIXING_RULES``). Several sub-models may read one property: they
share the one declaration. The elastic constants and the density are the material's own
(``Material``) and mixed into E* and G* by the Hertz rules (docs/models.md §1.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rollingdem.errors import ParameterError, check_finite


def arithmetic_mean(a: float, b: float) -> float:
    """(a + b) / 2."""
    return 0.5 * (a + b)


def geometric_mean(a: float, b: float) -> float:
    """sqrt(a b) (LAMMPS GRANULAR's ``mix_geom``; 0 when either is 0)."""
    return math.sqrt(a * b)


def harmonic_mean(a: float, b: float) -> float:
    """2 a b / (a + b), as two springs in series give twice their stiffness (0 when either is 0)."""
    return 0.0 if a == 0.0 or b == 0.0 else 2.0 * a * b / (a + b)


#: mixing rule name -> f(value of material a, value of material b)
MIXING_RULES = {"mean": arithmetic_mean, "geometric": geometric_mean, "harmonic": harmonic_mean, "max": max,
                "min": min}


@dataclass(frozen=True)
class MaterialProperty:
    """One material property a contact law reads.

    name: the keyword of ``Material`` and of a case file's material entry; unit: SI, "-" for a
    ratio; default: the value of a material that does not give it (None: it must be given); low, high: the allowed
    interval (None: unbounded), each end closed unless ``low_open``/``high_open``; mixing: the
    pair's value from the two materials' (a name in ``MIXING_RULES``); description: one line for
    the case-file schema.
    """

    name: str
    unit: str
    default: float | None
    description: str
    low: float | None = 0.0
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    mixing: str = "mean"

    def __post_init__(self):
        if self.mixing not in MIXING_RULES:
            raise TypeError(f"material property {self.name!r}: mixing = {self.mixing!r} is not known: allowed are "
                            f"{', '.join(MIXING_RULES)}")

    def check(self, value, owner: str = "") -> float:
        """``value`` as a float within the declared bounds, or one line naming it (``owner``: a
        prefix such as "material 'glass': ")."""
        x = check_finite(owner + self.name, value)
        low_bad = self.low is not None and (x <= self.low if self.low_open else x < self.low)
        high_bad = self.high is not None and (x >= self.high if self.high_open else x > self.high)
        if low_bad or high_bad:
            raise ParameterError(f"{owner}{self.name} = {x:g} is not allowed: must {self.allowed()}")
        return x

    def allowed(self) -> str:
        """The bounds in words: "be >= 0 (J/m^2)", "lie in (0, 1]"."""
        unit = "" if self.unit == "-" else f" ({self.unit})"
        if self.high is None:
            return f"be {'>' if self.low_open else '>='} {self.low:g}{unit}" if self.low is not None else "be finite"
        if self.low is None:
            return f"be {'<' if self.high_open else '<='} {self.high:g}{unit}"
        return (f"lie in {'(' if self.low_open else '['}{self.low:g}, {self.high:g}"
                f"{')' if self.high_open else ']'}{unit}")

    def mix(self, a: float, b: float) -> float:
        """The value of a pair of materials with values ``a`` and ``b``."""
        return MIXING_RULES[self.mixing](a, b)


class PropertiesByName:
    """Read the values of ``self.properties`` as attributes (``pair.friction``); reached only for a
    name that is no slot of the class."""

    __slots__ = ()

    def __getattr__(self, key):
        if key != "properties":
            try:
                return self.properties[key]
            except KeyError:
                pass
        raise AttributeError(f"{type(self).__name__} has no property {key!r}")


class PairProperties(PropertiesByName):
    """The mixed properties of one material pair, as the contact sub-models see them: E* and G*
    (Pa), the coarse-graining factor alpha of the parcels in contact (docs/models.md §18), and
    each declared material property by name (``pair.friction``)."""

    __slots__ = ("effective_youngs_modulus", "effective_shear_modulus", "coarse_graining", "properties")

    def __init__(self, effective_youngs_modulus: float, effective_shear_modulus: float, properties: dict,
                 coarse_graining: float = 1.0):
        self.effective_youngs_modulus = effective_youngs_modulus
        self.effective_shear_modulus = effective_shear_modulus
        self.coarse_graining = coarse_graining
        self.properties = dict(properties)

    def __repr__(self):
        return (f"PairProperties(E*={self.effective_youngs_modulus:g}, G*={self.effective_shear_modulus:g}, "
                f"alpha={self.coarse_graining:g}, {self.properties})")

#: name -> declaration, of every registered sub-model's properties, in the order declared
MATERIAL_PROPERTIES: dict[str, MaterialProperty] = {}


def declare(owner: str, properties) -> None:
    """Register the ``properties`` a sub-model (``owner``, for the message) reads; a name declared
    before must be declared the same."""
    for prop in properties:
        if not isinstance(prop, MaterialProperty):
            raise TypeError(f"{owner}.material_properties: {prop!r} is not a MaterialProperty")
        known = MATERIAL_PROPERTIES.setdefault(prop.name, prop)
        if known != prop:
            raise TypeError(f"{owner}: material property {prop.name!r} is declared differently by another "
                            f"sub-model ({known}); read the same declaration")


FRICTION = MaterialProperty("friction", "-", 0.5, "sliding friction coefficient mu (Coulomb limit mu F_n)")
ROLLING_FRICTION = MaterialProperty(
    "rolling_friction", "-", 0.0, "rolling friction coefficient mu_r = tan(beta), beta the steepest slope on "
    "which a sphere rests (seed report eq. 1)")
RESTITUTION = MaterialProperty("restitution", "-", 0.5, "coefficient of restitution e of a normal impact",
                               low_open=True, high=1.0)
ROLLING_DAMPING = MaterialProperty("rolling_damping", "-", 0.0,
                                   "rolling viscous damping ratio eta_r (seed report eq. 10)")
SURFACE_ENERGY = MaterialProperty(
    "surface_energy", "J/m^2", 0.0, "work of adhesion per unit area w of the jkr cohesion law (pull-off force "
    "3/2 pi w R*; LAMMPS's jkr gamma is w / 2)")
COHESION_ENERGY_DENSITY = MaterialProperty(
    "cohesion_energy_density", "J/m^3", 0.0, "k_c of the sjkr cohesion law F = k_c A (LIGGGHTS's "
    "cohesionEnergyDensity)")
