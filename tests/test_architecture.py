"""The package's structure: its import graph has no cycle, the layers import one way, every
module says in a docstring what it is for, and no plain-Python function takes more than 12
parameters.

The graph is read from the source with :mod:`ast` (nothing is imported): every ``import`` and
``from ... import`` in a module, at its top or inside a function, relative ones resolved, gives an
edge to the module of the package it names (``from .x import name`` goes to ``x``, ``from . import
y`` to ``y`` when that is a module and to the package otherwise).
"""

import ast
import re
from pathlib import Path

import pytest
import rollingdem as rd

PACKAGE = "rollingdem"
SOURCE = Path(__file__).parents[1] / "src" / PACKAGE


#: The layers, each a folder of the package (or a front end at its top), and the layers each may
#: import besides its own: engine below, then the scene a user builds, input and output, the
#: experiments, the studies over many runs, and the front ends above them all (docs/architecture.md).
#: ``analysis`` measures arrays of positions and radii and needs nothing else.
LAYER_IMPORTS = {
    "errors": set(),
    "physics": {"errors"},
    "engine": {"errors", "physics"},
    "analysis": {"errors"},
    "scene": {"errors", "physics", "engine"},
    "io": {"errors", "physics", "engine", "scene", "analysis"},
    "experiments": {"errors", "physics", "engine", "scene", "io", "analysis"},
    "studies": {"errors", "physics", "engine", "scene", "io", "analysis", "experiments"},
}
#: the front ends: the package's own namespace, the command line, ``validate`` and ``bench``
FRONT_ENDS = {"rollingdem", "cli", "validate", "bench"}


def layer_of(module: str) -> str:
    """The layer of a package module: its folder under the package, or its own name at the top."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def layer_violations(graph) -> list[str]:
    """Every import that goes against ``LAYER_IMPORTS`` (front ends may import anything), and every
    module in no known layer, as 'module (line n) -> module' lines."""
    found = []
    for module, edges in sorted(graph.items()):
        layer = layer_of(module)
        if layer in FRONT_ENDS:
            continue
        if layer not in LAYER_IMPORTS:
            found.append(f"{module}: in no layer (add its folder to LAYER_IMPORTS or put it in one)")
            continue
        for target, line in sorted(edges.items()):
            other = layer_of(target)
            if other != layer and other not in LAYER_IMPORTS[layer]:
                found.append(f"{module} (line {line}) -> {target}: {layer} may not import {other}")
    return found


def module_files() -> dict[str, Path]:
    """Module name -> its file, for every ``.py`` file of the package (a package is its ``__init__``)."""
    files = {}
    for path in sorted(SOURCE.rglob("*.py")):
        parts = (PACKAGE,) + path.relative_to(SOURCE).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        files[".".join(parts)] = path
    return files


def import_graph() -> dict[str, dict[str, int]]:
    """Module -> {module it imports: line of the first such import}, within the package only."""
    files = module_files()
    graph = {}
    for name, path in files.items():
        is_package = path.name == "__init__.py"
        edges: dict[str, int] = {}
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = name.split(".") if is_package else name.split(".")[:-1]
                    base = base[:len(base) - (node.level - 1)]
                    origin = ".".join(base + ([node.module] if node.module else []))
                else:
                    origin = node.module or ""
                for alias in node.names:
                    sub = f"{origin}.{alias.name}"
                    targets.append(sub if sub in files else origin)
            for target in targets:
                # "import a.b.c" of a module not in the table (an attribute path): its longest known prefix
                while target and target not in files:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    edges.setdefault(target, node.lineno)
        graph[name] = edges
    return graph


def strongly_connected(graph) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def a_cycle(graph, component) -> list[str]:
    """One cycle through the first module of ``component``, as 'module (line) -> ...' steps."""
    start, members = component[0], set(component)
    paths, seen = {start: [start]}, {start}
    queue = [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v]):
            if w == start:
                path = paths[v] + [start]
                return [f"{a} (line {graph[a][b]})" for a, b in zip(path, path[1:])] + [start]
            if w in members and w not in seen:
                seen.add(w)
                paths[w] = paths[v] + [w]
                queue.append(w)
    return component


def test_the_graph_sees_function_level_and_relative_imports():
    """The reader resolves what this test relies on: an import inside a function (the registry
    imports experiments.single_sphere when a rolling model is named) and ``from package import
    module`` (codegen imports the step template so)."""
    graph = import_graph()
    assert "rollingdem.experiments.single_sphere" in graph["rollingdem.experiments.registry"]
    assert "rollingdem.engine.template" in graph["rollingdem.engine.codegen"]
    assert "rollingdem.experiments" in graph["rollingdem.studies.sweep"]


def test_the_import_graph_has_no_cycle():
    graph = import_graph()
    cycles = list(strongly_connected(graph))
    report = "\n".join(" -> ".join(a_cycle(graph, c)) + f"\n    (all modules of this circle: {', '.join(c)})"
                       for c in cycles)
    assert not cycles, f"import cycles in {PACKAGE}:\n{report}"


def test_the_layer_check_finds_an_import_upwards_and_a_module_outside_the_layers():
    """On a made-up graph: physics importing the engine, the engine the scene, and a module at the
    top that is no front end are each reported; imports downwards and within a layer are not."""
    graph = {"rollingdem.physics.a": {"rollingdem.engine.b": 3, "rollingdem.physics.c": 4, "rollingdem.errors": 5},
             "rollingdem.engine.b": {"rollingdem.scene.d": 7, "rollingdem.physics.a": 8},
             "rollingdem.scene.d": {"rollingdem.engine.b": 9},
             "rollingdem.stray": {},
             "rollingdem.cli": {"rollingdem.studies.e": 1}}
    assert layer_violations(graph) == [
        "rollingdem.engine.b (line 7) -> rollingdem.scene.d: engine may not import scene",
        "rollingdem.physics.a (line 3) -> rollingdem.engine.b: physics may not import engine",
        "rollingdem.stray: in no layer (add its folder to LAYER_IMPORTS or put it in one)"]


def test_the_layers_import_one_way():
    """The compiled core (physics, engine) imports nothing above it; the scene no input or output,
    experiment or study; the experiments no study; every module sits in a layer."""
    found = layer_violations(import_graph())
    assert not found, "imports against the layers (docs/architecture.md, Layers):\n" + "\n".join(found)


def test_every_module_has_a_docstring():
    missing = [name for name, path in module_files().items()
               if not (ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or "").strip()]
    assert not missing, f"modules without a docstring saying what they are for: {', '.join(missing)}"


def worked_example(title: str = "### Worked example: a rolling law", block: int = 0) -> str:
    """The Python block number ``block`` (from 0) of the docs/architecture.md section ``title``."""
    text = (SOURCE.parents[1] / "docs" / "architecture.md").read_text()
    section = text[text.index(title):]
    return section.split("```python\n")[block + 1].split("```", 1)[0]


def test_worked_example_adds_a_backend():
    """docs/architecture.md's serial backend: registered by name, a Simulation steps on it, and a
    bed of 600 spheres (threaded on the ``cpu`` backend above 512) ends bit for bit where the ``cpu``
    backend's threads leave it."""
    import numpy as np

    import rollingdem as rd
    from rollingdem.engine.backends import BACKENDS

    scope = {}
    try:
        exec(compile(worked_example("### Worked example: a backend"), "architecture.md", "exec"), scope)
        ends = {}
        for name in ("cpu", "cpu-serial"):
            sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), dt=1e-5, backend=name)
            sim.add_material(rd.Material("m", 1e7, 0.3, 2500, friction=0.5, rolling_friction=0.1, restitution=0.5))
            sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
            sim.insert(rd.BoxRegion((-0.02, -0.02, 0.0), (0.02, 0.02, 0.05)), 600, 0.001, "m", seed=2)
            assert sim.backend == name
            sim.run(steps=300)
            ends[name] = (sim.positions, sim.angular_velocities)
        module = sim.engine_module()
        assert scope["SerialCpu"]().step_loop(None, module) is module.advance_serial
        assert BACKENDS["cpu"].step_loop(sim._state, module) is (module.advance_serial if sim._state.serial()
                                                                else module.advance)
        for a, b in zip(ends["cpu"], ends["cpu-serial"]):
            np.testing.assert_array_equal(a, b)
    finally:
        BACKENDS.pop("cpu-serial", None)


def test_worked_example_adds_a_wall_type():
    """docs/architecture.md's square plate: the sphere dropped on it rests at the Hertz overlap of
    its weight, delta = (3 m g / (4 E* sqrt(R)))^(2/3) with the wall of the sphere's material,
    E* = E / (2 (1 - nu^2)) (docs/models.md §0); to 2 % of delta, wider than the plate's residual
    motion (a speed of 1e-10 m/s) and narrower than a factor 2 wrong in E*, m or g (delta 59 %
    off) or the factor (1 - nu^2) left out (16 % off); and the plate's load is the weight, to 1e-6."""
    import math

    scope = {}
    exec(compile(worked_example("### Worked example: a wall type"), "architecture.md", "exec"), scope)
    sim = scope["sim"]
    radius, weight = 0.002, float(sim.masses[0]) * 9.81
    e_star = 1e7 / (2 * (1 - 0.45 ** 2))
    delta = (3 * weight / (4 * e_star * math.sqrt(radius))) ** (2 / 3)
    assert abs((radius - sim.positions[0, 2]) - delta) < 0.02 * delta
    fx, fy, fz = sim.wall_loads()["plate"]["force"]
    assert abs(fz + weight) < 1e-6 * weight and abs(fx) + abs(fy) < 1e-9 * weight


def test_worked_example_adds_an_experiment(tmp_path):
    """docs/architecture.md's free fall: registered by its definition, observed at a point against
    t = sqrt(2 (h - R) / g) to the example's own tolerance, validated (its checks pass),
    found by ``rollingdem validate`` and by a sweep file, and refused with its limits."""
    import math

    import pytest

    import rollingdem as rd
    from rollingdem import validate
    from rollingdem.experiments import EXPERIMENTS, get_experiment
    from rollingdem.studies.sweep import load_sweep, run_sweep

    scope = {}
    try:
        exec(compile(worked_example("### Worked example: an experiment"), "architecture.md", "exec"), scope)
        experiment = get_experiment("free-fall", observable=True)
        found = experiment.observe({"height": 0.1})["touch_time"]
        exact = math.sqrt(2 * (0.1 - 0.005) / 9.81)
        assert exact <= found + 1e-12 and found - exact <= 11e-5  # a look after the touch, within 10 steps and one
        assert experiment.validate(quick=True).passed
        assert "free-fall" in validate.available_experiments()
        results = validate.run_validation(tmp_path / "report", experiments=["free-fall"], quick=True, progress=False,
                                          workers=1)
        assert [r.passed for r in results] == [True]
        spec = load_sweep({"experiment": "free-fall", "grid": {"height": [0.02, 0.08]}})
        table = run_sweep(spec, tmp_path / "sweep", progress=False, summary=False, mapper=map).table
        assert sorted(table["touch_time"]) == pytest.approx([math.sqrt(2 * (h - 0.005) / 9.81) for h in (0.02, 0.08)],
                                                            abs=11e-5)
        with pytest.raises(rd.ParameterError, match="it takes no seed"):  # a deterministic experiment
            load_sweep({"experiment": "free-fall", "grid": {"height": [0.02]}, "seeds": 3})
        with pytest.raises(rd.ParameterError, match=r"height = 0.001 is not allowed: must lie in \[0.01, inf\) m"):
            experiment.observe({"height": 0.001})
    finally:
        EXPERIMENTS.pop("free-fall", None)


def test_experiments_share_one_registry_and_no_public_name():
    """Every experiment is in ``EXPERIMENTS`` once, ``rollingdem validate`` runs each, and sweeps
    take exactly those with parameters; no public function or class name is defined in two
    modules of ``experiments/``."""
    from rollingdem import validate
    from rollingdem.experiments import EXPERIMENTS

    assert set(EXPERIMENTS) <= set(validate.available_experiments())
    assert {n for n, e in EXPERIMENTS.items() if e.observable} == {
        "inclined-wall", "rolling-flat", "angle-of-repose", "repose-rough-base", "rotating-drum", "silo-discharge",
        "clump-stand-in", "coarse-graining", "simple-shear", "inclined-plane"}
    defined = {}
    for path in sorted((SOURCE / "experiments").glob("*.py")):
        for node in ast.parse(path.read_text()).body:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)) and not node.name.startswith("_"):
                defined.setdefault(node.name, []).append(path.name)
    twice = {name: where for name, where in defined.items() if len(where) > 1}
    assert not twice, f"public names defined in two modules: {twice}"


def test_worked_example_adds_a_per_particle_field(tmp_path):
    """docs/architecture.md's temperature field: declared once, every particle has it at its fill,
    the value set on one survives a checkpoint, and the step loop's record holds it."""
    import numpy as np

    import rollingdem as rd
    from rollingdem.engine.schema import PER_PARTICLE, SCHEMA

    scope = {}
    try:
        exec(compile(worked_example("### Worked example: a per-particle field"), "architecture.md", "exec"), scope)
        sim = scope["sim"]
        assert np.array_equal(sim.particle_field("temperature"), [293.15, 350.0])
        assert np.array_equal(sim._state.records()[0].temperature, [293.15, 350.0])
        back = rd.Simulation.restore(sim.checkpoint(tmp_path / "t.npz"))
        assert np.array_equal(back.particle_field("temperature"), [293.15, 350.0])
    finally:
        SCHEMA.fields[PER_PARTICLE] = [f for f in SCHEMA.of(PER_PARTICLE) if f.name != "temperature"]


def test_worked_example_adds_a_rolling_law_without_editing_the_package(tmp_path, monkeypatch):
    """docs/architecture.md's toy law, one class and one function in a module of its own, and the
    material property it declares beside it, run on the rolling-flat case (validation case 1) and
    stop the sphere when theory says.

    M0 = mu_r' R m g with mu_r' = 0.1 makes it CDT's moment at rest for mu_r' (the material's own
    mu_r is 0.2: a law reading that instead stops twice as early), so the analytic case-1 solution
    with mu_r' gives the stop, 1.02 s. Tolerance 0.5 %: the stop is detected at 1 mm/s, 1.4 ms
    (0.14 %) before rest, sampled every 0.1 ms; the wall contact's lever R - delta/2 differs from
    R by 1e-4 relative. The sphere and the plate are one material, so the run cannot see the
    mixing rule: materials of 4 and 1 uN m check it (geometric mean 2, arithmetic 2.5, min 1)."""
    import math
    import sys

    import rollingdem as rd
    from rollingdem.errors import ParameterError
    from rollingdem.experiments.single_sphere import G, RADIUS, TABLE1, analytic_flat, rolling_flat_run, stop_time
    from rollingdem.io.casefile import build_simulation, load_case
    from rollingdem.physics.contact import ROLLING_MODELS
    from rollingdem.physics.contact.model import ContactModel
    from rollingdem.physics.contact.properties import MATERIAL_PROPERTIES

    (tmp_path / "my_rolling_law.py").write_text(worked_example())
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        import my_rolling_law

        usage = worked_example("### Worked example: a rolling law", block=1)
        scope = {}
        exec(compile(usage, "architecture.md", "exec"), scope)
        assert scope["sim"].materials["glass"].rolling_moment == 2.7e-6

        contact = ContactModel("hertz", rolling="constant_moment")
        assert isinstance(contact.rolling, my_rolling_law.ConstantMoment)
        assert contact.layout()["N_PARAMS"] == contact.layout()["ROLLING_PARAMS"] + 1  # its declared parameter

        a = rd.Material("a", **TABLE1, rolling_moment=4e-6)
        b = rd.Material("b", **TABLE1, rolling_moment=1e-6)
        table = rd.MaterialTable()
        table.add(a), table.add(b)
        assert math.isclose(table.pair(0, 1).rolling_moment, 2e-6, rel_tol=1e-12)
        row = contact.pair_table(table.pairs())[0, 1]
        assert math.isclose(row[contact.layout()["ROLLING_PARAMS"]], 2e-6, rel_tol=1e-12)
        table.set_pair("a", "b", rolling_moment=3e-6)
        assert table.pair(1, 0).rolling_moment == 3e-6
        with pytest.raises(ParameterError, match=r"material 'c': rolling_moment = -1 is not allowed: must be >= 0 "
                                                 r"\(N m\)"):
            rd.Material("c", **TABLE1, rolling_moment=-1.0)

        case = load_case({"materials": [{"name": "glass", "youngs_modulus": 63e9, "poisson_ratio": 0.25,
                                         "density": 2500.0, "rolling_moment": 2.7e-6}],
                          "particles": [{"positions": [[0.0, 0.0, 0.01]], "radius": 0.005, "material": "glass"}],
                          "contact": {"rolling": "constant_moment"}, "stages": [{"duration": 1e-5}]})
        assert build_simulation(case).materials["glass"].rolling_moment == 2.7e-6

        mass = TABLE1["density"] * 4.0 / 3.0 * math.pi * RADIUS ** 3
        moment = 0.1 * RADIUS * mass * G
        traj = rolling_flat_run(contact.rolling, duration=1.2, material={"rolling_moment": moment})
        expected = analytic_flat(mu_r=0.1)[2]
        assert abs(stop_time(traj) - expected) <= 5e-3 * expected, (stop_time(traj), expected)
    finally:
        ROLLING_MODELS.pop("constant_moment", None)
        MATERIAL_PROPERTIES.pop("rolling_moment", None)
        sys.modules.pop("my_rolling_law", None)


#: The most parameters a plain-Python function of the package may take.
MAX_PARAMETERS = 12


def _is_exempt(func: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """Compiled by Numba (``@njit``/``@jit``, bare, called or as ``numba.njit``) or a typer command
    (a decorator whose text contains ``.command``, e.g. ``@app.command()``)."""
    for decorator in func.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit") or ".command" in ast.unparse(decorator):
            return True
    return False


def _parameter_count(func: ast.FunctionDef | ast.AsyncFunctionDef, in_class: bool) -> int:
    """Positional-only, positional and keyword-only parameters; not ``*args``/``**kwargs``, and not
    the ``self``/``cls`` of a method."""
    a = func.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    if in_class and names[:1] in (["self"], ["cls"]):
        names = names[1:]
    return len(names)


def _functions(tree: ast.AST, in_class: bool = False):
    """(function node, whether it is a method) for every function, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node, in_class
            yield from _functions(node, False)
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, True)
        else:
            yield from _functions(node, in_class)


def test_the_parameter_counter_sees_methods_and_exemptions():
    tree = ast.parse("class A:\n    def f(self, a, /, b, *args, c, **kw): pass\n"
                     "    @classmethod\n    def g(cls, a): pass\n"
                     "def h(self, a): pass\n"
                     "@njit(cache=True)\ndef k(a): pass\n@numba.jit\ndef m(a): pass\n"
                     "@app.command()\ndef n(a): pass\n@functools.cache\ndef p(a): pass\n")
    found = {f.name: (_parameter_count(f, in_class), _is_exempt(f)) for f, in_class in _functions(tree)}
    assert found == {"f": (3, False), "g": (1, False), "h": (2, False), "k": (1, True), "m": (1, True),
                     "n": (1, True), "p": (1, False)}


def test_no_python_function_takes_more_than_12_parameters():
    """No function of the package takes more than ``MAX_PARAMETERS`` parameters (positional-only,
    positional and keyword-only; not ``self``/``cls``, not ``*args``/``**kwargs``): related ones
    travel together in a small dataclass instead.

    Two kinds of function are exempt. Numba-compiled ones (``@njit``/``@jit``): their arguments are
    the kernel's contract, flat scalars and arrays that Numba inlines and specialises on, where a
    Python object would not compile or would cost a boxing per call. Typer commands (a decorator
    containing ``.command``): typer maps each parameter of the function to one command-line option,
    so the parameter list is the command's option list."""
    offenders = []
    for name, path in module_files().items():
        for func, in_class in _functions(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            count = _parameter_count(func, in_class)
            if count > MAX_PARAMETERS and not _is_exempt(func):
                offenders.append(f"{name}:{func.lineno} {func.name} {count}")
    assert not offenders, (f"functions with more than {MAX_PARAMETERS} parameters (group related ones in a "
                           "dataclass):\n" + "\n".join(offenders))


def test_the_contract_refuses_a_law_that_breaks_its_declaration():
    """A law must name its compiled function, and give as many values per pair as it declares:
    the kernel reads the row by the declared offsets, so a short row would shift every later law's
    parameters (a wrong result, not an error)."""
    import pytest

    from rollingdem.physics.contact import ROLLING_MODELS, SubModel
    from rollingdem.physics.contact.rolling import no_rolling
    from rollingdem.physics.records import slots

    with pytest.raises(TypeError, match="needs its compiled function"):
        type("NoFunction", (SubModel,), {"slot": "rolling", "name": "test_no_function"})
    short = type("Short", (SubModel,), {"slot": "rolling", "name": "test_short", "parameters": slots("a", "b"),
                                        "function": staticmethod(no_rolling),
                                        "pair_values": lambda self, pair: (1.0,)})
    try:
        assert short.n_parameters == 2 and short.history_size == 0
        with pytest.raises(TypeError, match="gave 1 values for its 2 declared parameters"):
            short().pair_row(None)
    finally:
        ROLLING_MODELS.pop("test_short", None)
        ROLLING_MODELS.pop("test_no_function", None)


def test_the_kernel_name_hashes_every_module_it_compiles_in():
    """Numba's disk cache checks only the file of the generated engine module, so that module's
    name hashes the source of every package module whose compiled functions it takes in: each one
    the template imports (the triangle-mesh passes and their geometry among them) and each one
    those import. Without one of them, a change there would run the old compiled code."""
    from rollingdem.engine import codegen

    covered = codegen._package_imports(codegen.template_modules())
    imported = {node.module for path in codegen.template_files() for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(PACKAGE)}
    assert imported <= covered and {"rollingdem.engine.mesh_passes", "rollingdem.physics.mesh"} <= covered


#: the most lines a part of the step loop's template may have: a pass a reader can hold at once
TEMPLATE_PART_LINES = 600


def test_the_step_loops_template_is_split_by_pass_and_each_part_is_small():
    """Each part of ``engine/template`` is under ``TEMPLATE_PART_LINES`` lines, and the parts are
    exactly the files of the folder (a new part must be named in ``PARTS``, or it would never be
    compiled)."""
    from rollingdem.engine import codegen, template

    files = codegen.template_files()
    folder = {p.name for p in files[0].parent.glob("*.py")} - {"__init__.py"}
    assert folder == {f"{part}.py" for part in template.PARTS}
    long = {p.name: n for p in files if (n := len(p.read_text().splitlines())) >= TEMPLATE_PART_LINES}
    assert not long, f"template parts of {TEMPLATE_PART_LINES} lines or more: {long}"


#: the most lines ``scene/simulation.py`` may have: a façade that hands each call to a collection
#: (particles, walls, bonds, boundaries), the schedule, the time-step policy or checkpoints, and
#: keeps the settings (it sets the dt the time-step policy returns)
SIMULATION_LINES = 420


def test_the_simulation_is_a_facade():
    """``Simulation`` stays a façade: its module is under ``SIMULATION_LINES`` lines and holds no
    loop over particles, walls or bonds of its own (no ``for`` in a method but the engine's)."""
    path = SOURCE / "scene" / "simulation.py"
    lines = len(path.read_text().splitlines())
    assert lines < SIMULATION_LINES, f"scene/simulation.py has {lines} lines"
    tree = ast.parse(path.read_text())
    loops = [getattr(node, "lineno", getattr(getattr(node, "target", None), "lineno", 0)) for node in ast.walk(tree)
             if isinstance(node, (ast.For, ast.While, ast.comprehension))]
    assert not loops, f"loops in scene/simulation.py at lines {loops}: they belong in a collection"


def foreign_reads(source: str, attribute: str) -> list[int]:
    """Lines of ``source`` that read ``attribute`` of an object other than ``self`` or ``cls``."""
    return sorted(node.lineno for node in ast.walk(ast.parse(source))
                  if isinstance(node, ast.Attribute) and node.attr == attribute
                  and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")))


def test_the_foreign_read_finder_sees_a_read_through_another_object():
    source = "def f(sim):\n    st = sim._state\n    return st\nclass A:\n    def g(self):\n        return self._state\n"
    assert foreign_reads(source, "_state") == [2]


def test_only_the_simulation_reads_its_engine_state():
    """The collections get the engine state in their constructors (it is the same object for the
    simulation's life: a restored checkpoint is loaded into it); no module but scene/simulation.py
    reaches for ``sim._state``."""
    found = {name: lines for name, path in module_files().items() if not path.match("scene/simulation.py")
             for lines in [foreign_reads(path.read_text(), "_state")] if lines}
    assert not found, f"sim._state read outside scene/simulation.py: {found}"


#: a namedtuple's own API (its methods and fields start with an underscore so as not to clash with a field)
NAMEDTUPLE_API = {"_fields", "_make", "_replace", "_asdict"}
#: private reads that stay, and why: each an object of the reading class itself, or a library's
ALLOWED_PRIVATE_READS = {
    ("scene/mesh.py", "part._clip"),  # a MeshRegion clipping a copy of itself
    ("engine/state.py", "st._slots"),  # EngineState.from_arrays building an EngineState
    # Numba gives no public path to a function's cache index
    ("engine/precompile.py", "FunctionCache(getattr(module, function).py_func)._cache_file"),
    ("engine/precompile.py", "FunctionCache(getattr(module, function).py_func)._cache_file._index_path"),
}


def private_reads(source: str) -> list[str]:
    """``object._name`` read in ``source`` on an object other than ``self`` or ``cls`` (dunders and a
    namedtuple's API aside), as written."""
    return [ast.unparse(node) for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
            and node.attr not in NAMEDTUPLE_API
            and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))]


def test_the_private_read_finder_sees_another_objects_private_attribute():
    source = "def f(wl, row):\n    a = wl._motion\n    b = self._own\n    c = row._replace(x=1)\n    return wl.__class__\n"
    assert private_reads(source) == ["wl._motion"]


def test_no_object_reads_another_objects_private_attributes():
    """An object reads and writes another only through what that one makes public (the walls'
    carried engine rows, an observer's position, a case's folder); the exceptions are listed
    with their reason (``ALLOWED_PRIVATE_READS``)."""
    found = sorted((str(path.relative_to(SOURCE)), read) for path in module_files().values()
                   for read in private_reads(path.read_text()))
    assert [f for f in found if f not in ALLOWED_PRIVATE_READS] == []


def test_the_collections_are_not_given_the_simulation():
    """The spheres, clumps, bonds, walls, boundaries and the time-step policy get the engine state
    and narrow handles in their constructors (docs/architecture.md, The scene), not the simulation:
    none keeps one, and a restore loads into the objects they were given."""
    sim = rd.Simulation()
    for collection in (sim.particle_set, sim.clump_set, sim.bond_set, sim.wall_set, sim.boundary_set,
                       sim.time_step_policy):
        held = [v for v in vars(collection).values() if isinstance(v, rd.Simulation)]
        assert not held, f"{type(collection).__name__} holds the Simulation"
        assert collection.state is sim.particle_set.state


#: the layers in the order they stand, bottom first (docs/architecture.md, Layers)
LAYER_ORDER = {"errors": 0, "physics": 1, "engine": 2, "analysis": 2, "scene": 3, "io": 4, "experiments": 5,
               "studies": 6}


def upward_calls(calls) -> list[str]:
    """The (caller module, callee module) pairs of ``calls`` that go from a layer into one above
    it, as 'caller -> callee' lines (modules outside the package, and the front ends, left out)."""
    found = []
    for caller, callee in calls:
        a, b = (layer_of(m) if m.startswith(PACKAGE + ".") else None for m in (caller, callee))
        if a in LAYER_ORDER and b in LAYER_ORDER and LAYER_ORDER[b] > LAYER_ORDER[a]:
            found.append(f"{caller} -> {callee}")
    return found


def test_upward_calls_are_found_on_a_made_up_trace():
    assert upward_calls([("rollingdem.physics.contact.model", "rollingdem.scene.materials"),
                         ("rollingdem.scene.simulation", "rollingdem.physics.contact.model"),
                         ("rollingdem.engine.state", "rollingdem.engine.backends"),
                         ("rollingdem.cli", "rollingdem.io.casefile"), ("numpy", "rollingdem.scene.walls")]) == [
        "rollingdem.physics.contact.model -> rollingdem.scene.materials"]


def test_a_case_files_parameters_go_down_the_layers_only():
    """Every Python call between the package's modules while a case file is read, its simulation
    built and run for 10 steps (``sys.setprofile``): none goes from a layer into one above it, so
    a material's rolling friction reaches the step loop down the layers once (docs/architecture.md,
    "One parameter, end to end")."""
    import sys

    from rollingdem.io import casefile

    case = {"name": "walk", "dt": 1e-5, "contact": {"normal": "hertz", "rolling": "epsd"},
            "materials": [{"name": "m", "youngs_modulus": 4e7, "poisson_ratio": 0.49, "density": 1056,
                           "friction": 0.8, "rolling_friction": 0.2}],
            "walls": [{"type": "plane", "name": "floor", "material": "m"}],
            "particles": [{"positions": [[0, 0, 0.005], [0.01, 0, 0.005]], "radius": 0.005, "material": "m"}],
            "stages": [{"name": "settle", "duration": 1e-4}]}
    casefile.build_simulation(casefile.load_case(case)).run(steps=10)  # compiled before the trace
    calls = []

    def profile(frame, event, arg):
        if event == "call" and frame.f_back is not None:
            calls.append((frame.f_back.f_globals.get("__name__", ""), frame.f_globals.get("__name__", "")))

    sys.setprofile(profile)
    try:
        casefile.build_simulation(casefile.load_case(case)).run(steps=10)
    finally:
        sys.setprofile(None)
    assert any(c[1] == "rollingdem.physics.contact.model" for c in calls)  # the trace saw the path
    assert not upward_calls(calls)


def test_every_mutation_targets_a_line_that_is_there():
    """Each mutation of ``tests/mutations.py`` names a line that occurs exactly once in its file: a
    line moved or reworded by a refactor would leave the mutation testing nothing."""
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location("mutations", SOURCE.parents[1] / "tests" / "mutations.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["mutations"] = module
    try:
        spec.loader.exec_module(module)
    finally:
        sys.modules.pop("mutations", None)
    stale = [f"{m.name}: {m.file} holds its line {(SOURCE.parents[1] / m.file).read_text().count(m.original)} times"
             for m in module.MUTATIONS if (SOURCE.parents[1] / m.file).read_text().count(m.original) != 1]
    assert not stale, "\n".join(stale)


def test_every_registered_experiment_has_its_own_validate():
    """``rollingdem validate`` runs each experiment's ``validate``: the base class's only raises, so
    an experiment whose method slipped out of its class (indented into a function below it) would
    fail there, not here."""
    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.experiments.registry import Experiment

    missing = [name for name, e in EXPERIMENTS.items() if type(e).validate is Experiment.validate]
    assert not missing


#: The longest a module may be without a reason given in docs/architecture.md ("Module sizes").
MAX_MODULE_LINES = 700


def _doc_section(title: str) -> str:
    text = (SOURCE.parents[1] / "docs" / "architecture.md").read_text()
    return text[text.index(title) + len(title):].split("\n#", 1)[0]


def _table_modules(section: str) -> list[str]:
    """The modules the first column of a docs table names, relative to the package: a name without
    a folder is in the folder of the name before it in its row (`experiments/repose`, `drum`)."""
    named = []
    for row in section.splitlines():
        if not row.startswith("| `"):
            continue
        folder = ""
        for name in re.findall(r"`([^`]+)`", row.split("|")[1]):
            if "/" in name.rstrip("/"):
                folder = name.rstrip("/").rsplit("/", 1)[0] + "/"
                named.append(name)
            else:
                named.append(folder + name)
    return named


def _package_modules() -> dict[str, int]:
    """Every module of the package but ``__init__``, relative to it without suffix: its lines."""
    return {f.relative_to(SOURCE).with_suffix("").as_posix(): len(f.read_text().splitlines())
            for f in SOURCE.rglob("*.py") if f.stem != "__init__"}


def test_module_map_names_every_module_and_only_modules_that_exist():
    named = _table_modules(_doc_section("### Module map"))
    modules = _package_modules()
    folders = [n for n in named if n.endswith("/")]
    unmapped = sorted(m for m in modules if m not in named and not any(m.startswith(f) for f in folders))
    absent = [n for n in named if n not in modules and not (n.endswith("/") and (SOURCE / n).is_dir())]
    assert not unmapped, f"modules docs/architecture.md's module map does not name: {unmapped}"
    assert not absent, f"the module map names modules that do not exist: {absent}"


def test_modules_over_the_size_limit_are_those_with_a_stated_reason():
    long = sorted(m for m, n in _package_modules().items() if n > MAX_MODULE_LINES)
    stated = sorted(_table_modules(_doc_section("### Module sizes")))
    assert long == stated, (f"modules over {MAX_MODULE_LINES} lines: {long}; docs/architecture.md, 'Module sizes', "
                            f"gives a reason for {stated}")


def test_the_table_readers_find_what_a_table_names():
    """The readers of the two tests above, on a made-up table: a module, a sibling named without its
    folder, a folder."""
    table = "| module | owns |\n|---|---|\n| `io/a`, `b` | x |\n| `engine/template/` | y |\n| `cli` | z |\n"
    assert _table_modules(table) == ["io/a", "io/b", "engine/template/", "cli"]


TESTS = SOURCE.parents[1] / "tests"


def test_tests_mirror_the_source_folders_and_import_no_other_test_file():
    """A test file lives in the folder of the layer it tests (tests/engine/ for src/rollingdem/engine/);
    at the top only the front ends' tests; shared helpers come from ``helpers`` or ``conftest``, never
    from another test file (which pytest may not have on its path)."""
    folders = {p.name for p in TESTS.iterdir() if p.is_dir() and not p.name.startswith((".", "__"))}
    assert folders <= set(LAYER_IMPORTS), f"test folders with no source folder: {sorted(folders - set(LAYER_IMPORTS))}"
    found = []
    for path in sorted(TESTS.rglob("test_*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            found += [f"{path.relative_to(TESTS)} (line {node.lineno}) imports {n}" for n in names
                      if n.split(".")[0].startswith("test_")]
    assert not found, "test files importing another test file:\n" + "\n".join(found)


def function_level_imports(source: str) -> list[tuple[int, str, bool]]:
    """(line, import, whether a comment on its lines says why) of every import inside a function."""
    lines = source.splitlines()
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for sub in ast.walk(node):
                if isinstance(sub, (ast.Import, ast.ImportFrom)):
                    said = any("#" in lines[k] for k in range(sub.lineno - 1, sub.end_lineno))
                    found.append((sub.lineno, ast.unparse(sub), said))
    return found


def test_imports_are_at_the_top_unless_a_comment_says_why():
    """An import inside a function is a slow-to-load or optional dependency (matplotlib, pandas,
    scipy's subpackages, scikit-learn, CUDA) or a command's machinery, and its line says so."""
    silent = [f"{path.relative_to(SOURCE)} (line {line}): {text}"
              for path in sorted(SOURCE.rglob("*.py"))
              for line, text, said in function_level_imports(path.read_text()) if not said]
    assert not silent, "imports inside functions without a reason:\n" + "\n".join(silent)


def test_the_import_finder_sees_imports_in_functions_and_their_comments():
    source = ("import os\n\ndef f():\n    import json  # deferred: why\n    from a import (\n        b,\n    )\n"
              "    if x:\n        import c\n")
    assert function_level_imports(source) == [(4, "import json", True), (5, "from a import b", False),
                                              (9, "import c", False)]


def test_wall_objects_follow_the_engine_at_its_sync_points_only():
    """docs/architecture.md, "No copies": the ``Wall`` objects are refreshed from the engine after
    every call of the step loop (``Schedule.run``, and once more as a run ends) and when a
    checkpoint is restored (``WallSet.restore``), nowhere else."""
    calls = []
    for path in sorted(SOURCE.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for func in ast.walk(tree):
            if isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
                calls += [f"{path.relative_to(SOURCE).as_posix()}:{func.name}" for node in ast.walk(func)
                          if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                          and node.func.attr == "refresh" and func.name != "refresh"]
    assert sorted(calls) == ["scene/schedule.py:run", "scene/schedule.py:run", "scene/wall_set.py:restore"], calls
