"""The case file's schema made from the objects' own declarations (``errors.Declared`` beside a
constructor, ``io.case_schema.spec_from``): a block takes the constructor's parameters, defaults
and declared description, unit and bounds, and nothing is written twice."""

import inspect
import json

import pytest
from pydantic import ValidationError
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem.cli import app
from rollingdem.errors import Declared
from rollingdem.io.case_schema import spec_from
from rollingdem.io.measurements import MassFlow, OutletTotals, Probe, WallLoad
from rollingdem.io.rig_measurements import DrumAngle, DrumFlow, PileAngle
from rollingdem.scene.bonds import ParallelBond
from rollingdem.scene.boundaries import Inflow, Outlet
from rollingdem.scene.conditions import Settled
from rollingdem.scene.insertion import ROUGH_BASE_DECLARED
from rollingdem.scene.motion import MotionTable, Oscillation, Servo
from rollingdem.scene.particles import PARTICLE_DECLARED
from rollingdem.scene.regions import BoxRegion, CylinderRegion, Disk, Rectangle
from rollingdem.scene.size_distributions import Discrete, MassFractions, Normal, SieveCurve, Uniform
from rollingdem.scene.walls import Cylinder, Plane

#: the classes whose case-file blocks are made from their declarations, and those blocks
DECLARED_BLOCKS = {Plane: "PlaneSpec", Cylinder: "CylinderSpec", Oscillation: "OscillateSpec", MotionTable: "TableSpec",
                   Servo: "ServoSpec", BoxRegion: "BoxRegionSpec", CylinderRegion: "CylinderRegionSpec",
                   Disk: "DiskFaceSpec", Rectangle: "RectangleFaceSpec", Uniform: "UniformSpec", Normal: "NormalSpec",
                   Discrete: "DiscreteSpec", MassFractions: "MassFractionsSpec", SieveCurve: "SieveSpec",
                   MassFlow: "MassFlowSpec", OutletTotals: "OutletMeasurementSpec", WallLoad: "WallMeasurementSpec",
                   PileAngle: "ReposeMeasurementSpec", DrumAngle: "DrumMeasurementSpec", DrumFlow: "DrumFlowSpec",
                   Outlet: "OutletSpec", Probe: "ProbeSpec", Settled: "SettledSpec", Inflow: "InflowSpec",
                   ParallelBond: "BondSpec"}


class Nozzle:
    """A made-up object: one required number, a vector, a name, a switch and an angle."""

    declared = {"radius": Declared("radius of the nozzle", "m", low=0.0, low_open=True),
                "point": Declared("centre of the nozzle", "m", "vector"),
                "label": Declared("its name", kind="text"),
                "open": Declared("whether it lets spheres through", kind="flag"),
                "tilt": Declared("tilt of the nozzle", "rad", high=1.5)}

    def __init__(self, radius, point=(0.0, 0.0, 0.0), label=None, open=True, tilt=0.0):
        pass


def test_a_block_made_from_a_constructor_takes_its_parameters_defaults_and_declarations():
    spec = spec_from(Nozzle, "NozzleSpec", "a nozzle", units={"tilt": "deg"}, exclude=("open",))
    assert list(spec.model_fields) == ["radius", "point", "label", "tilt"]
    block = spec.model_validate({"radius": 0.01})
    assert (block.radius, block.point, block.label, block.tilt) == (0.01, (0.0, 0.0, 0.0), None, 0.0)
    for bad in ({}, {"radius": "0.01"}, {"radius": True}, {"radius": 0.01, "point": [0, 0]},
                {"radius": 0.01, "open": False}):  # required, strict numbers, a vector of three, excluded
        with pytest.raises(ValidationError):
            spec.model_validate(bad)
    schema = spec.model_json_schema()
    assert schema["description"] == "a nozzle" and schema["required"] == ["radius"]
    radius, tilt = schema["properties"]["radius"], schema["properties"]["tilt"]
    assert (radius["description"], radius["unit"], radius["exclusiveMinimum"]) == ("radius of the nozzle", "m", 0.0)
    assert (tilt["unit"], tilt["maximum"]) == ("deg", 1.5)  # the case file's unit where it differs
    assert "unit" not in schema["properties"]["label"]  # a name has none
    required = spec_from(Nozzle, "NozzleSpec", "", required=("label",), optional=("radius",))
    assert required.model_json_schema()["required"] == ["label"]


@pytest.mark.parametrize("cls", list(DECLARED_BLOCKS))
def test_every_constructor_parameter_is_declared_once_and_every_declaration_is_a_parameter(cls):
    parameters = [k for k in inspect.signature(cls.__init__).parameters if k != "self"]
    assert sorted(cls.declared) == sorted(parameters)


@pytest.mark.parametrize("call", [rd.Simulation.add_particles, rd.Simulation.insert, rd.Simulation.add_clumps,
                                  rd.Simulation.add_inflow])
def test_the_particle_calls_take_declared_parameters_only(call):
    """The particle blocks follow the calls that add particles: each of their parameters is one of
    ``PARTICLE_DECLARED`` (an inflow's own ones, its ``declared``), and ``rough_base``'s are declared."""
    parameters = [k for k in inspect.signature(call).parameters if k != "self"]
    declared = Inflow.declared if call is rd.Simulation.add_inflow else PARTICLE_DECLARED
    assert set(parameters) <= set(declared), set(parameters) - set(declared)
    assert sorted(ROUGH_BASE_DECLARED) == sorted(inspect.signature(rd.rough_base).parameters)


def test_the_declared_blocks_of_the_schema_carry_descriptions_and_units():
    """``rollingdem schema``: every key of a declared block (walls, motion programs, regions, inflow
    faces, size distributions, measurements) says what it is, and every number its unit."""
    result = CliRunner().invoke(app, ["schema"])
    assert result.exit_code == 0
    defs = json.loads(result.output)["$defs"]
    for block in DECLARED_BLOCKS.values():
        for key, prop in defs[block]["properties"].items():
            if key in ("type", "distribution"):
                continue
            assert prop.get("description"), (block, key)
            if _holds_numbers(prop):
                assert prop.get("unit"), (block, key)
    assert defs["OscillateSpec"]["properties"]["phase"]["unit"] == "deg"  # the case file takes degrees
    assert defs["CylinderSpec"]["properties"]["radius"]["exclusiveMinimum"] == 0.0


def _holds_numbers(prop) -> bool:
    """Whether a property's JSON Schema takes a number anywhere (itself, an option, an item)."""
    if prop.get("type") == "number":
        return True
    parts = [*prop.get("anyOf", []), *prop.get("prefixItems", [])] + ([prop["items"]] if isinstance(prop.get("items"), dict) else [])
    return any(_holds_numbers(p) for p in parts)


def test_every_key_of_the_case_file_says_what_it_is_and_every_number_its_unit():
    """``rollingdem schema``, whole: every key of every block has a description, and every key that
    takes a number (alone, in a vector, in a list) a unit ("-" for a ratio); a count or a seed is
    a whole number and needs none."""
    result = CliRunner().invoke(app, ["schema"])
    assert result.exit_code == 0
    schema = json.loads(result.output)
    blocks = {**schema["$defs"], "CaseSpec": schema}
    assert len(blocks) > 50
    for block, spec in blocks.items():
        for key, prop in spec.get("properties", {}).items():
            assert prop.get("description"), (block, key)
            if _holds_numbers(prop):
                assert prop.get("unit"), (block, key)
