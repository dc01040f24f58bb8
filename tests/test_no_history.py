"""The product speaks of itself only: no tracked file tells how it was developed (work sessions, issue
numbers, the people who worked on it). A word such as "session" in its technical sense (an aiohttp
ClientSession, an operating-system session, a robot's protocol session) is fine."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# phrasings of development history, matched case-insensitively
HISTORY = re.compile(
    r"\bsessions?[ -]\d"                      # "session 5", "sessions 5 and 6", "the session-5 code"
    r"|\bthis session\b"
    r"|\b(?:last|earlier) session\b"
    r"|\bissue #?\d"                          # "issue 12", "issue #12"
    r"|\bengineers?\b"
    r"|\bshared with \d+ other\b",            # "shared with 6 other engineers"
    re.IGNORECASE,
)
ALLOWED = {"tests/test_no_history.py"}       # this file names the patterns


def history_lines(text: str) -> list[tuple[int, str]]:
    """(line number, line) of each line of `text` that speaks of development history."""
    return [(n, line.strip()) for n, line in enumerate(text.splitlines(), 1) if HISTORY.search(line)]


@pytest.mark.parametrize("line", [
    "re-run in session 6 on the current code", "Session 5's localizer ended 2.5 cm off",
    "as in sessions 5 and 6", "the session-5 explorer", "found this session", "Last session's figures",
    "Issue 12's measurement", "(issue 14, item 5)", "see issue #3", "shared with 6 other engineers",
    "an engineer who has not seen it",
])
def test_history_phrasing_is_found(line: str) -> None:
    assert history_lines(line) == [(1, line)]


@pytest.mark.parametrize("line", [
    "async with aiohttp.ClientSession() as session, session.ws_connect(url)",
    "Chromium in a session of its own, as a user's browser would be",
    "# the session starts with the limits CONFIG",
    "the robot is still open from a previous session; close it and start again",
    "`Session.functions()` gives the tables", "38400 for the session -> 9600 again on close",
    "tissue 3 mm", "engineering units", "reissue 2 commands",
])
def test_technical_words_are_not_history(line: str) -> None:
    assert history_lines(line) == []


def test_no_tracked_file_speaks_of_development_history() -> None:
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: no list of tracked files")
    found = []
    for name in sorted(filter(None, listed.decode().split("\0"))):
        path = ROOT / name
        if name in ALLOWED or not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data[:8192]:          # binary (images, bags)
            continue
        for n, line in history_lines(data.decode("utf-8", errors="replace")):
            found.append(f"{name}:{n}: {line[:120]}")
    assert not found, "development history in tracked files:\n" + "\n".join(found)
