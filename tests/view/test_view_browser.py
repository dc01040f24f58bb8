"""`robotexp explore --view` watched in headless Chromium: the page's map
canvas changes as the run goes, pause holds robot time, resume lets it go on, stop ends the run and
its record says it was stopped from the view (end reason STOPPED). Debian's chromium, driven by
playwright (never a downloaded browser). Skipped only off CI when chromium is missing; on CI
(CI=true) a missing browser fails."""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from robotexp.run.record import EndReason
from robotexp.output.results import read_records
from robotexp.view.observer import STOP_REASON

CHROMIUM = os.environ.get("ROBOTEXP_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
ON_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


def _need_browser() -> None:
    missing = []
    if not Path(CHROMIUM).exists():
        missing.append(f"{CHROMIUM} (apt-get install chromium)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        missing.append("playwright (pip install -e '.[test]')")
    if missing:
        if ON_CI:
            pytest.fail(f"CI must run the browser test of the live view; missing: {', '.join(missing)}")
        pytest.skip(f"missing {', '.join(missing)}")


HASH_JS = """() => { const c = document.getElementById('map');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let h = 0; for (let i = 0; i < d.length; i += 4) h = (h * 31 + d[i] + 7 * d[i + 1] + 13 * d[i + 2]) | 0;
  return h; }"""


def _robot_time(page: object) -> float:
    return float(page.evaluate("Number(document.body.dataset.t || -1)"))  # type: ignore[attr-defined]


def _settled_time(page: object, timeout: float = 30.0) -> float:
    """The page's robot time once it has kept its value for 0.5 s (paused: the loop may still be inside its
    tick and the page a frame behind); fails when it still changes after `timeout` s."""
    end = time.monotonic() + timeout
    t = _robot_time(page)
    while True:
        time.sleep(0.5)
        now = _robot_time(page)
        if now == t:
            return now
        assert time.monotonic() < end, f"robot time still runs while paused: {t} -> {now}"
        t = now


@contextmanager
def _page(url: str, **options: Any) -> Iterator[Any]:
    """A page of Debian's headless Chromium (through playwright) showing `url`."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(**options)
            page.goto(url)
            yield page
        finally:
            browser.close()


def test_explore_view_in_chromium(tmp_path: Path, view_cli: Any) -> None:
    _need_browser()
    out = tmp_path / "out"
    proc, url = view_cli.start("explore", "-w", "ufmg-static", "--view", "--view-speed", "5", "--max-time", "3600",
                               "-o", str(out))
    with _page(url, viewport={"width": 1200, "height": 800}) as page:
        page.wait_for_function("Number(document.getElementById('map').dataset.mapVersion) >= 1", timeout=30_000)
        before = page.evaluate(HASH_JS)
        page.wait_for_function("Number(document.body.dataset.t) > 4", timeout=30_000)
        page.wait_for_function(f"({HASH_JS})() !== {before}", timeout=30_000)   # the map canvas changed
        assert int(page.evaluate("Number(document.getElementById('map').dataset.mapVersion)")) >= 2

        page.click("#pause")
        page.wait_for_function("document.body.dataset.state === 'paused'", timeout=30_000)
        held = _settled_time(page)             # the loop held, its last frame shown (under load: seconds)
        time.sleep(1.5)                        # 7.5 s of robot time at 5x, were it running
        assert _robot_time(page) == held
        assert page.inner_text("#pause") == "Resume"

        page.click("#pause")                   # resume
        page.wait_for_function(f"Number(document.body.dataset.t) > {held + 1}", timeout=30_000)

        page.click("#stop")
        page.wait_for_function("document.body.dataset.state === 'ended'", timeout=30_000)
        assert STOP_REASON in page.inner_text("#reason")
        assert page.is_disabled("#pause") and page.is_disabled("#stop")
    # the run is over and written; the page stays up until Ctrl-C
    deadline = time.monotonic() + 20
    while not (out / "results.jsonl").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    assert proc.poll() is None, "the view must stay up after the run until Ctrl-C"
    rest = view_cli.interrupt(proc)
    assert "stopped from the live view" in rest
    records = read_records(out / "results.jsonl")
    assert [(r.end, r.reason, r.completed) for r in records] == [(EndReason.STOPPED, STOP_REASON, False)]
    assert records[0].robot_time_s > held + 1


CAMPAIGN = """[campaign]
name = "tiny"
max_time_s = 5
seeds = [0]

[[set]]
world = "ufmg-static"
poses = ["path1", "path2"]
methods = ["frontier"]
speeds_mm_s = [300]
"""


def test_campaign_view_in_chromium(tmp_path: Path, view_cli: Any) -> None:
    """`robotexp campaign run FILE --view`: the page shows the runs done of all and a row per finished run."""
    _need_browser()
    (tmp_path / "tiny.toml").write_text(CAMPAIGN)
    out = tmp_path / "out"
    proc, url = view_cli.start("campaign", "run", str(tmp_path / "tiny.toml"), "-j", "1", "-o", str(out), "--view",
                               first=False)
    with _page(url) as page:
        page.wait_for_function("document.body.dataset.state === 'ended'", timeout=60_000)
        rows = page.eval_on_selector_all("#runs tbody tr", "rs => rs.map(r => r.cells[0].textContent)")
        assert page.inner_text("#speedup") == "2 / 2"
        assert page.is_hidden("#map") and page.is_hidden("#controls")
    view_cli.interrupt(proc)
    assert sorted(rows) == sorted(r.run for r in read_records(out / "results.jsonl"))
    assert len(rows) == 2


FREE_PIXELS_JS = """() => { const c = document.getElementById('map');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] === 255) n++;
  return n; }"""


def test_replay_seek_in_chromium(tmp_path: Path, view_cli: Any) -> None:
    """`robotexp replay BAG --view`: the time box and the slider on the page seek; the map shows the
    free cells of that time (fewer early on), paused stays paused."""
    _need_browser()
    from click.testing import CliRunner

    from robotexp.cli import main

    bag = tmp_path / "run.mcap"
    res = CliRunner().invoke(main, ["explore", "-w", "ufmg-static", "--max-time", "12", "-o", str(tmp_path / "rec"),
                                    "--record", str(bag)])
    assert res.exit_code == 0, res.output
    proc, url = view_cli.start("replay", str(bag), "-o", str(tmp_path / "out"), "--view", "--view-speed", "1")
    with _page(url, viewport={"width": 1200, "height": 800}) as page:
        page.wait_for_selector("#seekbox:not([hidden])", timeout=30_000)
        assert page.get_attribute("#seek", "max") == "12"
        page.click("#pause")
        page.wait_for_function("document.body.dataset.state === 'paused'", timeout=30_000)
        page.fill("#seektime", "9")
        page.press("#seektime", "Enter")
        page.wait_for_function("Math.abs(Number(document.body.dataset.t) - 9) < 0.05", timeout=30_000)
        page.wait_for_timeout(300)
        late = page.evaluate(FREE_PIXELS_JS)
        page.eval_on_selector("#seek", "s => { s.value = '1'; s.dispatchEvent(new Event('change')); }")
        page.wait_for_function("Math.abs(Number(document.body.dataset.t) - 1) < 0.05", timeout=30_000)
        page.wait_for_timeout(300)
        early = page.evaluate(FREE_PIXELS_JS)
        assert 0 < early < late                     # the map of 1 s: less seen than at 9 s
        assert page.inner_text("#state") == "paused" and _robot_time(page) == pytest.approx(1.0, abs=0.05)
        page.click("#pause")                        # resume: plays on from 1 s
        page.wait_for_function("Number(document.body.dataset.t) > 1.5", timeout=30_000)
    view_cli.interrupt(proc)
