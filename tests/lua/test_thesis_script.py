"""The thesis's script (section 4.2.2, paths made relative) on the embedded simulator of `dense`."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from PIL import Image

from robotexp.lua import run_script, substitute_method
from robotexp.registry import EXPLORERS, available

SCRIPT = Path(__file__).parents[2] / "scripts_lua" / "thesis_dense_bvp.lua"
POSES = {1: [-5.0, 7.5, 0.0], 2: [-1.6, 7.5, 0.0], 3: [2.7, 7.5, 0.0]}


def check_outputs(out: Path, method: str, notices: list[str]) -> None:
    text = (out / "resultados.txt").read_text()
    # a long string drops the newline right after its `[[`: one line per run, as in the thesis's Lua
    runs = re.findall(r"Map: Denso_PVC Pose: (\d) Elapse time: (\d+) Path length: ([0-9.]+) ", text)
    assert sorted(int(n) for n, _, _ in runs) == [1, 2, 3]
    assert sorted(re.findall(r"Starting BVP in pose (\d)", text)) == ["1", "2", "3"]
    records = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert [r["method"] for r in records] == [method] * 3
    order = [int(n) for n, _, _ in runs]
    for (n, elapsed, path), rec in zip(runs, records, strict=True):
        assert rec["start_pose"] == pytest.approx(POSES[int(n)])
        assert int(elapsed) == round(rec["robot_time_s"] * 1000)
        assert float(path) == pytest.approx(rec["path_length_m"] * 1000, abs=0.1)
    for n in order:
        with Image.open(out / f"Denso_PVC_{n}.PNG") as img:
            assert img.format == "PNG"
    assert len(notices) == 1 and "--world dense" in notices[0]


@pytest.mark.slow
def test_thesis_script_with_frontier_in_place_of_bvp(tmp_path: Path) -> None:
    code = substitute_method(SCRIPT.read_text(), "BVP", "FRONTIER")
    assert code.replace("FRONTIER", "BVP") == SCRIPT.read_text()      # nothing else changed
    notices: list[str] = []
    run_script(SCRIPT, code=code, out=tmp_path, world="dense", notice=notices.append)
    check_outputs(tmp_path, "frontier", notices)


@pytest.mark.slow
@pytest.mark.skipif("bvp" not in available(EXPLORERS), reason="the bvp plugin is not installed")
def test_thesis_script_unchanged_with_bvp(tmp_path: Path) -> None:
    notices: list[str] = []
    run_script(SCRIPT, out=tmp_path, world="dense", notice=notices.append)
    check_outputs(tmp_path, "bvp", notices)
