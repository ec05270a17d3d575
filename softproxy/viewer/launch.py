"""Servo side of the viewer: the publisher plus the viewer process, started and stopped together.

    session = ViewerSession(loop, scene.path)   # shared memory + `python -m softproxy.viewer`
    session.start()                             # waits until the window is up (ViewerUnavailable if not)
    loop.run(ticks, realtime=True, on_tick=session)
    session.finish(); session.wait_closed(); session.close()

No GL is imported here: the servo process never loads glfw or moderngl for a window.
The viewer process runs at idle priority (SCHED_IDLE; nice 10 where there is none) and, on Mesa's software rasteriser,
with one rendering thread (LP_NUM_THREADS=1 unless set), so that it leaves the servo loop
its core.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

from softproxy.viewer.state import VIEWER_FAILED, VIEWER_RUNNING, StatePublisher


class ViewerUnavailable(RuntimeError):
    """The viewer window could not be opened; the message says why."""


def display_problem() -> str | None:
    """Why no window can open here (None if a display seems to be there)."""
    if sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            return "there is no display (neither DISPLAY nor WAYLAND_DISPLAY is set)"
    return None


class ViewerProcess:
    """`python -m softproxy.viewer SCENE --shm NAME ...` as a child process."""

    def __init__(self, scene_path, shm_name: str, offscreen: bool = False, stall_ms: float = 0.0,
                 size: tuple[int, int] | None = None, save_last=None, max_seconds: float | None = None) -> None:
        cmd = [sys.executable, "-m", "softproxy.viewer", str(scene_path), "--shm", shm_name]
        if offscreen:
            cmd.append("--offscreen")
        if stall_ms:
            cmd += ["--stall-ms", str(stall_ms)]
        if size:
            cmd += ["--size", f"{size[0]}x{size[1]}"]
        if save_last:
            cmd += ["--save-last", str(save_last)]
        if max_seconds is not None:
            cmd += ["--max-seconds", str(max_seconds)]
        env = dict(os.environ)
        env.setdefault("LP_NUM_THREADS", "1")
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, env=env)

    def running(self) -> bool:
        return self.proc.poll() is None

    def wait_ready(self, publisher: StatePublisher, timeout: float = 60.0) -> None:
        """Until the viewer says it is running; ViewerUnavailable if it failed or exited."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            status = publisher.viewer_status
            if status == VIEWER_RUNNING:
                return
            code = self.proc.poll()
            if status == VIEWER_FAILED or code is not None:
                self.wait(5.0)
                raise ViewerUnavailable(
                    f"the viewer could not open a window (exit code {self.proc.returncode})")
            time.sleep(0.02)
        self.terminate()
        raise ViewerUnavailable(f"the viewer did not open its window within {timeout:g} s")

    def wait(self, timeout: float | None = None) -> int | None:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return None

    def terminate(self, timeout: float = 5.0) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            if self.wait(timeout) is None:
                self.proc.kill()
                self.proc.wait()


class ViewerSession:
    """A publisher for `loop` and the viewer process reading it. Use it as `on_tick`."""

    def __init__(self, loop, scene_path, offscreen: bool = False, stall_ms: float = 0.0,
                 size: tuple[int, int] | None = None, display_hz: float = 60.0, save_last=None,
                 max_seconds: float | None = None) -> None:
        self.loop = loop
        self.offscreen = offscreen
        self.publisher = StatePublisher.for_loop(loop, display_hz)
        try:
            self.process = ViewerProcess(scene_path, self.publisher.name, offscreen, stall_ms, size, save_last,
                                         max_seconds)
        except Exception:
            self.publisher.close()
            raise

    def start(self, timeout: float = 60.0) -> "ViewerSession":
        """Publish the state before the first tick (the scene, no fingers yet) and wait until
        the viewer has drawn it: its window is up and its first, slowest frame is behind it."""
        try:
            self.publisher.publish(self.loop)
            self.process.wait_ready(self.publisher, timeout)
            deadline = time.monotonic() + timeout
            while self.publisher.viewer_frames < 1 and self.process.running() and time.monotonic() < deadline:
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

    def wait_closed(self, timeout: float | None = None) -> int | None:
        """Until the user closes the window (KeyboardInterrupt closes it)."""
        try:
            return self.process.wait(timeout)
        except KeyboardInterrupt:
            self.process.terminate()
            return self.process.proc.returncode

    def close(self, timeout: float = 5.0) -> None:
        """Tell the viewer the run is over and free the block. An offscreen viewer gets `timeout` s
        to draw its last frame and go; a window still open (the run was interrupted) is closed."""
        try:
            if self.process.running():
                self.publisher.finish()
                if not self.offscreen or self.process.wait(timeout) is None:
                    self.process.terminate()
        finally:
            self.publisher.close()
