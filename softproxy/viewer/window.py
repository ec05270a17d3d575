"""The glfw window: the viewer process's display, mouse and keys.

Mouse: left drag orbits, right drag (or shift + left) pans, middle drag or the wheel zooms.
Keys: space pauses the display (the servo keeps running), r resets the camera to frame the
scene, p switches the selected finger(s) between soft and point contact (a request through
the shared memory's command slot, applied by the servo side's publisher), 1-9 select one
finger, 0 or a select all, q or Esc close the window.

The window closes by itself once the servo process is gone (a `ServoWatch`). It bumps the
block's heartbeat at every turn of its loop, drawn or not (paused, minimised), so the
servo side can wait for the user to close it without waiting on a frozen window.
"""

from __future__ import annotations

import time

import glfw
import moderngl

from softproxy.viewer.camera import OrbitCamera, framing
from softproxy.viewer.render import SceneRenderer, overlay_lines
from softproxy.viewer.servo_watch import ServoWatch
from softproxy.viewer.state import F_MODE, POINT, SOFT, StateReader

HELP = "drag orbit | right-drag pan | wheel zoom | space pause | r camera | p soft/point ({sel}) | 1-9,0 select | q quit"


class NoDisplay(RuntimeError):
    """No window can be opened here."""


class ViewerWindow:
    """One window showing what `reader` receives, for `model` (the scene's compiled MJCF)."""

    def __init__(self, model, reader: StateReader, finger_names: list[str], size=(1024, 768),
                 title: str = "softproxy") -> None:
        self.model = model
        self.reader = reader
        self.finger_names = finger_names
        glfw.ERROR_REPORTING = "ignore"
        try:
            ok = glfw.init()
        except Exception as exc:  # the library itself missing, or an X error
            raise NoDisplay(f"glfw could not start ({exc})") from None
        if not ok:
            raise NoDisplay("glfw could not connect to a display")
        self.win = None
        for samples in (4, 0):
            glfw.default_window_hints()
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.SAMPLES, samples)
            self.win = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
            if self.win:
                break
        if not self.win:
            glfw.terminate()
            raise NoDisplay("glfw could not open an OpenGL 3.3 window")
        glfw.make_context_current(self.win)
        glfw.swap_interval(1)
        try:
            self.ctx = moderngl.create_context(require=330)
        except Exception as exc:
            glfw.terminate()
            raise NoDisplay(f"no OpenGL 3.3 context in the window ({exc})") from None
        self.scene = SceneRenderer(self.ctx, model, finger_names)
        self.camera: OrbitCamera | None = None
        self._auto_frame = True
        self.frame = None
        self.paused = False
        self.selected = -1  # -1: every finger
        self.requested: dict[int, int] = {}
        self._drag = None
        self._cursor = (0.0, 0.0)
        glfw.set_key_callback(self.win, self._on_key)
        glfw.set_mouse_button_callback(self.win, self._on_button)
        glfw.set_cursor_pos_callback(self.win, self._on_cursor)
        glfw.set_scroll_callback(self.win, self._on_scroll)

    # -- input ---------------------------------------------------------------------------
    def _on_key(self, win, key, scancode, action, mods) -> None:
        if action != glfw.PRESS:
            return
        if key in (glfw.KEY_ESCAPE, glfw.KEY_Q):
            glfw.set_window_should_close(win, True)
        elif key == glfw.KEY_SPACE:
            self.paused = not self.paused
        elif key == glfw.KEY_R:
            self.reset_camera()
        elif key == glfw.KEY_P:
            self.toggle_contact()
        elif key in (glfw.KEY_0, glfw.KEY_A):
            self.selected = -1
        elif glfw.KEY_1 <= key <= glfw.KEY_9:
            i = key - glfw.KEY_1
            if i < self.reader.layout.nfinger:
                self.selected = i

    def _on_button(self, win, button, action, mods) -> None:
        if action == glfw.PRESS:
            if button == glfw.MOUSE_BUTTON_LEFT:
                self._drag = "pan" if mods & glfw.MOD_SHIFT else "orbit"
            elif button == glfw.MOUSE_BUTTON_RIGHT:
                self._drag = "pan"
            elif button == glfw.MOUSE_BUTTON_MIDDLE:
                self._drag = "zoom"
            self._cursor = glfw.get_cursor_pos(win)
        elif action == glfw.RELEASE:
            self._drag = None

    def _on_cursor(self, win, x, y) -> None:
        dx, dy = x - self._cursor[0], y - self._cursor[1]
        self._cursor = (x, y)
        if self.camera is None or self._drag is None:
            return
        self._auto_frame = False
        if self._drag == "orbit":
            self.camera.orbit(dx, dy)
        elif self._drag == "pan":
            self.camera.pan(dx, dy, glfw.get_window_size(win)[1])
        else:
            self.camera.zoom(-dy / 20.0)

    def _on_scroll(self, win, dx, dy) -> None:
        if self.camera is not None:
            self._auto_frame = False
            self.camera.zoom(dy)

    # -- actions -------------------------------------------------------------------------
    def reset_camera(self) -> None:
        if self.frame is None:
            return
        w, h = glfw.get_framebuffer_size(self.win)
        self.camera = framing(self.model, self.frame, aspect=w / max(h, 1))

    def toggle_contact(self) -> None:
        """Ask the servo side to switch the selected finger(s): soft <-> point."""
        if self.frame is None or self.reader.closed:
            return
        n = self.reader.layout.nfinger
        fingers = range(n) if self.selected < 0 else [self.selected]
        modes = {i: self.requested.get(i, int(self.frame.fingers[i][F_MODE])) for i in fingers}
        target = POINT if any(m == SOFT for m in modes.values()) else SOFT
        for i in fingers:
            self.reader.request_mode(i, target)
            self.requested[i] = target

    # -- loop ----------------------------------------------------------------------------
    def status(self) -> str:
        if self.frame is None:
            return "waiting for the servo loop ..."
        parts = []
        if self.paused:
            parts.append("PAUSED (display only)")
        if self.reader.closed:
            parts.append("run finished")
        return "  ".join(parts)

    def step(self) -> None:
        """One display frame: heartbeat, events, the latest state (unless paused), draw, swap.
        A minimised window is not drawn (some systems block its buffer swap until it shows)."""
        self.reader.beat()
        glfw.poll_events()
        if glfw.get_window_attrib(self.win, glfw.ICONIFIED):
            return
        if not self.paused:
            frame = self.reader.read()
            if frame is not None:
                self.frame = frame
                if self.camera is None or (self._auto_frame and frame.ticks > 0):
                    self._auto_frame = frame.ticks == 0  # frame again once the fingers are there
                    self.reset_camera()
        w, h = glfw.get_framebuffer_size(self.win)
        if self.frame is not None and w > 0 and h > 0:
            ww = glfw.get_window_size(self.win)[0] or w
            sel = "all" if self.selected < 0 else self.finger_label(self.selected)
            lines = overlay_lines(self.frame, self.finger_names, self.status(), HELP.format(sel=sel))
            self.scene.render(self.frame, self.camera, w, h, framebuffer=self.ctx.screen, overlay=lines,
                              text_scale=(w / ww) * min(1.0, ww / 1000.0))
        else:
            self.ctx.screen.use()
            self.ctx.clear(0.17, 0.19, 0.23, 1.0)
        glfw.swap_buffers(self.win)
        self.reader.count_frame()

    def run(self, fps: float = 60.0, stall_s: float = 0.0, servo: ServoWatch | None = None) -> None:
        """Until the window closes or the `servo` process is gone: `step()` at `fps` (swap waits
        for vsync where there is one); `stall_s` s of sleep after each frame (a frozen viewer)."""
        servo = servo or ServoWatch(None)
        period = 1.0 / fps
        while not glfw.window_should_close(self.win) and not servo.gone():
            start = time.perf_counter()
            self.step()
            if stall_s > 0.0 and servo.sleep(stall_s):
                break
            servo.sleep(period - (time.perf_counter() - start))

    def finger_label(self, i: int) -> str:
        return self.finger_names[i] if i < len(self.finger_names) else f"finger {i + 1}"

    def close(self) -> None:
        try:
            self.scene.release()
        finally:
            glfw.destroy_window(self.win)
            glfw.terminate()
