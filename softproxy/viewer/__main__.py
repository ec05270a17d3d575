"""The viewer process: `python -m softproxy.viewer SCENE --shm NAME [--offscreen] ...`.

Opens the scene's model itself, attaches to the shared-memory block the servo side
publishes into, and shows it at display rate: in a glfw window, or (`--offscreen`) in an
EGL framebuffer (tests, machines without a display; `--save-last FILE.png` keeps the last
picture). It reports its state in the block's header (starting, running, failed, closed)
and bumps the block's heartbeat at every display-loop turn, so the servo side can tell the
user when no window could open and never waits on a viewer that stopped responding. It
closes itself within ~0.1 s once the servo process (`--parent PID`, else the block's
publisher) is gone. It never prints a traceback (set SOFTPROXY_DEBUG=1 to see one). Exit
codes: 0 done, 1 error, 2 bad arguments or block, 3 no display / no OpenGL.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import traceback


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"size must be positive, got {text!r}")
    return w, h


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m softproxy.viewer", description=__doc__.split("\n\n")[0])
    p.add_argument("scene", help="scene name or path to its .toml (the model is opened from it)")
    p.add_argument("--shm", required=True, help="name of the shared-memory block the servo side publishes into")
    p.add_argument("--offscreen", action="store_true", help="render into an EGL framebuffer instead of a window")
    p.add_argument("--size", type=_size, default=(1024, 768), help="WIDTHxHEIGHT (default 1024x768)")
    p.add_argument("--fps", type=float, default=60.0, help="display rate (default 60)")
    p.add_argument("--stall-ms", type=float, default=0.0, help="sleep this long after every frame (a frozen viewer)")
    p.add_argument("--save-last", default=None, help="offscreen: write the last frame to this PNG")
    p.add_argument("--max-seconds", type=float, default=None, help="offscreen: stop after this long")
    p.add_argument("--parent", type=int, default=None, metavar="PID",
                   help="the servo process: close once it is gone (default: the block's publisher)")
    return p


def _offscreen(model, reader, names, args, servo) -> int:
    from softproxy.viewer.offscreen import EGLUnavailable, OffscreenRenderer, save_png
    from softproxy.viewer.state import VIEWER_FAILED, VIEWER_RUNNING

    try:
        renderer = OffscreenRenderer(model, args.size, names)
    except EGLUnavailable as exc:
        reader.set_status(VIEWER_FAILED)
        print(f"softproxy viewer: {exc}", file=sys.stderr)
        return 3
    reader.set_status(VIEWER_RUNNING)
    period = 1.0 / args.fps
    begin = time.perf_counter()
    image = frame = None
    try:
        while True:
            start = time.perf_counter()
            reader.beat()
            finished = reader.closed  # read before the frame: the final frame is then drawn
            latest = reader.read()
            if latest is not None:
                frame = latest
            if frame is not None:
                image = renderer.render(frame)
                reader.count_frame()
            if finished or servo.gone():
                break
            if args.max_seconds is not None and start - begin > args.max_seconds:
                break
            if args.stall_ms > 0 and servo.sleep(args.stall_ms / 1000.0):
                break
            if servo.sleep(period - (time.perf_counter() - start)):
                break
        if args.save_last and image is not None:
            save_png(image, args.save_last)
    finally:
        renderer.release()
    return 0


def _yield_cpu() -> None:
    """The servo loop comes first: this process (and the threads it starts) runs at idle
    priority where Linux offers it, so it only gets CPU time no other task wants, else at
    nice 10. Measured on 2 cores with another process busy: an idle-priority viewer adds no
    deadline misses (it draws less); at nice 10 it cost 90-190 misses in 2000 ticks."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        return
    except (OSError, AttributeError):
        pass
    try:
        os.nice(10)
    except (OSError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    from softproxy.viewer.state import H_VIEWER_STATUS, VIEWER_CLOSED, VIEWER_FAILED, VIEWER_RUNNING, StateReader

    try:
        reader = StateReader(args.shm)
    except (FileNotFoundError, ValueError, OSError) as exc:
        print(f"softproxy viewer: cannot attach to shared memory {args.shm!r}: {exc}", file=sys.stderr)
        return 2
    _yield_cpu()
    from softproxy.viewer.servo_watch import ServoWatch

    servo = ServoWatch(args.parent if args.parent is not None else reader.servo_pid)
    code = 1
    try:
        from softproxy.scene import SceneError, load_scene

        try:
            scene = load_scene(args.scene)
            model = scene.load_model()
        except SceneError as exc:
            reader.set_status(VIEWER_FAILED)
            print(f"softproxy viewer: {exc}", file=sys.stderr)
            return 2
        if model.ngeom != reader.layout.ngeom:
            reader.set_status(VIEWER_FAILED)
            print(f"softproxy viewer: the scene has {model.ngeom} geoms, the servo side publishes "
                  f"{reader.layout.ngeom}: not the same model", file=sys.stderr)
            return 2
        names = [f.name for f in scene.fingers]
        if args.offscreen:
            code = _offscreen(model, reader, names, args, servo)
            return code
        from softproxy.viewer.window import NoDisplay, ViewerWindow

        try:
            window = ViewerWindow(model, reader, names, args.size, title=f"softproxy: {scene.name}")
        except NoDisplay as exc:
            reader.set_status(VIEWER_FAILED)
            print(f"softproxy viewer: {exc}", file=sys.stderr)
            return 3
        reader.set_status(VIEWER_RUNNING)
        try:
            window.run(args.fps, args.stall_ms / 1000.0, servo)
        finally:
            window.close()
        code = 0
        return code
    except KeyboardInterrupt:
        code = 0
        return code
    except Exception as exc:
        reader.set_status(VIEWER_FAILED)
        if os.environ.get("SOFTPROXY_DEBUG"):
            traceback.print_exc()
        print(f"softproxy viewer: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    finally:
        if reader.header is not None and int(reader.header[H_VIEWER_STATUS]) != VIEWER_FAILED:
            reader.set_status(VIEWER_CLOSED)
        reader.close()
        servo.close()


if __name__ == "__main__":
    sys.exit(main())
