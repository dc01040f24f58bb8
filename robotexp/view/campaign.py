"""The live view of a campaign (`robotexp campaign run FILE --view`): how many runs are done, the time
so far, and a row per finished run (world, method, pose, coverage, path, robot time, why it ended).

The runs go on in worker processes; the campaign's `progress(done, total, record)` callback, in the
parent, feeds the hub. The page has no buttons for a campaign: Ctrl-C stops it (runs written stay)."""

from __future__ import annotations

import time
from collections.abc import Callable

from robotexp.run.record import RunRecord
from robotexp.view.feed import Frame, ViewHub

__all__ = ["CampaignFeed"]


class CampaignFeed:
    """Publishes a campaign's progress to `hub`.

    Args:
        hub: where the frames go.
        name: the campaign's name.
        total: runs to make.
        jobs: parallel runs.
        clock: wall clock [s].
    """

    def __init__(self, hub: ViewHub, name: str, total: int, jobs: int,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.hub, self.clock, self.t0 = hub, clock, clock()
        self.coverages: list[float] = []
        hub.controls = ()
        hub.start({"kind": "campaign", "title": f"campaign {name}", "run": name, "total": total, "jobs": jobs})
        hub.set_status(done=0, total=total, speed=None)

    def progress(self, done: int, total: int, record: RunRecord | None) -> None:
        """The campaign's progress callback: `done` of `total` runs, `record` the one just finished (None: skipped)."""
        rows = []
        if record is not None:
            if record.coverage is not None:
                self.coverages.append(record.coverage)
            rows.append({"run": record.run, "world": record.world, "method": record.method,
                         "pose": record.pose, "coverage": record.coverage,
                         "path_m": round(record.path_length_m, 2), "robot_time_s": round(record.robot_time_s, 1),
                         "completed": record.completed, "reason": record.reason})
        mean = sum(self.coverages) / len(self.coverages) if self.coverages else None
        self.hub.publish(Frame(time=self.clock() - self.t0, rows=rows, coverage=mean))
        self.hub.set_status(done=done, total=total)

    def finish(self, reason: str) -> None:
        """The campaign is over (or stopped)."""
        self.hub.finish(reason)
