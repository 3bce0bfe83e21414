"""Case 1 (EPSD, v0 = 1 m/s) across an x-periodic boundary (L = 0.1 m) against the plane without one:
the stop distance and the analytic 0.18836 m (issue 28). usage: python benchmarks/periodic_case1.py"""
import rollingdem as rd
from rollingdem.experiments import single_sphere as ss
# EPSD across the periodic boundary
sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), gravity=(0, 0, -ss.G), dt=ss.DT, periodic={"x": (-0.02, 0.08)})
sim.add_material(rd.Material("table1", **ss.TABLE1))
sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="table1"))
sim.add_particles([[0.0, 0.0, ss.RADIUS]], ss.RADIUS, "table1")
sim.run(0.2); sim.set_velocities([0], velocity=(1.0, 0, 0), angular_velocity=(0, 0, 0))
x0 = sim.unwrapped_positions[0, 0]; sim.run(0.8)
d = sim.unwrapped_positions[0, 0] - x0; a = ss.analytic_flat()[3]
print(f"EPSD case 1 across x-periodic (L = 0.1 m): distance {d:.6f} m, analytic {a:.6f}, rel {(d-a)/a:+.2e}, image {sim._state.image[0]}")
# the same on the plane without periodic
sim = ss.sphere_on_wall("epsd"); tr = ss.launch(sim, 0.8)
print(f"  plane without periodic: {tr.x[-1]:.6f} m")
