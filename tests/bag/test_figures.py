"""Thesis figures on matplotlib: a recording's map (legend, scale bar, axes in metres) and a campaign's
box plots (points, units, axis from 0, n per group), each as PNG, SVG and PDF."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from click.testing import CliRunner
from PIL import Image

from robotexp.cli import main
from robotexp.output.figures import PAGE_WIDTH, box_figure
from robotexp.output.results import read_jsonl


def test_map_figure_of_a_recording(recorded: tuple[Path, dict[str, object]], tmp_path: Path) -> None:
    bag, _ = recorded
    res = CliRunner().invoke(main, ["figure", str(bag), "-o", str(tmp_path / "new" / "figs")])
    assert res.exit_code == 0, res.output
    run = read_jsonl(bag.parent / "out" / "results.jsonl")[-1]["run"]
    png, svg, pdf = (tmp_path / "new" / "figs" / f"{run}.map.{ext}" for ext in ("png", "svg", "pdf"))
    with Image.open(png) as im:
        assert im.width == round(PAGE_WIDTH * 200)          # the page's width at 200 dpi
    text = svg.read_text()
    for words in ("free", "occupied", "unknown", "obstacle not mapped", "path", "start", "end", "x [m]", "y [m]",
                  "ufmg-static - frontier", "cell 100 mm"):
        assert f">{words}<" in text or words in text, words
    assert " m<" in text                                   # the scale bar's label, e.g. "2 m"
    assert pdf.read_bytes().startswith(b"%PDF")


def test_campaign_box_figures(tmp_path: Path) -> None:
    results = tmp_path / "results.jsonl"
    lines = []
    runs = [("frontier", 0.9, 40.0), ("frontier", 0.92, 44.0), ("frontier", 0.95, 41.0), ("frontier", 0.91, 39.0),
            ("frontier", 0.93, 45.0), ("bvp", 0.8, 30.0), ("bvp", 0.85, 33.0)]
    for i, (method, cov, path) in enumerate(runs):
        lines.append(json.dumps({"run": f"r{i}", "method": method, "world": "dense", "start_pose": [0, 0, 0],
                                 "max_speed_m_s": 0.3, "path_length_m": path, "robot_time_s": 100.0 + i,
                                 "wall_time_s": 1.0, "coverage": cov, "collisions": 0, "nodes": None,
                                 "visited_cells": 10, "seed": i, "completed": True, "reason": "explored",
                                 "map_iou": 0.5, "cell_m": 0.1}))
    results.write_text("\n".join(lines) + "\n")
    res = CliRunner().invoke(main, ["figure", str(results), "--format", "svg,png"])
    assert res.exit_code == 0, res.output
    svg = (tmp_path / "box_path_length_m_dense.svg").read_text()
    assert "path length [m]" in svg and "n = 5" in svg and "n = 2" in svg and "cell 100 mm" in svg
    assert (tmp_path / "box_coverage_dense.png").is_file() and (tmp_path / "box_robot_time_s_dense.svg").is_file()
    assert not (tmp_path / "box_coverage_dense.pdf").exists()
    res = CliRunner().invoke(main, ["figure", str(results), "--format", "jpg"])
    assert res.exit_code == 2 and "--format" in res.output
    # a line that is no run record (not robotexp's results): one line, exit 2, as `campaign report` says it
    results.write_text("{}\n")
    res = CliRunner().invoke(main, ["figure", str(results), "--format", "svg"])
    assert res.exit_code == 2 and "record lacks run, world, method, visited_cells" in res.output, res.output


def test_box_figure_draws_boxes_only_for_enough_runs() -> None:
    fig = box_figure([("a", np.arange(6.0)), ("b", [1.0, 2.0])], ylabel="path length [m]", title="t")
    ax = fig.axes[0]
    assert ax.get_ylim()[0] == 0
    # one box (its median line is red) for the group of 6, none for the group of 2; 8 points in all
    medians = [ln for ln in ax.lines if ln.get_color() == (220 / 255, 40 / 255, 40 / 255)]
    points = sum(len(ln.get_xdata()) for ln in ax.lines if ln.get_marker() == "o")
    assert len(medians) == 1 and points == 8


def test_potential_gets_a_colour_bar(tmp_path: Path) -> None:
    from robotexp.output.figures import map_figure, save_figure
    from robotexp.mapping.geometry import GridGeometry

    geo = GridGeometry(0.0, 0.0, 0.1, 40, 60)
    states = np.zeros((40, 60), np.int8)
    states[0, :] = states[-1, :] = 100
    pot = np.tile(np.linspace(0, 1, 60), (40, 1))
    fig = map_figure(states, geo, potential=pot, title="t")
    assert len(fig.axes) == 2 and fig.axes[1].get_ylabel() == "potential"
    (svg,) = save_figure(fig, tmp_path / "pot", ("svg",))
    assert "potential" in svg.read_text()
