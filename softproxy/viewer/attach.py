"""What `softproxy run` attaches to a run: the window, a snapshot, a video.

`RunViews` gives `run_scene` its `on_built` and `on_tick` hooks. None of them changes the
simulation: the window's publisher copies the state every ~1/60 s (and applies the soft /
point switches the window asks for, between ticks); the snapshot copies the state once, at
the last tick (before the loop's final stop zeroes the forces); the video copies it at its
frame rate. Drawing happens after the run (snapshot, video) or in the viewer process
(window), never in the servo loop.
"""

from __future__ import annotations

import sys
from pathlib import Path

from softproxy.viewer.launch import ViewerSession
from softproxy.viewer.state import Layout, frame_of

MIN_SIZE = (640, 480)


def parse_size(text: str) -> tuple[int, int]:
    """"WIDTHxHEIGHT" -> (width, height), at least 640x480; ValueError otherwise."""
    try:
        w, h = (int(v) for v in str(text).lower().split("x"))
    except ValueError:
        raise ValueError(f"--size must be WIDTHxHEIGHT (e.g. 1024x768), got {text!r}") from None
    if w < MIN_SIZE[0] or h < MIN_SIZE[1] or w > 8192 or h > 8192:
        raise ValueError(f"--size must be at least {MIN_SIZE[0]}x{MIN_SIZE[1]} and at most 8192x8192, got {text!r}")
    return w, h


class RunViews:
    """The window (`window=True`), a PNG snapshot of the last tick, an MP4 of the run."""

    def __init__(self, scene, window: bool = False, snapshot=None, video=None, size=(1024, 768),
                 fps: float = 30.0, duration_s: float | None = None) -> None:
        self.scene = scene
        self.window = bool(window)
        self.snapshot = Path(snapshot) if snapshot else None
        self.video = Path(video) if video else None
        self.size = tuple(size)
        self.fps = float(fps)
        self.duration_s = duration_s if duration_s is not None else scene.duration_s
        self.session: ViewerSession | None = None
        self.renderer = None
        self.loop = None
        self.last = None
        self.frames: list = []
        self.note: str | None = None  # printed once the window is up
        if self.video is not None:
            from softproxy.viewer.offscreen import video_support

            problem = video_support()
            if problem:
                raise ValueError(problem)
            if self.size[0] % 2 or self.size[1] % 2:
                raise ValueError(f"--video needs an even --size, got {self.size[0]}x{self.size[1]}")
        if self.snapshot is not None or self.video is not None:
            from softproxy.viewer.offscreen import EGLUnavailable, OffscreenRenderer

            try:  # fail before the run, not after it
                self.renderer = OffscreenRenderer(scene.load_model(), self.size, [f.name for f in scene.fingers])
            except EGLUnavailable as exc:
                raise RuntimeError(f"--snapshot/--video render offscreen and need EGL: {exc}") from None

    def on_built(self, loop) -> None:
        self.loop = loop
        self.layout = Layout(loop.world.model.ngeom, len(loop.fingers))
        self.last_tick = int(round(self.duration_s * loop.rate_hz))
        self.video_every = max(1.0, loop.rate_hz / self.fps)  # ticks per video frame
        self._next_video = 1.0
        if self.window:
            self.session = ViewerSession(loop, self.scene.path, size=self.size).start()
            if self.note:
                print(self.note, file=sys.stderr)

    def on_tick(self, loop) -> None:
        if self.session is not None:
            self.session(loop)
        if self.video is not None and loop.ticks >= self._next_video:
            self._next_video += self.video_every
            self.frames.append(frame_of(loop, self.layout))
        if self.snapshot is not None and loop.ticks == self.last_tick:
            self.last = frame_of(loop, self.layout)

    def save(self) -> None:
        """Write the snapshot and the video (after the run); say where on stderr."""
        if self.renderer is None or self.loop is None:
            return
        if self.snapshot is not None:
            from softproxy.viewer.offscreen import save_png

            frame = self.last if self.last is not None else frame_of(self.loop, self.layout)
            save_png(self.renderer.render(frame), self.snapshot)
            print(f"softproxy run: snapshot of t = {frame.t:.3f} s written to {self.snapshot} "
                  f"({self.size[0]}x{self.size[1]})", file=sys.stderr)
        if self.video is not None:
            from softproxy.viewer.offscreen import write_video

            n = write_video(self.video, self.frames, self.renderer, self.fps)
            print(f"softproxy run: video of {n} frames at {self.fps:g} fps written to {self.video}", file=sys.stderr)

    def wait_window(self) -> None:
        """The run is over: tell the window, and wait until the user closes it (or it stops
        responding: then one line says so and the run's command goes on)."""
        if self.session is None:
            return
        self.session.finish()
        if self.session.process.running():
            print("softproxy run: the run is over; close the viewer window (or press q) to exit", file=sys.stderr)
            self.session.wait_closed()

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None
        if self.renderer is not None:
            self.renderer.release()
            self.renderer = None
