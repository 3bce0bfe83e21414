"""Mutation check: does the test suite catch a wrong physics factor?

Each mutation below is a one-line error put into a copy of the package (``src/`` and ``tests/``
copied to a temporary folder); the tests named with it are run there against the copy. A
mutation is *caught* when at least one of them fails. The unmutated copy is run first and must
pass, or the table means nothing.

    python tests/mutations.py                 # every mutation; a table at the end
    python tests/mutations.py --list          # the mutations, not run
    python tests/mutations.py --only epsd     # those whose name contains 'epsd'

Exit status 0 when every mutation is caught, 1 otherwise, 2 for bad arguments. Not part of the
default suite (each mutation recompiles the kernels it touches: about a minute each on 2 cores).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutation:
    name: str
    file: str        # relative to the repository root
    original: str    # must occur exactly once in the file
    replacement: str
    tests: tuple     # pytest node ids or files, relative to the repository root


M = Mutation
CONTACT = "src/rollingdem/contact/"
MUTATIONS = [
    # --- normal -----------------------------------------------------------------------------
    M("hertz normal stiffness 4/3 -> 1", CONTACT + "normal.py", "kn = (4.0 / 3.0) * p[P_YOUNG] * a",
      "kn = 1.0 * p[P_YOUNG] * a", ("tests/test_submodel_kernels.py", "tests/test_contacts.py")),
    M("hertz tangential dashpot halved", CONTACT + "normal.py", "return kn * overlap, -gamma_n * normal_velocity, kn, st, gamma_n * p[off + 1]",
      "return kn * overlap, -gamma_n * normal_velocity, kn, st, 0.5 * gamma_n * p[off + 1]",
      ("tests/test_submodel_kernels.py", "tests/test_contacts.py")),
    M("hertz damping factor sqrt(5/6) -> sqrt(2/3)", CONTACT + "normal.py",
      "return -2.0 * math.sqrt(5.0 / 6.0) * restitution_beta(e)", "return -2.0 * math.sqrt(2.0 / 3.0) * restitution_beta(e)",
      ("tests/test_hertz_damping.py", "tests/test_submodel_kernels.py", "tests/test_contacts.py")),
    # --- tangential -------------------------------------------------------------------------
    M("coulomb limit on |F_n| instead of max(F_n, 0)", CONTACT + "tangential.py",
      "limit = p[P_FRICTION] * max(normal_force, 0.0)", "limit = p[P_FRICTION] * abs(normal_force)",
      ("tests/test_submodel_kernels.py", "tests/test_contacts.py", "tests/test_slope.py")),
    M("tangential history not carried with the frame", CONTACT + "tangential.py",
      "    carry_with_frame(hist, k, off, frame)\n    x0 = hist[k, off]", "    x0 = hist[k, off]",
      ("tests/test_submodel_kernels.py", "tests/test_contacts.py")),
    # --- rolling ----------------------------------------------------------------------------
    M("epsd stiffness prefactor 2.25 -> 2.0", CONTACT + "rolling.py",
      "    def stiffness_coefficient(self):\n        return 2.25\n",
      "    def stiffness_coefficient(self):\n        return 2.0\n",
      ("tests/test_submodel_kernels.py", "tests/test_rolling_kernel.py", "tests/test_rolling.py",
       "tests/test_slope.py", "tests/test_inclined_wall.py")),
]


def _copy_tree(dest: Path) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache")
    for part in ("src", "tests"):
        shutil.copytree(ROOT / part, dest / part, ignore=ignore)
    shutil.copy2(ROOT / "pyproject.toml", dest / "pyproject.toml")


def _run_tests(copy: Path, tests, cache: Path) -> tuple[int, list[str], str]:
    """pytest on the copy; (exit code, failed test ids, last output lines)."""
    env = dict(os.environ, PYTHONPATH=str(copy / "src"), ROLLINGDEM_CACHE_DIR=str(cache),
               ROLLINGDEM_PRECOMPILE="0", PYTHONDONTWRITEBYTECODE="1")
    # the copy's package must be the one imported, not an installed one
    where = subprocess.run([sys.executable, "-c", "import rollingdem; print(rollingdem.__file__)"],
                           cwd=copy, env=env, capture_output=True, text=True)
    if not where.stdout.strip().startswith(str(copy)):
        raise SystemExit(f"error: the copy at {copy} is not the package imported ({where.stdout.strip()}"
                         f"{where.stderr.strip()[-300:]}); uninstall the editable install or run from a clean venv")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rf", *tests],
                          cwd=copy, env=env, capture_output=True, text=True)
    failed = re.findall(r"^FAILED (\S+)", proc.stdout, flags=re.M)
    tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-3:])
    return proc.returncode, failed, tail


def _apply(copy: Path, m: Mutation) -> None:
    path = copy / m.file
    text = path.read_text()
    count = text.count(m.original)
    if count != 1:
        raise SystemExit(f"error: mutation {m.name!r}: its original text occurs {count} times in {m.file}, "
                         "must occur once (the source changed: update the mutation)")
    path.write_text(text.replace(m.original, m.replacement))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--only", default=None, help="run the mutations whose name contains this text")
    args = parser.parse_args(argv)
    chosen = [m for m in MUTATIONS if args.only is None or args.only in m.name]
    if args.list:
        for m in MUTATIONS:
            print(f"{m.name}: {m.file}")
        return 0
    if not chosen:
        print(f"error: --only = {args.only!r} matches no mutation (see --list)", file=sys.stderr)
        return 2

    work = Path(tempfile.mkdtemp(prefix="rollingdem-mutations-"))
    cache = work / "kernels"
    try:
        base = work / "base"
        _copy_tree(base)
        all_tests = sorted({t for m in chosen for t in m.tests})
        t0 = time.perf_counter()
        code, failed, tail = _run_tests(base, all_tests, cache)
        if code != 0:
            print(f"error: the unmutated copy fails its tests ({', '.join(failed) or tail}): fix that first",
                  file=sys.stderr)
            return 1
        print(f"unmutated copy: {len(all_tests)} test files pass ({time.perf_counter() - t0:.0f} s)", flush=True)
        rows = []
        for i, m in enumerate(chosen):
            copy = work / f"m{i}"
            _copy_tree(copy)
            _apply(copy, m)
            t0 = time.perf_counter()
            code, failed, tail = _run_tests(copy, m.tests, cache)
            caught = code != 0
            if caught and not failed:
                failed = [tail.splitlines()[-1] if tail else f"exit {code}"]
            rows.append((m.name, caught, failed, time.perf_counter() - t0))
            print(f"{'caught' if caught else 'MISSED'}  {m.name}  ({len(failed)} failing)", flush=True)
            shutil.rmtree(copy, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    print("\n| mutation | caught | failing tests | s |\n|---|---|---|---|")
    for name, caught, failed, seconds in rows:
        shown = ", ".join(f.split("::")[-1] for f in failed[:3]) + (f" (+{len(failed) - 3})" if len(failed) > 3 else "")
        print(f"| {name} | {'yes' if caught else '**no**'} | {shown} | {seconds:.0f} |")
    missed = [r for r in rows if not r[1]]
    print(f"\n{len(rows) - len(missed)} of {len(rows)} mutations caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
