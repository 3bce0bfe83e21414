"""Ad-hoc speed check of issue 2 (until `rollingdem bench` exists): python benchmarks/engine_speed.py THREADS."""
import sys, time, numpy as np, numba, rollingdem as rd
threads = int(sys.argv[1]); numba.set_num_threads(threads)
R=0.005
def bed(n_side=25, layers=32):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=1e-5, skin=0.002)
    sim.add_material(rd.Material("t1", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5, rolling_damping=0.3))
    sim.add_wall(rd.Plane(point=(0,0,0), normal=(0,0,1), material="t1"))
    g = np.arange(n_side)*2*R*1.0001; z = R*1.0001 + np.arange(layers)*2*R*1.0001
    x = np.stack(np.meshgrid(g,g,z,indexing="ij"),-1).reshape(-1,3)
    sim.add_particles(x, R, "t1")
    return sim
t0=time.perf_counter(); sim=bed(); sim.run(steps=10); t_first=time.perf_counter()-t0
sim.run(steps=2000)   # contacts form under gravity
t0=time.perf_counter(); sim.run(steps=3000); t=time.perf_counter()-t0
print(f"bed20k threads={threads} N={sim.n_particles} contacts/particle={sim.number_of_contacts()/sim.n_particles:.2f} "
      f"{sim.n_particles*3000/t/1e6:.2f} M particle-steps/s  (first call incl. compile/load {t_first:.1f}s)")
# the default case, its tube removed at once after 0.6 s of settling
from rollingdem.io.casefile import load_case, build_simulation, default_case_path
spec = load_case(default_case_path()); sim = build_simulation(spec)
sim.run(0.6)
sim.remove_wall([w for w in sim.walls if w.name=="tube"][0])
t0=time.perf_counter(); sim.run(0.3); t=time.perf_counter()-t0
print(f"default-case collapse threads={threads} N={sim.n_particles} {sim.n_particles*30000/t/1e6:.2f} M particle-steps/s")
t0=time.perf_counter(); s1 = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=1e-5)
s1.add_material(rd.Material("t1", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2)); s1.add_wall(rd.Plane(material="t1"))
s1.add_particles([[0,0,R]], R, "t1"); s1.run(steps=10)
t0=time.perf_counter(); s1.run(steps=150000); print(f"single particle 150000 steps: {time.perf_counter()-t0:.2f}s threads={threads}")
