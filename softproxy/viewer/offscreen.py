"""Offscreen rendering: a moderngl standalone context (EGL, no display) and a framebuffer.

The same `SceneRenderer` as the window draws into a multisampled framebuffer, resolved into
a plain one and read back as an RGB image: `softproxy run --snapshot FILE.png` and
`--video FILE.mp4`, the viewer process's `--offscreen` mode, and the tests.
"""

from __future__ import annotations

import os
import sys

import moderngl
import numpy as np

from softproxy.viewer.camera import OrbitCamera, framing
from softproxy.viewer.render import SceneRenderer, overlay_lines
from softproxy.viewer.state import Frame

MIN_SIZE = (640, 480)


class EGLUnavailable(RuntimeError):
    """No offscreen OpenGL 3.3 context could be made."""


def create_context() -> moderngl.Context:
    """A standalone OpenGL >= 3.3 context through EGL (needs no display)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    try:
        return moderngl.create_standalone_context(backend="egl", require=330)
    except Exception as exc:
        raise EGLUnavailable(f"no offscreen OpenGL context through EGL: {exc}".strip()) from None


class OffscreenRenderer:
    """Renders frames of `model` to RGB images of `size` (width, height) px."""

    def __init__(self, model, size: tuple[int, int] = (1024, 768), finger_names: list[str] | None = None,
                 samples: int = 4, ctx: moderngl.Context | None = None) -> None:
        self.width, self.height = int(size[0]), int(size[1])
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image size must be positive, got {size!r}")
        self.ctx = ctx or create_context()
        self.finger_names = list(finger_names or [])
        self.scene = SceneRenderer(self.ctx, model, self.finger_names)
        self.model = model
        samples = min(int(samples), int(self.ctx.max_samples))
        size = (self.width, self.height)
        self._msaa = None
        if samples > 1:
            self._msaa = self.ctx.framebuffer(
                color_attachments=[self.ctx.renderbuffer(size, 4, samples=samples)],
                depth_attachment=self.ctx.depth_renderbuffer(size, samples=samples))
        self.fbo = self.ctx.framebuffer(color_attachments=[self.ctx.renderbuffer(size, 4)],
                                        depth_attachment=self.ctx.depth_renderbuffer(size))

    def camera(self, frame: Frame, **kw) -> OrbitCamera:
        """The default camera for `frame`: the whole scene, from the front and above."""
        return framing(self.model, frame, aspect=self.width / self.height, **kw)

    def render(self, frame: Frame, camera: OrbitCamera | None = None, overlay: bool | list[str] = True) -> np.ndarray:
        """An (height, width, 3) uint8 image of `frame`, top row first."""
        camera = camera or self.camera(frame)
        if overlay is True:
            overlay = overlay_lines(frame, self.finger_names)
        target = self._msaa or self.fbo
        self.scene.render(frame, camera, self.width, self.height, framebuffer=target, overlay=overlay or None,
                          text_scale=min(1.0, self.width / 1000.0))
        if self._msaa is not None:
            self.ctx.copy_framebuffer(self.fbo, self._msaa)
        raw = self.fbo.read(components=3, alignment=1)
        img = np.frombuffer(raw, dtype=np.uint8).reshape(self.height, self.width, 3)
        return np.ascontiguousarray(img[::-1])

    def release(self) -> None:
        self.scene.release()
        for fbo in (self._msaa, self.fbo):
            if fbo is not None:
                for a in (*fbo.color_attachments, fbo.depth_attachment):
                    if a is not None:
                        a.release()
                fbo.release()
        self.ctx.release()

    def __enter__(self) -> "OffscreenRenderer":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def save_png(image: np.ndarray, path) -> None:
    from PIL import Image

    Image.fromarray(image, "RGB").save(str(path))


def video_support() -> str | None:
    """None if MP4 can be written (imageio-ffmpeg's bundled ffmpeg), else why not."""
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except Exception as exc:
        return (f"--video needs the imageio-ffmpeg wheel (it bundles ffmpeg): "
                f"python3 -m pip install imageio-ffmpeg ({type(exc).__name__}: {exc})")
    return None


def fixed_camera(renderer: OffscreenRenderer, frames: list[Frame]) -> OrbitCamera:
    """One camera that frames the first, middle and last of `frames` (a video does not jump)."""
    cams = [renderer.camera(f) for f in (frames[0], frames[len(frames) // 2], frames[-1])]
    far = max(cams, key=lambda c: c.distance)
    centre = np.mean([c.lookat for c in cams], axis=0)
    spread = max(float(np.linalg.norm(c.lookat - centre)) for c in cams)
    return OrbitCamera(centre, far.distance + 2.0 * spread, far.azimuth, far.elevation, far.fovy)


def write_video(path, frames: list[Frame], renderer: OffscreenRenderer, fps: float) -> int:
    """Render `frames` with one fixed camera and encode them to MP4 (H.264, yuv420p: even sizes)
    through imageio-ffmpeg's bundled ffmpeg. Returns the number of frames written."""
    import imageio_ffmpeg

    if not frames:
        return 0
    if renderer.width % 2 or renderer.height % 2:
        raise ValueError(f"video size must be even, got {renderer.width}x{renderer.height}")
    cam = fixed_camera(renderer, frames)
    writer = imageio_ffmpeg.write_frames(str(path), (renderer.width, renderer.height), fps=fps, codec="libx264",
                                         pix_fmt_out="yuv420p", macro_block_size=1, quality=7,
                                         ffmpeg_log_level="error")
    writer.send(None)
    from tqdm import tqdm  # a bar on a terminal, nothing in a file or a pipe

    try:
        for f in tqdm(frames, desc="softproxy: rendering the video", unit="frame", leave=False,
                      disable=not sys.stderr.isatty()):
            writer.send(renderer.render(f, cam).tobytes())
    finally:
        writer.close()
    return len(frames)
