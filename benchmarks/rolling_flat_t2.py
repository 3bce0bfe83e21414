"""Seed report test case 1 (MODELS.md §13 T2) per rolling model: stop time, distance, residual speed."""
import numpy as np, rollingdem as rd, time
R=0.005
def t2(rolling):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling), dt=1e-5)
    sim.add_material(rd.Material("m", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5, rolling_damping=0.3))
    sim.add_wall(rd.Plane(material="m"))
    sim.add_particles([[0,0,R]], R, "m")
    sim.run(0.2)
    x0 = sim.positions[0,0]
    sim.set_velocities([0], velocity=(1,0,0), angular_velocity=(0,0,0))
    ts=[]; vs=[]; xs=[]
    for k in range(800):
        sim.run(steps=100); ts.append(sim.time-0.2); vs.append(sim.velocities[0,0]); xs.append(sim.positions[0,0]-x0)
    ts=np.array(ts); vs=np.array(vs); xs=np.array(xs)
    stop = ts[np.argmax(vs < 1e-4)]
    return stop, xs[-1], np.abs(vs[ts>0.7]).max()
for r in ["cdt", "epsd", rd.EPSD(parity="liggghts"), rd.EPSD(damping_ratio=0.0), "epsd2", rd.EPSD2(parity="liggghts")]:
    print(r, t2(r))
print("analytic 0.50968 0.18836")
