"""Seeking in a replay: `robotexp replay BAG --view` shows the recording at any robot
time asked for, with the map rebuilt to that tick (from a checkpoint or from the start) equal to the
map a straight pass integrates up to it; through the player directly, and end to end through the real
aiohttp server (websocket commands and POST /command) of a `robotexp replay --view` process."""

from __future__ import annotations

import asyncio
import bisect
import json
import time
import urllib.request
from pathlib import Path
from typing import Any

import aiohttp
import numpy as np
import pytest

from robotexp.bag.replay import Bag, read_bag, replay_bag
from robotexp.mapping.grid import OccupancyGrid
from robotexp.output.results import read_jsonl
from robotexp.view.feed import ViewClient, ViewHub, classes_of_states, decode_tiles
from robotexp.view.player import Checkpoints, ReplayPlayer, checkpoint_every


def _map_at(data: Bag, grid: OccupancyGrid, t: float) -> np.ndarray:
    """The map a straight pass over the recording has after its last tick at or before `t` [s]."""
    fresh = OccupancyGrid(grid.geo, model=grid.model, range_max=grid.range_max)
    for tick in data.ticks:
        if tick.time > t + 1e-9:
            break
        if tick.scan is not None:
            fresh.update(tick.pose, tick.scan)
    return fresh.states()


@pytest.mark.untimed
def test_checkpoint_spacing() -> None:
    assert checkpoint_every(25.0, 40_000) == 10.0                   # every 10 s
    assert checkpoint_every(3600.0, 40_000) == 60.0                 # a 60th of an hour
    assert checkpoint_every(3600.0, 10_000_000, budget=80e6 * 10) == pytest.approx(360.0)   # 10 fit


@pytest.mark.untimed
def test_seek_rebuilds_the_map_of_that_tick(recorded: tuple[Path, dict[str, object]]) -> None:
    bag, record = recorded
    data = read_bag(bag)
    checkpoints = Checkpoints(5.0)
    run = replay_bag(data, None, observers=(checkpoints,))
    assert run.record is not None and run.record.coverage == record["coverage"]     # results as without
    assert [round(t, 6) for t, _ in checkpoints.items] == [5.0, 10.0, 15.0, 20.0, 25.0]
    hub = ViewHub()
    player = ReplayPlayer(hub, data, run, checkpoints, speed=None)
    hub.start({"geo": {"rows": run.grid.geo.rows, "cols": run.grid.geo.cols}})
    client = ViewClient()
    seen = np.zeros(run.grid.shape, np.uint8)
    times = [t.time for t in data.ticks]
    for target in (20.0, 7.04, 7.05, 23.0, 0.0, 12.3, 24.95, 25.0):     # ahead, back (checkpoints), to the end
        player.seek_to(target)
        k = bisect.bisect_right(times, target + 1e-9) - 1
        assert player.i == k + 1 and hub.time == times[k]
        want = _map_at(data, run.grid, target)
        assert np.array_equal(player.grid.states(), want), f"map at {target} s"
        msg = hub.message_for(client)
        assert msg is not None and msg["t"] == times[k] and msg["path_from"] == 0
        if "map" in msg:                                          # a browser gets the tiles that changed
            decode_tiles(msg["map"], seen)
        assert np.array_equal(seen, classes_of_states(want)), f"the browser's map at {target} s"
        assert msg["pose"] == (data.ticks[k].pose.x, data.ticks[k].pose.y, data.ticks[k].pose.theta)
        curve_times = msg["curve"][0::2]
        assert curve_times == [round(c[0], 3) for c in run.metrics.curve if c[0] <= times[k] + 1e-9]
    assert np.array_equal(player.grid.values, run.grid.values)    # at the end: the replay's own map
    assert player.seeks == 8


def _post(url: str, body: bytes) -> int:
    req = urllib.request.Request(url, data=body, headers={"Content-Type": "application/json"}, method="POST")
    with urllib.request.urlopen(req, timeout=5) as r:
        return int(r.status)


async def _session(url: str, data: Bag, times: list[float], grid: OccupancyGrid) -> dict[str, Any]:
    """Drive a replay's view: pause, seek ahead and back over the websocket and once by POST /command,
    each time rebuilding the map the page would show; then resume."""
    seen: np.ndarray | None = None
    got: dict[str, Any] = {"maps": []}

    async with aiohttp.ClientSession() as session, session.ws_connect(url + "ws", max_msg_size=0) as ws:
        async def until(pred: Any, timeout: float = 20.0) -> dict[str, Any]:
            nonlocal seen
            deadline = time.monotonic() + timeout
            while True:
                raw = await asyncio.wait_for(ws.receive(), max(0.1, deadline - time.monotonic()))
                msg = json.loads(raw.data)
                if "meta" in msg:
                    got["meta"] = msg["meta"]
                    seen = np.zeros((msg["meta"]["geo"]["rows"], msg["meta"]["geo"]["cols"]), np.uint8)
                if "map" in msg and seen is not None:
                    decode_tiles(msg["map"], seen)
                if pred(msg):
                    return msg

        first = await until(lambda m: "meta" in m and m["status"]["state"] in ("running", "paused"))
        got["controls"] = first["controls"]
        await ws.send_str(json.dumps({"cmd": "pause"}))
        await until(lambda m: m["status"]["state"] == "paused")
        for target, how in ((20.0, "ws"), (3.0, "ws"), (11.55, "http")):
            k = bisect.bisect_right(times, target + 1e-9) - 1
            if how == "ws":
                await ws.send_str(json.dumps({"cmd": "seek", "value": target}))
            else:
                body = json.dumps({"cmd": "seek", "value": target}).encode()
                status = await asyncio.get_running_loop().run_in_executor(None, _post, url + "command", body)
                assert status == 204
            msg = await until(lambda m, k=k: m["t"] == times[k] and "map" in m)
            assert seen is not None
            got["maps"].append((target, msg["t"], msg["status"]["state"], seen.copy()))
        with pytest.raises(asyncio.TimeoutError):             # paused after the seeks: nothing moves
            await until(lambda m: m["t"] != times[k], 1.0)
        await ws.send_str(json.dumps({"cmd": "resume"}))
        got["after"] = (await until(lambda m: m["t"] > times[k] + 0.5))["t"]
    return got


def test_replay_view_seeks_end_to_end(recorded: tuple[Path, dict[str, object]], tmp_path: Path,
                                      view_cli: Any) -> None:
    bag, record = recorded
    data = read_bag(bag)
    reference = replay_bag(data, None)
    times = [t.time for t in data.ticks]
    out = tmp_path / "out"
    proc, url = view_cli.start("replay", str(bag), "-o", str(out), "--view", "--view-speed", "2")
    got = asyncio.run(_session(url, data, times, reference.grid))
    view_cli.interrupt(proc)
    assert "seek" in got["controls"] and got["meta"]["duration"] == pytest.approx(times[-1])
    for target, t, state, seen in got["maps"]:
        k = bisect.bisect_right(times, target + 1e-9) - 1
        assert t == times[k] and state == "paused"
        assert np.array_equal(seen, classes_of_states(_map_at(data, reference.grid, target))), f"map at {target} s"
    assert got["after"] > times[k] + 0.5                           # resumed from the last seek
    # the results are the replay's, whatever the page did
    assert read_jsonl(out / "results.jsonl")[-1]["coverage"] == record["coverage"]
