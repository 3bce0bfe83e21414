"""The material properties the contact laws declare (``physics/contact/properties.py``): each
mixing rule on values worked by hand, the declared bounds, and one declaration per name."""

import math

import pytest

from rollingdem.errors import ParameterError
from rollingdem.physics.contact.properties import MATERIAL_PROPERTIES, MIXING_RULES, MaterialProperty, declare


@pytest.mark.parametrize("rule,expected", [("mean", 2.5), ("geometric", 2.0), ("harmonic", 1.6), ("max", 4.0),
                                           ("min", 1.0)])
def test_each_mixing_rule_gives_its_pair_value(rule, expected):
    """Materials of 4 and 1: mean 5/2, geometric sqrt(4), harmonic 2*4*1/5, max, min (exact in
    binary but for the harmonic's 8/5)."""
    prop = MaterialProperty("stiffness_ratio", "-", 1.0, "a made-up ratio", mixing=rule)
    assert math.isclose(prop.mix(4.0, 1.0), expected, rel_tol=1e-15)
    assert math.isclose(prop.mix(1.0, 4.0), expected, rel_tol=1e-15)  # a pair has no order


def test_a_zero_gives_zero_under_the_products():
    """Two springs in series, one of zero stiffness, hold nothing: harmonic and geometric give 0."""
    assert MIXING_RULES["harmonic"](0.0, 3.0) == 0.0
    assert MIXING_RULES["geometric"](0.0, 3.0) == 0.0


def test_the_declared_bounds_refuse_in_one_line_naming_unit_and_interval():
    ratio = MaterialProperty("ratio", "-", 0.5, "a ratio", low=0.0, high=1.0, low_open=True)
    assert ratio.check(1.0) == 1.0
    with pytest.raises(ParameterError, match=r"^material 'm': ratio = 0 is not allowed: must lie in \(0, 1\]$"):
        ratio.check(0.0, "material 'm': ")
    energy = MaterialProperty("energy", "J/m^2", 0.0, "an energy")
    assert energy.check(0.0) == 0.0
    with pytest.raises(ParameterError, match=r"energy = -1 is not allowed: must be >= 0 \(J/m\^2\)$"):
        energy.check(-1.0)
    with pytest.raises(ParameterError, match="must be a number"):
        energy.check("1")


def test_a_name_is_declared_once():
    """A law that reads a built-in property reuses its declaration; one declared differently under the
    same name is refused when the class is defined, and an unknown mixing rule at once."""
    known = MATERIAL_PROPERTIES["friction"]
    declare("Reader", (known,))  # the same declaration: fine
    with pytest.raises(TypeError, match="declared differently"):
        declare("Rival", (MaterialProperty("friction", "-", 0.3, "another friction"),))
    assert MATERIAL_PROPERTIES["friction"] is known
    with pytest.raises(TypeError, match="mixing = 'median' is not known"):
        MaterialProperty("x", "-", 0.0, "x", mixing="median")
