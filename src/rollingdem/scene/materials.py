"""Materials and the pair mixing rules of docs/models.md §1.1.

:class:`Material`; :class:`MaterialTable`, the materials of a scene with the effective moduli E*
and G* of each pair and its coefficients (friction, rolling friction, restitution, rolling
damping, surface energy, cohesion energy density): the mean of the two materials' values unless set for the pair (``set_pair``)."""

from __future__ import annotations

import numpy as np

from dataclasses import dataclass, field, fields, replace

from rollingdem.errors import ParameterError, check_finite, check_non_negative, check_positive, check_range


#: Young's modulus (Pa) below which a material is taken for a unit mistake and warned of: soft
#: hydrogel beads, the softest granular particles simulated, are some kPa and up
SOFTEST_MODULUS = 1e3


@dataclass(frozen=True)
class Material:
    """A particle or wall material.

    Parameters
    ----------
    name: label used to refer to the material.
    youngs_modulus: E (Pa), > 0.
    poisson_ratio: nu, in (-1, 0.5).
    density: rho (kg/m^3), > 0.
    friction: sliding friction coefficient mu (-), >= 0.
    rolling_friction: rolling friction coefficient mu_r (-), >= 0; mu_r = tan(beta), beta the
        steepest slope on which a sphere rests (seed report eq. 1).
    restitution: coefficient of restitution e, in (0, 1].
    rolling_damping: rolling viscous damping ratio eta_r (-), >= 0 (seed report eq. 10).
    surface_energy: w (J/m^2), >= 0: the work of adhesion per unit area that the ``jkr`` cohesion
        law takes (pull-off force 3/2 pi w R*; LAMMPS's ``jkr`` gamma is w / 2).
    cohesion_energy_density: k_c (J/m^3), >= 0: the ``sjkr`` cohesion law's F = k_c A (LIGGGHTS's
        ``cohesionEnergyDensity``).
    coarse_graining: alpha (-), >= 1 (default 1: none): each sphere of this material is a parcel of
        alpha times the radius given, with the mass of alpha^3 real particles, and the contact laws'
        dimensional parameters scaled so that the bulk behaves as the real material
        (docs/models.md §18). Every other value stays the real material's.
    """

    name: str
    youngs_modulus: float
    poisson_ratio: float
    density: float
    friction: float = 0.5
    rolling_friction: float = 0.0
    restitution: float = 0.5
    rolling_damping: float = 0.0
    surface_energy: float = 0.0
    cohesion_energy_density: float = 0.0
    coarse_graining: float = 1.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"material name = {self.name!r} is not allowed: must be a non-empty string")
        p = f"material {self.name!r}: "
        object.__setattr__(self, "youngs_modulus", check_positive(p + "youngs_modulus", self.youngs_modulus, "Pa"))
        if self.youngs_modulus < SOFTEST_MODULUS:
            import warnings

            warnings.warn(f"{p}youngs_modulus = {self.youngs_modulus:g} Pa is below {SOFTEST_MODULUS:g} Pa, softer than "
                          "soft hydrogel beads: a value meant in MPa? The run goes on with it (and a time step to "
                          "match)", RuntimeWarning, stacklevel=3)
        object.__setattr__(self, "poisson_ratio", check_range(p + "poisson_ratio", self.poisson_ratio, -1.0, 0.5,
                                                              low_open=True, high_open=True))
        object.__setattr__(self, "density", check_positive(p + "density", self.density, "kg/m^3"))
        object.__setattr__(self, "friction", check_non_negative(p + "friction", self.friction))
        object.__setattr__(self, "rolling_friction", check_non_negative(p + "rolling_friction", self.rolling_friction))
        object.__setattr__(self, "restitution", check_range(p + "restitution", self.restitution, 0.0, 1.0,
                                                            low_open=True))
        object.__setattr__(self, "rolling_damping", check_non_negative(p + "rolling_damping", self.rolling_damping))
        object.__setattr__(self, "surface_energy", check_non_negative(p + "surface_energy", self.surface_energy, "J/m^2"))
        object.__setattr__(self, "cohesion_energy_density",
                           check_non_negative(p + "cohesion_energy_density", self.cohesion_energy_density, "J/m^3"))
        alpha = check_finite(p + "coarse_graining", self.coarse_graining)
        if alpha < 1.0:
            raise ParameterError(f"{p}coarse_graining = {alpha:g} is not allowed: must be >= 1 (a parcel is alpha times "
                                 "the real particle's radius; 1 is no coarse graining)")
        object.__setattr__(self, "coarse_graining", alpha)

    @property
    def shear_modulus(self) -> float:
        """G = E / (2 (1 + nu)) (Pa)."""
        return self.youngs_modulus / (2.0 * (1.0 + self.poisson_ratio))


PAIR_COEFFICIENTS = ("friction", "rolling_friction", "restitution", "rolling_damping", "surface_energy",
                     "cohesion_energy_density")


@dataclass(frozen=True)
class PairProperties:
    """Mixed properties of one material pair, as the contact sub-models see them."""

    effective_youngs_modulus: float  # E* (Pa)
    effective_shear_modulus: float   # G* (Pa)
    friction: float
    rolling_friction: float
    restitution: float
    rolling_damping: float
    surface_energy: float = 0.0
    cohesion_energy_density: float = 0.0
    coarse_graining: float = 1.0     # alpha of the parcels in contact (docs/models.md §18)


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
            if key not in PAIR_COEFFICIENTS:
                raise ParameterError(f"pair coefficient {key!r} is not known: allowed are {', '.join(PAIR_COEFFICIENTS)}")
            probe = replace(self.materials[ia], **{key: value})  # reuses the Material checks
            checked[key] = getattr(probe, key)
        key = (min(ia, ib), max(ia, ib))
        self.overrides.setdefault(key, {}).update(checked)

    def pair(self, i: int, j: int) -> PairProperties:
        a, b = self.materials[i], self.materials[j]
        coeffs = {c: 0.5 * (getattr(a, c) + getattr(b, c)) for c in PAIR_COEFFICIENTS}
        coeffs.update(self.overrides.get((min(i, j), max(i, j)), {}))
        # a parcel meets a wall, or a real sphere, as a parcel: the pair takes the larger factor
        return PairProperties(effective_youngs_modulus(a, b), effective_shear_modulus(a, b), **coeffs,
                              coarse_graining=max(a.coarse_graining, b.coarse_graining))

    def pairs(self) -> list[list[PairProperties]]:
        """``pair(a, b)`` of every pair of materials, as rows: what ``ContactModel.pair_table`` takes."""
        n = len(self.materials)
        return [[self.pair(a, b) for b in range(n)] for a in range(n)]

    def to_dict(self) -> dict:
        return {
            "materials": [{f.name: getattr(m, f.name) for f in fields(m)} for m in self.materials],
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
