"""Continuum fields as a measurement: coarse-grained fields on a grid sampled during a run
(``rollingdem.analysis.fields``), as MercuryDPM's MercuryCG or LIGGGHTS's ``fix ave/euler``.

Each sample's grid is written as ParaView ImageData (``{name}/{name}_NNNNN.vti``, listed with its
time in ``{name}.pvd``) and the window's samples averaged node by node as ``{name}_mean.vti``; the
profile along one axis, averaged over the window, as ``{name}_profile.csv`` (columns with their
units); and per sample the grid's volume averages as the measurement's quantities (``{name}.csv``,
the summary and the report)."""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from rollingdem.analysis.fields import Gaussian, Grid, Lucy, coarse_grain, profile
from rollingdem.errors import Declared, ParameterError, check_vector
from rollingdem.io.measurements import Measurement

KERNELS = {"lucy": Lucy, "gaussian": Gaussian}


def stress_invariants(stress: np.ndarray) -> tuple[float, float]:
    """(p, sqrt J2) of a stress tensor (Pa, compressive positive): the mean normal stress tr(sigma)/3
    and the shear stress sqrt(s:s / 2) of its deviator s = sigma - p I."""
    sym = 0.5 * (stress + stress.T)
    p = float(np.trace(sym)) / 3.0
    s = sym - p * np.eye(3)
    return p, float(math.sqrt(0.5 * float(np.sum(s * s))))


class ContinuumFields(Measurement):
    """Coarse-grained fields of all particles and their contacts on a grid (docs/analysis.md,
    "Continuum fields"), with a ``kernel`` ("lucy": cutoff 2 w; "gaussian": cut at 3 w) of ``width``
    w, at least the largest particle's radius. The grid's nodes are ``cells`` along x, y, z (default:
    a node per w) from ``lower`` to ``upper`` (default: the particles at the first sample, a cutoff
    beyond them; a periodic axis spans its box and wraps).

    Quantities, each sample's average over the grid's volume: ``solid_fraction``, ``pressure`` (the
    mean normal stress tr(sigma)/3, kinetic and contact, Pa), ``shear_stress`` (sqrt J2 of the mean
    stress's deviator, Pa), ``stress_ratio`` (their ratio: the bulk friction tau / p) and
    ``couple_stress`` (the Frobenius norm of the mean couple stress, N/m: what rolling and twisting
    resistance carry). A grid that covers the material and no more (a periodic box) makes them the
    material's; a wider grid's averages include its empty part."""

    kind = "fields"
    INTERVAL = 0.01
    QUANTITIES = {"solid_fraction": "1", "pressure": "Pa", "shear_stress": "Pa", "stress_ratio": "1",
                  "couple_stress": "N/m"}
    declared = {**Measurement.declared,
                "width": Declared("the kernel's width w: Lucy's cutoff is 2 w, the Gaussian is cut at 3 w; at "
                                  "least the largest particle's radius", "m", low=0.0, low_open=True),
                "kernel": Declared("the coarse-graining kernel: lucy or gaussian", kind="text"),
                "cells": Declared("grid nodes along x, y and z (default: one per kernel width)", "-",
                                  kind="numbers"),
                "lower": Declared("the grid's lower corner (default: a kernel cutoff below the particles; a "
                                  "periodic axis: its box)", "m", kind="vector"),
                "upper": Declared("the grid's upper corner (default: a kernel cutoff above the particles; a "
                                  "periodic axis: its box)", "m", kind="vector"),
                "axis": Declared("the axis of the time-averaged profile: x, y or z", kind="text"),
                "vtk": Declared("write each sample's grid for ParaView (.vti files and a .pvd series)", kind="flag")}

    def __init__(self, name: str, width: float, kernel: str = "lucy", cells=None, lower=None, upper=None,
                 axis: str = "z", vtk: bool = True, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        if kernel not in KERNELS:
            raise ParameterError(f"fields kernel = {kernel!r} is not allowed: must be 'lucy' or 'gaussian'")
        self.kernel = KERNELS[kernel](width)
        if axis not in ("x", "y", "z"):
            raise ParameterError(f"fields axis = {axis!r} is not allowed: must be 'x', 'y' or 'z'")
        self.axis = axis
        if cells is not None:
            if (np.ndim(cells) != 1 or len(cells) != 3
                    or not all(isinstance(c, (int, float, np.integer, np.floating)) and not isinstance(c, bool)
                               and float(c).is_integer() and c >= 1 for c in cells)):
                raise ParameterError(f"fields cells = {cells!r} is not allowed: must be three whole numbers >= 1 "
                                     "(nodes along x, y, z)")
            cells = tuple(int(c) for c in cells)
        self.cells = cells
        self.lower = None if lower is None else np.array(check_vector("fields lower", lower), float)
        self.upper = None if upper is None else np.array(check_vector("fields upper", upper), float)
        if self.lower is not None and self.upper is not None and not (self.upper > self.lower).all():
            raise ParameterError(f"fields lower = {self.lower.tolist()}, upper = {self.upper.tolist()} is not "
                                 "allowed: upper must be above lower on every axis (m)")
        self.vtk = bool(vtk)
        self.grid: Grid | None = None
        self._profiles: list[dict] = []
        self._series: list[tuple[float, str]] = []  # (time, .vti file) of each written sample

    def describe(self) -> str:
        k = self.kernel
        return f"continuum fields, {type(k).__name__} kernel of width {k.width:g} m"

    # --- the grid ----------------------------------------------------------------------------------
    def check(self, sim) -> None:
        if sim.shear.active:
            raise ParameterError(f"fields {self.name!r} is not allowed in a sheared (Lees-Edwards) box: its kernels "
                                 "wrap across the gradient's ends without the images' shift and velocity jump; "
                                 "rollingdem.analysis.rheology.box_stress gives the box's mean stress")
        if sim.mesh_walls():
            raise ParameterError(f"fields {self.name!r} is not allowed in a scene with triangle-mesh walls: their "
                                 "contact points are not kept, so their contact stress cannot be spread")
        if sim.n_particles:
            largest = float(sim.radii.max())
            if self.kernel.width < largest:
                raise ParameterError(f"fields width = {self.kernel.width:g} m is not allowed: must be at least the "
                                     f"largest particle's radius, {largest:g} m (a narrower kernel resolves "
                                     "single particles, not a continuum)")

    def grid_for(self, sim) -> Grid:
        """The grid: as given, else the particles' extent now widened by a kernel cutoff (a periodic
        axis: its box); refused where the kernel is wider than the grid."""
        x, r = sim.positions, sim.radii
        cut = self.kernel.cutoff
        lo = self.lower if self.lower is not None else (x - r[:, None]).min(axis=0) - cut
        hi = self.upper if self.upper is not None else (x + r[:, None]).max(axis=0) + cut
        lo, hi = np.array(lo, float), np.array(hi, float)
        periodic = [False, False, False]
        for a, axis in enumerate("xyz"):
            if axis in sim.periodic:
                lo[a], hi[a] = sim.periodic[axis]
                periodic[a] = True
        extent = hi - lo
        if self.kernel.width > extent.min():
            raise ParameterError(f"fields width = {self.kernel.width:g} m is not allowed: must be below the grid's "
                                 f"smallest side, {extent.min():g} m")
        cells = self.cells or tuple(max(1, int(round(e / self.kernel.width))) for e in extent)
        return Grid(tuple(lo), tuple(hi), cells, tuple(periodic))

    # --- a sample ----------------------------------------------------------------------------------
    def fields(self, sim):
        """The fields now (``rollingdem.analysis.fields.Fields``) on this measurement's grid."""
        if self.grid is None:
            self.grid = self.grid_for(sim)
        r = sim.radii
        return coarse_grain(self.grid, self.kernel, sim.positions, sim.masses, sim.velocities, sim.contact_forces(),
                            volumes=4.0 / 3.0 * math.pi * r ** 3)

    def values(self, sim):
        return self._quantities(self.fields(sim))

    def observe(self, sim) -> None:
        f = self.fields(sim)
        self._profiles.append(profile(f, self.axis))
        if self.vtk and self.directory is not None:
            folder = self.directory / self.name
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f"{self.name}_{len(self._series):05d}.vti"
            write_vti(path, f)
            self._series.append((sim.time, f"{self.name}/{path.name}"))
            write_pvd(self.directory / f"{self.name}.pvd", self._series)
        self._record(sim, self._quantities(f))

    @staticmethod
    def _quantities(f) -> list[float]:
        p, tau = stress_invariants(f.stress.mean(axis=(0, 1, 2)))
        couple = f.couple_stress.mean(axis=(0, 1, 2))
        return [float(f.solid_fraction.mean()), p, tau, tau / p if p > 0.0 else math.nan,
                float(np.sqrt(np.sum(couple * couple)))]

    # --- the end -----------------------------------------------------------------------------------
    def mean_profile(self) -> dict:
        """The profile along ``axis`` averaged over the samples in the window ({column (unit): array});
        empty without samples there."""
        chosen = self._in_window(self._profiles)
        if not chosen:
            return {}
        return {column: np.mean([p[column] for p in chosen], axis=0) for column in chosen[0]}

    def _in_window(self, per_sample: list) -> list:
        """The entries of ``per_sample`` (one per sample) of the samples in the summary's window."""
        if not self._rows:
            return []
        return [item for item, inside in zip(per_sample, self._inwindow_of()[2]) if inside]

    def finish(self, sim, failure=None) -> None:
        super().finish(sim, failure)
        mean = self.mean_profile()
        if self.directory is not None and mean:
            with open(self.directory / f"{self.name}_profile.csv", "w", newline="") as out:
                t0, t1 = self._inwindow_of()[1]
                out.write(f"# {self.name}: {self.describe()}; the profile along {self.axis} averaged over "
                          f"{t0:.6g}-{t1:.6g} s\n")
                writer = csv.writer(out)
                writer.writerow(list(mean))
                for row in zip(*mean.values()):
                    writer.writerow([repr(float(v)) for v in row])
            self._write_mean_grid()

    def _write_mean_grid(self) -> None:
        """``NAME_mean.vti``: the grids of the window's samples (their .vti files) averaged node by node."""
        files = [self.directory / name for _, name in self._in_window(self._series)]
        if not files:
            return
        total = {}
        for path in files:  # one file at a time: a long run's samples need not fit in memory together
            for name, values in read_vti(path).items():
                total[name] = total.get(name, 0.0) + values.astype(np.float64)
        write_vti_arrays(self.directory / f"{self.name}_mean.vti", self.grid,
                         {k: v / len(files) for k, v in total.items()})

    def summary(self) -> dict:
        out = super().summary()
        if out["samples"]:
            out["grid"] = {"lower": list(self.grid.lower), "upper": list(self.grid.upper),
                           "cells": list(self.grid.shape), "periodic": list(self.grid.periodic)}
            out["profile"] = {column: values.tolist() for column, values in self.mean_profile().items()}
        return out

    def headline(self):
        return ["solid_fraction", "pressure", "stress_ratio"]


#: the fields a .vti file holds: name, the Fields attribute, components
VTI_ARRAYS = (("density", "density", 1), ("solid_fraction", "solid_fraction", 1), ("velocity", "velocity", 3),
              ("stress", "stress", 9), ("kinetic_stress", "kinetic_stress", 9), ("contact_stress", "contact_stress", 9),
              ("couple_stress", "couple_stress", 9))


def write_vti(path: Path, f) -> None:
    """The fields ``f`` as VTK ImageData (``write_vti_arrays``)."""
    nx, ny, nz = f.grid.shape
    arrays = {name: getattr(f, attribute).reshape(nx, ny, nz, components).transpose(2, 1, 0, 3).reshape(-1, components)
              for name, attribute, components in VTI_ARRAYS if getattr(f, attribute) is not None}
    write_vti_arrays(path, f.grid, arrays)


def write_vti_arrays(path: Path, grid: Grid, arrays: dict) -> None:
    """Arrays (nodes x components, nodes in VTK's order: x fastest) on ``grid`` as VTK ImageData,
    nodes at the cells' centres, as 32-bit floats appended raw after the XML (each array a UInt32
    byte count, then its bytes)."""
    nx, ny, nz = grid.shape
    origin = np.asarray(grid.lower, float) + 0.5 * grid.spacing
    heads, blocks, offset = [], [], 0
    for name, values in arrays.items():
        raw = np.ascontiguousarray(values, dtype="<f4").tobytes()
        heads.append(f'<DataArray type="Float32" Name="{name}" NumberOfComponents="{values.shape[1]}" '
                     f'format="appended" offset="{offset}"/>')
        blocks += [np.uint32(len(raw)).astype("<u4").tobytes(), raw]
        offset += 4 + len(raw)
    extent = f"0 {nx - 1} 0 {ny - 1} 0 {nz - 1}"
    xml = ('<?xml version="1.0"?>\n<VTKFile type="ImageData" version="0.1" byte_order="LittleEndian" '
           'header_type="UInt32">\n'
           f'<ImageData WholeExtent="{extent}" Origin="{" ".join(map(repr, origin.tolist()))}" '
           f'Spacing="{" ".join(map(repr, grid.spacing.tolist()))}">\n<Piece Extent="{extent}">\n'
           '<PointData Scalars="density">\n' + "\n".join(heads) + "\n</PointData>\n</Piece>\n</ImageData>\n"
           '<AppendedData encoding="raw">\n_')
    with open(path, "wb") as out:
        out.write(xml.encode("ascii"))
        for block in blocks:
            out.write(block)
        out.write(b"\n</AppendedData>\n</VTKFile>\n")


def read_vti(path: Path) -> dict:
    """The point arrays of a .vti file ``write_vti_arrays`` wrote, by name (nodes x components,
    float32, VTK's order)."""
    data = Path(path).read_bytes()
    mark = b'<AppendedData encoding="raw">\n_'
    start = data.index(mark) + len(mark)
    out = {}
    for name, components, offset in re.findall(rb'Name="([^"]+)" NumberOfComponents="(\d+)" format="appended" '
                                                rb'offset="(\d+)"', data[:start]):
        at = start + int(offset)
        count = int(np.frombuffer(data[at:at + 4], "<u4")[0])
        out[name.decode()] = np.frombuffer(data[at + 4:at + 4 + count], "<f4").reshape(-1, int(components))
    return out


def write_pvd(path: Path, series) -> None:
    """A ParaView collection of (time, file) pairs."""
    rows = "\n".join(f'<DataSet timestep="{t!r}" group="" part="0" file="{name}"/>' for t, name in series)
    path.write_text('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n<Collection>\n'
                    f"{rows}\n</Collection>\n</VTKFile>\n")


__all__ = ["ContinuumFields", "read_vti", "stress_invariants", "write_pvd", "write_vti", "write_vti_arrays"]
