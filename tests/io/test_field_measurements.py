"""The ``fields`` measurement (``rollingdem.ContinuumFields``): its quantities are the grid's
volume averages of what the particles and contacts hold, its time-averaged profile keeps the
momentum balance of a bed at rest, its .vti files hold the fields, and bad input is one line."""

import math
import re

import numpy as np
import pandas as pd
import pytest

import rollingdem as rd
from helpers import settled_glass_bed
from rollingdem.io.field_measurements import ContinuumFields, read_vti, stress_invariants


@pytest.fixture(scope="module")
def measured_bed(tmp_path_factory):
    """400 glass spheres (radius 0.9-1.1 mm, EPSD rolling resistance mu_r 0.2) settled on a floor in a
    box periodic along x and y, 14 mm wide, then 300 steps with the fields sampled every 100 steps
    (Lucy, w = 1.2 mm, written to a folder)."""
    sim = settled_glass_bed(0.014, 0.04, 400, seed=3)
    folder = tmp_path_factory.mktemp("fields")
    m = ContinuumFields("bed", width=0.0012, interval=100 * sim.dt).write_to(folder)
    sim.run(steps=300, observers=[m])
    return sim, m, folder


def test_its_quantities_are_the_grids_volume_averages(measured_bed):
    """With the grid's weights summing to one per particle and contact, the solid fraction averaged
    over the grid is the spheres' volume over the grid's (the box across x and y, the bed and a
    kernel cutoff each side along z), and the mean stress is the virial sum (kinetic and contact)
    over that volume: each to 1e-9 of itself, computed here from the state, not from the fields."""
    sim, m, _ = measured_bed
    g = m.grid
    assert g.periodic == (True, True, False) and g.lower[:2] == (0.0, 0.0) and g.upper[:2] == (0.014, 0.014)
    volume = float(np.prod(np.subtract(g.upper, g.lower)))
    row = m.series().iloc[-1]
    solid = float((4 / 3 * math.pi * sim.radii ** 3).sum()) / volume
    assert row["solid_fraction"] == pytest.approx(solid, rel=1e-9)
    c = sim.contact_forces()
    virial = np.einsum("ka,kb->ab", c["force"], c["branch"])
    v = sim.velocities  # the grid's mean velocity differs from node to node: the kinetic part is small
    kinetic = np.einsum("k,ka,kb->ab", sim.masses, v, v)
    p, tau = stress_invariants((virial + kinetic) / volume)
    assert row["pressure"] == pytest.approx(p, rel=1e-6)
    assert row["shear_stress"] == pytest.approx(tau, rel=1e-3)
    assert row["stress_ratio"] == pytest.approx(tau / p, rel=1e-3)
    couple = np.einsum("ka,kb->ab", c["moment"], c["branch"]) / volume
    assert row["couple_stress"] == pytest.approx(float(np.linalg.norm(couple)), rel=1e-9)
    assert row["couple_stress"] > 0.0  # rolling resistance carries moments in the bed


def test_the_mean_profile_holds_the_weight_above(measured_bed):
    """The written profile (the samples of the window averaged): at rest, sigma_zz(z) is g times the
    mass per area above z within 2 % from a kernel's cutoff above the floor to 2 mm below the top
    (momentum balance); the columns carry their units."""
    sim, m, folder = measured_bed
    text = (folder / "bed_profile.csv").read_text()
    assert text.startswith("# bed: ")
    df = pd.read_csv(folder / "bed_profile.csv", comment="#")
    assert {"z (m)", "solid_fraction (1)", "density (kg/m^3)", "stress_zz (Pa)", "couple_stress_xy (N/m)"} <= set(df)
    z, szz, rho = df["z (m)"].to_numpy(), df["stress_zz (Pa)"].to_numpy(), df["density (kg/m^3)"].to_numpy()
    dz = z[1] - z[0]
    weight_above = 9.81 * (np.cumsum(rho[::-1])[::-1] - 0.5 * rho) * dz
    top = float((sim.positions[:, 2] + sim.radii).max())
    inside = (z > m.kernel.cutoff) & (z < top - 0.002)
    assert inside.sum() >= 8
    np.testing.assert_allclose(szz[inside], weight_above[inside], rtol=0.02)
    assert 0.5 < df["solid_fraction (1)"][inside].mean() < 0.66  # a random packing of spheres


def _vti_array(data: bytes, name: str) -> np.ndarray:
    """An array of a .vti file with raw appended data, read as VTK reads it: its offset after the
    "_" that opens the appended data, a UInt32 byte count, then little-endian float32 values."""
    head = re.search(rb'Name="' + name.encode() + rb'" NumberOfComponents="(\d+)" format="appended" offset="(\d+)"',
                     data)
    start = data.index(b'<AppendedData encoding="raw">\n_') + len(b'<AppendedData encoding="raw">\n_') + int(head.group(2))
    count = int(np.frombuffer(data[start:start + 4], "<u4")[0])
    return np.frombuffer(data[start + 4:start + 4 + count], "<f4").reshape(-1, int(head.group(1)))


def test_each_sample_is_a_vti_file_in_a_pvd_series(measured_bed):
    """Four samples (steps 0, 100, 200, 300), four .vti files listed with their times in bed.pvd; a
    file's density and stress, in VTK's order (x fastest), are the fields' now as 32-bit floats, its
    extent the grid's."""
    sim, m, folder = measured_bed
    pvd = (folder / "bed.pvd").read_text()
    files = re.findall(r'timestep="([^"]+)" group="" part="0" file="([^"]+)"', pvd)
    assert [f for _, f in files] == [f"bed/bed_{k:05d}.vti" for k in range(4)]
    assert [float(t) for t, _ in files] == pytest.approx(list(m.series()["time"]))
    last = (folder / files[-1][1]).read_bytes()
    nx, ny, nz = m.grid.shape
    assert f'WholeExtent="0 {nx - 1} 0 {ny - 1} 0 {nz - 1}"'.encode() in last
    f = m.fields(sim)
    np.testing.assert_array_equal(_vti_array(last, "density")[:, 0],
                                  f.density.transpose(2, 1, 0).ravel().astype(np.float32))
    np.testing.assert_array_equal(_vti_array(last, "stress").reshape(nz, ny, nx, 3, 3),
                                  f.stress.transpose(2, 1, 0, 3, 4).astype(np.float32))
    assert last.endswith(b"</AppendedData>\n</VTKFile>\n")


def test_the_mean_grid_averages_the_windows_samples(measured_bed):
    """bed_mean.vti: the samples in the window (the second half of the samples' span: the last two of
    four) averaged node by node, each array; the arrays read back as VTK reads them."""
    _, m, folder = measured_bed
    window = [f"bed/bed_{k:05d}.vti" for k in (2, 3)]
    mean = (folder / "bed_mean.vti").read_bytes()
    for name in ("density", "solid_fraction", "velocity", "stress", "couple_stress"):
        expected = np.mean([_vti_array((folder / f).read_bytes(), name).astype(np.float64) for f in window], axis=0)
        np.testing.assert_allclose(_vti_array(mean, name), expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())
    assert read_vti(folder / window[0]).keys() == {"density", "solid_fraction", "velocity", "stress",
                                                   "kinetic_stress", "contact_stress", "couple_stress"}


def test_the_summary_carries_the_grid_and_the_profile(measured_bed):
    _, m, _ = measured_bed
    s = m.summary()
    assert s["samples"] >= 1 and s["grid"]["cells"] == list(m.grid.shape)
    assert len(s["profile"]["stress_zz (Pa)"]) == m.grid.shape[2]
    assert "solid_fraction" in m.summary_line() and "stress_ratio" in m.summary_line()


def test_stress_invariants_of_known_tensors():
    """Isotropic p I: (p, 0); simple shear tau (e_x e_z + e_z e_x): (0, tau); uniaxial s e_z e_z:
    (s/3, s/sqrt 3)."""
    assert stress_invariants(np.eye(3) * 7.0) == pytest.approx((7.0, 0.0))
    shear = np.zeros((3, 3))
    shear[0, 2] = shear[2, 0] = 3.0
    assert stress_invariants(shear) == pytest.approx((0.0, 3.0))
    axial = np.zeros((3, 3))
    axial[2, 2] = 6.0
    assert stress_invariants(axial) == pytest.approx((2.0, 6.0 / math.sqrt(3.0)))


@pytest.mark.parametrize("kwargs, message", [
    (dict(width=0.001, kernel="tophat"), "fields kernel = 'tophat' is not allowed: must be 'lucy' or 'gaussian'"),
    (dict(width=0.001, axis="r"), "fields axis = 'r' is not allowed"),
    (dict(width=0.001, cells=(4, 0, 4)), "fields cells = (4, 0, 4) is not allowed"),
    (dict(width=0.001, cells=(4, 4)), "fields cells = (4, 4) is not allowed"),
    (dict(width=-0.001), "kernel width = -0.001"),
    (dict(width=0.001, lower=(0, 0, 1), upper=(1, 1, 0)), "upper must be above lower"),
])
def test_bad_settings_are_one_line_each(kwargs, message):
    with pytest.raises(rd.ParameterError, match=re.escape(message)) as refused:
        ContinuumFields("f", **kwargs)
    assert "\n" not in str(refused.value)


def test_a_kernel_narrower_than_a_particle_or_wider_than_the_grid_is_refused(measured_bed):
    sim, _, _ = measured_bed
    with pytest.raises(rd.ParameterError, match=r"fields width = 0.0005 m is not allowed: must be at least the "
                                                r"largest particle.s radius, 0.0010"):
        ContinuumFields("f", width=0.0005).check(sim)
    with pytest.raises(rd.ParameterError, match=r"fields width = 0.02 m is not allowed: must be below the grid's "
                                                r"smallest side, 0.014 m"):
        ContinuumFields("f", width=0.02).grid_for(sim)


FIELDS_CASE = """\
name: fields-bed
materials:
  - {name: glass, youngs_modulus: 5.0e6, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, rolling_friction: 0.2}
contact: {normal: hertz, rolling: epsd}
periodic: {x: [0.0, 0.01], y: [0.0, 0.01]}
walls:
  - {type: plane, material: glass, point: [0, 0, 0], normal: [0, 0, 1]}
particles:
  - insert: {type: box, lo: [0, 0, 0], hi: [0.01, 0.01, 0.02]}
    count: 100
    radius: 0.001
    material: glass
    seed: 1
measurements:
  - {name: bed, type: fields, width: WIDTH, axis: z, interval: 0.01, window: [0.02, 0.04]}
stages:
  - {name: fall, duration: 0.04}
"""


def test_a_case_file_writes_the_fields_and_summarises_them(tmp_path):
    """``type: fields`` in a case file (100 spheres falling onto a floor for 0.04 s, sampled every
    0.01 s): its per-sample CSV, the profile averaged over the window, the .vti series, its entry
    in summary.json with the grid, and its plot in the report."""
    import json

    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(FIELDS_CASE.replace("WIDTH", "0.0015"))
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    out = tmp_path / "o" / "measurements"
    samples = pd.read_csv(out / "bed.csv", comment="#")
    assert len(samples) == 5 and (samples["solid_fraction"] > 0).all()
    profile = pd.read_csv(out / "bed_profile.csv", comment="#")
    assert list(profile.columns[:3]) == ["z (m)", "solid_fraction (1)", "density (kg/m^3)"]
    assert len(list((out / "bed").glob("bed_*.vti"))) == 5 and (out / "bed.pvd").exists()
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())["measurements"]["bed"]
    assert summary["kind"] == "fields" and summary["window"] == [0.02, 0.04] and summary["samples"] == 3
    assert summary["grid"]["periodic"] == [True, True, False]
    assert (tmp_path / "o" / "report" / "measurement_bed.png").exists()


def test_a_case_files_kernel_narrower_than_its_spheres_is_one_line_exit_2(tmp_path):
    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(FIELDS_CASE.replace("WIDTH", "0.0005"))
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 2
    assert "fields width = 0.0005 m is not allowed: must be at least the largest particle's radius" in result.output
    assert "Traceback" not in result.output


def test_a_window_after_the_run_is_one_line_exit_2(tmp_path):
    from typer.testing import CliRunner

    from rollingdem.cli import app

    case = FIELDS_CASE.replace("WIDTH", "0.0015").replace("window: [0.02, 0.04]", "window: [0.05, 0.06]")
    (tmp_path / "case.yaml").write_text(case)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 2
    assert "window = [0.05, 0.06] is not allowed: it starts after the run, which lasts at most 0.04 s" in result.output
