"""Calling the kernels from Python: `entry` (no per-call dispatch) and `announced` (compile progress).

numba resolves the types of every argument on every call. For a numpy record array that
costs ~3 µs (its dtype is walked field by field), more than a finger's whole tick, so the
servo loop resolves the types once, when it is built, and then calls the compiled entry
point straight (~0.1 µs). The caller promises to pass arguments of exactly those types (the
same arrays every tick): the entry point does not check them.

The first run after an install or an update compiles the kernels (about a minute of CPU on a
2-core machine); later runs load them from numba's
on-disk cache in about a second. `announced` says so while it happens, so a first run is
never silent for a minute; a load from the cache is never announced, however long a busy
machine takes over it (numba's "numba:compile" event marks a real compile, a cache hit
raises none).
"""

from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager

from numba.core import event

ANNOUNCE_AFTER_S = 1.5
"""A compile that takes longer than this is announced."""


class _Compiles(event.Listener):
    """Sets `seen` when numba starts a compile (not on a load from its cache)."""

    def __init__(self) -> None:
        self.seen = threading.Event()

    def on_start(self, ev) -> None:
        self.seen.set()

    def on_end(self, ev) -> None:
        pass


@contextmanager
def announced(what: str, stream=None, after_s: float = ANNOUNCE_AFTER_S):
    """While the block runs: if numba compiles in it and the block takes longer than
    `after_s`, say on `stream` (stderr) that `what` is compiling, with the seconds elapsed
    every few seconds, and how long it took. Loading from the cache is said nothing of."""
    stream = sys.stderr if stream is None else stream
    done = threading.Event()
    start = time.monotonic()
    said = []
    compiles = _Compiles()

    def watch() -> None:
        if done.wait(after_s):
            return
        while not compiles.seen.is_set():  # (a long load from the cache: nothing to say yet)
            if done.wait(0.1):
                return
        live = getattr(stream, "isatty", lambda: False)()
        print(f"softproxy: compiling {what} (first run after an install or an update; cached after)"
              + ("" if live else " ..."), file=stream, end="" if live else "\n", flush=True)
        said.append(live)
        while not done.wait(1.0 if live else 15.0):
            elapsed = time.monotonic() - start
            if live:
                print(f"\rsoftproxy: compiling {what} ... {elapsed:3.0f} s", file=stream, end="", flush=True)
            else:
                print(f"softproxy: still compiling {what} ({elapsed:.0f} s)", file=stream, flush=True)

    thread = threading.Thread(target=watch, name="softproxy-compile-progress", daemon=True)
    thread.start()
    try:
        with event.install_listener("numba:compile", compiles):
            yield
    finally:
        done.set()
        thread.join()
        if said:
            elapsed = time.monotonic() - start
            print(("\r" if said[0] else "") + f"softproxy: compiled {what} in {elapsed:.0f} s" + " " * (20 * said[0]),
                  file=stream, flush=True)


def entry(kernel, args: tuple, what: str | None = None):
    """The compiled `kernel` for the types of `args` (compiling it, announced as `what`, or
    loading it from the cache, if needed), as a plain callable; `kernel` itself where nothing
    is compiled (NUMBA_DISABLE_JIT=1)."""
    kernel = getattr(kernel, "python", kernel)  # a `Kernel`: its twin with numba's Python wrapper
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return kernel
    types = tuple(kernel.typeof_pyval(a) for a in args)
    if types not in overloads:
        with announced(what or f"{kernel.__module__}.{kernel.__name__}"):
            kernel.compile(types)
    return overloads[types].entry_point


class EntryPoints:
    """Calls kernels through their entry points, each resolved on its first call here: for an
    owner (a table of fingers, a set of shapes) whose arrays keep their types for life."""

    __slots__ = ("_entries",)

    def __init__(self) -> None:
        self._entries = {}

    def __call__(self, kernel, *args):
        call = self._entries.get(kernel)
        if call is None:
            call = self._entries[kernel] = entry(kernel, args)
        return call(*args)
