"""The benchmarks folder: every script is indexed, and the performance page is what the result files give."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def test_every_script_is_in_the_index() -> None:
    index = (BENCH / "README.md").read_text()
    scripts = sorted(p for p in BENCH.glob("*/*.py"))
    assert scripts, "no benchmark scripts found"
    missing = [str(p.relative_to(BENCH)) for p in scripts if p.name not in index]
    assert not missing, f"benchmarks/README.md does not list {missing}"
    assert not list(BENCH.glob("bench_*.py")), "benchmark scripts belong in a subfolder (speed/, links/, ...)"


def test_a_result_file_becomes_a_table_with_command_commit_and_machine(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    perflog = _load("perflog")
    make = _load("make_performance")
    monkeypatch.setenv("ROBOTEXP_BENCH_RESULTS", str(tmp_path / "results"))
    monkeypatch.setattr(sys, "argv", [str(BENCH / "speed" / "bench_x.py"), "--world", "dense"])
    path = perflog.record("x-speed", [perflog.Figure("robot time / wall time", 612.34, "x", "loop")],
                          title="A trial", parameters={"world": "dense"})
    doc = json.loads(path.read_text())
    assert doc["command"] == "python benchmarks/speed/bench_x.py --world dense"
    assert doc["commit"] and doc["machine"]["cores"]
    page = make.render(make.load(tmp_path / "results"))
    assert "### A trial" in page
    assert "| robot time / wall time | 612 | x | loop |" in page
    assert "`python benchmarks/speed/bench_x.py --world dense`" in page and doc["commit"] in page
    assert "- M1: " in page
    out = tmp_path / "measured.md"
    assert make.main(["--results", str(tmp_path / "results"), "--out", str(out), "--check"]) == 1
    assert make.main(["--results", str(tmp_path / "results"), "--out", str(out)]) == 0
    assert make.main(["--results", str(tmp_path / "results"), "--out", str(out), "--check"]) == 0


def test_bad_names_and_files_are_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    perflog = _load("perflog")
    make = _load("make_performance")
    monkeypatch.setenv("ROBOTEXP_BENCH_RESULTS", str(tmp_path))
    with pytest.raises(ValueError, match="lowercase"):
        perflog.record("../x", [], title="t")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(SystemExit, match="broken.json"):
        make.load(tmp_path)


def test_the_performance_page_is_generated_from_the_results() -> None:
    make = _load("make_performance")
    assert make.main(["--check"]) == 0, "docs/performance/measured.md: run python benchmarks/make_performance.py"
