"""A run recorded once for the bag tests: `robotexp explore --record --frames` on the small static room."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from robotexp.cli import main
from robotexp.output.results import read_jsonl


@pytest.fixture(scope="session")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, object]]:
    """A 25 s run on the small static room, recorded through `robotexp explore --record` (and its
    frames saved every 5 s of robot time in `frames/` beside the bag)."""
    tmp = tmp_path_factory.mktemp("rec")
    bag = tmp / "run.mcap"
    res = CliRunner().invoke(main, ["explore", "-w", "ufmg-static", "--max-time", "25", "--noise-sigma", "10",
                                    "-o", str(tmp / "out"), "--record", str(bag), "--frames", str(tmp / "frames"),
                                    "--frame-every", "5"])
    assert res.exit_code == 0, res.output
    return bag, read_jsonl(tmp / "out" / "results.jsonl")[-1]
