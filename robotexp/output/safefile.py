"""Results that survive faults: JSON-lines appends that repair a torn tail, tolerant readers, and
a lock on an output folder.

- `append_line` takes an exclusive lock on the file, repairs a torn last line first (a run killed
  or a disk filled while writing left bytes without their newline: they are moved to
  `<file>.torn` and the repair is reported through `note`), writes the line, flushes and fsyncs
  it; a write that fails (ENOSPC, EFBIG, ...) is undone (the file is cut back to its size before)
  before the error is raised, so the file never holds half a record.
- `read_records` returns every JSON object of the file and reports each line that is not one
  (torn or damaged) instead of refusing the file.
- `folder_lock` holds `OUT/.robotexp.lock` (fcntl.flock) while a campaign writes into OUT: a
  second campaign into the same folder is refused with one line instead of running every run twice.
"""

from __future__ import annotations

import errno
import fcntl
import json
import logging
import os
import re
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from robotexp.errors import ConfigError

__all__ = ["append_line", "read_records", "record_skipped", "folder_lock", "check_results_file", "LOCK_NAME",
           "MAX_NAME", "safe_name", "writable_folder"]

log = logging.getLogger(__name__)


def writable_folder(out: Path, option: str = "--out") -> None:
    """Check, before any run starts, that the output folder `out` can be made and written.

    Raises:
        ConfigError: it cannot (under a file, in /proc, no permission, a read-only file system), or
            (--out) its results.jsonl is a folder or another file that cannot take records.
    """
    import tempfile

    made = [d for d in (out, *out.parents) if not d.exists()]     # removed again: nothing is left behind
    try:
        for attempt in range(5):
            out.mkdir(parents=True, exist_ok=True)
            try:
                with tempfile.NamedTemporaryFile(dir=out, prefix=".robotexp-check-"):
                    pass
                break
            except FileNotFoundError:
                # another robotexp checking the same new folder removed it between our mkdir and the
                # probe (both saw it missing): make it again; a folder that keeps vanishing is an error
                if attempt == 4:
                    raise
    except OSError as exc:
        raise ConfigError(f"{option} {out}: cannot write there ({exc.strerror or exc}); give a folder you can "
                          "create and write") from None
    finally:
        for d in made:
            try:
                d.rmdir()
            except OSError:
                break
    if option == "--out":
        pass
        check_results_file(out / "results.jsonl")


MAX_NAME = 120      # [characters] longest run name (a file name holds 255 bytes, the run's suffixes included)


def safe_name(text: object) -> str:
    """`text` as a run name that is one plain file name: letters, digits, "_", "-" and single dots between
    them; every other character, and ".." (a way out of the folder), becomes "-"; no leading or trailing
    "-" or "." (no hidden file), at most MAX_NAME characters; "run" when nothing is left. What names a run's
    files (`run_id`, a recording's `run` in `robotexp.bag.replay`) goes through here."""
    name = re.sub(r"\.\.+", "-", re.sub(r"[^A-Za-z0-9_.-]+", "-", str(text))).strip("-.")
    return name[:MAX_NAME].rstrip("-.") or "run"

LOCK_NAME = ".robotexp.lock"
MAX_LINE = 16 * 2**20       # [bytes] a longer line of a results file is not a record: skipped unread
_BLOCK = 1 << 20            # [bytes] what a long line or a torn tail is read by


def warn(text: str) -> None:
    """The default `note`: one line on stderr, where the user sees it."""
    print(f"robotexp: warning: {text}", file=sys.stderr, flush=True)


def _repair_locked(fd: int, path: Path, note: Callable[[str], None]) -> bool:
    """Cut a torn last line off the open file `fd` (lock held); True when there was one."""
    size = os.fstat(fd).st_size
    if size == 0:
        return False
    os.lseek(fd, size - 1, os.SEEK_SET)
    if os.read(fd, 1) == b"\n":
        return False
    # find the start of the torn line: the byte after the last newline
    block, end = 65536, size
    start = 0
    while end > 0:
        begin = max(0, end - block)
        os.lseek(fd, begin, os.SEEK_SET)
        chunk = os.read(fd, end - begin)
        i = chunk.rfind(b"\n")
        if i >= 0:
            start = begin + i + 1
            break
        end = begin
    with open(f"{path}.torn", "ab") as keep:      # copied in blocks: a torn tail may be of any size
        at = start
        while at < size:
            block_data = os.pread(fd, min(_BLOCK, size - at), at)
            if not block_data:
                break
            keep.write(block_data)
            at += len(block_data)
        keep.write(b"\n")
    os.ftruncate(fd, start)
    line = 1 + _count_newlines(fd, start)
    note(f"{path}:{line}: a torn last line ({size - start} bytes, a run cut off while it was written) was moved "
         f"to {path}.torn before appending")
    return True


def _count_newlines(fd: int, upto: int) -> int:
    os.lseek(fd, 0, os.SEEK_SET)
    n, left = 0, upto
    while left > 0:
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            break
        n += chunk.count(b"\n")
        left -= len(chunk)
    return n


def _repair_tail(path: Path, note: Callable[[str], None] = warn) -> bool:
    """Repair a torn last line of `path` (see the module docstring); True when there was one."""
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        return _repair_locked(fd, path, note)
    finally:
        os.close(fd)


def check_results_file(path: Path) -> None:
    """Refuse, before any run starts, a results file that cannot take records (a folder, a device).

    Raises:
        ConfigError: `path` exists and is not a regular file (symbolic links followed).
    """
    if os.path.lexists(path) and not os.path.isfile(path):
        what = "a folder" if os.path.isdir(path) else "not a regular file"
        raise ConfigError(f"{path}: is {what}, not a results file; move it away or give another --out "
                          "(the runs' records go there)")


def append_line(path: Path, record: dict[str, Any], note: Callable[[str], None] = warn) -> None:
    """Append `record` as one JSON line to `path`, whole or not at all, and force it to disk.

    Raises:
        OSError: the write failed (the file is left as it was before the call).
    """
    data = (json.dumps(record, sort_keys=False) + "\n").encode("utf-8")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)     # workers of one campaign append to the same file
        _repair_locked(fd, path, note)
        size = os.fstat(fd).st_size
        try:
            os.lseek(fd, size, os.SEEK_SET)
            view = memoryview(data)
            while view:
                n = os.write(fd, view)
                if n <= 0:
                    raise OSError(errno.EIO, "write returned 0")
                view = view[n:]
            os.fsync(fd)
        except OSError:
            try:
                os.ftruncate(fd, size)      # never leave half a record behind
            except OSError:
                log.exception("%s: could not cut a failed append back", path)
            raise
    finally:
        os.close(fd)


def _skip_line(f: Any) -> int:
    """Read past the rest of a line in blocks; the number of bytes skipped (its newline included)."""
    n = 0
    while True:
        block = f.readline(_BLOCK)
        n += len(block)
        if not block or block.endswith(b"\n"):
            return n


def record_skipped(path: Path, number: int, problem: str) -> str:
    """What a reader of results files says of line `number` of `path`, a record it skips for `problem`."""
    return f"{path}:{number}: record skipped: {problem}; correct or delete the line"


def read_records(path: Path, note: Callable[[str], None] = warn,
                 check: Callable[[dict[str, Any]], str | None] | None = None) -> list[dict[str, Any]]:
    """Every JSON object (one per line) of `path`; each other non-empty line is reported and skipped, and
    so is an object for which `check` gives a problem (the words after "record skipped: ").

    Raises:
        OSError: the file cannot be read.
    """
    records: list[dict[str, Any]] = []
    with open(path, "rb") as f:
        number = 0
        while True:
            raw = f.readline(MAX_LINE + 1)
            if not raw:
                break
            number += 1
            if len(raw) > MAX_LINE and not raw.endswith(b"\n"):
                skipped = len(raw) + _skip_line(f)
                note(f"{path}:{number}: line of {skipped} bytes skipped (a record is at most {MAX_LINE} bytes)")
                continue
            line = raw.strip()
            if not line:
                continue
            try:
                value = json.loads(line.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                value = None
            if not isinstance(value, dict):
                what = "torn last line" if not raw.endswith(b"\n") else "line that is not a JSON record"
                note(f"{path}:{number}: {what} skipped ({len(raw)} bytes)")
                continue
            problem = check(value) if check is not None else None
            if problem is not None:
                note(record_skipped(path, number, problem))
                continue
            records.append(value)
    return records


@contextmanager
def folder_lock(out: Path, what: str) -> Iterator[None]:
    """Hold the output folder `out` for `what` (e.g. "campaign thesis") while the block runs.

    Raises:
        ConfigError: another process holds the folder (its pid and task are named).
    """
    out.mkdir(parents=True, exist_ok=True)
    path = out / LOCK_NAME
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EACCES):
                raise
            holder = os.pread(fd, 200, 0).decode("utf-8", "replace").strip() or "another process"
            raise ConfigError(f"{out}: in use by {holder}; wait for it to finish or give another --out "
                              "(two campaigns in one folder would run every run twice)") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{what} (pid {os.getpid()})\n".encode(), 0)
        yield
    finally:
        os.close(fd)       # closing releases the lock
