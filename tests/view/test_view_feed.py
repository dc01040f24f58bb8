"""The live view's frame feed: map encoding, laser points, arrows, and what the hub
sends each browser (the newest state, path and curve points once, a new run from scratch)."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from robotexp.robot import LaserScan
from robotexp.view.feed import FREE, OCCUPIED, TILE, UNKNOWN, Frame, ViewClient, ViewHub, changed_tiles, \
    classes_of_states, decode_classes, decode_tiles, encode_classes, encode_tiles, laser_points, packed_laser, \
    unpack_laser, vector_arrows


def test_classes_of_ros_states() -> None:
    states = np.array([[-1, 0, 100], [49, 50, -1]], np.int8)
    assert classes_of_states(states).tolist() == [[UNKNOWN, FREE, OCCUPIED], [FREE, OCCUPIED, UNKNOWN]]


def test_map_encoding_round_trip_and_size() -> None:
    rng = np.random.default_rng(3)
    classes = rng.integers(0, 3, size=(37, 53)).astype(np.uint8)
    text = encode_classes(classes)
    assert np.array_equal(decode_classes(text, 37, 53), classes)
    # row-major bytes, zlib stream (what the page's DecompressionStream("deflate") inflates)
    import base64
    assert zlib.decompress(base64.b64decode(text)) == classes.tobytes()
    with pytest.raises(ValueError, match="expected 38 x 53"):
        decode_classes(text, 38, 53)
    # a large, mostly uniform map compresses to a small message: 1000 x 1000 cells under 20 kB
    big = np.zeros((1000, 1000), np.uint8)
    big[200:400, 300:700] = FREE
    big[200, 300:700] = OCCUPIED
    assert len(encode_classes(big)) < 20_000


def test_laser_points_in_world_frame() -> None:
    # robot at (1, 2) facing +y, laser 0.1 m ahead: a beam straight ahead at 1 m hits (1, 3.1);
    # a beam to the left (+90 deg) at 0.5 m hits (0.5, 2.1); the inf beam is left out
    angles = np.array([0.0, math.pi / 2, -math.pi / 2])
    ranges = np.array([1.0, 0.5, math.inf])
    pts = laser_points(1.0, 2.0, math.pi / 2, angles, ranges, offset_x=0.1)
    assert pts == pytest.approx([1.0, 3.1, 0.5, 2.1], abs=1e-9)
    many = laser_points(0, 0, 0, np.linspace(-1, 1, 1000), np.ones(1000), max_points=100)
    assert len(many) // 2 == 100


def test_packed_laser_is_the_points_to_the_cm() -> None:
    rng = np.random.default_rng(2)
    angles = np.linspace(-2.0, 2.0, 500)
    ranges = rng.uniform(0.05, 30.0, 500)
    ranges[::7] = np.inf
    args = (-3.2, 14.7, 0.8, angles, ranges, 0.12)
    packed = packed_laser(*args)
    assert isinstance(packed["cm"], str) and len(packed["cm"]) < 4 * 360 * 4 / 3 + 4   # 4 bytes a point
    assert unpack_laser(packed) == pytest.approx(laser_points(*args), abs=0.005 + 1e-9)
    assert len(unpack_laser(packed)) == len(laser_points(*args)) == 2 * 214     # 428 finite beams: every 2nd


def test_vector_arrows_lattice() -> None:
    vec = np.zeros((10, 20, 2))
    vec[..., 0] = 3.0                     # all pointing +x, not unit length
    vec[5, 11] = 0.0                      # one without direction (on the lattice)
    spacing, arrows = vector_arrows(vec, (-1.0, -2.0), 0.1, max_arrows=50)
    step = math.ceil(math.sqrt(200 / 50))     # 2 cells
    assert spacing == pytest.approx(step * 0.1)
    a = np.array(arrows).reshape(-1, 4)
    assert len(a) == 5 * 10 - 1           # rows 1, 3, .., 9 x cols 1, 3, .., 19 but (5, 11)
    assert np.allclose(a[:, 2:], [1.0, 0.0])
    assert a[0, :2] == pytest.approx([-1.0 + 1.5 * 0.1, -2.0 + 1.5 * 0.1])


def test_changed_tiles_and_their_encoding() -> None:
    rng = np.random.default_rng(5)
    old = rng.integers(0, 3, size=(70, 45)).astype(np.uint8)     # 3 x 2 tiles of 32, the last ones cut
    assert changed_tiles(None, old).tolist() == [[True, True]] * 3
    new = old.copy()
    new[33, 40] = (new[33, 40] + 1) % 3                            # tile (1, 1)
    new[69, 0] = (new[69, 0] + 1) % 3                              # tile (2, 0), the cut one
    which = changed_tiles(old, new)
    assert which.tolist() == [[False, False], [False, True], [True, False]]
    msg = encode_tiles(new, which)
    assert msg["tiles"] == [1, 1, 2, 0] and msg["tile"] == TILE
    raw = zlib.decompress(__import__("base64").b64decode(msg["data"]))
    assert raw == new[32:64, 32:45].tobytes() + new[64:70, 0:32].tobytes()      # row-major, tile after tile
    painted = old.copy()
    decode_tiles(msg, painted)
    assert np.array_equal(painted, new)
    whole = np.zeros_like(old)
    decode_tiles(encode_tiles(new, changed_tiles(None, new)), whole)
    assert np.array_equal(whole, new)
    with pytest.raises(ValueError, match="tiles of a 70 x 45 map"):
        decode_tiles(msg, np.zeros((45, 70), np.uint8))


def _classes(rows: int, cols: int, free: tuple[int, int] | None = None) -> np.ndarray:
    out = np.zeros((rows, cols), np.uint8)
    if free is not None:
        out[free] = FREE
    return out


def test_hub_sends_newest_state_and_points_once() -> None:
    hub = ViewHub()
    client = ViewClient()
    first = hub.message_for(client)
    assert first is not None and "meta" not in first            # nothing started yet
    hub.start({"geo": {"origin_x": 0, "origin_y": 0, "cell": 0.1, "rows": 40, "cols": 40}, "radius": 0.2})
    hub.publish(Frame(time=0.1, pose=(0, 0, 0), path=[0.0, 0.0], map=_classes(40, 40, (0, 0))))
    hub.publish(Frame(time=0.2, pose=(1, 0, 0), path=[1.0, 0.0], curve=[0.0, 0.5]))
    hub.publish(Frame(time=0.3, pose=(2, 0, 0), path=[2.0, 0.0],
                      scan=LaserScan(np.array([0.0, 1.0]), np.array([1.0, np.inf]), 4.0)))
    msg = hub.message_for(client)
    assert msg is not None
    assert msg["meta"]["radius"] == 0.2
    assert msg["t"] == 0.3 and msg["pose"] == (2, 0, 0)             # the stale poses were skipped
    assert unpack_laser(msg["laser"]) == [3.0, 0.0]                  # the scan's points, made at the send
    assert msg["path_from"] == 0 and msg["path"] == [0.0, 0.0, 1.0, 0.0, 2.0, 0.0]
    assert msg["curve"] == [0.0, 0.5] and msg["map"]["tiles"] == [0, 0, 0, 1, 1, 0, 1, 1]   # all of it
    assert hub.message_for(client) is None                          # nothing new
    hub.publish(Frame(time=0.4, path=[3.0, 0.0], map=_classes(40, 40, (0, 0))))   # the same map: no tiles
    msg = hub.message_for(client)
    assert msg is not None and "meta" not in msg and "map" not in msg
    assert msg["path_from"] == 3 and msg["path"] == [3.0, 0.0] and msg["pose"] == (2, 0, 0)
    hub.publish(Frame(time=0.5, map=_classes(40, 40, (35, 0))))     # cell (0, 0) back to unknown, (35, 0) free
    msg = hub.message_for(client)
    assert msg is not None and msg["map"]["tiles"] == [0, 0, 1, 0]  # only the tiles that changed
    late = ViewClient()                                             # a browser that joins now gets it all
    msg = hub.message_for(late)
    assert msg is not None and msg["path"] == [0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 3.0, 0.0]
    assert len(msg["map"]["tiles"]) == 8
    got = np.full((40, 40), 9, np.uint8)
    decode_tiles(msg["map"], got)
    assert np.array_equal(got, _classes(40, 40, (35, 0)))
    hub.restart(0.2)                                                # a replay seeks back: path from scratch,
    hub.publish(Frame(time=0.2, path=[1.0, 0.0], map=_classes(40, 40, (0, 0))))     # the map's changes only
    msg = hub.message_for(client)
    assert msg is not None and "meta" not in msg and msg["path_from"] == 0 and msg["path"] == [1.0, 0.0]
    assert msg["map"]["tiles"] == [0, 0, 1, 0] and msg["t"] == 0.2
    hub.start({"geo": {"origin_x": 0, "origin_y": 0, "cell": 0.1, "rows": 2, "cols": 2}, "radius": 0.3})
    msg = hub.message_for(client)                                   # a new run: from scratch
    assert msg is not None and msg["meta"]["radius"] == 0.3 and msg["path"] == [] and "map" not in msg
    hub.publish(Frame(time=0.1, map=_classes(2, 2)))
    msg = hub.message_for(client)
    assert msg is not None and msg["map"]["tiles"] == [0, 0] and msg["map"]["rows"] == 2
    hub.finish("stopped from the live view")
    msg = hub.message_for(client)
    assert msg is not None and msg["status"]["state"] == "ended"


def test_hub_commands_follow_controls() -> None:
    got: list[dict[str, object]] = []
    hub = ViewHub(controls=("pause", "stop"), on_command=got.append)
    for cmd in ("pause", "resume", "step", "speed", "stop", "rm -rf"):
        hub.command({"cmd": cmd})
    assert [g["cmd"] for g in got] == ["pause", "resume", "stop"]


def test_potential_levels_log_scale_on_free_cells() -> None:
    from robotexp.view.observer import potential_levels

    # 1 - p = 1e-1, 1e-3, 1e-5 on three free cells: equal steps on the log scale; the rest not drawn
    p = np.array([[1 - 1e-1, 1 - 1e-3, 1 - 1e-5, 0.5, 1.0]])
    free = np.array([[True, True, True, False, True]])
    assert potential_levels(p, free).tolist() == [[0, 127, 254, 255, 254]]
    assert potential_levels(p, np.zeros_like(free)).tolist() == [[255] * 5]


@pytest.mark.parametrize("method", ["srt-star", "bvp", "frontier"])
def test_explorer_overlays_reach_the_hub(method: str) -> None:
    """The run's last frame carries what the explorer exposes: SRT's nodes, tree and safe regions, BVP's
    potential and vectors, the frontier target (while it has one)."""
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment
    from robotexp.view.observer import ViewObserver

    hub = ViewHub()
    out = run_experiment(RunSpec(world="ufmg-static", method=method, max_time=15.0), None,
                         observers=[ViewObserver(hub, speed=None)], image=False)
    ov = hub.overlays
    explorer = out.run.explorer
    if method == "srt-star":
        nodes = len(explorer.tree)  # type: ignore[attr-defined]
        assert len(ov["points"]["SRT nodes"]) == 2 * nodes >= 2
        assert len(ov["polygons"]["safe regions"]) == nodes
        assert len(ov["lines"]["SRT tree"]) == 4 * (nodes - 1)
    elif method == "bvp":
        geo = out.run.grid.geo
        levels = decode_classes(ov["potential"].data, geo.rows, geo.cols)
        assert ((levels < 255) == out.run.grid.free()).all()          # drawn on the free cells only
        assert ov["vectors"]["spacing"] > 0 and len(ov["vectors"]["arrows"]) % 4 == 0
    else:
        goal = explorer.goal  # type: ignore[attr-defined]
        assert (goal is None and "points" not in ov) or ov["points"]["frontier target"] == \
            pytest.approx(list(goal), abs=1e-3)


def test_hub_sends_campaign_rows_once() -> None:
    hub = ViewHub()
    client = ViewClient()
    hub.start({"kind": "campaign", "title": "campaign x"})
    hub.publish(Frame(time=1.0, rows=[{"run": "a"}]))
    msg = hub.message_for(client)
    assert msg is not None and msg["rows_from"] == 0 and msg["rows"] == [{"run": "a"}]
    hub.publish(Frame(time=2.0, rows=[{"run": "b"}]))
    hub.publish(Frame(time=3.0))
    msg = hub.message_for(client)
    assert msg is not None and msg["rows_from"] == 1 and msg["rows"] == [{"run": "b"}] and msg["t"] == 3.0
    hub.publish(Frame(time=4.0))
    msg = hub.message_for(client)
    assert msg is not None and "rows" not in msg


def test_observer_skips_the_map_while_nobody_watches() -> None:
    """Without a browser the observer publishes no maps (the run does not build them); one that connects
    gets the run's current map at once."""
    from robotexp.run.spec import RunSpec
    from robotexp.experiment import run_experiment
    from robotexp.run.loop import ExplorationRun
    from robotexp.run.observers import RunObserver, StepEvent
    from robotexp.view.observer import ViewObserver

    hub = ViewHub()
    versions: list[tuple[float, int]] = []

    class Browser(RunObserver):
        """Connects at 5 s of robot time; notes the hub's map version at every tick."""

        def on_step(self, run: ExplorationRun, step: StepEvent) -> None:
            if step.time >= 5.0 and not hub.watched:
                hub.add_listener(lambda: None)
            versions.append((step.time, hub.map_version))

    clock = [0.0]

    def tick() -> float:              # a wall clock that moves 10 ms a call: maps fall due as they would
        clock[0] += 0.01
        return clock[0]

    out = run_experiment(RunSpec(world="ufmg-static", method="frontier", max_time=10.0), None,
                         observers=[Browser(), ViewObserver(hub, speed=None, clock=tick)], image=False)
    before = {v for t, v in versions if t < 5.0}
    after = [v for t, v in versions if t >= 5.2]
    assert before == {1}                          # the map of the start only (sent with the run's meta)
    assert after[-1] > 2                          # maps flow once watched
    assert hub.classes is not None and np.array_equal(hub.classes, classes_of_states(out.run.grid.states()))
