"""A map whose file name is not UTF-8 (b"box\\xff.map": Python sees "box\\udcff") runs and draws its
figures (PNG, SVG, PDF; map, coverage, box plots) with U+FFFD in the titles instead of a traceback."""

from __future__ import annotations

import os
from pathlib import Path

from click.testing import CliRunner

from robotexp.cli import main
from robotexp.output.figures import displayable

BOX = "2D-Map\nLINES\n-3000 -3000 3000 -3000\n3000 -3000 3000 3000\n3000 3000 -3000 3000\n-3000 3000 -3000 -3000\n"


def test_displayable() -> None:
    assert displayable("box\udcff") == "box\ufffd"
    assert displayable("caf\u00e9 \ud800") == "caf\u00e9 ?"
    assert displayable("plain") == "plain"


def test_run_and_figures_of_a_non_utf8_map_name(tmp_path: Path) -> None:
    world = os.fsdecode(os.fsencode(str(tmp_path)) + b"/box\xff.map")
    Path(world).write_text(BOX)
    out = tmp_path / "out"
    res = CliRunner().invoke(main, ["explore", "-w", world, "--max-time", "1", "-o", str(out),
                                    "--image-format", "png,svg,pdf"])
    assert res.exit_code == 0, (res.output, res.exception)
    assert "Traceback" not in res.output
    assert len(list(out.glob("*.map.yaml"))) == 1
    assert {p.suffix for p in out.glob("*") if ".coverage." not in p.name} >= {".png", ".svg", ".pdf"}
    svg = next(p for p in out.glob("*.svg") if ".coverage." not in p.name)
    assert "box\ufffd" in svg.read_text(encoding="utf-8")
    res = CliRunner().invoke(main, ["figure", str(out / "results.jsonl"), "--include-incomplete",
                                    "-o", str(tmp_path / "fig"), "--format", "svg"])
    assert res.exit_code == 0, (res.output, res.exception)
    assert list((tmp_path / "fig").glob("box_*.svg"))
