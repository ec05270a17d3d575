"""Servo side of the viewer: the publisher plus the viewer process, started and stopped together.

    session = ViewerSession(loop, scene.path)   # shared memory + the viewer process
    session.start()                             # waits until the window is up (ViewerUnavailable if not)
    loop.run(ticks, realtime=True, on_tick=session)
    session.finish(); session.wait_closed(); session.close()

No GL is imported here: the servo process never loads glfw or moderngl for a window.
The viewer process runs at idle priority (SCHED_IDLE; nice 10 where there is none) and, on Mesa's software rasteriser,
with one rendering thread (LP_NUM_THREADS=1 unless set), so that it leaves the servo loop
its core.

The viewer never runs the user's files. `python -m` would put the working directory first
on `sys.path`, so an `argparse.py` or `numpy.py` in the folder where `softproxy run` was
typed would run in the viewer. It is started as `python -P -c BOOT PACKAGE_DIR ...`: `-P`
(Python >= 3.11) prepends nothing to `sys.path`, and BOOT loads `softproxy` from the
directory the servo process loaded it from (so both sides run the same code, installed or
from a source tree) before it imports the viewer. `-P` rather than `-I`: `-I` would also
drop PYTHONPATH and the user's site-packages, which may be where numpy, mujoco or moderngl
are installed; both are settings the user made, the working directory is not.

The servo side never waits on the viewer without a bound: ready (`start`), the offscreen
last frame and the exit (`close`) have timeouts; `wait_closed` waits for the user only
while the viewer's heartbeat moves. A viewer that stopped responding is stopped (SIGTERM,
then SIGKILL) if it is ours, else left behind, with one line on stderr; the CLI goes on.
The viewer closes itself once the servo process is gone (`--parent`, our pid).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

from softproxy.viewer.state import VIEWER_FAILED, VIEWER_RUNNING, StatePublisher

READY_S = 60.0   # the viewer's window is up and has drawn once within this (s)
STALE_S = 5.0    # a heartbeat that has not moved for this long: the viewer stopped responding (s)
LAST_FRAME_S = 5.0  # an offscreen viewer draws its last frame and exits within this after `finish` (s)
STOP_S = 2.0     # SIGTERM, then SIGKILL, each given this long to end the process (s)
POLL_S = 0.05    # how often the waits look (s)

# Run in the viewer process with `-P`: load softproxy from the package directory given as the
# first argument (nothing from the working directory), then run the viewer's main().
_BOOT = """\
import importlib.util, os, sys
package = sys.argv.pop(1)
spec = importlib.util.spec_from_file_location(
    "softproxy", os.path.join(package, "__init__.py"), submodule_search_locations=[package])
module = importlib.util.module_from_spec(spec)
sys.modules["softproxy"] = module
spec.loader.exec_module(module)
from softproxy.viewer.__main__ import main
sys.exit(main())
"""


class ViewerUnavailable(RuntimeError):
    """The viewer window could not be opened; the message says why."""


def display_problem() -> str | None:
    """Why no window can open here (None if a display seems to be there)."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            return "there is no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    return None


def viewer_command(args: list[str]) -> list[str]:
    """The command line starting the viewer with `args` (after `python -m softproxy.viewer`),
    isolated from the working directory and running this very softproxy package."""
    import softproxy

    package = str(Path(softproxy.__file__).resolve().parent)
    return [sys.executable, "-P", "-c", _BOOT, package, *args]


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


class ViewerProcess:
    """The viewer as a child process (see `viewer_command`); it watches this process."""

    def __init__(self, scene_path, shm_name: str, offscreen: bool = False, stall_ms: float = 0.0,
                 size: tuple[int, int] | None = None, save_last=None, max_seconds: float | None = None) -> None:
        args = [str(Path(scene_path).resolve()), "--shm", shm_name, "--parent", str(os.getpid())]
        if offscreen:
            args.append("--offscreen")
        if stall_ms:
            args += ["--stall-ms", str(stall_ms)]
        if size:
            args += ["--size", f"{size[0]}x{size[1]}"]
        if save_last:
            args += ["--save-last", str(Path(save_last).resolve())]
        if max_seconds is not None:
            args += ["--max-seconds", str(max_seconds)]
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "1")
        env["PYTHONSAFEPATH"] = "1"  # and every Python the viewer starts (GLFW's probe): nothing from the folder
        self.proc = subprocess.Popen(viewer_command(args), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     env=env)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def running(self) -> bool:
        return self.proc.poll() is None

    def wait_ready(self, publisher: StatePublisher, timeout: float = READY_S) -> None:
        """Until the viewer says it is running; ViewerUnavailable if it failed, exited or took
        longer than `timeout` s (then it is stopped)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            status = publisher.viewer_status
            if status == VIEWER_RUNNING:
                return
            code = self.proc.poll()
            if status == VIEWER_FAILED or code is not None:
                if self.wait(STOP_S) is None:
                    self.stop()
                raise ViewerUnavailable(
                    f"the viewer could not open a window (exit code {self.proc.returncode})")
            time.sleep(0.02)
        self.stop()
        raise ViewerUnavailable(f"the viewer did not open its window within {timeout:g} s")

    def wait(self, timeout: float) -> int | None:
        """Its exit code once it ended, None if it still runs after `timeout` s."""
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def stop(self, timeout: float = STOP_S) -> str:
        """End it: SIGTERM, then SIGKILL (a stopped process does not act on SIGTERM), each given
        `timeout` s. "ended" (by itself or on SIGTERM), "killed", or "left" (it did not end)."""
        if self.proc.poll() is not None:
            return "ended"
        self.proc.terminate()
        if self.wait(timeout) is not None:
            return "ended"
        self.proc.kill()
        return "killed" if self.wait(timeout) is not None else "left"


class ViewerSession:
    """A publisher for `loop` and the viewer process reading it. Use it as `on_tick`.

    Every wait here is bounded; what was not waited for is said in one line through `say`
    (stderr by default)."""

    def __init__(self, loop, scene_path, offscreen: bool = False, stall_ms: float = 0.0,
                 size: tuple[int, int] | None = None, display_hz: float = 60.0, save_last=None,
                 max_seconds: float | None = None, say=None) -> None:
        self.loop = loop
        self.offscreen = offscreen
        self.say = say or _say
        self.unresponsive = False  # said once that the viewer stopped responding
        self.publisher = StatePublisher.for_loop(loop, display_hz)
        try:
            self.process = ViewerProcess(scene_path, self.publisher.name, offscreen, stall_ms, size, save_last,
                                         max_seconds)
        except Exception:
            self.publisher.close()
            raise

    def start(self, timeout: float = READY_S) -> "ViewerSession":
        """Publish the state before the first tick (the scene, no fingers yet) and wait until
        the viewer has drawn it: its window is up and its first, slowest frame is behind it.
        A viewer up but not drawing within `timeout` s is not waited for (one line says so)."""
        try:
            self.publisher.publish(self.loop)
            self.process.wait_ready(self.publisher, timeout)
            deadline = time.monotonic() + timeout
            while self.publisher.viewer_frames < 1 and self.process.running():
                if time.monotonic() >= deadline:
                    self.say(f"softproxy: the viewer (pid {self.process.pid}) has drawn nothing in {timeout:g} s; "
                             f"the run goes on without it")
                    break
                time.sleep(0.01)
        except ViewerUnavailable:
            self.close()
            raise
        return self

    def __call__(self, loop) -> None:
        self.publisher(loop)

    def finish(self, loop=None) -> None:
        """The run is over: publish `loop`'s last state if given and tell the viewer."""
        self.publisher.finish(loop)

    def wait_closed(self, timeout: float | None = None, stale_s: float = STALE_S) -> int | None:
        """Until the user closes the window: its exit code. None if `timeout` s passed, or if
        the viewer stopped responding (heartbeat still for `stale_s` s; one line says so; `close`
        then stops it). Ctrl-C closes the window."""
        try:
            if self._wait(stale_s, timeout) == "exited":
                return self.process.proc.returncode
            return None
        except KeyboardInterrupt:
            self.process.stop()
            return self.process.proc.returncode

    def _wait(self, stale_s: float, timeout: float | None) -> str:
        """Until the viewer exits ("exited"), its heartbeat stalls `stale_s` s ("stale") or
        `timeout` s pass ("timeout")."""
        start = time.monotonic()
        beat, moved = self.publisher.viewer_beat, start
        while True:
            if self.process.wait(POLL_S) is not None:
                return "exited"
            now = time.monotonic()
            b = self.publisher.viewer_beat
            if b != beat:
                beat, moved = b, now
            elif now - moved > stale_s:
                self.unresponsive = True
                self.say(f"softproxy: the viewer (pid {self.process.pid}) has not responded for {now - moved:.1f} s; "
                         f"not waiting for it")
                return "stale"
            if timeout is not None and now - start >= timeout:
                return "timeout"

    def close(self, timeout: float = LAST_FRAME_S, stop_s: float = STOP_S) -> None:
        """Tell the viewer the run is over and free the block. An offscreen viewer gets `timeout` s
        to draw its last frame and go; a window still open (the run was interrupted, or it
        stopped responding) is closed. A viewer that does not end is stopped (SIGTERM, then
        SIGKILL, `stop_s` s each) and, if even that fails, left behind; one line says so."""
        try:
            if not self.process.running():
                return
            self.publisher.finish()
            late = self.offscreen and self.process.wait(timeout) is None
            how = self.process.stop(stop_s)
            who = f"softproxy: the viewer (pid {self.process.pid})"
            if how == "left":
                self.say(f"{who} does not end; left behind")
            elif late and not self.unresponsive:
                self.say(f"{who} did not finish its last frame within {timeout:g} s; stopped it")
            elif how == "killed" and not self.unresponsive:
                self.say(f"{who} did not close within {stop_s:g} s; killed it")
            self.unresponsive = self.unresponsive or late
        finally:
            self.publisher.close()
