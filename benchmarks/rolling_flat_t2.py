"""Seed report test case 1 (docs/models.md §13 T2) per rolling model: stop time, distance, residual speed.

    python benchmarks/rolling_flat_t2.py
"""
import numpy as np

import rollingdem as rd

R = 0.005


def t2(rolling):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling=rolling), dt=1e-5)
    sim.add_material(rd.Material("m", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5,
                                 rolling_damping=0.3))
    sim.add_wall(rd.Plane(material="m"))
    sim.add_particles([[0, 0, R]], R, "m")
    sim.run(0.2)
    x0 = sim.positions[0, 0]
    sim.set_velocities([0], velocity=(1, 0, 0), angular_velocity=(0, 0, 0))
    ts, vs, xs = [], [], []
    for _ in range(800):
        sim.run(steps=100)
        ts.append(sim.time - 0.2)
        vs.append(sim.velocities[0, 0])
        xs.append(sim.positions[0, 0] - x0)
    ts, vs, xs = np.array(ts), np.array(vs), np.array(xs)
    return ts[np.argmax(vs < 1e-4)], xs[-1], np.abs(vs[ts > 0.7]).max()


MODELS = [("cdt", "cdt"), ("cdt liggghts", rd.CDT(parity="liggghts")), ("epsd", "epsd"),
          ("epsd liggghts", rd.EPSD(parity="liggghts")), ("epsd eta=0", rd.EPSD(damping_ratio=0.0)),
          ("epsd liggghts eta=0", rd.EPSD(damping_ratio=0.0, parity="liggghts")), ("epsd2", "epsd2"),
          ("epsd2 liggghts", rd.EPSD2(parity="liggghts")), ("epsd3 c=2.25", "epsd3"), ("rrlinear", "rrlinear"),
          ("sds k_roll=1e4", rd.SDS(1e4)), ("displacement_damping", rd.DisplacementDamping(damping=0.3))]
if __name__ == "__main__":
    print(f"{'model':24s} {'stop (s)':>9s} {'distance (m)':>12s} {'|v| after 0.7 s':>16s}")
    for label, model in MODELS:
        stop, dist, rest = t2(model)
        print(f"{label:24s} {stop:9.5f} {dist:12.5f} {rest:16.2e}")
    print("analytic                 0.50968      0.18836")
