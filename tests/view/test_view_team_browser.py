"""`robotexp explore --team 2 --view` watched in headless Chromium: the page draws both robots (robot 1 in
red, robot 2 and its path in its team colour) and the feed gives each teammate's pose and path."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from robotexp.experiment import run_team
from robotexp.output.render import TEAM_COLORS
from robotexp.output.results import read_records
from robotexp.run.spec import RunSpec
from robotexp.run.team import TeamSpec
from robotexp.testing.explorer_contract import make_room
from robotexp.view.feed import Frame, ViewClient, ViewHub
from robotexp.view.observer import ViewObserver

from test_view_browser import _need_browser, _page


# pixels of the moving layer (#dyn) of exactly one colour
COUNT_JS = """([r, g, b]) => { const c = document.getElementById('dyn');
  const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let n = 0;
  for (let i = 0; i < d.length; i += 4) if (d[i] === r && d[i + 1] === g && d[i + 2] === b && d[i + 3] === 255) n++;
  return n; }"""


def test_the_hub_sends_each_teammate_its_pose_and_new_path_points() -> None:
    hub = ViewHub()
    hub.start({"geo": {}, "team": [{"robot": "p3dx", "radius": 0.26}]})
    hub.publish(Frame(time=0.1, pose=(0.0, 0.0, 0.0), team=[((1.0, 2.0, 0.5), [1.0, 2.0])]))
    client = ViewClient()
    first = hub.message_for(client)
    assert first is not None and first["team"] == [{"pose": (1.0, 2.0, 0.5), "path_from": 0, "path": [1.0, 2.0]}]
    hub.publish(Frame(time=0.2, team=[(None, [1.1, 2.0])]))
    second = hub.message_for(client)            # only the new point; the pose kept
    assert second is not None and second["team"] == [{"pose": (1.0, 2.0, 0.5), "path_from": 1, "path": [1.1, 2.0]}]
    late = hub.message_for(ViewClient())        # a browser that comes later gets the whole path
    assert late is not None and late["team"][0]["path"] == [1.0, 2.0, 1.1, 2.0]
    hub.restart(0.0)                            # a seek: the paths are sent again from the start
    assert hub.message_for(client)["team"] == [{"pose": (1.0, 2.0, 0.5), "path_from": 0, "path": []}]


@pytest.mark.untimed
def test_a_team_frame_shows_every_robot_at_the_same_tick_and_the_teams_path() -> None:
    # a frame at every tick (speed max, 1 MHz frame rate): each is sent once every robot has stepped, so the
    # teammate's pose and the team's path are the tick's, not the previous one's (a frame sent at robot 1's
    # step showed robot 2 where it stood a tick before)
    hub = ViewHub()
    observer = ViewObserver(hub, speed=None, frame_rate=1e6)
    frames: list[tuple[float, list[float], float, float, tuple[float, float, float] | None, Any]] = []
    publish = hub.publish

    def noting(frame: Frame) -> None:
        run: Any = observer.run
        if frame.team is not None:
            mate = run.members[1].state.pose
            times = [run.members[i].state.time - run._t0 for i in run.active]
            frames.append((frame.time, times, run.metrics.path_length, sum(m.metrics.path_length for m in run.members),
                           frame.team[0][0], (mate.x, mate.y, mate.theta)))
        publish(frame)

    hub.publish = noting        # type: ignore[method-assign]
    spec = RunSpec(world="conformance-room", method="frontier", max_time=8.0, laser_range=3.0)
    out = run_team(spec, TeamSpec(robots=("p3dx", "kobuki"), coordinator="greedy"), None, image=False,
                   world=make_room(), observers=[observer])
    assert len(frames) >= 80                                       # a frame a tick
    assert sum(len(times) == 2 for _, times, *_ in frames) >= 10   # both robots exploring in many of them
    for t, times, path, total, mate, truth in frames[1:-1]:    # the first: the start; the last: the end's
        assert times == [pytest.approx(t, abs=1e-9)] * len(times), (t, times)   # the robots still exploring
        assert path == pytest.approx(total, abs=1e-9) and mate == truth
    assert frames[-1][2] == pytest.approx(out.record["path_length_m"], abs=1e-3) and frames[-1][2] > 1.0


def test_explore_team_view_in_chromium_draws_both_robots(tmp_path: Path, view_cli: Any, team_room: str) -> None:
    _need_browser()
    (tmp_path / "room.map").write_text(team_room)
    out = tmp_path / "out"
    # the team explores the room in 15 s of robot time: at 5x the page has 3 s to pause it before it ends
    proc, url = view_cli.start("explore", "-w", str(tmp_path / "room.map"), "--team", "2", "--coordinator", "greedy",
                               "--view", "--view-speed", "5", "--max-time", "3600", "-o", str(out))
    with _page(url, viewport={"width": 1000, "height": 700}) as page:
        page.wait_for_function("document.body.dataset.robots === '2' && Number(document.body.dataset.t) > 2",
                               timeout=30_000)
        page.click("#pause")
        page.wait_for_function("document.body.dataset.state === 'paused'", timeout=30_000)
        time.sleep(0.5)
        red = page.evaluate(COUNT_JS, [220, 40, 40])                   # robot 1's outline
        purple = page.evaluate(COUNT_JS, list(TEAM_COLORS[0]))          # robot 2's outline and path
        assert red > 20 and purple > 20, (red, purple)
        page.click("#stop")
        page.wait_for_function("document.body.dataset.state === 'ended'", timeout=30_000)
    deadline = time.monotonic() + 20
    while not (out / "results.jsonl").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(0.5)
    view_cli.interrupt(proc)
    (record,) = read_records(out / "results.jsonl")
    assert record.team_size == 2 and record.robot_time_s > 2
