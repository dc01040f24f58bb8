"""Signal handlers held back while numba's Python code runs (robotexp.signals).

A compiled kernel that returns arrays calls numba's Python code (`_numba_unpickle`) while it builds its result;
a handler that raises there breaks the result (SystemError, or a crash when the caller unpacks it). The tests
make a handler fire exactly there: a profile hook calls it with the frame of `_numba_unpickle`, as Python
does when a signal lands at that frame's first bytecode.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from robotexp.mapping.kernels import label8
from robotexp.signals import (
    FIRST_RETRY,
    LAST_RETRY,
    children_start_deaf,
    held,
    in_numba,
    install_safe,
    safe_handler,
)

MASK = np.zeros((20, 20), np.bool_)
MASK[2:5, 2:5] = True
MASK[10:15, 10:12] = True


def _call_with_handler_inside_numba(handler):  # noqa: ANN001, ANN202
    """label8(MASK) with `handler(SIGINT, frame)` called at the start of numba's `_numba_unpickle`, once; gives
    the result and whether the handler was called there."""
    fired = []

    def hook(frame, event, arg):  # noqa: ANN001, ANN202, ARG001
        if event == "call" and frame.f_code.co_name == "_numba_unpickle" and not fired:
            fired.append(in_numba(frame))
            handler(signal.SIGINT, frame)

    sys.setprofile(hook)
    try:
        result = label8(MASK)
    finally:
        sys.setprofile(None)
    return result, fired


def test_a_ctrl_c_inside_a_kernels_call_comes_after_the_kernel_returned_whole() -> None:
    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, safe_handler(signal.default_int_handler))
    try:
        labels, count = None, None
        with pytest.raises(KeyboardInterrupt):
            (labels, count), fired = _call_with_handler_inside_numba(signal.getsignal(signal.SIGINT))
            assert fired == [True]          # the handler was asked inside numba's code, and held back
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:      # the signal, sent again, acts here
                time.sleep(0.001)
        assert count == 2 and labels is not None
        assert labels.dtype == np.int32 and set(np.unique(labels[MASK])) == {1, 2} and not labels[~MASK].any()
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_handler_that_raises_inside_numbas_code_breaks_the_kernels_result() -> None:
    """What the wrapper prevents, shown in a separate process (it may crash)."""
    code = textwrap.dedent(f"""
        import signal, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_signals import _call_with_handler_inside_numba
        try:
            _call_with_handler_inside_numba(signal.default_int_handler)
        except SystemError as exc:
            print("SystemError", exc.__cause__.__class__.__name__)
        except KeyboardInterrupt:
            print("KeyboardInterrupt")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode < 0 or out.stdout.split() == ["SystemError", "KeyboardInterrupt"], (out.stdout, out.stderr)


def test_a_signal_outside_numba_calls_the_handler_at_once() -> None:
    calls = []
    safe = safe_handler(lambda signum, frame: calls.append((signum, frame)))
    frame = sys._getframe()
    assert not in_numba(frame)
    safe(signal.SIGTERM, frame)
    safe(signal.SIGTERM, None)
    assert calls == [(signal.SIGTERM, frame), (signal.SIGTERM, None)]
    assert safe_handler(safe) is safe


def test_the_retry_delay_doubles_while_numba_runs_and_starts_again_after() -> None:
    import robotexp.signals as s

    sent = []
    calls = []
    real = s._send_later
    s._send_later = lambda signum, delay: sent.append((signum, delay))
    try:
        safe = safe_handler(lambda signum, frame: calls.append(signum))
        for _ in range(9):
            _call_with_handler_inside_numba(safe)
        safe(signal.SIGINT, None)
        _call_with_handler_inside_numba(safe)
    finally:
        s._send_later = real
        s._Retry.delay, s._Retry.since = FIRST_RETRY, None
    delays = [d for _, d in sent]
    assert delays[:7] == pytest.approx([0.001, 0.002, 0.004, 0.008, 0.016, 0.032, 0.05])
    assert delays[7:9] == [LAST_RETRY, LAST_RETRY] and delays[9] == FIRST_RETRY
    assert calls == [signal.SIGINT]


def test_a_second_signal_acts_at_once_when_the_first_has_waited_long_enough() -> None:
    """A first compilation can hold numba's code on the stack for tens of seconds: a second Ctrl-C then cuts it."""
    import robotexp.signals as s

    frames = []
    _call_with_handler_inside_numba(lambda signum, frame: frames.append(frame))
    (inside,) = frames
    calls = []
    real = s._send_later

    def held_copy(signum: int, delay: float) -> None:          # a copy sent again that has not arrived yet
        s._Retry.waiting += 1

    s._send_later = held_copy
    try:
        safe = safe_handler(lambda signum, frame: calls.append(signum))
        safe(signal.SIGINT, inside)                 # the first: held back, a copy on its way
        safe(signal.SIGINT, inside)                 # a second one at once: the first is on its way
        assert calls == [] and s._Retry.waiting == 1
        s._Retry.since -= s.CUT_AFTER               # the first has waited CUT_AFTER
        safe(signal.SIGINT, inside)
        assert calls == [signal.SIGINT] and s._Retry.since is None
    finally:
        s._send_later = real
        s._Retry.waiting, s._Retry.delay, s._Retry.since = 0, FIRST_RETRY, None


def test_install_safe_wraps_the_handler_in_place_and_leaves_default_actions() -> None:
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGUSR1)}
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        install_safe(signal.SIGINT)
        handler = signal.getsignal(signal.SIGINT)
        assert handler is not signal.default_int_handler and handler.__wrapped__ is signal.default_int_handler
        install_safe(signal.SIGINT)
        assert signal.getsignal(signal.SIGINT) is handler
        signal.signal(signal.SIGUSR1, signal.SIG_DFL)
        install_safe(signal.SIGUSR1)
        assert signal.getsignal(signal.SIGUSR1) is signal.SIG_DFL
    finally:
        for sig, h in previous.items():
            signal.signal(sig, h)


def test_the_command_line_holds_its_handlers_back_inside_numba() -> None:
    from robotexp.cli.common import watch_signals

    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        watch_signals()
        for sig in (signal.SIGINT, signal.SIGTERM):
            assert getattr(signal.getsignal(sig), "_robotexp_safe", False)
    finally:
        for sig, h in previous.items():
            signal.signal(sig, h)


def _streams() -> tuple[tuple[int, int], ...]:
    return tuple((os.fstat(fd).st_dev, os.fstat(fd).st_ino) for fd in (1, 2))


def test_held_keeps_a_signal_for_the_end_of_the_block_and_a_second_acts_at_once() -> None:
    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    reached = []
    try:
        with pytest.raises(KeyboardInterrupt):
            with held():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)
                reached.append("end of the block")
        assert reached == ["end of the block"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        with pytest.raises(KeyboardInterrupt):
            with held():
                os.kill(os.getpid(), signal.SIGINT)
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.05)
                reached.append("not reached")
        assert reached == ["end of the block"]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_ctrl_c_as_the_simulators_output_is_silenced_leaves_the_streams_back() -> None:
    """pybullet's output is silenced by pointing stdout and stderr at the null device around it; a Ctrl-C that
    lands just as that switch is made (in the context manager's entry, after the streams were pointed away)
    used to leave them there, and the command's "interrupted" line unseen."""
    from robotexp.sim.engine import _quiet_stdout

    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    before = _streams()
    fired = []

    def hook(frame, event, arg):  # noqa: ANN001, ANN202
        if event != "c_return" or arg is not next or frame.f_code.co_name != "__enter__" or fired:
            return
        if getattr(getattr(frame.f_locals.get("self"), "gen", None), "__name__", "") == "_quiet_stdout":
            fired.append(_streams() != before)          # the streams are pointed away here
            signal.getsignal(signal.SIGINT)(signal.SIGINT, frame)

    caught = []
    try:
        sys.setprofile(hook)
        try:
            with _quiet_stdout():
                sys.setprofile(None)
        except KeyboardInterrupt:
            # the command says "interrupted" here, while the exception (and its traceback) is alive
            caught.append(_streams() == before)
        finally:
            sys.setprofile(None)
        assert fired == [True]
        assert caught == [True]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_a_process_started_deaf_takes_a_ctrl_c_of_its_start_up_once_it_hears() -> None:
    # the child is sent Ctrl-C while it is still starting (blocked: pending), installs its handler, unblocks:
    # the handler runs then, once; the parent's own Ctrl-C in the block waits for the block's end
    child = textwrap.dedent("""
        import os, signal, sys, time
        from robotexp.signals import hear_signals
        print("blocked" if signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, []) else "open", flush=True)
        sys.stdin.readline()                    # the parent has sent SIGINT by now
        got = []
        signal.signal(signal.SIGINT, lambda s, f: got.append(s))
        print("pending" if signal.SIGINT in signal.sigpending() else "none", flush=True)
        hear_signals()
        print("heard", len(got), flush=True)
    """)
    got: list[int] = []
    before = signal.signal(signal.SIGINT, lambda s, f: got.append(s))
    try:
        with children_start_deaf():
            proc = subprocess.Popen([sys.executable, "-c", child], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    text=True)
            signal.pthread_kill(threading.main_thread().ident or 0, signal.SIGINT)
            assert got == []                        # held for the block's end
        assert got == [signal.SIGINT]
        assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, [])     # the mask as it was
        assert proc.stdout is not None and proc.stdin is not None
        assert proc.stdout.readline().strip() == "blocked"
        proc.send_signal(signal.SIGINT)
        proc.stdin.write("go\n")
        proc.stdin.flush()
        out, _ = proc.communicate(timeout=30)
    finally:
        signal.signal(signal.SIGINT, before)
    assert proc.returncode == 0 and out.split() == ["pending", "heard", "1"]


def test_first_stop_only_takes_the_first_of_two_signals() -> None:
    # process-wide: in a process of its own
    code = textwrap.dedent("""
        import os, signal
        from robotexp.signals import first_stop_only, safe_handler
        got = []
        signal.signal(signal.SIGINT, safe_handler(lambda s, f: got.append(s)))
        signal.signal(signal.SIGTERM, safe_handler(lambda s, f: got.append(s)))
        os.kill(os.getpid(), signal.SIGINT)
        first_stop_only()
        for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGTERM):
            os.kill(os.getpid(), sig)
        print(got)
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    # before: every signal taken; after: the first one only, whichever it is
    assert done.stdout.strip() == f"[{int(signal.SIGINT)}, {int(signal.SIGTERM)}]"
