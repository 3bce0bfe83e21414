"""Wheels for a GPU machine without PyPI: the packages rollingdem needs that the machine lacks.

A GPU node is often cut off from the internet but has a CUDA Python stack (numba, numba-cuda,
numpy, ...). This lists rollingdem's dependencies, with theirs, as installed here, leaves out those
the machine has (``--have``: its ``python3 -m pip list --format=freeze``, or one name per line),
and downloads wheels of the rest for the machine's Python into DIR, at the versions installed here.
There, ``WHEELS=DIR benchmarks/gpu.sh`` installs them beside the machine's own packages.

usage: python benchmarks/gpu_wheels.py DIR --have FILE [--python 3.12]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

PLATFORMS = ("manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64",
             "manylinux1_x86_64")


def needed(root: str, python: str) -> dict[str, str]:
    """{name: version installed here} of ``root``'s dependencies and theirs, with the markers
    evaluated for CPython ``python`` on x86-64 Linux."""
    environment = {"python_version": python, "python_full_version": python + ".0", "sys_platform": "linux",
                   "platform_system": "Linux", "platform_machine": "x86_64", "implementation_name": "cpython",
                   "platform_python_implementation": "CPython", "os_name": "posix"}
    found, todo, seen = {}, [(root, ())], set()
    while todo:
        name, extras = todo.pop()
        if (name, extras) in seen:
            continue
        seen.add((name, extras))
        for line in metadata.requires(name) or []:
            req = Requirement(line)
            if req.marker is not None and not any(req.marker.evaluate({**environment, "extra": e})
                                                  for e in ("", *extras)):
                continue
            dep = canonicalize_name(req.name)
            try:
                found[dep] = metadata.version(dep)
            except metadata.PackageNotFoundError:
                sys.exit(f"{dep} (needed by {name}) is not installed here: install rollingdem first")
            todo.append((dep, tuple(sorted(req.extras))))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--have", type=Path, required=True, help="the machine's pip list --format=freeze")
    parser.add_argument("--python", default="3.12", help="the machine's Python version (default 3.12)")
    args = parser.parse_args()
    have = {canonicalize_name(re.split(r"[=<>!~ ]", line.strip())[0])
            for line in args.have.read_text().splitlines() if line.strip() and not line.startswith("#")}
    missing = {name: version for name, version in sorted(needed("rollingdem", args.python).items())
               if name not in have}
    print("the machine lacks:", ", ".join(f"{n}=={v}" for n, v in missing.items()) or "nothing")
    args.folder.mkdir(parents=True, exist_ok=True)
    for name, version in missing.items():
        platforms = [a for p in PLATFORMS for a in ("--platform", p)]
        subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:",
                        "--python-version", args.python, "--implementation", "cp", *platforms, "-d",
                        str(args.folder), f"{name}=={version}"], check=True)
    print(f"{len(list(args.folder.glob('*.whl')))} wheels in {args.folder}")


if __name__ == "__main__":
    main()
