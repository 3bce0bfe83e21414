"""Sphere-size distributions: the radii an insertion or an inflow draws (constant, uniform,
normal, discrete by number, by mass fraction, a sieve curve, and coarse-grained parcels of any
of them).

    sim.insert(region, 500, Uniform(0.004, 0.005), "glass", seed=3)

How each is drawn and what a realised distribution reports: docs/studies.md."""

from __future__ import annotations

import math

import numpy as np

from rollingdem.errors import Declared, ParameterError, check_non_negative, check_positive


def _fmt(x: float) -> str:
    return f"{x:g}"


class SizeDistribution:
    """Base class of radius distributions; ``sample(rng, n)`` gives n radii (m)."""

    max_radius: float
    min_radius: float

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        raise NotImplementedError


class Constant(SizeDistribution):
    """All spheres of the same ``radius`` (m); what a plain number means."""

    def __init__(self, radius):
        self.radius = check_positive("radius", radius, "m")
        self.max_radius = self.min_radius = self.radius

    def sample(self, rng, n):
        return np.full(int(n), self.radius)

    def __repr__(self) -> str:
        return f"Constant({_fmt(self.radius)})"


class Uniform(SizeDistribution):
    """Radius uniform in [low, high] (m)."""

    declared = {"low": Declared("smallest radius", "m", low=0.0, low_open=True),
                "high": Declared("largest radius", "m", low=0.0, low_open=True)}

    def __init__(self, low, high):
        self.low = check_positive("Uniform low", low, "m")
        self.high = check_positive("Uniform high", high, "m")
        if self.low > self.high:
            raise ParameterError(f"Uniform low = {_fmt(self.low)} is not allowed: must be <= high "
                                 f"= {_fmt(self.high)} (m)")
        self.max_radius = self.high
        self.min_radius = self.low

    def sample(self, rng, n):
        return rng.uniform(self.low, self.high, int(n))

    def __repr__(self) -> str:
        return f"Uniform({_fmt(self.low)}, {_fmt(self.high)})"


class Normal(SizeDistribution):
    """Normal radius distribution (m) truncated to [low, high] by resampling.

    ``low`` defaults to max(mean - 3 std, 0) and ``high`` to mean + 3 std; radii are always > 0.
    """

    declared = {"mean": Declared("mean radius", "m", low=0.0, low_open=True),
                "std": Declared("standard deviation of the radius", "m", low=0.0),
                "low": Declared("smallest radius (default max(mean - 3 std, 0))", "m", low=0.0, low_open=True),
                "high": Declared("largest radius (default mean + 3 std)", "m", low=0.0, low_open=True)}

    def __init__(self, mean, std, low=None, high=None):
        self.mean = check_positive("Normal mean", mean, "m")
        self.std = check_non_negative("Normal std", std, "m")
        self.low = (max(self.mean - 3.0 * self.std, 0.0) if low is None
                    else check_positive("Normal low", low, "m"))
        self.high = self.mean + 3.0 * self.std if high is None else check_positive("Normal high", high, "m")
        if self.low > self.high:
            raise ParameterError(f"Normal low = {_fmt(self.low)} is not allowed: must be <= high "
                                 f"= {_fmt(self.high)} (m)")
        if self.std == 0.0:
            if not self.low <= self.mean <= self.high:
                raise ParameterError(f"Normal mean = {_fmt(self.mean)} with std = 0 is not allowed: must lie in "
                                     f"[low, high] = [{_fmt(self.low)}, {_fmt(self.high)}] (m)")
            self._p = 1.0
        else:
            a = (self.low - self.mean) / (self.std * math.sqrt(2.0))
            b = (self.high - self.mean) / (self.std * math.sqrt(2.0))
            self._p = 0.5 * (math.erf(b) - math.erf(a))
            if self._p < 1e-4:
                raise ParameterError(f"Normal [low, high] = [{_fmt(self.low)}, {_fmt(self.high)}] is not allowed: it "
                                     f"lies too far in the tail of mean = {_fmt(self.mean)}, std = {_fmt(self.std)} "
                                     f"(probability {self._p:.2g} < 1e-4)")
        self.max_radius = self.high
        self.min_radius = self.low

    def sample(self, rng, n):
        n = int(n)
        if self.std == 0.0:
            return np.full(n, self.mean)
        out = np.empty(0)
        while out.size < n:
            need = n - out.size
            draw = rng.normal(self.mean, self.std, int(need / self._p * 1.1) + 16)
            keep = draw[(draw >= self.low) & (draw <= self.high) & (draw > 0.0)]
            out = np.concatenate([out, keep[:need]])
        return out

    def __repr__(self) -> str:
        return f"Normal({_fmt(self.mean)}, {_fmt(self.std)}, low={_fmt(self.low)}, high={_fmt(self.high)})"


class Discrete(SizeDistribution):
    """Radii drawn from ``values`` (m) with relative ``weights`` (default: equal)."""

    declared = {"values": Declared("the radii", "m", "numbers"),
                "weights": Declared("relative weight of each radius in number (default: equal)", "-", "numbers")}

    def __init__(self, values, weights=None):
        try:
            vals = [float(v) for v in values]
        except (TypeError, ValueError):
            raise ParameterError(f"Discrete values = {values!r} is not allowed: must be a sequence of radii") from None
        if not vals:
            raise ParameterError("Discrete values = [] is not allowed: need at least one radius")
        for k, v in enumerate(vals):
            check_positive(f"Discrete values[{k}]", v, "m")
        if weights is None:
            w = [1.0] * len(vals)
        else:
            try:
                w = [float(v) for v in weights]
            except (TypeError, ValueError):
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: must be numbers") from None
            if len(w) != len(vals):
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: need one per value "
                                     f"({len(vals)}), got {len(w)}")
            for k, v in enumerate(w):
                check_non_negative(f"Discrete weights[{k}]", v)
            if sum(w) <= 0.0:
                raise ParameterError(f"Discrete weights = {weights!r} is not allowed: must have a positive sum")
        self.values = np.array(vals)
        self.weights = np.array(w) / sum(w)
        self.max_radius = float(self.values[self.weights > 0].max())
        self.min_radius = float(self.values[self.weights > 0].min())

    def sample(self, rng, n):
        return rng.choice(self.values, size=int(n), p=self.weights)

    def __repr__(self) -> str:
        return f"Discrete({self.values.tolist()}, weights={self.weights.tolist()})"


class MassFractions(Discrete):
    """Radii ``radii`` (m) making up the given ``fractions`` of the mass (a bulk solid's size classes):
    each drawn with the number weight f_k / r_k^3 (so N_k m_k is in proportion to f_k). The realised
    mass fractions are ``realised(radii)``."""

    declared = {"radii": Declared("the radius of each size class", "m", "numbers"),
                "fractions": Declared("the fraction of the mass each class makes up", "-", "numbers")}

    def __init__(self, radii, fractions):
        super().__init__(radii, fractions)
        self.fractions = self.weights.copy()
        number = self.fractions / self.values ** 3
        self.weights = number / number.sum()
        self.classes = [(float(v), float(v)) for v in self.values]

    def class_volumes(self, radii) -> np.ndarray:
        """The volume (m^3) of ``radii``'s spheres of each radius."""
        r = np.asarray(radii, dtype=float)
        return np.array([4.0 / 3.0 * math.pi * np.sum(r[np.isclose(r, v, rtol=1e-12, atol=0.0)] ** 3)
                         for v in self.values])

    def realised(self, radii) -> np.ndarray:
        """The mass fraction of each radius among ``radii`` (equal density)."""
        volume = self.class_volumes(radii)
        return volume / max(float(volume.sum()), 1e-300)

    asked = property(lambda self: self.fractions)

    def __repr__(self) -> str:
        return f"MassFractions({self.values.tolist()}, {self.fractions.tolist()})"


class SieveCurve(SizeDistribution):
    """A grading curve: the mass fraction ``passing`` (0 to 1, not decreasing, from 0 to 1) at each of
    the sieve ``diameters`` (m, increasing), as a sieve analysis gives it. Between two sieves the
    passing fraction is taken linear in the diameter: a constant mass per unit of diameter, so a
    number density c / d^3, drawn by inverting its distribution; the class takes the number share
    (P_k+1 - P_k) / (d_k+1 - d_k) (d_k^-2 - d_k+1^-2) / 2 (up to a common factor), which gives it
    the mass share P_k+1 - P_k. ``realised(radii)``: the mass fraction in each class."""

    declared = {"diameters": Declared("the sieves' openings, increasing", "m", "numbers"),
                "passing": Declared("the mass fraction passing each sieve, from 0 to 1, not decreasing", "-",
                                    "numbers")}

    def __init__(self, diameters, passing):
        try:
            d = np.asarray(diameters, dtype=float).reshape(-1)
            p = np.asarray(passing, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ParameterError(f"SieveCurve diameters = {diameters!r}, passing = {passing!r} is not allowed: must "
                                 "be numbers") from None
        if len(d) < 2 or len(p) != len(d):
            raise ParameterError(f"SieveCurve passing = {p.tolist()} is not allowed: need one per diameter "
                                 f"({len(d)}), and at least two")
        if not (np.all(np.isfinite(d)) and d[0] > 0.0 and np.all(np.diff(d) > 0.0)):
            raise ParameterError(f"SieveCurve diameters = {d.tolist()} is not allowed: must be > 0 (m) and increasing")
        if not (np.all(np.isfinite(p)) and np.all(np.diff(p) >= 0.0) and p[0] == 0.0 and p[-1] == 1.0):
            raise ParameterError(f"SieveCurve passing = {p.tolist()} is not allowed: the fraction of the mass passing "
                                 "each sieve must not decrease, from 0 at the first to 1 at the last")
        self.diameters, self.passing = d, p
        self.mass_shares = np.diff(p)
        inv2 = 1.0 / d ** 2
        number = self.mass_shares / np.diff(d) * 0.5 * (inv2[:-1] - inv2[1:])
        self.number_shares = number / number.sum()
        self.min_radius = 0.5 * float(d[np.argmax(self.mass_shares > 0)])
        self.max_radius = 0.5 * float(d[len(self.mass_shares) - np.argmax(self.mass_shares[::-1] > 0)])
        self.classes = [(0.5 * float(a), 0.5 * float(b)) for a, b in zip(d[:-1], d[1:])]

    def sample(self, rng, n):
        n = int(n)
        k = rng.choice(len(self.number_shares), size=n, p=self.number_shares)
        u = rng.random(n)
        lo2, hi2 = self.diameters[k] ** -2.0, self.diameters[k + 1] ** -2.0
        return 0.5 / np.sqrt(lo2 - u * (lo2 - hi2))  # the inverse of F(d) = (d_k^-2 - d^-2) / (d_k^-2 - d_k+1^-2)

    def class_volumes(self, radii) -> np.ndarray:
        """The volume (m^3) of ``radii``'s spheres in each class between two sieves."""
        d = 2.0 * np.asarray(radii, dtype=float)
        k = np.clip(np.searchsorted(self.diameters, d, side="right") - 1, 0, len(self.mass_shares) - 1)
        return np.bincount(k, weights=math.pi / 6.0 * d ** 3, minlength=len(self.mass_shares))

    def realised(self, radii) -> np.ndarray:
        """The mass fraction of ``radii`` in each class between two sieves (equal density)."""
        volume = self.class_volumes(radii)
        return volume / max(float(volume.sum()), 1e-300)

    asked = property(lambda self: self.mass_shares)

    def __repr__(self) -> str:
        return f"SieveCurve({self.diameters.tolist()}, {self.passing.tolist()})"


class Parcels(SizeDistribution):
    """Coarse-grained parcels of the ``real`` particles' distribution: each radius ``alpha`` times one
    drawn from it, from the same random numbers (docs/models.md §18). A distribution by mass keeps its
    classes: ``realised`` and ``class_volumes`` take parcels' radii and answer for the real ones."""

    def __init__(self, real: SizeDistribution, alpha: float):
        self.real, self.alpha = real, float(alpha)
        self.min_radius, self.max_radius = self.alpha * real.min_radius, self.alpha * real.max_radius

    def sample(self, rng, n):
        return self.alpha * np.asarray(self.real.sample(rng, n), dtype=float)

    def __getattr__(self, name):
        if name in ("realised", "class_volumes"):  # only where the real distribution has them
            of_real = getattr(self.__dict__["real"], name)
            return lambda radii: of_real(np.asarray(radii, dtype=float) / self.alpha)
        if name == "asked":
            return self.__dict__["real"].asked
        raise AttributeError(name)

    def __repr__(self) -> str:
        return f"Parcels({self.real!r}, alpha={self.alpha:g})"


def parcels_of(radius, alpha: float) -> SizeDistribution:
    """The distribution of the spheres placed for ``radius`` (a number or a distribution, the real
    particles') of a material coarse-grained by ``alpha``."""
    real = as_distribution(radius)
    return real if alpha == 1.0 else Parcels(real, alpha)


def realised_line(distribution, radii) -> str:
    """The realised mass fraction of each class beside the one asked for, for a distribution by mass;
    for another, the radii's range and mean."""
    r = np.asarray(radii, dtype=float)
    if not len(r):
        return "no spheres"
    if hasattr(distribution, "realised"):
        return fractions_line(distribution.realised(r), distribution.asked)
    return f"radius {r.min():.4g}-{r.max():.4g} m, mean {r.mean():.4g} m"


def fractions_line(got, asked) -> str:
    return "mass fractions " + " ".join(f"{g:.3f}" for g in got) + " (asked " + " ".join(f"{a:.3f}" for a in asked) + ")"


def as_distribution(radius) -> SizeDistribution:
    """A ``SizeDistribution`` as is; a plain number as ``Constant``."""
    if isinstance(radius, SizeDistribution):
        return radius
    if isinstance(radius, (bool, np.bool_)):
        raise ParameterError(f"radius = {radius!r} is not allowed: must be a number (m) or a size distribution")
    try:
        float(radius)
    except (TypeError, ValueError):
        raise ParameterError(f"radius = {radius!r} is not allowed: must be a number (m) or a size distribution "
                             "(Uniform, Normal, Discrete, MassFractions, SieveCurve)") from None
    return Constant(radius)
