"""20,000 fcc-packed spheres on a plate, Hertz + CDT: python benchmarks/packed_bed_speed.py THREADS."""
import sys, time, numpy as np, numba, rollingdem as rd
threads = int(sys.argv[1]); numba.set_num_threads(threads)
R=0.005
a = 2*np.sqrt(2)*R*(1-2e-5)   # fcc, neighbours overlap by ~1e-7 m: every sphere has 12 contacts
basis = np.array([[0,0,0],[0.5,0.5,0],[0.5,0,0.5],[0,0.5,0.5]])
n=18
cells = np.stack(np.meshgrid(np.arange(n),np.arange(n),np.arange(n),indexing="ij"),-1).reshape(-1,3)
x = ((cells[:,None,:]+basis[None]).reshape(-1,3))*a
x = x[:20000] + [0,0,R]
sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=1e-5, skin=0.002)
sim.add_material(rd.Material("t1", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5, rolling_damping=0.3))
sim.add_wall(rd.Plane(point=(0,0,0), normal=(0,0,1), material="t1"))
sim.add_particles(x, R, "t1", allow_overlap=True)
sim.run(steps=1000)
t0=time.perf_counter(); sim.run(steps=3000); t=time.perf_counter()-t0
print(f"fcc bed threads={threads} N={sim.n_particles} contact pairs/particle={sim.number_of_contacts()/sim.n_particles:.2f} "
      f"{sim.n_particles*3000/t/1e6:.2f} M particle-steps/s, rebuilds {sim._state.info[3]}")
