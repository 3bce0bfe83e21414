"""The examples of README.md run as a user would paste them, scaled down where the text says how
long they take, and deliver what their text promises."""

from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).parents[1]


def python_block(path: Path, after: str) -> str:
    """The first ```python block of ``path`` after the line ``after``."""
    text = path.read_text()
    return text[text.index(after):].split("```python\n", 1)[1].split("```", 1)[0]


def scaled(code: str, replacements: dict) -> str:
    """``code`` with each replacement made exactly once (a README edit that drops one fails here
    instead of running the example at full size)."""
    for old, new in replacements.items():
        assert code.count(old) == 1, f"README example changed: {old!r} found {code.count(old)} times"
        code = code.replace(old, new)
    return code


def test_the_readme_python_example_runs_and_its_checkpoint_continues_bit_for_bit(tmp_path, monkeypatch):
    """README, "Python": 1,000 spheres settled 0.6 s, the tube lifted, 1.5 s more, at 1/17 the
    spheres and 1/60 and 1/150 the durations (60 spheres, 0.01 s each, 2,000 steps in all). It writes
    the time series every 1 ms with particle 0's columns, VTK snapshots with their PVD, and a
    checkpoint from which ``rd.Simulation.restore`` continues bit for bit: 300 more steps of the
    restored run and of the original give equal positions and angular velocities."""
    import rollingdem as rd

    code = scaled(python_block(ROOT / "README.md", "## Python"),
                  {"count=1000": "count=60", "sim.run(0.6,": "sim.run(0.01,", "sim.run(1.5,": "sim.run(0.01,",
                   'rd.VTKSnapshots("out/vtk", interval=0.05)': 'rd.VTKSnapshots("out/vtk", interval=0.005)'})
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(code, "README.md", "exec"), scope)
    sim = scope["sim"]
    assert sim.n_particles == 60 and sim.step == 2000
    series = pd.read_csv(tmp_path / "out" / "series.csv")
    assert len(series) == 21  # t = 0, 1, ..., 20 ms: one row a millisecond, the settle's last sample not repeated
    assert any(c.startswith("p0_") for c in series.columns)
    assert len(list((tmp_path / "out" / "vtk").glob("*.vtu"))) >= 3
    assert list((tmp_path / "out" / "vtk").glob("*.pvd"))
    restored = rd.Simulation.restore("out/final.npz")
    sim.run(steps=300)
    restored.run(steps=300)
    np.testing.assert_array_equal(restored.positions, sim.positions)
    np.testing.assert_array_equal(restored.angular_velocities, sim.angular_velocities)
