"""Termination signals become an orderly exit, so that a driven motor is always sent zero force.

By default SIGTERM (`kill PID`, a service stop), SIGHUP (a closed terminal), SIGQUIT
(Ctrl-\\), SIGUSR1/2, SIGALRM and the other signals whose default action ends the process
(`HANDLED`) end a Python process on the spot: no `finally` block runs, no exit hook, and a
haptic device keeps the last force it was sent. While a servo loop is open
(`ServoLoop.start` to `close`), the handlers this module installs turn each into
`SystemExit(128 + signal number)` (the exit status a shell reports for the signal), and
SIGINT into `KeyboardInterrupt` as Python does, so every `finally`, `with` block and exit
hook on the way out runs and sends zero force (a servo thread is stopped first:
`ServoLoop.close`). SIGPIPE and SIGXFSZ are ignored by Python itself (a write then raises);
they are taken over only where an application set them back to their default. The faults a
program raises on itself (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGTRAP, SIGSYS) are not:
a Python handler cannot run before the process dies of them.

A signal that arrives while a loop is sending its zero force (inside `deferred()`) is held
until that is done and raised then: a second Ctrl-C cannot cut the safe state short.
Only handlers still at Python's defaults are replaced (an application's own handlers are
left alone), only from the main thread (where Python runs signal handlers), and they are put
back when the last open loop closes. SIGKILL and power loss cannot be caught by any
process: only the device's own firmware watchdog can answer those.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

_ENDING = ("SIGTERM", "SIGHUP", "SIGINT", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGPIPE", "SIGVTALRM",
           "SIGPROF", "SIGIO", "SIGPWR", "SIGSTKFLT", "SIGXCPU", "SIGXFSZ")
HANDLED = tuple(getattr(signal, name) for name in _ENDING if hasattr(signal, name)) + (
    tuple(range(signal.SIGRTMIN, signal.SIGRTMAX + 1)) if hasattr(signal, "SIGRTMIN") else ())
"""The signals turned into exceptions: every one a process can catch whose default action
ends it, the real-time signals included (those a platform lacks are left out)."""

_installed: dict[int, object] = {}  # signal -> the handler it had before ours
_users = 0  # open loops relying on the handlers
_deferring = 0  # depth of deferred() blocks in progress
_pending: int | None = None  # a signal that arrived inside deferred()


def _default(sig: int) -> object:
    return signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL


def _raise(sig: int) -> None:
    if sig == signal.SIGINT:
        raise KeyboardInterrupt
    raise SystemExit(128 + sig)


def _handler(sig: int, frame) -> None:
    global _pending
    if _deferring:
        if _pending is None:
            _pending = sig
        return
    _raise(sig)


def install() -> bool:
    """Take over the termination signals still at their defaults (main thread only); counted,
    so every True answer is matched by one `uninstall()`. False when nothing was taken over
    (another thread, or the application handles them all itself)."""
    global _users
    if threading.current_thread() is not threading.main_thread():
        return False
    for sig in HANDLED:
        if sig not in _installed and signal.getsignal(sig) is _default(sig):
            try:
                _installed[sig] = signal.signal(sig, _handler)
            except (OSError, ValueError):  # a signal this platform reserves: left as it is
                pass
    if not _installed:
        return False
    _users += 1
    return True


def uninstall() -> None:
    """Give back the defaults once the last loop that installed the handlers is closed."""
    global _users
    _users = max(0, _users - 1)
    if _users or threading.current_thread() is not threading.main_thread():
        return
    for sig, before in list(_installed.items()):
        if signal.getsignal(sig) is _handler:
            signal.signal(sig, before)
        del _installed[sig]


@contextmanager
def deferred():
    """Hold termination signals while the block runs (re-entrant); raise the first held one
    when the outermost block ends."""
    global _deferring, _pending
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if not _deferring and _pending is not None:
            sig, _pending = _pending, None
            _raise(sig)
