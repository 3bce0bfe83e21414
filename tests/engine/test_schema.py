"""The engine state's schema (``rollingdem.engine.schema``): a per-particle field declared once is
made, grown, re-sorted, taken out with its particles, saved and restored, and handed to the step
loop, with no other edit. (That it reaches the GPU is checked on the simulator, tests/engine/test_cuda.py.)"""

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.engine.schema import PER_PARTICLE, SCHEMA, Field
from rollingdem.engine.state import EngineState

TEMPERATURE = Field("temperature", fill=293.15, doc="K")


def marked(state) -> np.ndarray:
    """The value each particle should hold: 300 K + its tag (its number for good)."""
    return 300.0 + state.tags


def box_of_spheres(count=40, seed=4):
    sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=1e-5)
    sim.add_material(rd.Material("m", 1e7, 0.3, 2500, friction=0.5, rolling_friction=0.1, restitution=0.5))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_wall(rd.Cylinder(0.01, material="m"))
    sim.insert(rd.CylinderRegion(0.01, 0.0, 0.03), count, 0.001, "m", seed=seed)
    return sim


def test_a_declared_particle_field_follows_its_particles_everywhere(tmp_path):
    with SCHEMA.declared(TEMPERATURE):
        sim = box_of_spheres()
        st = sim._state
        assert st.temperature.shape == (40,) and np.all(st.temperature == 293.15)  # made, with its fill
        st.temperature[:] = marked(st)
        sim.insert(rd.CylinderRegion(0.01, 0.03, 0.05), 10, 0.001, "m", seed=5)  # grown: old rows kept, new ones filled
        assert np.array_equal(st.temperature[:40], marked(st)[:40]) and np.all(st.temperature[40:] == 293.15)
        st.temperature[:] = marked(st)
        sim.run(steps=200)
        before = st.ids.copy()
        st.sort(0.002)  # re-sorted in Morton order of 2 mm cells: the values move with their slots
        assert not np.array_equal(st.ids, before)  # the insertion's order was not that order
        assert np.array_equal(st.temperature, marked(st))
        gone = np.zeros(st.n, dtype=bool)
        gone[::3] = True
        st.remove(gone)  # taken out with its particles
        assert st.n == 50 - gone.sum() and np.array_equal(st.temperature, marked(st))
        assert "temperature" in st.records()[0]._fields  # handed to the step loop (and so to the device)
        assert np.array_equal(st.records()[0].temperature, marked(st))
        path = sim.checkpoint(tmp_path / "c.npz")  # saved and restored
        back = rd.Simulation.restore(path)
        assert np.array_equal(back._state.temperature, marked(back._state))
        assert np.array_equal(back._state.tags, st.tags)
    assert all(f.name != "temperature" for f in SCHEMA.of(PER_PARTICLE))
    assert not hasattr(EngineState(6), "temperature")  # gone with the declaration


def test_a_checkpoint_without_a_declared_field_restores_it_at_its_fill(tmp_path):
    """A checkpoint written before a field was declared gives its particles the field's fill."""
    sim = box_of_spheres(count=12)
    path = sim.checkpoint(tmp_path / "old.npz")
    with SCHEMA.declared(TEMPERATURE):
        back = rd.Simulation.restore(path)
        assert back._state.temperature.shape == (12,) and np.all(back._state.temperature == 293.15)


def test_a_field_is_declared_once():
    with pytest.raises(ValueError, match="'x' is declared already"):
        SCHEMA.declare(Field("x"))


def test_the_records_hold_the_fields_in_the_step_loops_order():
    """The particles' record is the schema's fields with a step-loop name, then the bonds', the
    clumps', the bond index and the clump index; tags (the user's numbers) stay on the host."""
    st = EngineState(6)
    fields = st.records()[0]._fields
    assert fields[:5] == ("x", "v", "w", "f", "t")
    assert fields[-4:] == ("bond_start", "bond_ends", "clump_start", "clump_members")
    assert fields.index("bond_pairs") < fields.index("clump_x") < fields.index("bond_start")
    assert "tags" not in fields and "bond_pairs" in fields
    assert st.records()[1]._fields[:12] == ("kind", "geometry", "velocity", "angular_velocity", "material", "program",
                                            "geometry_built", "moved", "history", "touching", "near", "load")


def test_a_simulation_reads_and_writes_a_field_in_the_particles_order():
    """``particle_field`` and ``set_particle_field`` go by the user's particle index, whatever the
    storage order; a lazy field gets rows when set; a bad name or value is one line."""
    from rollingdem.errors import ParameterError

    sim = box_of_spheres(count=12)
    sim.set_particle_field("fixed", [3], 1)  # lazy: no rows until now
    assert np.flatnonzero(sim.particle_field("fixed")).tolist() == [3] and sim.fixed[3]
    with SCHEMA.declared(TEMPERATURE):
        sim = box_of_spheres(count=12)
        sim._state.sort(0.002)  # storage order no longer the particles' order
        sim.set_particle_field("temperature", [0, 5], [310.0, 320.0])
        values = sim.particle_field("temperature")
        assert values[0] == 310.0 and values[5] == 320.0 and np.all(np.delete(values, [0, 5]) == 293.15)
        with pytest.raises(ParameterError, match="values = .* is not allowed for temperature"):
            sim.set_particle_field("temperature", [0, 1], [1.0, 2.0, 3.0])
    with pytest.raises(ParameterError, match="field = 'temperature' is not allowed: the per-particle fields are x, v"):
        sim.particle_field("temperature")
    with pytest.raises(ParameterError, match="field = 'ids' is not allowed: the engine keeps it; settable are x, v"):
        sim.set_particle_field("ids", [0], 5)


def test_taking_particles_out_keeps_the_states_backend():
    """``EngineState.remove`` (an outlet) makes the state anew from its arrays: the backend it
    steps on and what the backend keeps with it stay (a GPU run must not go on on the CPU)."""
    from rollingdem.engine.backends import BACKENDS, CpuBackend, register

    class Marked(CpuBackend):
        name = "cpu-marked"

    register(Marked())
    try:
        sim = box_of_spheres(count=12)
        sim.backend = "cpu-marked"
        sim._state.backend_data["cpu-marked"] = "kept"
        gone = np.zeros(12, dtype=bool)
        gone[:4] = True
        sim._state.remove(gone)
        assert sim.backend == "cpu-marked" and sim._state.backend_data == {"cpu-marked": "kept"}
        assert sim.n_particles == 8
    finally:
        BACKENDS.pop("cpu-marked", None)


def test_the_step_loops_record_types_pickle_by_reference():
    """Numba's disk cache keys each compiled function by its argument types and pickles them; a
    record class that plain pickle cannot find by its module and name is pickled by value and
    never matches in the next process, so every process would compile the step loop anew (30 s
    per contact law). The declared schema's particle and wall record types are their module's
    attributes; a field declared at run time gives types pickled by value, which a process that
    does not declare it can still read."""
    import pickle

    from numba import typeof
    from numba.core import serialize

    from rollingdem.engine import schema

    particles, walls = EngineState(6).records()[:2]
    for record in (particles, walls):
        assert pickle.loads(pickle.dumps(type(record))) is type(record)
        assert pickle.loads(pickle.dumps(typeof(record))) == typeof(record)
    assert type(particles) is schema.ParticleArrays and type(walls) is schema.WallArrays
    with SCHEMA.declared(TEMPERATURE):
        declared = EngineState(6).records()[0]
        assert type(declared) is not schema.ParticleArrays
        with pytest.raises(pickle.PicklingError):
            pickle.dumps(type(declared))  # not findable by name: numba's pickler takes it by value
        assert pickle.loads(serialize.dumps(typeof(declared))) == typeof(declared)
