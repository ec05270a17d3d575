"""The viewer: offscreen pictures, the seqlock and command slot, a stalled or frozen viewer, no display,
the viewer process isolated from the working directory and gone with its servo process.

GL tests render through EGL (Mesa llvmpipe needs no display and no GPU); they are skipped,
with the reason, only where no EGL context can be made.
"""

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time

import mujoco
import numpy as np
import pytest
from PIL import Image

from softproxy.run import build, open_device, run_scene
from softproxy.scene import load_scene
from softproxy.viewer import state
from softproxy.viewer.camera import OrbitCamera, framing
from softproxy.viewer.state import POINT, SOFT, Layout, StatePublisher, StateReader, frame_of

BOX_RGBA = (0.85, 0.45, 0.2)


@pytest.fixture(scope="module")
def egl():
    """Skip GL tests, saying why, if no EGL context can be created here."""
    try:
        from softproxy.viewer.offscreen import create_context

        ctx = create_context()
    except Exception as exc:  # EGLUnavailable, or moderngl missing
        pytest.skip(f"no offscreen OpenGL (EGL) context: {exc}")
    ctx.release()


def _grasp_at(seconds=1.2):
    """The grasp scene run in lockstep for `seconds`; the frame of its last tick (forces on)."""
    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=False)
    ticks = int(round(seconds * loop.rate_hz))
    captured = {}

    def keep_last(lp):
        if lp.ticks == ticks:
            captured["frame"] = frame_of(lp)

    loop.run(ticks, on_tick=keep_last)
    return scene, loop, captured["frame"]


def _pixel(img, cam, point):
    h, w = img.shape[:2]
    x, y, _ = cam.project(point, w, h)
    assert 2 <= x < w - 2 and 2 <= y < h - 2, f"{point} projects outside the picture at ({x:.0f}, {y:.0f})"
    patch = img[int(y) - 2:int(y) + 3, int(x) - 2:int(x) + 3].reshape(-1, 3).astype(float)
    return np.median(patch, axis=0) / 255.0


def _close_in_colour(rgb, target, min_bright=0.25):
    """Same hue and saturation (lighting scales brightness), not too dark."""
    rgb, target = np.asarray(rgb, float), np.asarray(target, float)
    if rgb.max() < min_bright:
        return False
    return float(np.abs(rgb / rgb.max() - target / target.max()).max()) < 0.2


# --- the picture -------------------------------------------------------------------------
@pytest.mark.slow
def test_offscreen_grasp_shows_the_box_and_both_fingers(egl, tmp_path):
    from softproxy.viewer.offscreen import OffscreenRenderer, save_png
    from softproxy.viewer.render import finger_color

    scene, loop, frame = _grasp_at(1.2)
    box = loop.world.data.body("box").xpos.copy()
    assert box[2] > 0.045, "the box is being lifted at 1.2 s"
    assert all(f.god.contact for f in loop.fingers), "both fingers touch the box"
    with OffscreenRenderer(loop.world.model, (800, 600), [f.name for f in scene.fingers]) as r:
        cam = r.camera(frame)
        img = r.render(frame, cam)
    save_png(img, tmp_path / "grasp.png")
    assert img.shape == (600, 800, 3)
    assert img.std() > 20, "the picture is not blank"
    assert _close_in_colour(_pixel(img, cam, box), BOX_RGBA), _pixel(img, cam, box)
    for i, f in enumerate(loop.fingers):
        centre = (f.god.x, f.god.y, f.god.z)
        got = _pixel(img, cam, centre)
        assert _close_in_colour(got, finger_color(i)), (f.params.name, got, finger_color(i))
    # the force arrows are drawn (red) beside the fingers: some strongly red pixels exist
    red = (img[..., 0] > 150) & (img[..., 1] < 60) & (img[..., 2] < 60)
    assert red.sum() > 30


def test_every_geom_type_is_drawn(egl):
    """plane, sphere, capsule, ellipsoid, cylinder, box and mesh, from sizes, rgba and mesh data."""
    from softproxy.viewer.offscreen import OffscreenRenderer

    xml = textwrap.dedent("""
        <mujoco><asset>
          <mesh name="tet" vertex="0 0 0  0.04 0 0  0 0.04 0  0 0 0.04"/>
        </asset><worldbody>
          <geom type="plane" size="0.5 0.5 0.01" rgba="0.9 0.9 0.9 1"/>
          <geom name="sphere" type="sphere" pos="-0.2 0.1 0.03" size="0.03" rgba="1 0 0 1"/>
          <geom name="capsule" type="capsule" pos="-0.1 0.1 0.03" size="0.02 0.02" rgba="0 1 0 1"/>
          <geom name="ellipsoid" type="ellipsoid" pos="0 0.1 0.03" size="0.03 0.02 0.02" rgba="0 0 1 1"/>
          <geom name="cylinder" type="cylinder" pos="0.1 0.1 0.03" size="0.03 0.02" rgba="1 1 0 1"/>
          <geom name="box" type="box" pos="0.2 0.1 0.03" size="0.03 0.02 0.02" rgba="0 1 1 1"/>
          <body pos="0 -0.1 0.0"><geom name="mesh" type="mesh" mesh="tet" rgba="1 0 1 1"/></body>
        </worldbody></mujoco>""")
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    layout = Layout(model.ngeom, 0)
    frame_data = layout.empty()
    frame_data[layout.xpos:layout.xmat] = data.geom_xpos.ravel()
    frame_data[layout.xmat:layout.fingers] = data.geom_xmat.ravel()
    frame = state.Frame(layout, frame_data)
    cam = OrbitCamera((0.0, 0.0, 0.0), 0.9, 90.0, -89.0)  # from above
    with OffscreenRenderer(model, (800, 600)) as r:
        img = r.render(frame, cam, overlay=False)
    for g in range(1, model.ngeom):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        got = _pixel(img, cam, data.geom_xpos[g])  # seen from above: the geom's own colour
        assert _close_in_colour(got, model.geom_rgba[g][:3], min_bright=0.2), (name, got)


# --- shared memory -----------------------------------------------------------------------
def test_seqlock_publisher_reader_round_trip():
    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=False)
    pub = StatePublisher.for_loop(loop)
    reader = StateReader(pub.name)
    try:
        assert reader.read() is None, "nothing published yet"
        loop.run(700, on_tick=pub)
        pub.publish(loop)
        frame = reader.read()
        assert frame is not None and frame.ticks == loop.ticks and frame.t == pytest.approx(loop.t)
        np.testing.assert_array_equal(frame.geom_xpos, loop.world.data.geom_xpos)
        np.testing.assert_array_equal(frame.geom_xmat.reshape(-1, 9), loop.world.data.geom_xmat)
        for f, rec in zip(loop.fingers, frame.fingers):
            assert tuple(rec[state.F_PROXY:state.F_PROXY + 3]) == (f.god.x, f.god.y, f.god.z)
            assert tuple(rec[state.F_DEVICE:state.F_DEVICE + 3]) == (f.xd, f.yd, f.zd)
            assert rec[state.F_RADIUS] == f.params.radius and rec[state.F_MODE] == SOFT
            assert rec[state.F_ENERGY] == f.energy  # the passivity observer, shown beside the slips
        assert pub.publishes >= 700 // pub.every
        # a writer caught mid-write (odd counter): the reader gives up rather than return a torn frame
        pub.header[state.SEQ] += 1
        assert reader.read(tries=5) is None
        pub.header[state.SEQ] += 1
        assert reader.read() is not None
        # the command slot: the viewer asks, the publisher switches between ticks
        reader.request_mode(1, POINT)
        loop.run(2 * pub.every, on_tick=pub)
        assert loop.fingers[1].torsion is None and loop.fingers[0].torsion is not None
        assert reader.read().fingers[1][state.F_MODE] == POINT
        reader.request_mode(1, SOFT)
        loop.run(2 * pub.every, on_tick=pub)
        assert loop.fingers[1].torsion is not None and loop.fingers[1].model.name == "CH"
    finally:
        reader.close()
        pub.close()


def test_seqlock_never_returns_a_torn_frame(tmp_path):
    """A writer process rewrites a large block as fast as it can, each time with one value
    everywhere; every frame the reader accepts holds a single value."""
    stop = tmp_path / "stop"
    code = textwrap.dedent(f"""
        import os, time, numpy as np
        from softproxy.viewer.state import Layout, StatePublisher
        pub = StatePublisher(Layout(4000, 2))
        print(pub.name, flush=True)
        data = np.empty(pub.layout.size)
        k, end = 0, time.monotonic() + 60.0
        while time.monotonic() < end and not (k % 256 == 0 and os.path.exists({str(stop)!r})):
            k += 1
            data.fill(k)
            pub.write(data)
        pub.close()
    """)
    writer = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        name = writer.stdout.readline().strip()
        reader = StateReader(name)
        seen = set()
        deadline = time.monotonic() + 1.5
        # at least 1.5 s, and on (the writer runs until told to stop, at most a minute) until
        # the reader has seen it progress and overlap: a loaded machine may starve either
        while writer.poll() is None and (time.monotonic() < deadline or len(seen) <= 10 or reader.retries == 0):
            frame = reader.read()
            if frame is None:
                continue
            values = np.unique(frame.data)
            assert values.size == 1, f"torn frame: {values[:5]}"
            seen.add(float(values[0]))
        stop.touch()
        assert len(seen) > 10, "the reader saw the writer progress"
        assert reader.retries > 0, "reads did overlap writes (the test exercised the seqlock)"
        reader.close()
        assert writer.wait(20) == 0
    finally:
        stop.touch()
        if writer.poll() is None:
            writer.kill()
            writer.wait()


def test_switching_both_fingers_to_point_contact_live_lets_the_box_spin():
    """The viewer's `p`: through the command slot, mid-grasp, soft -> point; the box swings."""
    scene = load_scene("two_finger_grasp")
    holder = {}

    def on_built(loop):
        holder["pub"] = StatePublisher.for_loop(loop)
        holder["reader"] = StateReader(holder["pub"].name)

    def on_tick(loop):
        holder["pub"](loop)
        if loop.ticks == 1000:  # t = 1.0 s: squeezed, lifting
            holder["reader"].request_mode(0, POINT)
            holder["reader"].request_mode(1, POINT)

    try:
        result = run_scene(scene, open_device("sim", scene), on_built=on_built, on_tick=on_tick)
        assert holder["pub"].switches == 2
        assert abs(result["object_rotation_deg"]) > 20.0, result  # soft fingers hold it within 2 deg
    finally:
        holder["reader"].close()
        holder["pub"].close()


# --- a stalled viewer --------------------------------------------------------------------
@pytest.mark.slow
def test_a_stalled_viewer_never_delays_a_tick(egl, tmp_path):
    """A viewer that draws nothing at all while the servo runs (its process stopped: the
    extreme of a frozen window) holds back no tick: the paced 1 kHz run of 2000 ticks ends,
    having published every frame it was to publish, while the viewer took none of them. A
    servo that waited for its viewer (a lock, a full pipe) would never end the run. Continued,
    the viewer draws the final frame, and what it drew from the shared memory is the scene.
    (How many deadlines such a run misses is a matter of the machine's load: printed only.)"""
    import signal

    from softproxy.viewer.launch import ViewerSession
    from softproxy.viewer.render import finger_color

    ticks = 2000
    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=True)
    shot = tmp_path / "viewer.png"
    session = ViewerSession(loop, scene.path, offscreen=True, size=(640, 480), save_last=shot).start()
    pid = session.process.pid
    try:
        os.kill(pid, signal.SIGSTOP)
        frames, publishes = session.publisher.viewer_frames, session.publisher.publishes
        servo = loop.run_in_thread(ticks, realtime=True, on_tick=session)
        servo.join(600)  # (a servo waiting for its viewer: fail, not hang)
        assert not servo.is_alive(), "the servo waited for a stopped viewer"
        assert loop.error is None and loop.ticks == ticks
        assert session.publisher.publishes - publishes == len(range(1, ticks + 1, session.publisher.every))
        assert session.publisher.viewer_frames == frames, "the stopped viewer drew nothing"
        print(f"\n{ticks} paced ticks with the viewer stopped: {loop.stats.misses} deadline misses")
        os.kill(pid, signal.SIGCONT)
        session.finish(loop)
        assert session.process.wait(60) == 0, "the viewer drew the final frame and left"
        frame = frame_of(loop)
    finally:
        if session.process.running():
            _end(pid)
        session.close()
    img = np.asarray(Image.open(shot).convert("RGB"))
    cam = framing(loop.world.model, frame, aspect=640 / 480)
    assert _close_in_colour(_pixel(img, cam, loop.world.data.body("box").xpos), BOX_RGBA)
    f = loop.fingers[0]
    assert _close_in_colour(_pixel(img, cam, (f.god.x, f.god.y, f.god.z)), finger_color(0))


# --- the command line --------------------------------------------------------------------
def _cli(*args, env=None, timeout=120):
    return subprocess.run([sys.executable, "-m", "softproxy.cli", *args], capture_output=True, text=True,
                          env=env, timeout=timeout)


@pytest.mark.slow
def test_no_display_says_use_headless_without_a_traceback():
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = _cli("run", "two_finger_grasp", "--duration", "0.2", env=env)
    assert out.returncode != 0
    assert "--headless" in out.stderr and "Traceback" not in out.stderr, out.stderr
    # a DISPLAY that leads nowhere: the viewer process fails to open its window, the run says so
    env["DISPLAY"] = ":4187"
    out = _cli("run", "two_finger_grasp", "--duration", "0.2", env=env)
    assert out.returncode != 0
    assert "--headless" in out.stderr and "Traceback" not in out.stderr, out.stderr


@pytest.mark.slow
def test_snapshot_writes_a_picture_and_leaves_the_json_alone(egl, tmp_path):
    png = tmp_path / "end.png"
    plain = _cli("run", "two_finger_grasp", "--headless", "--json", "--duration", "1.2")
    shot = _cli("run", "two_finger_grasp", "--headless", "--json", "--duration", "1.2", "--snapshot", str(png))
    assert plain.returncode == 0 and shot.returncode == 0, shot.stderr
    a, b = json.loads(plain.stdout), json.loads(shot.stdout)
    a.pop("tick_us"), b.pop("tick_us")  # wall-clock timings differ run to run
    assert a == b
    img = np.asarray(Image.open(png).convert("RGB"))
    assert img.shape[0] >= 480 and img.shape[1] >= 640 and img.std() > 20


@pytest.mark.slow
def test_video(egl, tmp_path):
    pytest.importorskip("imageio_ffmpeg", reason="--video needs the imageio-ffmpeg wheel")
    import imageio_ffmpeg

    mp4 = tmp_path / "run.mp4"
    out = _cli("run", "two_finger_grasp", "--headless", "--duration", "0.5", "--video", str(mp4), "--size", "640x480")
    assert out.returncode == 0, out.stderr
    reader = imageio_ffmpeg.read_frames(str(mp4))
    meta = next(reader)
    assert tuple(meta["size"]) == (640, 480)
    assert sum(1 for _ in reader) >= 14  # 0.5 s at 30 fps


def test_softproxy_imports_without_gl():
    code = ("import sys, softproxy, softproxy.cli, softproxy.viewer, softproxy.viewer.state, "
            "softproxy.viewer.launch, softproxy.viewer.attach; "
            "bad = [m for m in ('glfw', 'moderngl') if m in sys.modules]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True)


# --- the window (only where an X server can be started) --------------------------------
_WINDOW_SCRIPT = """
import glfw, numpy as np
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.viewer.state import StatePublisher, StateReader
from softproxy.viewer.render import finger_color
from softproxy.viewer.window import ViewerWindow
from test_viewer import BOX_RGBA, _close_in_colour, _pixel

scene = load_scene("two_finger_grasp")
loop = build(scene, open_device("sim", scene), realtime=False)
pub = StatePublisher.for_loop(loop)
loop.run(1000, on_tick=pub)
reader = StateReader(pub.name)
win = ViewerWindow(loop.world.model, reader, [f.name for f in scene.fingers], (800, 600))
pub.publish(loop)
win.step()
w, h = glfw.get_framebuffer_size(win.win)
win.scene.render(win.frame, win.camera, w, h, framebuffer=win.ctx.screen)
img = np.frombuffer(win.ctx.screen.read(components=3), np.uint8).reshape(h, w, 3)[::-1]
assert _close_in_colour(_pixel(img, win.camera, loop.world.data.body("box").xpos), BOX_RGBA)
f = loop.fingers[1]
assert _close_in_colour(_pixel(img, win.camera, (f.god.x, f.god.y, f.god.z)), finger_color(1))
az = win.camera.azimuth
win._on_button(win.win, glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
x, y = win._cursor
win._on_cursor(win.win, x + 40, y)
win._on_button(win.win, glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
assert win.camera.azimuth != az
win._on_key(win.win, glfw.KEY_R, 0, glfw.PRESS, 0)
assert win.camera.azimuth == az
win._on_key(win.win, glfw.KEY_SPACE, 0, glfw.PRESS, 0)
assert win.paused
win._on_key(win.win, glfw.KEY_1, 0, glfw.PRESS, 0)
win._on_key(win.win, glfw.KEY_P, 0, glfw.PRESS, 0)
pub.poll_commands(loop)  # what the publisher does at its next publish
assert loop.fingers[0].torsion is None and loop.fingers[1].torsion is not None
win.close()
reader.close()
pub.close()
print("window ok")
"""


@pytest.fixture
def xvfb_display():
    """An X display (Xvfb) for the length of a test; skip if there is no Xvfb."""
    if shutil.which("Xvfb") is None:
        pytest.skip("no Xvfb to open a window in")
    read_fd, write_fd = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write_fd), "-screen", "0", "1024x768x24"],
                            pass_fds=(write_fd,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write_fd)
    try:
        with os.fdopen(read_fd) as pipe:
            display = ":" + pipe.readline().strip()
        yield display
    finally:
        xvfb.terminate()
        xvfb.wait()


@pytest.mark.slow
def test_window_draws_and_keys_work(xvfb_display):
    """In its own process (an X error ends a process; EGL and GLX do not mix in one)."""
    env = dict(os.environ, DISPLAY=xvfb_display, PYTHONPATH=os.path.dirname(__file__))
    out = subprocess.run([sys.executable, "-c", _WINDOW_SCRIPT], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and "window ok" in out.stdout, out.stderr


def test_tick_percentiles_follow_the_ring_buffer():
    from softproxy.servo import TickStats

    stats = TickStats(capacity=16)
    for k in range(1, 21):  # wraps: the ring holds 5..20 (written as the compiled tick writes it)
        stats.duration[stats.count % stats.capacity] = k * 1e-6
        stats.counters[0] += 1
    p50, p99 = state.tick_percentiles_us(stats, window=8)  # the last 8: 13..20
    assert p50 == pytest.approx(16.0) and p99 == pytest.approx(19.0)
    assert state.tick_percentiles_us(TickStats(4)) == (0.0, 0.0)


# --- the viewer process: isolated, never waited on without a bound, gone with its servo ----
TRAPS = ("argparse", "numpy", "softproxy", "mujoco", "moderngl", "glfw", "PIL", "select")


def _small_session(loop, scene, **kw):
    from softproxy.viewer.launch import ViewerSession

    said = []
    session = ViewerSession(loop, scene.path, offscreen=True, size=(160, 120), say=said.append, **kw)
    return session, said


def _alive(pid):
    """The process exists and is not a zombie (an orphan's zombie may wait long for its reaper)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


def _end(pid):
    """Test cleanup: a stopped or running process is killed."""
    import signal

    for sig in (signal.SIGCONT, signal.SIGKILL):
        try:
            os.kill(pid, sig)
        except (ProcessLookupError, PermissionError):
            return


_TRAPPED_SERVO = """
import sys
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.viewer.launch import ViewerSession
scene = load_scene("two_finger_grasp")
loop = build(scene, open_device("sim", scene), realtime=False)
session = ViewerSession(loop, scene.path, offscreen=True, size=(160, 120), save_last=sys.argv[1]).start(timeout=60)
loop.run(300, on_tick=session)
session.finish(loop)
code = session.process.wait(30)
frames = session.publisher.viewer_frames
session.close()
print(code, frames)
"""


@pytest.mark.slow
def test_the_viewer_runs_none_of_the_files_in_the_working_directory(egl, tmp_path):
    """A servo process started in a folder holding argparse.py, numpy.py, softproxy.py,
    select.py ... that each leave a mark when imported starts its viewer (and the resource
    tracker that unlinks its shared memory): neither imports any of them, and the viewer
    still draws the run."""
    work, marks = tmp_path / "work", tmp_path / "marks"
    work.mkdir()
    marks.mkdir()
    for name in TRAPS:
        (work / f"{name}.py").write_text(f"open({str(marks / name)!r}, 'w').close()\n")
    servo = tmp_path / "servo.py"  # outside `work`: the servo script's own folder is not the trap
    servo.write_text(_TRAPPED_SERVO)
    shot = tmp_path / "last.png"
    out = subprocess.run([sys.executable, str(servo), str(shot)], cwd=work, capture_output=True, text=True,
                         timeout=120)
    imported = sorted(os.listdir(marks))
    assert imported == [], f"imported from the working directory: {imported}"
    assert out.returncode == 0, out.stderr
    code, frames = (int(v) for v in out.stdout.split())
    assert code == 0 and frames >= 2, (code, frames, out.stderr)
    assert np.asarray(Image.open(shot)).std() > 10, "the last frame is a picture"


@pytest.mark.slow
@pytest.mark.parametrize("freeze", ["stall", "sigstop"])
def test_a_frozen_viewer_does_not_hold_the_cli(egl, freeze):
    """A viewer that stops turning its loop (sleeps for ever, or SIGSTOP) makes `wait_closed`
    give up once its heartbeat has been still for `stale_s`, and `close` stop it within its
    bounds (SIGTERM, then SIGKILL for a stopped process); each says so in one line."""
    import signal

    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=False)
    session, said = _small_session(loop, scene, stall_ms=1e7 if freeze == "stall" else 0.0)
    pid = session.process.pid
    try:
        session.start(timeout=60)
        if freeze == "sigstop":
            os.kill(pid, signal.SIGSTOP)
        loop.run(100, on_tick=session)
        session.finish(loop)
        t0 = time.monotonic()
        assert session.wait_closed(timeout=5.0, stale_s=0.5) is None  # (the timeout: fail, not hang)
        waited = time.monotonic() - t0
        assert 0.5 <= waited < 1.5, waited
        assert len(said) == 1 and "not responded" in said[0], said
        t0 = time.monotonic()
        session.close(timeout=0.3, stop_s=0.5)
        closed = time.monotonic() - t0
        assert closed < 0.3 + 2 * 0.5 + 0.5, closed
        assert not _alive(pid)
        assert session.process.proc.returncode == (-signal.SIGKILL if freeze == "sigstop" else -signal.SIGTERM)
        assert len(said) == 1, said  # stopping a viewer already reported is not reported again
    finally:
        _end(pid)
        session.close(timeout=0.1, stop_s=0.1)


@pytest.mark.slow
def test_closing_a_stopped_offscreen_viewer_is_bounded(egl):
    """`close` without `wait_closed`: a SIGSTOPped offscreen viewer gets `timeout` s for its
    last frame, is killed, and one line says it did not finish."""
    import signal

    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=False)
    session, said = _small_session(loop, scene)
    pid = session.process.pid
    try:
        session.start(timeout=60)
        os.kill(pid, signal.SIGSTOP)
        t0 = time.monotonic()
        session.close(timeout=0.3, stop_s=0.5)
        assert time.monotonic() - t0 < 0.3 + 2 * 0.5 + 0.5
        assert not _alive(pid) and session.process.proc.returncode == -signal.SIGKILL
        assert len(said) == 1 and "last frame" in said[0], said
    finally:
        _end(pid)


@pytest.mark.slow
def test_wait_closed_waits_for_a_viewer_that_keeps_responding(egl):
    """A live viewer (heartbeat moving, run not finished) is waited for past `stale_s`, up to
    the `timeout`, and nothing is said; a heartbeat counted per loop turn moves ~fps times a second."""
    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), realtime=False)
    session, said = _small_session(loop, scene)
    try:
        session.start(timeout=60)
        beat = session.publisher.viewer_beat
        t0 = time.monotonic()
        assert session.wait_closed(timeout=1.5, stale_s=0.6) is None
        waited = time.monotonic() - t0
        assert 1.5 <= waited < 2.5 and said == [], (waited, said)
        assert session.process.running()
        assert session.publisher.viewer_beat - beat >= 10
    finally:
        session.close(timeout=5)
    assert session.process.proc.returncode == 0, "the finished viewer left by itself"


_ORPHAN_PARENT = """
import sys, time
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.viewer.launch import ViewerSession
scene = load_scene("two_finger_grasp")
loop = build(scene, open_device("sim", scene), realtime=False)
window = sys.argv[1] == "window"
session = ViewerSession(loop, scene.path, offscreen=not window, size=(320, 240)).start(timeout=60)
loop.run(200, on_tick=session)
print(session.process.pid, flush=True)
time.sleep(120)
"""


def _viewer_outlives_no_servo(mode, env, tmp_path):
    import signal

    log = open(tmp_path / "parent.err", "w")
    parent = subprocess.Popen([sys.executable, "-c", _ORPHAN_PARENT, mode], stdout=subprocess.PIPE, stderr=log,
                              text=True, env=env)
    pid = None
    try:
        line = parent.stdout.readline().strip()
        assert line.isdigit(), (tmp_path / "parent.err").read_text()
        pid = int(line)
        time.sleep(0.3)
        assert _alive(pid), "the viewer runs while its servo process does"
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
        t0 = time.monotonic()
        while _alive(pid) and time.monotonic() - t0 < 5.0:
            time.sleep(0.05)
        gone_after = time.monotonic() - t0
        assert not _alive(pid), "the viewer drew on after its servo process was killed"
        return gone_after
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if pid is not None:
            _end(pid)
        log.close()


@pytest.mark.slow
def test_an_orphaned_offscreen_viewer_closes_itself(egl, tmp_path):
    """SIGKILL the servo process: its offscreen viewer notices (pidfd / parent pid) and exits."""
    gone_after = _viewer_outlives_no_servo("offscreen", None, tmp_path)
    assert gone_after < 3.0, gone_after


@pytest.mark.slow
def test_an_orphaned_viewer_window_closes_itself(xvfb_display, tmp_path):
    """SIGKILL the servo process: the viewer's window closes by itself."""
    gone_after = _viewer_outlives_no_servo("window", dict(os.environ, DISPLAY=xvfb_display), tmp_path)
    assert gone_after < 3.0, gone_after
