"""No traceback for a user's mistake (issue 25): bad input gets one line naming the parameter, its
value and what is allowed, from the Python API (``ParameterError``), case files and every command
(``error: ...``, exit status 2); ``rollingdem check`` refuses what ``rollingdem run`` refuses, and a
refused run leaves no output folder. Tiny scenes, a few steps at most."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem.cli import app

# two spheres resting just above a floor; 4 steps of the automatic dt
BASE = """\
name: tiny
materials:
  - {name: m, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 1000.0, friction: 0.5, restitution: 0.5}
walls:
  - {type: plane, name: floor, material: m}
particles:
  - positions: [[0, 0, 0.006], [0.02, 0, 0.006]]
    radius: 0.005
    material: m
stages:
  - {name: s, duration: 0.0002}
output:
  time_series: {interval: 0.0001}
  plot: false
"""


def edit(old, new, text=BASE):
    assert old in text, old
    return text.replace(old, new)


STAGE = "  - {name: s, duration: 0.0002}"
FLOOR = "{type: plane, name: floor, material: m}"
SERIES = "time_series: {interval: 0.0001}"

# (name, case-file text, a piece of the one-line message)
CATALOGUE = [
    ("rolling sds without its stiffness", edit("walls:", "contact: {rolling: sds}\nwalls:"),
     "rolling model 'sds': parameter rolling_stiffness is missing"),
    ("rolling {model: sds} without its stiffness", edit("walls:", "contact: {rolling: {model: sds}}\nwalls:"),
     "rolling model 'sds': parameter rolling_stiffness is missing"),
    ("twisting {model: sds} without its stiffness", edit("walls:", "contact: {twisting: {model: sds}}\nwalls:"),
     "twisting model 'sds': parameter twisting_stiffness is missing"),
    ("rolling parameter of the wrong type",
     edit("walls:", "contact: {rolling: {model: cdt, limiter: abc}}\nwalls:"),
     "rolling model 'cdt': parameter limiter = 'abc' is not allowed: must be a number"),
    ("jkr cohesion on hooke", edit("walls:", "contact: {normal: hooke, cohesion: jkr}\nwalls:"),
     "cohesion model 'jkr' with normal model 'hooke' is not allowed: JKR's force-overlap relation is built on Hertz"),
    ("jkr cohesion with no surface energy anywhere", edit("walls:", "contact: {cohesion: jkr}\nwalls:"),
     "contact: cohesion = 'jkr' is not allowed here: every material pair's surface_energy is 0, so it would do nothing; give "
     "the materials (or a pair) a surface_energy (J/m^2), or use cohesion 'none'"),
    ("coarse graining below 1", edit("restitution: 0.5}", "restitution: 0.5, coarse_graining: 0.5}"),
     "material 'm': coarse_graining = 0.5 is not allowed: must be >= 1"),
    ("unknown cohesion model", edit("walls:", "contact: {cohesion: dmt}\nwalls:"),
     "cohesion model = 'dmt' is not known: allowed are 'jkr', 'none', 'sjkr'"),
    ("negative surface energy", edit("restitution: 0.5}", "restitution: 0.5, surface_energy: -0.1}"),
     "surface_energy = -0.1 is not allowed"),
    ("walton_braun given both k1 and a characteristic velocity",
     edit("walls:", "contact: {normal: {model: walton_braun, loading_stiffness: 1.0e5, characteristic_velocity: 1}}\nwalls:"),
     "walton_braun characteristic_velocity = 1 is not allowed together with loading_stiffness = 100000.0"),
    ("walton tangential exponent 0", edit("walls:", "contact: {tangential: {model: walton, exponent: 0}}\nwalls:"),
     "walton exponent = 0"),
    ("unknown rolling model", edit("walls:", "contact: {rolling: banana}\nwalls:"),
     "rolling model = 'banana' is not known: allowed are"),
    ("rolling model that is a number", edit("walls:", "contact: {rolling: 5}\nwalls:"),
     "rolling model = 5 is not allowed: must be a model name"),
    ("three radii for two positions", edit("radius: 0.005", "radius: [0.005, 0.005, 0.005]"),
     "particles.0: radius with 3 values is not allowed for 2 positions"),
    ("set_velocity of a particle that does not exist",
     edit(STAGE, "  - {name: s, duration: 0.0002, set_velocity: {particles: [7], velocity: [1, 0, 0]}}"),
     "stage 's': set_velocity particles = 7 is not allowed: must be in [0, 1]"),
    ("set_velocity with nothing to set", edit(STAGE, "  - {name: s, duration: 0.0002, set_velocity: {}}"),
     "stage 's': set_velocity = {'particles': 'all'} is not allowed: give velocity and/or angular_velocity"),
    ("dt above the stable limit", edit("name: tiny", "name: tiny\ndt: 1.0e-2"),
     "dt = 0.01 s exceeds the stable limit"),
    ("negative duration", edit("duration: 0.0002", "duration: -1"),
     "stage 's': duration = -1 is not allowed: must be >= 0 (s)"),
    ("time-series particle that does not exist", edit(SERIES, "time_series: {interval: 0.0001, particles: [5]}"),
     "output.time_series.particles = 5 is not allowed: must be in [0, 1]"),
    ("negative output interval", edit(SERIES, "time_series: {interval: -0.0001}"),
     "output.time_series.interval = -0.0001 is not allowed: must be > 0 (s)"),
    ("negative snapshot interval", edit(SERIES, SERIES + "\n  snapshots: {interval: -1}"),
     "output.snapshots.interval = -1 is not allowed: must be > 0 (s)"),
    ("unknown key", edit("name: tiny", "name: tiny\ntimestep: 1.0e-6"),
     "key 'timestep': not a known key (misspelled?): allowed are name, dt"),
    ("missing required key", edit("    material: m\n", ""), "key 'particles.0.material': missing (required)"),
    ("missing stages", BASE[:BASE.index("stages:")], "key 'stages': missing (required)"),
    ("negative radius", edit("radius: 0.005", "radius: -0.005"),
     "particles.0: radius of particle 0 = -0.005 is not allowed: must be > 0 (m)"),
    ("unknown material in a particle block", edit("    material: m\n", "    material: steel\n"),
     "particles.0: material = 'steel' is not known: known materials are 'm'"),
    ("unknown material of a wall", edit("name: floor, material: m", "name: floor, material: steel"),
     "walls.0: material = 'steel' is not known: known materials are 'm'"),
    ("youngs_modulus that is not a number", edit("youngs_modulus: 1.0e7", "youngs_modulus: abc"),
     "key 'materials.0.youngs_modulus' = \"abc\" is not allowed: must be a number"),
    ("a boolean for a number", edit("duration: 0.0002", "duration: true"),
     "key 'stages.0.duration' = true is not allowed: must be a number"),
    ("count that is not whole",
     edit("particles:\n", "particles:\n  - {insert: {type: box, lo: [0.1, 0.1, 0.1], hi: [0.2, 0.2, 0.2]}, "
                          "count: 2.5, radius: 0.005, material: m}\n"),
     "key 'particles.0.count' = 2.5 is not allowed: must be a whole number"),
    ("vector of two numbers", edit("name: tiny", "name: tiny\ngravity: [0, -9.81]"),
     "key 'gravity' = [0, -9.81] is not allowed: must be three numbers"),
    ("unknown wall type", edit("type: plane", "type: sphere"),
     "key 'walls.0.type' = \"sphere\" is not allowed: must be one of 'plane', 'cylinder'"),
    ("wall removed by a stage that does not exist",
     edit(STAGE, "  - {name: s, duration: 0.0002, remove_walls: [tube]}"),
     "stage 's': remove_walls = 'tube' is not allowed: no wall has that name; wall names are 'floor'"),
    ("wall removed twice",
     edit(STAGE, STAGE.replace("}", ", remove_walls: [floor]}") + "\n" + STAGE.replace("s,", "t,").replace(
         "}", ", remove_walls: [floor]}")),
     "stage 't': remove_walls = 'floor' is not allowed: an earlier stage removed that wall already"),
    ("two walls of one name",
     edit("  - {type: plane, name: floor, material: m}\n",
          "  - {type: plane, name: floor, material: m}\n  - {type: plane, name: floor, material: m, "
          "point: [0, 0, -1]}\n"),
     "walls: name = 'floor' is not allowed: it names two walls"),
    ("non-finite stage gravity", edit(STAGE, "  - {name: s, duration: 0.0002, gravity: [.nan, 0, 0]}"),
     "stage 's': gravity = (nan, 0.0, 0.0) is not allowed: components must be finite"),
    ("overlapping spheres", edit("[0.02, 0, 0.006]", "[0.001, 0, 0.006]"),
     "set allow_overlap: true in the particle block"),
    ("mesh file that does not exist", edit("walls:", "walls:\n  - {type: mesh, name: hopper, material: m, file: hop.stl}"),
     "walls.0: mesh file"),
    ("mesh with a file and a shape",
     edit("walls:", "walls:\n  - {type: mesh, material: m, file: a.stl, shape: disk, size: {radius: 1.0}}"),
     "walls.0: file = 'a.stl', shape = 'disk' is not allowed: give exactly one of file"),
    ("mesh 40,000 diameters across (a file in mm read as m)",
     edit("walls:", "walls:\n  - {type: mesh, name: big, material: m, shape: disk, size: {radius: 200.0}}"),
     "walls.0: disk: the mesh is 400 m across, 4e+04 mean particle diameters (0.01 m), more than 10000: a "
     "unit mistake? give its scale (0.001 for a file in mm), or check_size: false to accept it"),
    ("mesh shape that does not exist", edit("walls:", "walls:\n  - {type: mesh, material: m, shape: cone}"),
     "walls.0: mesh shape = 'cone' is not known: allowed are 'drum'"),
    ("mesh shape without a dimension", edit("walls:", "walls:\n  - {type: mesh, material: m, shape: disk}"),
     "walls.0: mesh shape 'disk': radius missing"),
    ("mesh turning without its rate", edit("walls:", "walls:\n  - {type: mesh, material: m, shape: disk, "
                                                     "size: {radius: 1.0}, motion: {rotate: {axis: [0, 0, 1]}}}"),
     "walls.0: motion rotate: angular_velocity missing"),
    ("plane turning out of itself",
     edit("{type: plane, name: floor, material: m}", "{type: plane, name: floor, material: m, "
                                                     "angular_velocity: [1, 0, 0]}"),
     "walls.0: wall angular_velocity = [1.0, 0.0, 0.0] is not allowed for a plane: it must lie along its normal"),
    ("a stage's shear rate in a box not sheared",
     edit(STAGE, "  - {name: s, duration: 0.0002, shear_rate: 5.0}"),
     "stage 's': shear_rate = 5.0 is not allowed: the box is not sheared"),
    ("wall_motion of a wall that is not there",
     edit(STAGE, "  - {name: s, duration: 0.0002, wall_motion: [{wall: roof, velocity: [0, 0, 1]}]}"),
     "stage 's': wall_motion wall = 'roof' is not allowed: no wall in place has that name"),
    ("periodic length below two cutoffs", edit("walls:", "periodic: {y: [-0.005, 0.005]}\nwalls:"),
     "periodic y length = 0.01 m is not allowed: must be at least 2 (2 R_max + skin)"),
    ("a shear rate along an axis that is not periodic",
     edit("walls:", "periodic: {x: [-0.1, 0.1], shear_rate: 10.0}\nwalls:"),
     "periodic: lees_edwards = LeesEdwards(shear_rate=10.0, gradient='z', shear_velocity=None) is not allowed: the flow "
     "axis x and the gradient axis z must be periodic, and z is not"),
    ("periodic axis that does not exist", edit("walls:", "periodic: {w: [0, 1]}\nwalls:"),
     "key 'periodic.w': not a known key"),
    ("unknown backend", edit("walls:", "backend: gpu\nwalls:"),
     "backend = 'gpu' is not allowed: must be one of cpu, cuda"),
    ("outlet that holds every particle",
     edit("stages:", "outlets:\n  - {region: {type: box, lo: [-1, -1, -1], hi: [1, 1, 1]}}\nstages:"),
     "outlets.0: outlet region BoxRegion(lo=[-1.0, -1.0, -1.0], hi=[1.0, 1.0, 1.0]) is not allowed: it contains every"),
    ("inflow region smaller than one particle",
     edit("stages:", "inflows:\n  - {region: {type: box, lo: [0, 0, 0.1], hi: [0.005, 0.1, 0.2]}, radius: 0.005, "
                     "material: m, rate: 10}\nstages:"),
     "inflows.0: inflow region BoxRegion(lo=[0.0, 0.0, 0.1], hi=[0.005, 0.1, 0.2]) is not allowed: a sphere of radius"),
    ("inflow without a rate",
     edit("stages:", "inflows:\n  - {region: {type: box, lo: [0, 0, 0.1], hi: [0.1, 0.1, 0.2]}, radius: 0.005, "
                     "material: m}\nstages:"),
     "inflows.0: inflow rate = None, mass_rate = None is not allowed: give exactly one"),
    ("fixed particles that overlap",
     edit("    material: m\n", "    material: m\n  - {positions: [[0, 0.1, 0.006], [0.005, 0.1, 0.006]], radius: 0.005, "
                                "material: m, fixed: true}\n"),
     "particles.1: particles 2 and 3 overlap by 0.005 m at insertion"),
    ("rough base with too much jitter",
     edit("    material: m\n", "    material: m\n  - {rough_base: {radius: 0.005, extent: [[-0.1, 0.1], [0.05, 0.2]], "
                                "jitter: 0.01}, material: m}\n"),
     "particles.1: jitter = 0.01 is not allowed with spacing = 0.011 m"),
    ("until without a maximum duration", edit(STAGE, "  - {name: s, until: settled}"),
     "stage 's': until is not allowed without max_duration (s)"),
    ("until with duration", edit(STAGE, "  - {name: s, until: settled, duration: 1, max_duration: 2}"),
     "stage 's': duration = 1 is not allowed with until: give max_duration"),
    ("max_duration without until", edit(STAGE, "  - {name: s, max_duration: 2}"),
     "stage 's': max_duration = 2 is not allowed without until"),
    ("until an unknown measurement", edit(STAGE, "  - {name: s, until: {measurement: out.count, above: 5}, "
                                                 "max_duration: 1}"),
     "stage 's': until: measurement = 'out.count' is not allowed: no measurement is named 'out'; the measurements "
     "give none"),
    ("until a quantity the measurement lacks",
     edit("stages:", "measurements:\n  - {name: load, type: wall, wall: floor}\nstages:",
          edit(STAGE, "  - {name: s, until: {measurement: load.count, above: 5}, max_duration: 1}")),
     "stage 's': until: until load.count is not allowed: 'load' measures fx, fy, fz, tx, ty, tz, power, x, y, z"),
    ("until no condition", edit(STAGE, "  - {name: s, until: {every: 0.01}, max_duration: 1}"),
     "give settled, empty or measurement"),
    ("a measurement of an unknown wall", edit("stages:", "measurements:\n  - {name: load, type: wall, wall: lid}\n"
                                                         "stages:"),
     "measurements.0: measurement 'load': wall = 'lid' is not allowed: no wall in place has that name; walls are "
     "'floor'"),
    ("two measurements of one name",
     edit("stages:", "measurements:\n  - {name: a, type: wall, wall: floor}\n  - {name: a, type: wall, wall: floor}"
                     "\nstages:"),
     "measurements.1: name = 'a' is not allowed: it names two measurements"),
    ("a sensor far outside the scene (mm for m)",
     edit("stages:", "measurements:\n  - {name: f, type: mass_flow, point: [0, 0, -50], normal: [0, 0, -1]}\n"
                     "stages:"),
     "measurements.0: mass flow 'f' point = (0, 0, -50) is not allowed: it is outside the scene"),
    ("a probe in an open mesh", edit("stages:", "measurements:\n  - {name: p, type: probe, region: {type: mesh, shape: "
                                     "drum, size: {radius: 0.02, length: 0.05, caps: false}}}\nstages:"),
     "measurements.0: tube: a region's mesh must be closed, but edge"),
    ("an unknown measurement type", edit("stages:", "measurements:\n  - {name: a, type: speedometer}\nstages:"),
     "key 'measurements.0.type' = \"speedometer\" is not allowed: must be one of"),
    ("two motion programs on one wall", edit(FLOOR, FLOOR[:-1] + ", oscillate: {frequency: 10, amplitude: [0, 0, 0.001]}, "
                                               "servo: {direction: [0, 0, 1], max_speed: 0.1, force: 1}}"),
     "walls.0: oscillate and servo are not allowed together: a wall follows one motion program"),
    ("a plane oscillating by an angle", edit(FLOOR, FLOOR[:-1] + ", oscillate: {frequency: 10, angle: 5, axis: [0, 0, 1]}}"),
     "walls.0: wall 'floor' motion: an oscillation with an angle is not allowed for a plane (it moves only by "
     "translation"),
    ("a stage turning a plane by a table",
     edit(STAGE, "  - {name: s, duration: 0.0002, wall_motion: [{wall: floor, table: {times: [0, 1], angles: [0, 5], "
                 "axis: [0, 0, 1]}}]}"),
     "stage 's': wall_motion 'floor': wall 'floor' motion: a motion table with an angle is not allowed for a plane"),
    ("a motion table whose times do not increase",
     edit(FLOOR, FLOOR[:-1] + ", table: {times: [0, 0.1, 0.1], displacements: [[0, 0, 0], [0, 0, 0.001], [0, 0, 0]]}}"),
     "walls.0: table: motion table times = [0.0, 0.1, 0.1] is not allowed: need at least two finite times, each later"),
    ("a motion table file that is not there", edit(FLOOR, FLOOR[:-1] + ", table: {file: nothere.csv}}"),
     "walls.0: table: file = "),
    ("a servo pressure without its area",
     edit(FLOOR, FLOOR[:-1] + ", servo: {direction: [0, 0, 1], max_speed: 0.1, pressure: 1000}}"),
     "walls.0: servo: servo area = None is not allowed with pressure = 1000.0: give the area (m^2)"),
    ("an oscillation of no frequency", edit(FLOOR, FLOOR[:-1] + ", oscillate: {frequency: 0, amplitude: [0, 0, 1]}}"),
     "walls.0: oscillate: oscillation frequency = 0 is not allowed: must be > 0 (Hz)"),
    ("a servo without its speed limit",
     edit(STAGE, "  - {name: s, duration: 0.0002, wall_motion: [{wall: floor, servo: {direction: [0, 0, 1], force: 1}}]}"),
     "key 'stages.0.wall_motion.0.servo.max_speed': missing (required)"),
    ("a plane across a periodic axis", edit("walls:", "periodic: {z: [-0.1, 0.1]}\nwalls:"),
     "periodic: wall 'floor': a plane of normal [0.0, 0.0, 1.0] is not allowed with the periodic z: it cuts across "
     "that axis"),
    ("an inflow inside the floor",
     edit("stages:", "inflows:\n  - {region: {type: box, lo: [0, 0, -0.2], hi: [0.1, 0.1, -0.1]}, radius: 0.005, "
                     "material: m, rate: 10}\nstages:"),
     "inflows: inflow region BoxRegion(lo=[0.0, 0.0, -0.2], hi=[0.1, 0.1, -0.1]) is not allowed: the walls leave no "
     "room in it for a sphere of radius 0.005 m (wall 'floor' covers all of it)"),
    ("an insert with a count and a fraction",
     edit("    material: m\n", "    material: m\n  - {insert: {type: box, lo: [0, 0.1, 0.01], hi: [0.1, 0.2, 0.1]}, count: 10, "
                                "fraction: 0.2, radius: 0.005, material: m}\n"),
     "particles.1: count = 10, fraction = 0.2 is not allowed: give exactly one of count, mass (kg) and fraction"),
    ("an insert to a fraction random insertion cannot reach",
     edit("    material: m\n", "    material: m\n  - {insert: {type: box, lo: [0, 0.1, 0.01], hi: [0.1, 0.2, 0.1]}, "
                                "fraction: 0.7, radius: 0.005, material: m}\n"),
     "particles.1: fraction = 0.7 is not allowed: must be in (0, 0.55] (random insertion tops out near 0.3-0.35"),
    ("an insert into the mesh of a wall that is not there",
     edit("    material: m\n", "    material: m\n  - {insert: {type: mesh, wall: bin}, count: 10, radius: 0.005, "
                                "material: m}\n"),
     "particles.1: wall = 'bin' is not allowed: no mesh wall has that name; mesh walls are none"),
    ("a sieve curve that does not reach 1",
     edit("    material: m\n", "    material: m\n  - {insert: {type: box, lo: [0, 0.1, 0.01], hi: [0.1, 0.2, 0.1]}, "
                                "count: 10, radius: {distribution: sieve, diameters: [0.004, 0.006], passing: [0, 0.9]}, "
                                "material: m}\n"),
     "particles.1: SieveCurve passing = [0.0, 0.9] is not allowed: the fraction of the mass passing each sieve must "
     "not decrease, from 0 at the first to 1 at the last"),
    ("an inflow going back through its face",
     edit("stages:", "inflows:\n  - {region: {type: disk, center: [0, 0, 0.1], normal: [0, 0, -1], radius: 0.02}, "
                     "radius: 0.005, material: m, rate: 10, velocity: [0, 0, 1]}\nstages:"),
     "inflows.0: inflow velocity = [0.0, 0.0, 1.0] is not allowed through Disk(center=[0.0, 0.0, 0.1], normal=[0.0, "
     "0.0, -1.0], radius=0.02): it points back through the face (against its normal)"),
    ("a misspelled key of an insert's region, named where the file has it",
     edit("  - positions: [[0, 0, 0.006], [0.02, 0, 0.006]]\n    radius: 0.005\n", "  - insert: {type: cylinder, radius: 0.05, "
          "zmin: 0.01, z_max: 0.1}\n    count: 10\n    radius: 0.005\n"),
     "key 'particles.0.insert.zmin': not a known key: did you mean 'z_min'? (allowed are type, radius, z_min, z_max, "
     "center)"),
    ("an unknown region type, named where the file has it",
     edit("  - positions: [[0, 0, 0.006], [0.02, 0, 0.006]]\n    radius: 0.005\n", "  - insert: {type: cone, radius: 0.05, "
          "z_min: 0.01, z_max: 0.1}\n    count: 10\n    radius: 0.005\n"),
     "key 'particles.0.insert.type' = \"cone\" is not allowed: must be one of 'box', 'cylinder', 'mesh'"),
    ("a servo with no target", edit(FLOOR, FLOOR[:-1] + ", servo: {direction: [0, 0, 1], max_speed: 0.1}}"),
     "walls.0: servo: servo force = None is not allowed with pressure = None: give one of force (N) and pressure (Pa)"),
    ("a clump template with no sphere",
     edit("    material: m\n", "    material: m\n  - {clump: {spheres: []}, positions: [[0, 0, 0.1]], material: m}\n"),
     "particles.1: clump centres = [] is not allowed: a clump needs at least one sphere"),
    ("a clump member of zero radius",
     edit("    material: m\n", "    material: m\n  - {clump: {spheres: [[0, 0, 0, 0.0]]}, positions: [[0, 0, 0.1]], "
          "material: m}\n"),
     "particles.1: clump radii[0] = 0 is not allowed: must be > 0 (m)"),
    ("clump members apart",
     edit("    material: m\n", "    material: m\n  - {clump: {spheres: [[0, 0, 0, 0.002], [0.01, 0, 0, 0.002]]}, "
          "positions: [[0, 0, 0.1]], material: m}\n"),
     "its members do not all overlap or touch (it would be several bodies); set clump.connected: false"),
    ("a clump shape misspelled",
     edit("    material: m\n", "    material: m\n  - {clump: {shape: cube, radius: 0.002}, positions: [[0, 0, 0.1]], "
          "material: m}\n"),
     "key 'particles.1.clump.shape' = \"cube\" is not allowed: must be 'dimer', 'trimer', 'tetrahedron', 'ring_prism' or "
     "'rod'"),
    ("a clump larger than half the periodic length",
     edit("walls:", "periodic: {x: [-0.05, 0.05]}\nwalls:",
          edit("    material: m\n", "    material: m\n  - {clump: {shape: rod, n: 8, radius: 0.004}, "
               "positions: [[0, 0, 0.1]], material: m}\n")),
     "must span less than half the periodic length (4 x its reach), or it would touch its own image"),
    ("clumps both inserted and placed",
     edit("    material: m\n", "    material: m\n  - {clump: {shape: dimer, radius: 0.002}, positions: [[0, 0, 0.1]], "
          "count: 3, material: m}\n"),
     "particles.1: count, mass and fraction go with insert: with positions each position is a clump"),
    ("an outlet's refill region behind the floor",
     edit("stages:", "outlets:\n  - {name: out, region: {type: box, lo: [0.5, 0.5, 0.0], hi: [1, 1, 1]}, refill: {type: box, "
                     "lo: [0, 0, -0.2], hi: [0.1, 0.1, -0.1]}}\nstages:"),
     "outlets: outlet out refill region BoxRegion(lo=[0.0, 0.0, -0.2], hi=[0.1, 0.1, -0.1]) is not allowed: the walls "
     "leave no room in it for a sphere of radius 0.005 m (wall 'floor' covers all of it)"),
    ("a stage turning a wall far past the time step it was given",
     edit("name: tiny", "name: tiny\ndt: 1.0e-5", edit(STAGE, "  - {name: s, duration: 0.0002, wall_motion: [{wall: floor, "
                                                         "rotate: {axis: [0, 0, 1], angular_velocity: 1.0e5}}]}")),
     "stage 's': dt = 1e-05 s exceeds the stable limit"),
    ("a window after the run", edit("stages:", "measurements:\n  - {name: p, type: probe, region: {type: box, lo: [0, 0, 0], "
                                               "hi: [0.02, 0.01, 0.01]}, window: [0.5, 0.6]}\nstages:"),
     "measurements.0: window = [0.5, 0.6] is not allowed: it starts after the run, which lasts at most 0.0002 s"),
    ("a window from a stage that is not there",
     edit("stages:", "measurements:\n  - {name: p, type: probe, region: {type: box, lo: [0, 0, 0], hi: [0.02, 0.01, 0.01]}, "
                     "window: {stage: drain, start: 0}}\nstages:"),
     "measurements.0: window stage = 'drain' is not allowed: no stage has that name; the stages are 's'"),
    ("a negative dt beside a periodic axis, named as dt", edit("walls:", "dt: -1.0e-5\nperiodic: {x: [-0.1, 0.1]}\nwalls:"),
     "error: dt = -1e-05 is not allowed: must be > 0 (s)"),
    ("YAML syntax error", BASE + "  - [unclosed\n", "is not valid YAML: expected <block end>, but found '-' at line 15"),
    ("empty file", "", "is empty: must hold a mapping of keys"),
    ("a list, not a mapping", "- a\n- b\n", "must hold a mapping of keys, got list"),
]


def _error_lines(output):
    return [line for line in output.splitlines() if line.startswith("error:")]


@pytest.mark.parametrize("name,text,expected", CATALOGUE, ids=[c[0] for c in CATALOGUE])
def test_check_and_run_refuse_a_bad_case_alike(tmp_path, name, text, expected):
    """Every malformed case: exit status 2 from both commands, the same one-line message (naming
    the key and its value), no traceback, and no output folder left by the refused run."""
    case = tmp_path / "case.yaml"
    case.write_text(text)
    out = tmp_path / "out"
    checked = CliRunner().invoke(app, ["check", str(case)])
    ran = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    for result in (checked, ran):
        assert result.exit_code == 2, result.output
        assert isinstance(result.exception, SystemExit), result.exception
        assert "Traceback" not in result.output
        assert len(_error_lines(result.output)) == 1 and result.output.count("\n") == 1, result.output
        assert expected in result.output, result.output
    assert checked.output == ran.output
    assert not out.exists()


def test_check_refuses_an_output_folder_a_run_could_not_write(tmp_path, monkeypatch):
    """The case's output.directory under a file: ``check`` refuses it in the line ``run`` (without
    --out, so writing there) refuses it with, and leaves nothing."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    case = tmp_path / "case.yaml"
    case.write_text(edit("  plot: false", "  plot: false\n  directory: afile/out"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    ran = CliRunner().invoke(app, ["run", str(case), "--no-progress"])
    for result in (checked, ran):
        assert result.exit_code == 2, result.output
        assert result.output.startswith("error: output.directory = 'afile/out' is not allowed: ")
        assert result.output.endswith("afile is a file; must be a folder\n") and result.output.count("\n") == 1
    assert checked.output == ran.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "case.yaml"]


def test_valid_case_is_checked_valid_and_runs(tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text(edit("walls:", "check_timestep: true\nwalls:"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    assert checked.exit_code == 0 and "valid; 2 particles, 1 walls, 1 stages" in checked.output, checked.output
    out = tmp_path / "out"
    ran = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert ran.exit_code == 0, ran.output
    assert json.loads((out / "summary.json").read_text())["status"] == "ok"


def test_check_says_how_long_the_run_is_and_warns_of_runs_that_never_end(tmp_path):
    """check prints each stage's steps at its dt and the run's wall time at the dense-bed rate (2
    particles x 20 steps); it warns of a run estimated past a day (a duration of 1e9 s), of until:
    empty without an outlet, and of a wall surface at 2,000 m/s (rad/s where rpm was meant)."""
    from rollingdem.io.casefile import DENSE_BED_RATE

    case = tmp_path / "case.yaml"
    case.write_text(edit("name: tiny", "name: tiny\ndt: 1.0e-5"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    assert checked.exit_code == 0 and "stage 's': up to 20 steps at dt = 1e-05 s" in checked.output, checked.output
    assert f"in all up to 20 steps of 2 particles: about {2 * 20 / DENSE_BED_RATE:.0f} s on 2 cores" in checked.output
    assert "warning" not in checked.output
    case.write_text(edit(STAGE, "  - {name: s, duration: 1.0e9}\n  - {name: e, until: empty, max_duration: 0.001}\n"
                                "  - {name: t, duration: 0.001, wall_motion: [{wall: floor, rotate: {axis: [0, 0, 1], "
                                "angular_velocity: 1.0e5}}]}"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    assert checked.exit_code == 0, checked.output
    warned = [line for line in checked.output.splitlines() if line.startswith("warning: ")]
    assert len(warned) == 3, checked.output
    assert "stage 'e': until: empty is never met without an outlet" in warned[0]
    assert "stage 't': a wall surface moves at 2e+03 m/s" in warned[1]
    assert "days: check each stage's duration" in warned[2]


def test_check_timestep_false_in_the_case_file_runs_anyway(tmp_path):
    """The dt refusal names the case-file key; setting it lets the case through."""
    case = tmp_path / "case.yaml"
    case.write_text(edit("name: tiny", "name: tiny\ndt: 1.0e-3\ncheck_timestep: false"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    assert checked.exit_code == 0, checked.output


def test_case_file_messages_name_the_case_file_key(tmp_path):
    from rollingdem.io.case_check import check_case
    from rollingdem.io.casefile import load_case

    case = tmp_path / "case.yaml"
    case.write_text(edit("name: tiny", "name: tiny\ndt: 1.0e-2"))
    spec = load_case(case)
    with pytest.raises(rd.ParameterError, match="set check_timestep: false in the case file") as err:
        check_case(spec)
    assert "check_timestep=False" not in str(err.value)


# --- item 1: sub-models ---------------------------------------------------------------------
@pytest.mark.parametrize("kwargs,expected", [
    (dict(rolling="sds"), "rolling model 'sds': parameter rolling_stiffness is missing"),
    (dict(rolling={"model": "sds"}), "rolling model 'sds': parameter rolling_stiffness is missing"),
    (dict(twisting={"model": "sds"}), "twisting model 'sds': parameter twisting_stiffness is missing"),
    (dict(rolling={"model": "sds", "rolling_stiffness": "stiff"}), "rolling_stiffness = 'stiff' is not allowed"),
    (dict(rolling={"model": "sds", "rolling_stiffness": True}), "rolling_stiffness = True is not allowed"),
    (dict(rolling={"model": "cdt", "limiter": [1]}), "parameter limiter = [1] is not allowed: must be a number"),
    (dict(rolling={"model": "viscous", "form": 3}), "parameter form = 3 is not allowed: must be a name"),
    (dict(rolling={"rolling_stiffness": 1.0}), "a mapping must name its model"),
    (dict(rolling=["cdt"]), "rolling model = ['cdt'] is not allowed"),
    (dict(rolling={"model": ["cdt"]}), "rolling model = ['cdt'] is not known"),
])
def test_contact_model_refuses_bad_submodels(kwargs, expected):
    with pytest.raises(rd.ParameterError) as err:
        rd.ContactModel(**kwargs)
    assert expected in str(err.value) and "\n" not in str(err.value)


# --- items 2, 4: the Python API -------------------------------------------------------------
@pytest.fixture
def sim():
    s = rd.Simulation(dt=1e-6)
    s.add_material(rd.Material("m", 1e7, 0.3, 1000.0))
    s.add_wall(rd.Plane(material="m", name="floor"))
    s.add_particles([[0, 0, 0.006]], radius=0.005, material="m")
    return s


@pytest.mark.parametrize("kwargs,expected", [
    (dict(positions=[[0, 0, 0.1]], radius="big"), "radius = 'big' is not allowed: must be a number"),
    (dict(positions=[[0, 0, 0.1], [0, 0, 0.2]], radius=[0.005, 0.005, 0.005]),
     "radius with 3 values is not allowed for 2 positions"),
    (dict(positions=[[0, 0, "a"]], radius=0.005), "positions = [[0, 0, 'a']] is not allowed"),
    (dict(positions=[[0, 0]], radius=0.005), "positions with shape (1, 2) are not allowed"),
    (dict(positions=[[0, 0, 0.1]], radius=0.005, velocity=[1, 2]), "velocity = [1, 2] is not allowed"),
    (dict(positions=[[0, 0, 0.1]], radius=0.005, material=["m", "m"]),
     "material with 2 entries is not allowed for 1 positions"),
])
def test_add_particles_refuses_bad_input(sim, kwargs, expected):
    kwargs.setdefault("material", "m")
    with pytest.raises(rd.ParameterError) as err:
        sim.add_particles(**kwargs)
    assert expected in str(err.value)
    assert sim.n_particles == 1


@pytest.mark.parametrize("indices,expected", [
    ([5], "indices = [5] is not allowed: particle 5 does not exist; must be in [0, 0]"),
    (-1, "particle -1 does not exist"),
    ([0.5], "indices = [0.5] is not allowed: must be particle indices"),
    ("0", "indices = '0' is not allowed: must be particle indices"),
])
def test_set_velocities_refuses_bad_indices(sim, indices, expected):
    with pytest.raises(rd.ParameterError) as err:
        sim.set_velocities(indices, velocity=(1.0, 0.0, 0.0))
    assert expected in str(err.value)
    with pytest.raises(rd.ParameterError, match=r"velocity = \(1, 0\) is not allowed: must be three numbers"):
        sim.set_velocities([0], velocity=(1, 0))


def test_restore_refuses_a_missing_or_foreign_file(tmp_path):
    with pytest.raises(rd.ParameterError, match="it does not exist; must be a checkpoint .npz file written by "
                                                "Simulation.checkpoint"):
        rd.Simulation.restore(tmp_path / "missing.npz")
    with pytest.raises(rd.ParameterError, match="it is a folder"):
        rd.Simulation.restore(tmp_path)
    (tmp_path / "text.npz").write_text("hello")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    np.save(tmp_path / "array.npy", np.zeros(3))
    (tmp_path / "broken.npz").write_bytes(b"PK\x03\x04 not a zip")
    for name in ("text.npz", "other.npz", "array.npy", "broken.npz"):
        with pytest.raises(rd.ParameterError, match="is not allowed: it is not a rollingdem checkpoint"):
            rd.Simulation.restore(tmp_path / name)


def test_listed_positions_of_a_coarse_grained_material_that_overlap_name_the_parcels_radius():
    """Spheres 0.02 m apart of r = 5 mm at coarse_graining 1000 are parcels of 5 m: the refusal says so,
    instead of an overlap of 9.98 m that the positions given cannot explain."""
    sim = rd.Simulation()
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, coarse_graining=1000))
    with pytest.raises(rd.ParameterError, match=r"overlap by 9.98 m at insertion; they are parcels of coarse_graining "
                                                r"1000, of radius alpha r = 5 m for r = 0.005 m"):
        sim.add_particles([[0, 0, 0.01], [0.02, 0, 0.01]], 0.005, "m")


def test_restore_refuses_a_checkpoint_cut_or_of_a_later_format_and_checkpoint_an_unwritable_path(sim, tmp_path):
    """A checkpoint missing an array (cut or edited), one of a format newer than this code reads, and a
    checkpoint path that cannot be written: one line each, naming the file and what is wrong."""
    import json

    from rollingdem.scene.checkpoint import FORMAT

    sim.checkpoint(tmp_path / "whole.npz")
    with np.load(tmp_path / "whole.npz") as data:
        arrays = {k: data[k] for k in data.files}
    assert json.loads(str(arrays["meta"]))["format"] == FORMAT
    np.savez(tmp_path / "cut.npz", **{k: v for k, v in arrays.items() if k != "x"})
    with pytest.raises(rd.ParameterError, match=r"cut.npz' is not allowed: its array 'x' is missing"):
        rd.Simulation.restore(tmp_path / "cut.npz")
    meta = json.loads(str(arrays["meta"]))
    np.savez(tmp_path / "later.npz", **dict(arrays, meta=np.array(json.dumps(dict(meta, format=FORMAT + 1)))))
    with pytest.raises(rd.ParameterError, match=rf"it is of format {FORMAT + 1}, .* reads formats up to {FORMAT}"):
        rd.Simulation.restore(tmp_path / "later.npz")
    meta.pop("format")  # a checkpoint from before formats were recorded is read as format 1
    np.savez(tmp_path / "older.npz", **dict(arrays, meta=np.array(json.dumps(meta))))
    assert rd.Simulation.restore(tmp_path / "older.npz").n_particles == 1
    (tmp_path / "afile").write_text("x")
    with pytest.raises(rd.ParameterError, match=r"checkpoint = '.*afile/c.npz' cannot be written \(.*\): give a path"):
        sim.checkpoint(tmp_path / "afile" / "c.npz")


# --- item 8: run's arguments ----------------------------------------------------------------
@pytest.mark.parametrize("kwargs,expected", [
    (dict(steps=2.5), "steps = 2.5 is not allowed: must be a whole number"),
    (dict(steps=-1), "steps = -1 is not allowed: must be a whole number >= 0"),
    (dict(steps=True), "steps = True is not allowed"),
    (dict(steps="3"), "steps = '3' is not allowed"),
    (dict(steps=float("nan")), "steps = nan is not allowed"),
    (dict(duration=float("nan")), "duration = nan is not allowed: must be a finite number"),
    (dict(duration=float("inf")), "duration = inf is not allowed: must be a finite number"),
    (dict(duration=-1.0), "duration = -1 is not allowed: must be >= 0 (s)"),
    (dict(duration="1"), "duration = '1' is not allowed: must be a number"),
    (dict(), "give exactly one of duration (s) and steps"),
    (dict(duration=1.0, steps=1), "give exactly one of duration (s) and steps"),
    (dict(steps=1, observers=["series"]), "observers[0] = 'series' is not allowed: must be a rollingdem observer"),
    (dict(steps=1, label=3), "label = 3 is not allowed: must be a string"),
])
def test_run_refuses_bad_arguments(sim, kwargs, expected):
    with pytest.raises(rd.ParameterError) as err:
        sim.run(**kwargs)
    assert expected in str(err.value)
    assert sim.step == 0


def test_run_refuses_a_time_series_particle_before_writing(sim, tmp_path):
    series = rd.TimeSeries(tmp_path / "s.csv", 1e-6, particles=[3])
    with pytest.raises(rd.ParameterError, match=r"time series particle = 3 is not allowed: must be in \[0, 0\]"):
        sim.run(steps=1, observers=[series])
    assert not (tmp_path / "s.csv").exists()
    with pytest.raises(rd.ParameterError, match="time series particle = 1.5 is not allowed: must be a whole number"):
        rd.TimeSeries(tmp_path / "s.csv", 1e-6, particles=[1.5])


def test_dt_refusal_tells_a_python_user_the_argument(sim):
    sim.dt = 1.0
    with pytest.raises(rd.ParameterError, match="pass check_timestep=False to the Simulation"):
        sim.run(steps=1)


# --- item 9: walls --------------------------------------------------------------------------
def test_removing_a_wall_twice_names_it(sim):
    floor = sim.walls[0]
    sim.remove_wall(floor)
    with pytest.raises(rd.ParameterError) as err:
        sim.remove_wall(floor)
    assert str(err.value) == "wall = 'floor' is not allowed: it was removed already"
    unnamed = sim.add_wall(rd.Plane(point=(0, 0, -1), material="m"))
    sim.remove_wall(unnamed)
    with pytest.raises(rd.ParameterError, match=r"wall = #1 \(plane\) is not allowed: it was removed already"):
        sim.remove_wall(unnamed)
    with pytest.raises(rd.ParameterError, match="it is not part of this simulation"):
        sim.remove_wall(rd.Plane(material="m", name="other"))
    with pytest.raises(rd.ParameterError, match="wall = 'floor' is not allowed: it was removed already"):
        sim.remove_wall("floor")  # by name as well
    with pytest.raises(rd.ParameterError, match="wall = 'roof' is not allowed: no wall has that name"):
        sim.set_wall_velocity("roof", (1, 0, 0))
    with pytest.raises(rd.ParameterError, match="wall = 3 is not allowed: must be a wall of this simulation"):
        sim.set_wall_velocity(3, (1, 0, 0))
    with pytest.raises(rd.ParameterError, match="wall = 'floor' is not allowed: it was removed already"):
        sim.set_wall_velocity(floor, (1, 0, 0))
    wall = sim.add_wall(rd.Plane(point=(0, 0, -2), material="m", name="low"))
    with pytest.raises(rd.ParameterError, match="wall = 'low' is not allowed: it is part of this simulation already"):
        sim.add_wall(wall)
    assert "object at" not in repr(wall) and "name='low'" in repr(wall)
    sim.set_wall_velocity("low", (0.0, 0.0, 1.0))
    sim.remove_wall("low")
    assert [w.name for w in sim.walls] == []


# --- item 10: every command -----------------------------------------------------------------
@pytest.fixture
def afile(tmp_path):
    path = tmp_path / "afile"
    path.write_text("x")
    return path


def _refused(args, expected):
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    assert isinstance(result.exception, SystemExit), result.exception
    assert "Traceback" not in result.output and len(_error_lines(result.output)) == 1, result.output
    assert expected in result.output, result.output


def test_commands_refuse_bad_files_and_options_in_one_line(tmp_path, afile):
    case = tmp_path / "case.yaml"
    case.write_text(BASE)
    (tmp_path / "case.toml").write_text("name = [unclosed\n")
    (tmp_path / "binary.yaml").write_bytes(b"\xff\xfe\x00\x01")
    for cmd in ("run", "check"):
        _refused([cmd, tmp_path / "missing.yaml"], "does not exist")
        _refused([cmd, tmp_path], "is a folder: must be a YAML or TOML file")
        _refused([cmd, tmp_path / "case.toml"], "is not valid TOML")
        _refused([cmd, tmp_path / "binary.yaml"], "is not a text file")
    _refused(["run", case, "--out", afile, "--no-progress"], "is not allowed: it is a file; must be a folder")
    _refused(["run", case, "--out", afile / "sub", "--no-progress"], "is a file; must be a folder")
    _refused(["run", case, "--threads", 0], "--threads = 0 is not allowed")
    for cmd in (["run", case, "--no-progress"], ["bench"], ["validate", "--out", tmp_path / "v", "--no-progress"]):
        _refused(cmd + ["--backend", "gpu"], "backend = 'gpu' is not allowed: must be one of cpu, cuda")
    _refused(["bench", "--scene", "nope"], "scene = nope is not known: allowed are")
    _refused(["bench", "--from-dump", tmp_path], "--from-dump = ")
    _refused(["bench", "--json", tmp_path], "it is a folder; must be a file name")
    _refused(["sweep", tmp_path / "missing.yaml"], "sweep file")
    _refused(["sweep", tmp_path], "it is a folder; must be a file")
    (tmp_path / "sweep.yaml").write_text("case: rolling-flat\ngrid: {mur: [0.1]}\n")
    _refused(["sweep", tmp_path / "sweep.yaml", "--out", afile], "--out = ")
    _refused(["calibrate", "--experiment", "nope", "--target", 1], "experiment = 'nope' is not known")
    _refused(["calibrate", "--case", "nope", "--target", 1], "experiment = 'nope' is not known")  # the older name
    _refused(["calibrate", "--case", "rolling-flat", "--target", 1, "--out", afile], "it is a file; must be a folder")
    _refused(["validate", "--out", afile, "--no-progress"], "it is a file; must be a folder")
    _refused(["validate", "--experiment", "nope", "--out", tmp_path / "v", "--no-progress"],
             "experiment = nope is not known")
    _refused(["validate", "--case", "rolling-flat", "-w", 0, "--out", tmp_path / "v", "--no-progress"],
             "workers = 0 is not allowed")
    assert not (tmp_path / "v").exists()


# --- item 7: validate --model ---------------------------------------------------------------
def test_validate_refuses_an_unknown_model_up_front(tmp_path):
    _refused(["validate", "--model", "nonsense", "--out", tmp_path / "v", "--no-progress", "-w", 1],
             "model = 'nonsense' is not known to the experiments chosen: allowed are")
    _refused(["validate", "--case", "angle-of-repose", "--model", "sds", "--out", tmp_path / "v", "--no-progress"],
             "model = 'sds' is not known to the experiments chosen: allowed are angle-of-repose: 'cdt', 'epsd'")
    _refused(["validate", "--case", "repose-sweep", "--model", "cdt", "--model", "epsd", "--out", tmp_path / "v",
              "--no-progress"], "it sweeps one rolling model")
    assert not (tmp_path / "v").exists()


def test_python_api_refuses_output_and_input_paths_by_name(tmp_path):
    """The refusals the CLI makes up front hold for the Python functions too: an output folder that
    is a file, a dump that is a folder, a JSON path that is a folder; nothing is run or written."""
    from rollingdem.bench import column_from_dump, write_json
    from rollingdem.studies.calibration import Execution, calibrate
    from rollingdem.studies.sweep import run_sweep

    afile = tmp_path / "afile"
    afile.write_text("x")
    spec = {"case": "rolling-flat", "grid": {"mur": [0.1]}, "seeds": 1}
    with pytest.raises(rd.ParameterError, match=r"out = .*afile.* is a file; must be a folder"):
        run_sweep(spec, afile, workers=1)
    with pytest.raises(rd.ParameterError, match=r"out = .*under.* is not allowed: .*afile is a file"):
        run_sweep(spec, afile / "under", workers=1)
    with pytest.raises(rd.ParameterError, match=r"out = .*afile.* is a file; must be a folder"):
        calibrate("rolling-flat", target=0.1, fix={}, free="mur", out=afile, execution=Execution(workers=1))
    with pytest.raises(rd.ParameterError, match=r"from_dump = .* is a folder; must be the dump file"):
        column_from_dump(tmp_path)
    with pytest.raises(rd.ParameterError, match=r"json = .* is a folder; must be a file name"):
        write_json([], tmp_path)
    assert afile.read_text() == "x" and sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_sweep_refuses_a_twisting_model_that_needs_parameters():
    """A sweep parameter names a model only: 'sds' needs its constants, so it is refused when the
    sweep file is read, not as a failed run; 'marshall' (no parameters) is taken."""
    from rollingdem.studies.sweep import load_sweep

    spec = {"case": "angle-of-repose", "points": [{"mur": 0.1}], "seeds": 1}
    with pytest.raises(rd.ParameterError, match=r"twisting = 'sds' is not allowed: .*twisting_stiffness is missing"):
        load_sweep({**spec, "fixed": {"twisting": "sds"}})
    load_sweep({**spec, "fixed": {"twisting": "marshall"}})


def test_pile_run_refuses_settings_that_are_not_its_dataclasses():
    """pile_run's grouped settings come as PileMaterial and Collapse; anything else (a dict of the
    old keywords, say) is refused by name before a sphere is made."""
    from rollingdem.experiments.pile import pile_run

    with pytest.raises(rd.ParameterError, match=r"^material = \{'friction': 0.5\} is not allowed: .*PileMaterial"):
        pile_run(material={"friction": 0.5})
    with pytest.raises(rd.ParameterError, match=r"^collapse = 1.5 is not allowed: .*Collapse$"):
        pile_run(collapse=1.5)


def test_an_existing_output_file_may_be_written_again(tmp_path):
    """``--json results.json`` where results.json exists (a second run of a script) is allowed; a
    file where a folder is wanted, or a folder where a file is, is refused."""
    from rollingdem.errors import ParameterError, check_output_path

    old = tmp_path / "results.json"
    old.write_text("{}")
    assert check_output_path("--json", old, folder=False) == old
    with pytest.raises(ParameterError, match="it is a file; must be a folder"):
        check_output_path("--out", old)
    with pytest.raises(ParameterError, match="it is a folder; must be a file name"):
        check_output_path("--json", tmp_path, folder=False)
    with pytest.raises(ParameterError, match="is a file; must be a folder"):
        check_output_path("--json", old / "x.json", folder=False)


def test_a_youngs_modulus_in_pa_meant_in_mpa_is_warned_of(tmp_path):
    """E = 40 Pa (40 MPa meant): ``rollingdem check`` says valid, with a warning naming the material
    and the value (the command line prints it on one line: test_outlets_inflows); 40 MPa draws none."""
    import warnings

    case = tmp_path / "case.yaml"
    case.write_text(edit("youngs_modulus: 1.0e7", "youngs_modulus: 40.0"))
    with pytest.warns(RuntimeWarning, match="material 'm': youngs_modulus = 40 Pa is below 1000 Pa"):
        result = CliRunner().invoke(app, ["check", str(case)])
    assert result.exit_code == 0, result.output
    case.write_text(edit("youngs_modulus: 1.0e7", "youngs_modulus: 4.0e7"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert CliRunner().invoke(app, ["check", str(case)]).exit_code == 0
