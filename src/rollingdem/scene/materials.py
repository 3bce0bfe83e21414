"""Materials and the pair mixing rules of docs/models.md §1.1.

:class:`Material`: the elastic constants and density of docs/models.md §1.1, and the material
properties the contact laws declare (``physics.contact.properties``: friction, rolling friction,
restitution, ...); :class:`MaterialTable`, the materials of a scene with the effective moduli E*
and G* of each pair and each declared property mixed by its declared rule (the mean for the
built-in ones) unless set for the pair (``set_pair``)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from rollingdem.errors import ParameterError, check_finite
from rollingdem.physics.contact import SubModel  # noqa: F401 (importing the laws registers what they read)
from rollingdem.physics.contact.properties import (MATERIAL_PROPERTIES, MaterialProperty, PairProperties,
                                                   PropertiesByName)


#: Young's modulus (Pa) below which a material is taken for a unit mistake and warned of: soft
#: hydrogel beads, the softest granular particles simulated, are some kPa and up
SOFTEST_MODULUS = 1e3

#: the material's own values: mixed into E* and G* (docs/models.md §1.1), not by a declared rule,
#: or not mixed at all; declared as the laws' properties are, for the checks and the schema
YOUNGS_MODULUS = MaterialProperty("youngs_modulus", "Pa", None, "Young's modulus E", low_open=True)
POISSON_RATIO = MaterialProperty("poisson_ratio", "-", None, "Poisson's ratio nu", low=-1.0, high=0.5,
                                 low_open=True, high_open=True)
DENSITY = MaterialProperty("density", "kg/m^3", None, "density rho of the solid", low_open=True)
COARSE_GRAINING = MaterialProperty(
    "coarse_graining", "-", 1.0, "coarse-graining factor alpha: each sphere is a parcel alpha times the radius "
    "given, with the mass of alpha^3 real particles (docs/models.md §18); 1 is none", low=1.0)
OWN_PROPERTIES = {p.name: p for p in (YOUNGS_MODULUS, POISSON_RATIO, DENSITY, COARSE_GRAINING)}
OWN_FIELDS = ("name", *OWN_PROPERTIES)


def _unknown_property(owner: str, key: str) -> ParameterError:
    known = ", ".join(OWN_FIELDS[1:] + tuple(MATERIAL_PROPERTIES))
    return ParameterError(f"{owner}{key} is not a material property: allowed are {known} (a contact law declares "
                          "the properties it reads)")


class Material(PropertiesByName):
    """A particle or wall material.

    Parameters
    ----------
    name: label used to refer to the material.
    youngs_modulus: E (Pa), > 0.
    poisson_ratio: nu, in (-1, 0.5).
    density: rho (kg/m^3), > 0.
    coarse_graining: alpha (-), >= 1 (default 1: none): each sphere of this material is a parcel of
        alpha times the radius given, with the mass of alpha^3 real particles, and the contact laws'
        dimensional parameters scaled so that the bulk behaves as the real material
        (docs/models.md §18). Every other value stays the real material's.
    **properties: the material properties the contact laws read, by keyword, each within its
        declared bounds, unset ones at their declared default (``rollingdem schema`` lists them):
        friction mu (-, default 0.5), rolling_friction mu_r = tan(beta) (-, 0; beta the steepest
        slope on which a sphere rests, seed report eq. 1), restitution e (in (0, 1], 0.5),
        rolling_damping eta_r (-, 0; seed report eq. 10), surface_energy w (J/m^2, 0; the ``jkr``
        law's work of adhesion, pull-off force 3/2 pi w R*), cohesion_energy_density k_c (J/m^3,
        0; the ``sjkr`` law's F = k_c A), and any a user's law declares.

    Immutable; ``replace`` gives a copy with values changed.
    """

    __slots__ = ("name", "youngs_modulus", "poisson_ratio", "density", "coarse_graining", "properties")

    def __init__(self, name: str, youngs_modulus: float, poisson_ratio: float, density: float, *,
                 coarse_graining: float = 1.0, **properties: float):
        if not isinstance(name, str) or not name:
            raise ParameterError(f"material name = {name!r} is not allowed: must be a non-empty string")
        p = f"material {name!r}: "
        own = {"name": name, "youngs_modulus": YOUNGS_MODULUS.check(youngs_modulus, p)}
        if own["youngs_modulus"] < SOFTEST_MODULUS:
            warnings.warn(f"{p}youngs_modulus = {own['youngs_modulus']:g} Pa is below {SOFTEST_MODULUS:g} Pa, softer "
                          "than soft hydrogel beads: a value meant in MPa? The run goes on with it (and a time step "
                          "to match)", RuntimeWarning, stacklevel=2)
        own["poisson_ratio"] = POISSON_RATIO.check(poisson_ratio, p)
        own["density"] = DENSITY.check(density, p)
        for key in properties:
            if key not in MATERIAL_PROPERTIES:
                raise _unknown_property(p, key)
        values = {key: prop.check(properties[key], p) if key in properties else prop.default
                  for key, prop in MATERIAL_PROPERTIES.items()}
        alpha = check_finite(p + "coarse_graining", coarse_graining)
        if alpha < 1.0:
            raise ParameterError(f"{p}coarse_graining = {alpha:g} is not allowed: must be >= 1 (a parcel is alpha times "
                                 "the real particle's radius; 1 is no coarse graining)")
        own["coarse_graining"] = alpha
        for key, value in own.items():
            object.__setattr__(self, key, value)
        object.__setattr__(self, "properties", values)

    def __setattr__(self, key, value):
        raise AttributeError(f"Material is immutable: use material.replace({key}=...)")

    def to_dict(self) -> dict:
        """Every value by keyword: ``Material(**m.to_dict())`` is ``m``."""
        own = {key: getattr(self, key) for key in OWN_FIELDS}
        alpha = own.pop("coarse_graining")
        return {**own, **self.properties, "coarse_graining": alpha}

    def replace(self, **changes) -> "Material":
        """A copy with ``changes`` (checked as a new material's)."""
        return Material(**{**self.to_dict(), **changes})

    def __eq__(self, other):
        return type(other) is Material and self.to_dict() == other.to_dict()

    def __hash__(self):
        return hash(tuple(self.to_dict().items()))

    def __repr__(self):
        return "Material(" + ", ".join(f"{k}={v!r}" for k, v in self.to_dict().items()) + ")"

    def __reduce__(self):
        return _material_from_dict, (self.to_dict(),)

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


def _material_from_dict(values: dict) -> Material:
    return Material(**values)


def effective_youngs_modulus(a: Material, b: Material) -> float:
    return 1.0 / ((1.0 - a.poisson_ratio ** 2) / a.youngs_modulus + (1.0 - b.poisson_ratio ** 2) / b.youngs_modulus)


def effective_shear_modulus(a: Material, b: Material) -> float:
    inv = (2.0 * (2.0 - a.poisson_ratio) * (1.0 + a.poisson_ratio) / a.youngs_modulus
           + 2.0 * (2.0 - b.poisson_ratio) * (1.0 + b.poisson_ratio) / b.youngs_modulus)
    return 1.0 / inv


@dataclass
class MaterialTable:
    """The materials of a scene and their per-pair overrides."""

    materials: list[Material] = field(default_factory=list)
    overrides: dict[tuple[int, int], dict[str, float]] = field(default_factory=dict)

    def add(self, material: Material, contact=None) -> int:
        """Add ``material`` (once; the same again gives its index); with ``contact`` (the scene's
        ``ContactModel``) a coarse-graining factor its sub-models have no rule for is refused."""
        if not isinstance(material, Material):
            raise ParameterError(f"material = {material!r} is not allowed: must be a rollingdem.Material")
        if contact is not None:
            contact.check_coarse_graining(material.coarse_graining)
        for k, m in enumerate(self.materials):
            if m.name == material.name:
                if m == material:
                    return k
                raise ParameterError(f"material name = {material.name!r} is already used by a different material")
        for m in self.materials:
            if 1.0 != m.coarse_graining != material.coarse_graining != 1.0:
                raise ParameterError(f"material {material.name!r}: coarse_graining = {material.coarse_graining:g} is not "
                                     f"allowed beside material {m.name!r}'s {m.coarse_graining:g}: one coarse-graining "
                                     "factor per scene (materials without coarse graining, as walls', take 1)")
        self.materials.append(material)
        return len(self.materials) - 1

    def replace(self, material: Material) -> bool:
        """Replace the material of the same name by ``material`` (e.g. between the stages of a run):
        its contact properties (stiffness, friction, rolling friction, restitution, cohesion) act
        from the next step; its density and coarse-graining factor must stay, as the particles'
        masses were made with them. Stored contact springs are capped by the new limits at their
        next step. Returns whether anything changed."""
        if not isinstance(material, Material):
            raise ParameterError(f"material = {material!r} is not allowed: must be a rollingdem.Material")
        k = self.index(material.name)
        old = self.materials[k]
        for key in ("density", "coarse_graining"):
            if getattr(material, key) != getattr(old, key):
                raise ParameterError(f"material {material.name!r}: {key} = {getattr(material, key):g} is not allowed: "
                                     f"it is {getattr(old, key):g}, and the particles' masses were made with it; only "
                                     "its contact properties may change")
        self.materials[k] = material
        return material != old

    def index(self, material: Material | str | int) -> int:
        if isinstance(material, Material):
            return self.add(material)
        if isinstance(material, (int,)) and not isinstance(material, bool):
            if 0 <= material < len(self.materials):
                return int(material)
            raise ParameterError(f"material = {material} is not allowed: index must be in [0, {len(self.materials) - 1}]")
        for k, m in enumerate(self.materials):
            if m.name == material:
                return k
        known = ", ".join(repr(m.name) for m in self.materials) or "none yet"
        raise ParameterError(f"material = {material!r} is not known: known materials are {known}")

    def __len__(self) -> int:
        return len(self.materials)

    def __getitem__(self, key) -> Material:
        return self.materials[self.index(key)]

    def set_pair(self, a, b, **coefficients: float) -> None:
        """Override mixed coefficients for the pair (a, b), e.g. ``set_pair("glass", "steel", friction=0.3)``."""
        ia, ib = self.index(a), self.index(b)
        checked = {}
        for key, value in coefficients.items():
            if key not in MATERIAL_PROPERTIES:
                raise ParameterError(f"pair coefficient {key!r} is not known: allowed are {', '.join(MATERIAL_PROPERTIES)}")
            checked[key] = MATERIAL_PROPERTIES[key].check(value, f"pair ({self.materials[ia].name!r}, "
                                                                 f"{self.materials[ib].name!r}): ")
        key = (min(ia, ib), max(ia, ib))
        self.overrides.setdefault(key, {}).update(checked)

    def pair(self, i: int, j: int) -> PairProperties:
        a, b = self.materials[i], self.materials[j]
        # a material made before a law declared a property has its default
        mixed = {key: prop.mix(a.properties.get(key, prop.default), b.properties.get(key, prop.default))
                 for key, prop in MATERIAL_PROPERTIES.items()}
        mixed.update(self.overrides.get((min(i, j), max(i, j)), {}))
        # a parcel meets a wall, or a real sphere, as a parcel: the pair takes the larger factor
        return PairProperties(effective_youngs_modulus(a, b), effective_shear_modulus(a, b), mixed,
                              coarse_graining=max(a.coarse_graining, b.coarse_graining))

    def pairs(self) -> list[list[PairProperties]]:
        """``pair(a, b)`` of every pair of materials, as rows: what ``ContactModel.pair_table`` takes."""
        n = len(self.materials)
        return [[self.pair(a, b) for b in range(n)] for a in range(n)]

    def to_dict(self) -> dict:
        return {
            "materials": [m.to_dict() for m in self.materials],
            "overrides": [[i, j, dict(v)] for (i, j), v in self.overrides.items()],
        }

    @classmethod
    def from_dict(cls, data: dict) -> "MaterialTable":
        table = cls()
        table.load(data)
        return table

    def coarse_graining_factors(self) -> np.ndarray:
        """alpha of each material, by material index."""
        return np.array([m.coarse_graining for m in self.materials] or [1.0])

    def load(self, data: dict) -> None:
        """The materials and overrides of ``data`` (``to_dict``) in place of this table's (a restored
        checkpoint: the scene's collections keep this table)."""
        self.materials[:] = [Material(**m) for m in data["materials"]]
        self.overrides.clear()
        for i, j, v in data["overrides"]:
            self.overrides[(int(i), int(j))] = dict(v)
