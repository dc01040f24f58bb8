"""`check_explorer`: does an explorer plugin keep the contract of `robotexp.explorer.Explorer`?

A plugin author calls it from a test (``robotexp.check_explorer(MyExplorer)``); robotexp's own tests
call it for every installed explorer. It checks, in this order, and raises `PluginError` naming the
plugin and the first rule broken:

1. the class subclasses `Explorer`, and its class attributes (`grid_model`, `preferred_cell`,
   `uses_sonar`, `needs_range`) have legal values;
2. every `__init__` parameter (through `**kwargs` forwarded to a base class) is keyword-only, has
   a default, and is annotated with a type the CLI and Lua can pass: bool, int, float, str, a
   `Literal` of those, a sequence of those (a JSON array: ``-p goals=[[1, 2]]``), or one of these or
   None; each default fits its annotation and its declared range (`parameter_bounds`, whose names
   must be parameters), and the class builds with the defaults alone;
3. on a small generated world (a 5 x 4 m room with a crate, `make_room`) in the simulator, for a
   bounded robot time, `reset` accepts an `ExplorerContext` and every `step` returns a `Twist` of
   finite floats or a `Done` with a string reason; `result_fields` is a dict of JSON values keyed by
   strings, `overlays` a dict of arrays, `markers` a markers dict (`robotexp.markers`: kinds points,
   circles, lines, polygons of finite numbers);
4. it never reads a clock or sleeps (`time.time`, `monotonic`, `perf_counter`, `process_time`,
   `thread_time` and their `_ns` forms, `clock_gettime`, `sleep`, `datetime.now`/`utcnow`/`today`):
   while the plugin's code runs, a profile hook records the C functions called from frames of the
   plugin's own modules, however they were imported (``from time import monotonic as m`` too);
5. with the same seed it decides the same: a second instance repeats the first steps bit for bit
   (randomness comes from `ExplorerContext.rng` only), with `markers()` called after each of its steps
   (as the live view and recordings do: drawing must not change decisions), each return checked.

A clock read through a helper of another package (say a logging call) is that package's business,
not the plugin's: only frames whose module is the plugin's module, or a module of its package, count.
"""

from __future__ import annotations

import datetime
import inspect
import json
import math
import sys
import time
import types
import typing
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from robotexp.errors import PluginError, RobotexpError
from robotexp.explorer import Done, Explorer, ExplorerContext
from robotexp.markers import markers_problem
from robotexp.robot import Pose, Twist

if TYPE_CHECKING:
    from robotexp.world.model import World

__all__ = ["check_explorer", "make_room", "ExplorerReport"]

PERIOD = 0.1            # [s] control period of the check (the run loop's default)
REPEAT_STEPS = 40       # steps the second, same-seed run must repeat
_SCALARS = (bool, int, float, str)
_TIME_FUNCTIONS = frozenset({
    "time", "time_ns", "monotonic", "monotonic_ns", "perf_counter", "perf_counter_ns", "process_time",
    "process_time_ns", "thread_time", "thread_time_ns", "clock_gettime", "clock_gettime_ns", "sleep",
})
_DATE_FUNCTIONS = frozenset({"now", "utcnow", "today"})


@dataclass(frozen=True)
class ExplorerReport:
    """What `check_explorer` saw: the parameters it checked and how the trial run went."""

    parameters: dict[str, object]      # name -> default
    steps: int                         # steps taken on the generated world
    robot_time: float                  # [s] robot time they covered
    done: str | None                   # the Done reason, or None when the time ran out first


def make_room() -> World:
    """The check's world: a closed 5 x 4 m room with a 0.8 x 0.5 m crate, a start pose and a goal list.

    Returns:
        The world (start pose "start" at (1.0, 1.0) m facing +x; goal list "start" of three points).
    """
    from robotexp.world.model import World, segment_box

    wall = 0.1
    boxes = [segment_box(0, 0, 5, 0, wall), segment_box(5, 0, 5, 4, wall), segment_box(5, 4, 0, 4, wall),
             segment_box(0, 4, 0, 0, wall), (3.0, 2.2, 0.4, 0.25, 0.3)]
    return World("conformance-room", np.array(boxes, dtype=np.float64), bounds=(-0.1, -0.1, 5.1, 4.1),
                 poses={"start": Pose(1.0, 1.0, 0.0)},
                 goals={"start": [(2.0, 1.0), (4.0, 1.0), (4.0, 3.2), (1.0, 3.2)]},
                 description="conformance check: a room with a crate")


def check_explorer(cls: type, *, name: str | None = None, robot_time: float = 20.0, seed: int = 0,
                   robot: str = "p3dx") -> ExplorerReport:
    """Check that the explorer class `cls` keeps the plugin contract (see the module docstring).

    Args:
        cls: the explorer class (not an instance).
        name: its plugin name, used in messages (default: the class's qualified name).
        robot_time: [s] robot time of the trial run on the generated world (it ends earlier on Done).
        seed: seed of the trial runs.
        robot: simulated robot preset of the trial run.

    Returns:
        What the check saw.

    Raises:
        PluginError: the first contract rule broken, naming the plugin, the rule and where.
    """
    label = _label(cls, name)
    if not (isinstance(cls, type) and issubclass(cls, Explorer)):
        raise PluginError(f"explorer {label}: is not a subclass of robotexp.explorer.Explorer")
    _check_class_attributes(cls, label)
    params = _check_parameters(cls, label)
    watch = _ClockWatch(cls)
    with watch:
        explorer = _build(cls, label)
    watch.raise_if_read(label)
    steps, t_end, done, decisions = _trial(cls, explorer, label, watch, robot_time, seed, robot, None)
    _check_outputs(explorer, label)
    watch.raise_if_read(label)
    with watch:
        again = _build(cls, label)
    _trial(cls, again, label, watch, robot_time, seed, robot, decisions[:REPEAT_STEPS])
    watch.raise_if_read(label)
    return ExplorerReport(params, steps, t_end, done)


def _label(cls: object, name: str | None) -> str:
    where = f"{getattr(cls, '__module__', '?')}:{getattr(cls, '__qualname__', repr(cls))}"
    return f"{name!r} ({where})" if name else where


def _check_class_attributes(cls: type[Explorer], label: str) -> None:
    if cls.grid_model not in ("logodds", "himm"):
        raise PluginError(f"explorer {label}: grid_model must be 'logodds' or 'himm', got {cls.grid_model!r}")
    cell = cls.preferred_cell
    if cell is not None and not (isinstance(cell, float | int) and not isinstance(cell, bool) and 0 < cell <= 2.0):
        raise PluginError(f"explorer {label}: preferred_cell must be None or a cell size in (0, 2] m, got {cell!r}")
    for flag in ("uses_sonar", "needs_range"):
        if not isinstance(getattr(cls, flag), bool):
            raise PluginError(f"explorer {label}: {flag} must be True or False, got {getattr(cls, flag)!r}")


def _check_parameters(cls: type[Explorer], label: str) -> dict[str, object]:
    """The keyword parameters of `cls` (through **kwargs into its bases) and their defaults."""
    found: dict[str, object] = {}
    for klass in cls.__mro__:
        if klass is Explorer or klass is object:
            break
        init = klass.__dict__.get("__init__")
        if init is None:
            continue
        try:
            signature = inspect.signature(init)
            hints = typing.get_type_hints(init)
        except Exception as exc:        # an annotation naming something that does not exist
            raise PluginError(f"explorer {label}: the annotations of {klass.__qualname__}.__init__ do not "
                              f"resolve ({type(exc).__name__}: {exc})") from exc
        forwards = False
        for i, (pname, param) in enumerate(signature.parameters.items()):
            if i == 0:                  # self
                continue
            where = f"{klass.__qualname__}.__init__ parameter {pname!r}"
            if param.kind is param.VAR_KEYWORD:
                forwards = True
                continue
            if param.kind is not param.KEYWORD_ONLY:
                raise PluginError(f"explorer {label}: {where} must be keyword-only (put it after `*`)")
            if param.default is param.empty:
                raise PluginError(f"explorer {label}: {where} has no default (every parameter needs one, "
                                  "so the plugin runs without any)")
            if param.annotation is param.empty or pname not in hints:
                raise PluginError(f"explorer {label}: {where} has no type annotation (the CLI and Lua "
                                  "convert values by it)")
            hint = hints[pname]
            if not _parseable(hint):
                raise PluginError(f"explorer {label}: {where} is annotated {hint!r}, which the CLI cannot "
                                  "parse: use bool, int, float, str, a Literal, a sequence of these, or X | None")
            if not _fits(param.default, hint):
                raise PluginError(f"explorer {label}: {where} defaults to {param.default!r}, which is not "
                                  f"a {hint!r}")
            found.setdefault(pname, param.default)
        if not forwards:
            break
    _check_bounds(cls, label, found)
    return found


def _check_bounds(cls: type[Explorer], label: str, params: dict[str, object]) -> None:
    """Each declared range (`parameter_bounds`) names a parameter, is ordered and holds its default."""
    from robotexp.registry import parameter_bounds

    for pname, (lo, hi) in parameter_bounds(cls).items():
        if pname not in params:
            raise PluginError(f"explorer {label}: parameter_bounds names {pname!r}, which is not a parameter")
        if lo is not None and hi is not None and not lo <= hi:
            raise PluginError(f"explorer {label}: parameter_bounds[{pname!r}] = {(lo, hi)!r} is empty")
        default = params[pname]
        if isinstance(default, (int, float)) and not isinstance(default, bool) and not (
                (lo is None or default >= lo) and (hi is None or default <= hi)):
            raise PluginError(f"explorer {label}: parameter {pname!r} defaults to {default!r}, outside its "
                              f"declared range {(lo, hi)!r}")


def _parseable(hint: Any) -> bool:
    """True for the annotations the CLI's JSON values and Lua's values can fill."""
    origin = typing.get_origin(hint)
    if hint in _SCALARS:
        return True
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        return bool(args) and all(_parseable(a) for a in args)
    if origin is typing.Literal:
        return all(isinstance(a, _SCALARS) for a in typing.get_args(hint))
    if origin in (list, tuple, Sequence):
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        return bool(args) and all(_parseable(a) for a in args)
    return False


def _fits(value: object, hint: Any) -> bool:
    """True when `value` is a legal value of the (parseable) annotation `hint`."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, a) for a in typing.get_args(hint))
    if hint is type(None):
        return value is None
    if origin is typing.Literal:
        return value in typing.get_args(hint)
    if origin in (list, tuple, Sequence):
        if not isinstance(value, list | tuple):
            return False
        args = [a for a in typing.get_args(hint) if a is not Ellipsis]
        if origin is tuple and Ellipsis not in typing.get_args(hint):
            return len(value) == len(args) and all(_fits(v, a) for v, a in zip(value, args, strict=True))
        return all(_fits(v, args[0]) for v in value)
    if hint is float:
        return isinstance(value, float | int) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, hint)


def _build(cls: type[Explorer], label: str) -> Explorer:
    try:
        return cls()
    except RobotexpError as exc:
        raise PluginError(f"explorer {label}: does not build with its defaults: {exc}") from exc
    except Exception as exc:
        raise PluginError(f"explorer {label}: __init__ with the defaults raised {type(exc).__name__}: {exc}") from exc


def _trial(cls: type[Explorer], explorer: Explorer, label: str, watch: _ClockWatch, robot_time: float, seed: int,
           robot_name: str, expect: list[Twist | Done] | None) -> tuple[int, float, str | None, list[Twist | Done]]:
    """Run `explorer` on `make_room` for `robot_time` (or the steps of `expect`, which it must repeat)."""
    from robotexp.mapping.geometry import GridGeometry
    from robotexp.mapping.grid import OccupancyGrid
    from robotexp.sim import SimRobot

    world = make_room()
    start = world.poses["start"]
    assert world.bounds is not None
    geo = GridGeometry.covering(*world.bounds, cell=cls.preferred_cell or 0.1, margin=0.5)
    decisions: list[Twist | Done] = []
    done: str | None = None
    with SimRobot(world, robot=robot_name, pose=start, seed=seed, sonar=cls.uses_sonar) as sim:
        clock = sim.make_clock(PERIOD)
        state = sim.read()
        grid = OccupancyGrid(geo, model=cls.grid_model, range_max=state.laser.range_max if state.laser else None)
        ctx = ExplorerContext(radius=sim.radius, limits=sim.limits, period=PERIOD, start=state.pose,
                              laser_range=state.laser.range_max if state.laser else 0.0,
                              rng=np.random.default_rng(seed), sonar=state.sonar is not None,
                              goals=dict(world.goals), start_name="start", footprint=sim.footprint)
        with watch:
            _call(label, "reset", explorer.reset, ctx)
        t0 = state.time
        limit = len(expect) if expect is not None else int(math.ceil(robot_time / PERIOD))
        for k in range(limit):
            if state.laser is not None:
                grid.update(state.pose, state.laser)
            with watch:
                decision = _call(label, "step", explorer.step, state, grid)
            when = f"step {k + 1} (robot time {state.time - t0:.1f} s)"
            _check_decision(decision, label, when)
            decisions.append(decision)
            if expect is not None:          # drawn between steps, as the live view and recordings do
                with watch:
                    _check_markers(_call(label, "markers", explorer.markers), label, f" after {when}")
            if expect is not None and decision != expect[k]:
                raise PluginError(f"explorer {label}: with the same seed, {when} returned {decision!r} the first "
                                  f"time and {expect[k]!r} now; randomness must come from ExplorerContext.rng "
                                  "and state only from reset()")
            if isinstance(decision, Done):
                done = decision.reason
                break
            sim.command(decision)
            clock.tick()
            state = sim.read()
    return len(decisions), state.time - t0, done, decisions


def _call(label: str, what: str, fn: Callable[..., Any], *args: Any) -> Any:
    try:
        return fn(*args)
    except RobotexpError as exc:
        raise PluginError(f"explorer {label}: {what}() raised {type(exc).__name__} on the check's room: {exc}") from exc
    except Exception as exc:
        raise PluginError(f"explorer {label}: {what}() raised {type(exc).__name__}: {exc}") from exc


def _check_decision(decision: object, label: str, when: str) -> None:
    if isinstance(decision, Twist):
        if not all(isinstance(v, float | int) and not isinstance(v, bool) and math.isfinite(v)
                   for v in (decision.v, decision.w)):
            raise PluginError(f"explorer {label}: step returned {decision!r} at {when}; a Twist holds finite "
                              "floats v [m/s] and w [rad/s]")
        return
    if isinstance(decision, Done):
        if not isinstance(decision.reason, str):
            raise PluginError(f"explorer {label}: step returned Done with reason {decision.reason!r} at {when}; "
                              "the reason is a string")
        return
    raise PluginError(f"explorer {label}: step returned {decision!r} ({type(decision).__name__}) at {when}; "
                      "it must return a robotexp.robot.Twist or a robotexp.explorer.Done")


def _check_outputs(explorer: Explorer, label: str) -> None:
    fields = _call(label, "result_fields", explorer.result_fields)
    if not isinstance(fields, dict) or not all(isinstance(k, str) for k in fields):
        raise PluginError(f"explorer {label}: result_fields() must return a dict with string keys, got {fields!r}")
    try:
        json.dumps(fields, allow_nan=True)
    except (TypeError, ValueError) as exc:
        raise PluginError(f"explorer {label}: result_fields() holds a value JSON cannot store ({exc}); "
                          "use numbers, strings, booleans, lists and dicts") from exc
    overlays = _call(label, "overlays", explorer.overlays)
    if not isinstance(overlays, dict) or not all(isinstance(k, str) and isinstance(v, np.ndarray)
                                                 for k, v in overlays.items()):
        raise PluginError(f"explorer {label}: overlays() must return a dict of name -> numpy array, "
                          f"got {type(overlays).__name__}")
    _check_markers(_call(label, "markers", explorer.markers), label, "")


def _check_markers(value: object, label: str, when: str) -> None:
    problem = markers_problem(value)
    if problem is not None:
        raise PluginError(f"explorer {label}: {problem}{when} (see robotexp.markers)")


class _ClockWatch:
    """A profile hook, on while the plugin runs, that records clock reads from the plugin's modules.

    Re-entrant across `with` blocks: the reads accumulate until `raise_if_read`.
    """

    def __init__(self, cls: type) -> None:
        self.modules: set[str] = set()
        self.packages: tuple[str, ...] = ()
        packages = []
        for klass in cls.__mro__:
            module = getattr(klass, "__module__", "")
            if klass is Explorer or module in ("builtins", "abc") or module.startswith("robotexp."):
                continue
            self.modules.add(module)
            if "." in module:
                packages.append(module.rpartition(".")[0] + ".")
        self.packages = tuple(packages)
        self.reads: list[str] = []
        self._previous: Any = None

    def _ours(self, module: str) -> bool:
        return module in self.modules or module.startswith(self.packages)

    def _hook(self, frame: types.FrameType, event: str, arg: Any) -> None:
        if event != "c_call":
            return
        owner = getattr(arg, "__self__", None)
        fname = getattr(arg, "__name__", "")
        if owner is time and fname in _TIME_FUNCTIONS:
            what = f"time.{fname}()"
        elif isinstance(owner, type) and issubclass(owner, datetime.date) and fname in _DATE_FUNCTIONS:
            what = f"{owner.__module__}.{owner.__qualname__}.{fname}()"
        else:
            return
        module = frame.f_globals.get("__name__", "")
        if self._ours(module) and len(self.reads) < 5:
            code = frame.f_code
            self.reads.append(f"{what} at {code.co_filename}:{frame.f_lineno} in {code.co_name}")

    def __enter__(self) -> _ClockWatch:
        self._previous = sys.getprofile()
        sys.setprofile(self._hook)
        return self

    def __exit__(self, *exc: object) -> None:
        sys.setprofile(self._previous)

    def raise_if_read(self, label: str) -> None:
        if self.reads:
            raise PluginError(f"explorer {label}: reads the clock or sleeps ({'; '.join(self.reads)}); an explorer "
                              "takes time from RobotState.time only and never sleeps")
