"""The figures of issue 45's closing note (wall motion, mesh fills, inflows), measured on the test scenes:
python benchmarks/geometry_figures.py (about a minute on 2 cores)."""
import math, time, numpy as np, sys
sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[1] / "tests" / "scene"))
import rollingdem as rd
import test_wall_motion as W
# servo
sim, lid, servo, area = W.servo_box()
sim.run(0.15)
held = []
for _ in range(50):
    sim.run(1e-3); held.append(sim.wall_loads()["lid"]["force"][2] / area)
held = np.array(held); print(f"servo 2000 Pa: min {held.min():.2f} max {held.max():.2f} mean {held.mean():.3f} Pa; max rel dev {np.abs(held/2000-1).max():.2e}")
# sideways plate
f, A = 5.0, 2e-3
sim, floor = W.sphere_on_floor(rd.Oscillation(frequency=f, amplitude=(A, 0, 0), phase=math.pi / 2))
t0, x0 = sim.time, sim.positions[0, 0]; worst = 0
for _ in range(20):
    sim.run(0.01); plate = A * (math.cos(2 * math.pi * f * (sim.time - t0)) - 1.0)
    worst = max(worst, abs((sim.positions[0, 0] - x0) - 2 / 7 * plate))
print(f"2/7 rolling: worst |x - 2/7 x_p| = {worst:.3e} m, {worst / (4/7*A):.2e} of the sphere's travel")
# vertical plate
for gamma in (0.8, 1.5):
    amp = gamma * 9.81 / (2 * math.pi * 20) ** 2
    sim, floor = W.sphere_on_floor(rd.Oscillation(frequency=20.0, amplitude=(0, 0, amp), phase=math.pi / 2))
    touching = []
    for k in range(150):
        sim.run(1e-3)
        if k >= 50: touching.append(sim.wall_loads()["floor"]["force"][2] < 0)
    print(f"Gamma {gamma}: in contact at {sum(touching)} of {len(touching)} samples")
# mesh fill
from rollingdem.scene.mesh import SHAPES
for amount, target in (("count", 800), ("mass", 0.15), ("fraction", 0.25)):
    sim = rd.Simulation(); sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    drum = sim.add_wall(rd.MeshWall(SHAPES["drum"](radius=0.05, length=0.04, segments=64), material="m"))
    reg = rd.MeshRegion(drum); t = time.perf_counter()
    sim.insert(reg, radius=rd.Uniform(0.002, 0.003), material="m", seed=5, **{amount: target})
    el = time.perf_counter() - t
    print(f"fill {amount}={target}: {sim.n_particles} spheres, mass {sim.masses.sum():.5f} kg, fraction {np.sum(4/3*np.pi*sim.radii**3)/reg.volume():.5f}, outside {int((~reg.contains(sim.positions, sim.radii)).sum())}, {el:.2f} s")
# ray test speed
reg = rd.MeshRegion(SHAPES["drum"](radius=0.05, length=0.1, segments=64))
x = np.random.default_rng(1).uniform(-0.06, 0.11, (200000, 3)); reg.inside(x[:10])
t = time.perf_counter(); reg.inside(x); print(f"ray test: 200,000 points, 256 triangles: {time.perf_counter()-t:.3f} s")
# inflow fractions
dist = rd.MassFractions([0.001, 0.002], [0.5, 0.5])
sim = rd.Simulation(gravity=(0, 0, 0)); sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
inflow = sim.add_inflow(rd.Rectangle((0, 0, 0), (0, 0, -1), (0.06, 0.06)), radius=dist, material="m", mass_rate=0.05, velocity=(0, 0, -1.0), seed=2, name="feed")
sim.run(0.2); print(inflow.realised())
# face inflow rate
for face in (rd.Disk(center=(0, 0, 0.1), normal=(0, 0, -1), radius=0.02),):
    sim = rd.Simulation(gravity=(0, 0, 0)); sim.add_material(rd.Material("m", 1e7, 0.3, 2500.0))
    sim.add_inflow(face, radius=0.002, material="m", mass_rate=0.05, velocity=(0, 0, -0.5), seed=1)
    flow = rd.MassFlow("face", point=(0, 0, 0.1), normal=(0, 0, -1), interval=1e-3, window=(0.1, 0.3))
    sim.run(0.3, observers=[flow]); print(f"disk face: mass rate through it {flow.summary()['rate']['mean']:.5f} kg/s (asked 0.05)")
