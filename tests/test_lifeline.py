"""`exit_without_teardown`: a worker process ends right after its exit handlers, its output and logs
flushed (the interpreter's teardown with numba's kernels loaded took seconds at a campaign's end)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

SCRIPT = textwrap.dedent("""
    import atexit, logging, sys
    from robotexp.lifeline import exit_without_teardown
    from robotexp.world.groundtruth import occupancy  # numba kernels loaded
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.world.loader import load_world

    atexit.register(print, "registered before: skipped")
    exit_without_teardown()
    exit_without_teardown()                                      # twice: armed once
    logging.basicConfig(filename=sys.argv[1], level=logging.INFO)
    world = load_world("ufmg-static")
    occ = occupancy(world, GridGeometry.covering(*world.bounds, cell=0.1))
    atexit.register(print, "registered after: ran")
    logging.getLogger("worker").info("occupied %d", occ.sum())
    sys.stdout.write("unflushed line without a newline")
""")


def test_a_worker_ends_after_its_exit_handlers_with_its_output_and_logs(tmp_path: Path) -> None:
    log = tmp_path / "worker.log"
    proc = subprocess.run([sys.executable, "-c", SCRIPT, str(log)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "unflushed line without a newline" in proc.stdout
    assert "registered after: ran" in proc.stdout and "registered before" not in proc.stdout
    assert "INFO:worker:occupied" in log.read_text()
