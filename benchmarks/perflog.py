"""Machine-readable results of the benchmarks: one JSON file per benchmark, read by make_performance.py.

A benchmark calls `record(name, figures, ...)` once it has measured: the file
`benchmarks/results/<name>.json` is replaced with the figures, the command line that measured them,
the commit of the tree (with `+dirty` when it had uncommitted changes) and the machine (processor,
cores, memory, Python and the versions of the libraries that set the speed). The performance pages of
the documentation are built from these files (`python benchmarks/make_performance.py`), so a figure
in the docs always names the command, commit and machine it came from.

    from perflog import Figure, record
    record("explore", [Figure("frontier on dense, robot time / wall time", 579.0, "x")],
           title="A whole exploration")

Scripts in the subfolders import it with `sys.path.insert(0, <benchmarks folder>)`.
`ROBOTEXP_BENCH_RESULTS=DIR` writes elsewhere (tests, trial runs); `--no-record` is left to each
script.
"""

from __future__ import annotations

import json
import os
import platform
import shlex
import subprocess
import sys
from dataclasses import asdict, dataclass
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"
LIBRARIES = ("numpy", "numba", "pybullet", "scipy", "lupa", "aiohttp", "mcap", "dask")
FORMAT = 1


@dataclass(frozen=True)
class Figure:
    """One measured figure: what it is, its value and its unit ("x" for ratios, "ms", "MB", ...)."""

    label: str
    value: float
    unit: str = ""
    note: str = ""


def commit() -> str:
    """The tree's commit, `+dirty` when tracked files differ from it; "unknown" outside git."""
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short=10", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               check=True, capture_output=True, text=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if dirty else "")


def _processor() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gib() -> float | None:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                return round(int(line.split()[1]) / 2**20, 1)
    except OSError:
        pass
    return None


def machine() -> dict[str, object]:
    """What the figures depend on: processor, cores, memory, OS, Python and library versions."""
    versions = {}
    for lib in LIBRARIES:
        try:
            versions[lib] = metadata.version(lib)
        except metadata.PackageNotFoundError:
            continue
    return {"processor": _processor(), "cores": os.cpu_count(), "memory_gib": _memory_gib(),
            "system": f"{platform.system()} {platform.release()}", "arch": platform.machine(),
            "python": platform.python_version(), "libraries": versions}


def command() -> str:
    """The command line that ran the benchmark, relative to the repository root where it can be."""
    script = Path(sys.argv[0]).resolve()
    try:
        shown = str(script.relative_to(ROOT))
    except ValueError:
        shown = script.name
    return shlex.join(["python", shown, *sys.argv[1:]])


def results_dir() -> Path:
    return Path(os.environ.get("ROBOTEXP_BENCH_RESULTS", RESULTS))


def record(name: str, figures: list[Figure], *, title: str, section: str = "speed",
           parameters: dict[str, object] | None = None) -> Path:
    """Write `<results>/<name>.json` (replacing an earlier one) and return its path.

    `section` groups the tables of the performance page (speed, links, lasers, campaigns, studies,
    fuzzing); `parameters` are the settings the figures hold for (world, method, counts).
    """
    if not name or any(c not in "abcdefghijklmnopqrstuvwxyz0123456789-_" for c in name):
        raise ValueError(f"benchmark name {name!r}: use lowercase letters, digits, '-' and '_'")
    folder = results_dir()
    folder.mkdir(parents=True, exist_ok=True)
    doc = {"format": FORMAT, "name": name, "title": title, "section": section, "command": command(),
           "commit": commit(), "machine": machine(), "parameters": parameters or {},
           "figures": [asdict(f) for f in figures]}
    path = folder / f"{name}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    tmp.replace(path)
    print(f"figures written to {path}")
    return path
