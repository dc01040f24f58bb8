"""Visited-cells comparison tables (Santos 2016 Table 8 with Welch's test), `campaign report` and
`campaign plot`."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from robotexp.cli import main
from robotexp.campaign.compare import comparison_tables, load_results
from robotexp.errors import ConfigError
from robotexp.output.figures import DPI, PAGE_WIDTH, PALETTE


def _rec(world: str, method: str, seed: int, cells: int, *, completed: bool = True, coverage: float | None = 0.9,
         path: float = 40.0, reason: str = "explored", speed: float = 0.3) -> dict[str, Any]:
    return {"run": f"{world}_{method}_1_300mms_s{seed}", "world": world, "method": method, "pose": "1",
            "seed": seed, "visited_cells": cells, "coverage": coverage, "path_length_m": path,
            "robot_time_s": 600.0, "max_speed_m_s": speed, "completed": completed, "reason": reason,
            "nodes": None}


# Santos-like samples (see tests/campaign/test_statistics.py for the hand computation of this pair):
# fa: mean 1426, s = sqrt(56250) = 237.2; ga: mean 1923, s = sqrt(25000) = 158.1;
# t = -497 / sqrt(16250) = -3.899, df = 6.969
FA = [1126, 1276, 1426, 1576, 1726]
GA = [1723, 1823, 1923, 2023, 2123]


def _santos_records() -> list[dict[str, Any]]:
    recs = [_rec("sparse", "meta-firefly", i, c, coverage=0.8 + 0.01 * i, path=30.0 + i) for i, c in enumerate(FA)]
    recs += [_rec("sparse", "meta-ga", i, c, path=50.0) for i, c in enumerate(GA)]
    recs += [_rec("dense", "meta-ga", i, 1000 + i) for i in range(3)]        # one method only: no table
    return recs


def test_comparison_table_layout_and_numbers_by_hand() -> None:
    (t,) = comparison_tables(_santos_records())
    assert t.title == "sparse, max speed 300 mm/s: visited cells per run"
    assert t.header == ["method", "n", "visited cells", "coverage", "path (m)"]
    fa, ga, pair, mwu, ci = t.rows
    # coverage mean (0.80 + 0.81 + ... + 0.84) / 5 = 0.82; path mean (30 + ... + 34) / 5 = 32
    assert fa == ["meta-firefly", "5", "1426.0 ± 237.2", "0.820", "32.0"]
    assert ga == ["meta-ga", "5", "1923.0 ± 158.1", "0.900", "50.0"]
    assert pair[0] == "Welch p, meta-firefly vs meta-ga"
    assert pair[2].startswith("0.00") and "t = -3.90" in pair[2] and "df = 7.0" in pair[2]
    # every FA below every GA but 1726 > 1723: U = 1; exact p = 2 P(U <= 1) = 2 * 2 / C(10, 5)
    assert mwu[0] == "Mann-Whitney p, meta-firefly vs meta-ga" and mwu[2] == f"{4 / 252:.3g} (U = 1)"
    assert ci[0] == "95% CI of mean meta-firefly - meta-ga" and ci[2].startswith("-497.0 [")
    low, high = (float(v) for v in ci[2].split("[")[1].split("]")[0].split(", "))
    assert -800 < low < -497 < high < -200


def test_comparison_leaves_incomplete_and_interrupted_runs_out() -> None:
    recs = [_rec("w", "a", 0, 10), _rec("w", "a", 1, 20), _rec("w", "a", 2, 999, completed=False,
                                                                reason="time limit of 20 s reached"),
            _rec("w", "a", 3, 5000, completed=False, reason="interrupted by Ctrl-C"),
            _rec("w", "b", 0, 30, coverage=None), _rec("w", "b", 1, 30, coverage=None)]
    (t,) = comparison_tables(recs)
    a, b, pair = t.rows[:3]
    assert a[:3] == ["a", "2 +1*", "15.0 ± 7.1"]          # stdev(10, 20) = 7.07; interrupted not counted
    assert b[1:4] == ["2", "30.0 ± 0.0", "-"]             # no coverage known
    # a: s^2 = 50, b: s^2 = 0 -> t = (15 - 30) / sqrt(50 / 2) = -3, df = n_a - 1 = 1; p = 1 - (2/pi) atan 3
    p = 1 - 2 / math.pi * math.atan(3)
    assert pair[2] == f"{p:.3g} (t = -3.00, df = 1.0)"
    (t2,) = comparison_tables(recs, include_incomplete=True)
    # 10, 20, 999: mean 343, deviations -333, -323, 656: s = sqrt(645554 / 2) = 568.13
    assert t2.rows[0][:3] == ["a", "3", "343.0 ± 568.1"]


def test_comparison_of_three_methods_has_three_pairs_and_handles_single_runs() -> None:
    recs = [_rec("w", "c", 0, 7), _rec("w", "a", 0, 1), _rec("w", "a", 1, 3), _rec("w", "b", 0, 2),
            _rec("w", "b", 1, 6)]
    (t,) = comparison_tables(recs)
    assert [r[0] for r in t.rows if not r[0].startswith(("Mann", "95%"))] == [
        "a", "b", "c", "Welch p, a vs b", "Welch p, a vs c", "Welch p, b vs c"]
    assert t.rows[2][2] == "7.0"                           # one run: no sd
    rows = {r[0]: r for r in t.rows}
    assert rows["Welch p, a vs c"][2] == "- (fewer than 2 runs)"
    # a: mean 2, s^2 = 2; b: mean 4, s^2 = 8; t = -2 / sqrt(1 + 4) = -0.894, df = 25 / (1 + 16) = 1.47
    assert "t = -0.89, df = 1.5" in rows["Welch p, a vs b"][2]
    # separate speeds are separate tables
    assert len(comparison_tables(recs + [_rec("w", "a", 0, 1, speed=0.1), _rec("w", "b", 0, 1, speed=0.1)])) == 2


def test_no_variance_is_said_not_p_zero() -> None:
    # deterministic methods over seeds: same count every run
    recs = [_rec("w", "a", i, 100) for i in range(3)] + [_rec("w", "b", i, 120) for i in range(3)]
    (t,) = comparison_tables(recs)
    rows = {r[0]: r[2] for r in t.rows}
    assert rows["Welch p, a vs b"].startswith("no variance")
    assert "inf" not in " ".join(rows.values()) and "p 0" not in " ".join(rows.values())
    # ranks still order them: U = 0, ties -> normal approximation, z = (9/2 - 1/2) / sqrt(9 * 7 / 12 - tie term)
    assert rows["Mann-Whitney p, a vs b"].endswith("(U = 0)")
    assert rows["95% CI of mean a - b"] == "-20.0 (no variance: no interval)"
    recs = [_rec("w", "a", i, 100) for i in range(3)] + [_rec("w", "b", i, 100) for i in range(3)]
    rows = {r[0]: r[2] for r in comparison_tables(recs)[0].rows}
    assert rows["Mann-Whitney p, a vs b"].startswith("no variance")


def test_mixed_cell_sizes_are_never_tested_against_each_other() -> None:
    # srt-laser maps at 0.1 m, meta-ga at 0.05 m (4x the cells for the same area): no test between them
    recs = [{**_rec("w", "srt-laser", i, 1700 + i), "cell_m": 0.1} for i in range(3)]
    recs += [{**_rec("w", "meta-ga", i, 4124 + 7 * i), "cell_m": 0.05} for i in range(3)]
    recs += [{**_rec("w", "meta-pso", i, 4000 + 9 * i), "cell_m": 0.05} for i in range(3)]
    fine, coarse = comparison_tables(recs)
    assert fine.title.endswith("cells of 0.05 m") and coarse.title.endswith("cells of 0.1 m")
    assert fine.methods == ["meta-ga", "meta-pso"] and coarse.methods == ["srt-laser"]
    labels = [r[0] for r in fine.rows + coarse.rows]
    assert "Welch p, meta-ga vs meta-pso" in labels
    assert not any("srt-laser vs" in lab or "vs srt-laser" in lab for lab in labels)
    assert fine.rows[-1][0] == "not compared" and "srt-laser (cells of 0.1 m)" in fine.rows[-1][2]
    assert "meta-ga, meta-pso (cells of 0.05 m)" in coarse.rows[-1][2]


def test_report_lists_the_runs_left_out(tmp_path: Path) -> None:
    recs = _santos_records()
    recs.append(_rec("sparse", "meta-ga", 7, 10, completed=False, reason="stalled: no progress for 60 s"))
    recs.append(_rec("sparse", "meta-ga", 8, 11, completed=False, reason="interrupted by Ctrl-C"))
    dup = {**recs[0], "pose_spec": "1", "world_spec": "sparse"}
    recs[0] = dup
    recs.append({**dup, "visited_cells": 5})           # recorded twice (a campaign run twice into a folder)
    results = _jsonl(tmp_path / "results.jsonl", recs)
    r = CliRunner().invoke(main, ["campaign", "report", str(results), "--out", str(tmp_path / "rep")])
    assert r.exit_code == 0, r.output
    assert "runs left out of the statistics: 3" in r.output
    assert "not completed (stalled): stalled: no progress" in r.output
    assert "interrupted (--resume makes it again)" in r.output
    assert "recorded more than once" in r.output
    assert "runs left out of the statistics: 3" in (tmp_path / "rep" / "tables.md").read_text(encoding="utf-8")


def _jsonl(path: Path, records: list[dict[str, Any]]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in records), encoding="utf-8")
    return path


def test_report_writes_the_comparison_besides_the_thesis_tables(tmp_path: Path) -> None:
    results = _jsonl(tmp_path / "results.jsonl", _santos_records())
    r = CliRunner().invoke(main, ["campaign", "report", str(results), "--out", str(tmp_path / "rep")])
    assert r.exit_code == 0, r.output
    assert "Welch p, meta-firefly vs meta-ga" in r.output and "1426.0 ± 237.2" in r.output
    assert "dense, max speed 300 mm/s" in r.output                 # a thesis table is still there
    with open(tmp_path / "rep" / "tables.csv", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    titles = [row[0] for row in rows if len(row) == 1]
    assert titles == ["dense, max speed 300 mm/s", "sparse, max speed 300 mm/s",
                      "sparse, max speed 300 mm/s: visited cells per run"]
    assert ["meta-ga", "5", "1923.0 ± 158.1", "0.900", "50.0"] in rows
    md = (tmp_path / "rep" / "tables.md").read_text(encoding="utf-8")
    assert "### sparse, max speed 300 mm/s: visited cells per run" in md
    assert "| meta-firefly | 5 | 1426.0 ± 237.2 | 0.820 | 32.0 |" in md


@pytest.mark.parametrize("content, words", [
    (None, "no such results file"),
    ("", "no runs recorded"),
    ("pose,x\n1,2\n", "results.jsonl:1: not a JSON record"),
    ('{"run": "a", "world": "w", "method": "m", "visited_cells": 1}\n[1, 2]\n', ":2: expected a JSON object"),
    ('{"foo": 1}\n', "lacks run, world, method, visited_cells"),
])
@pytest.mark.parametrize("command", ["report", "plot"])
def test_bad_results_files_give_one_line_and_exit_2(tmp_path: Path, content: str | None, words: str,
                                                    command: str) -> None:
    results = tmp_path / "results.jsonl"
    if content is not None:
        results.write_text(content, encoding="utf-8")
    r = CliRunner().invoke(main, ["campaign", command, str(results)])
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robotexp: error:") and words in lines[0]


def test_load_results_skips_a_torn_last_line(tmp_path: Path) -> None:
    p = tmp_path / "results.jsonl"
    p.write_text(json.dumps(_rec("w", "a", 0, 1)) + "\n" + '{"run": "b", "wor', encoding="utf-8")
    assert [r["run"] for r in load_results(p)] == ["w_a_1_300mms_s0"]
    p.write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(ConfigError, match="not UTF-8"):
        load_results(p)


def test_plot_two_tiny_runs(tmp_path: Path) -> None:
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment

    out = tmp_path / "camp"
    for pose in ("1", "2"):
        run_experiment(RunSpec(world="dense", method="frontier", pose=pose, max_time=20), out, image=False,
                       record_extra={"world_spec": "dense", "pose_spec": pose})
    records = load_results(out / "results.jsonl")
    pics = tmp_path / "pics"
    r = CliRunner().invoke(main, ["campaign", "plot", str(out / "results.jsonl"), "--out", str(pics),
                                  "--include-incomplete"])
    assert r.exit_code == 0, r.output
    with Image.open(pics / "visited_cells.png") as box:
        assert box.width == round(PAGE_WIDTH * DPI)                       # a page's width at 200 dpi
    with Image.open(pics / "coverage_dense.png") as cov:
        assert cov.width == round(PAGE_WIDTH * DPI)
        cpx = np.asarray(cov.convert("RGB"))
    assert _count(cpx, PALETTE[0]) > 100                                 # the frontier runs' curves
    with Image.open(pics / "paths_dense_frontier.png") as paths:
        assert paths.width == round(PAGE_WIDTH * DPI) and 0.5 * paths.width < paths.height < 1.6 * paths.width
        px = np.asarray(paths.convert("RGB"))
    # both runs are drawn, in their own colours
    assert _count(px, PALETTE[0]) > 100 and _count(px, PALETTE[1]) > 100

    # a missing path file: the run is skipped with a one-line note, the other still drawn
    (out / f"{records[1]['run']}.path.csv").unlink()
    r = CliRunner().invoke(main, ["campaign", "plot", str(out / "results.jsonl"), "--out", str(pics)])
    assert r.exit_code == 0, r.output
    assert f"{records[1]['run']}: no path file" in r.output
    with Image.open(pics / "paths_dense_frontier.png") as again:
        px2 = np.asarray(again.convert("RGB"))
    assert _count(px2, PALETTE[0]) > 100 and _count(px2, PALETTE[1]) == 0


def _count(px: Any, hex_colour: str, tol: int = 30) -> int:
    want = np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)])
    return int((np.abs(px.astype(int) - want).max(axis=2) <= tol).sum())


def test_box_plot_separates_cell_sizes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import robotexp.output.figures
    from robotexp.campaign.compare import campaign_plots

    seen: list[list[tuple[str, list[float]]]] = []
    labels: list[str] = []
    real = robotexp.output.figures.box_figure

    def spy(groups: list[tuple[str, list[float]]], **kw: Any) -> Any:
        seen.append(groups)
        labels.append(kw["ylabel"])
        return real(groups, **kw)

    monkeypatch.setattr(robotexp.output.figures, "box_figure", spy)
    recs = [{**_rec("dense", "srt-laser", i, 1700 + i), "cell_m": 0.1} for i in range(3)]
    recs += [{**_rec("dense", "meta-ga", i, 4124 + i), "cell_m": 0.05} for i in range(3)]
    recs += [{**_rec("sparse", "meta-ga", i, 900 + i), "cell_m": 0.05} for i in range(2)]
    campaign_plots(recs, tmp_path, tmp_path / "pics", note=lambda text: None)
    (groups,) = seen
    assert [label for label, _ in groups] == ["dense meta-ga (cells of 0.05 m)", "dense srt-laser (cells of 0.1 m)",
                                              "sparse meta-ga"]
    assert groups[1][1] == [1700.0, 1701.0, 1702.0]
    assert labels == ["visited cells [cells of each run's map]"]         # sizes differ: named under each box
    labels.clear()
    campaign_plots(recs[3:], tmp_path, tmp_path / "pics", note=lambda text: None)
    assert labels == ["visited cells [cells of 50 mm]"]                   # one size: on the axis
