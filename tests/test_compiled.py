"""The compiled tick (`ServoLoop(compiled=True)`) gives the Python engine's answers: to the last bit on primitives, to rounding on meshes."""

import math

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from softproxy.cli import main
from softproxy.compiled import godobject, layout as L
from softproxy.compiled.shapes import shape_tables
from softproxy.geometry import shapes_of
from softproxy.proxy import GodObject
from softproxy.run import build, open_device
from softproxy.scene import load_scene


def _god_state(god):
    """Everything a GodObject carries from tick to tick, shapes by name."""
    return (god.x, god.y, god.z, god.contact, god.nx, god.ny, god.nz, god.shape and god.shape.name, god.depth,
            god.sticking, god.lx, god.ly, god.lz, god._bx, god._by, god._bz, god._room, god._rounding,
            [(*p[:4], p[4].name) for p in god.planes], [s.name for s in god.near])


def _finger_state(f):
    tors = f.torsion
    t = () if tors is None else (tors.in_contact, tors.alpha_0, tors.alpha_p, tors.alpha_g, tors.torque,
                                 tors.limit, tors.slipping, tors.slip_events)
    return (f.fx, f.fy, f.fz, f.torque, f.tx, f.ty, f.tz, f.px, f.py, f.pz, f.body, f.normal_force, f.valid,
            f.max_force_seen, f.penetration_max, f.slide_events, f.spikes_rejected, f._spike_run,
            f._was_sticking, f.placed, f._ramp, f.xd, f.yd, f.zd, f._sx, f._sy, f._sz, f._stwist, t,
            _god_state(f.god))


def _twins(scene_name, device_config=None):
    """The same scene built twice, driven by identical devices (the scene's [device] table
    with `device_config` merged in): one loop Python, one compiled; and the scene's ticks."""
    scene = load_scene(scene_name)
    scene.device.update(device_config or {})
    loops = [build(scene, open_device("sim", scene), realtime=False, audit=True, compiled=compiled)
             for compiled in (False, True)]
    return loops, int(round(scene.duration_s * loops[0].rate_hz))


def _assert_same_run(loops, ticks, full_every=1):
    a, b = loops
    for i in range(ticks):
        a.tick()
        b.tick()
        for fa, fb in zip(a.fingers, b.fingers):
            # what each engine sent the device and did to the world, every tick
            assert (fa.fx, fa.fy, fa.fz, fa.tx, fa.ty, fa.tz, fa.body, fa.valid) == \
                   (fb.fx, fb.fy, fb.fz, fb.tx, fb.ty, fb.tz, fb.body, fb.valid), f"tick {i}"
        assert a.device.last_force == b.device.last_force and a.device.last_torque == b.device.last_torque
        assert np.array_equal(a.world.data.qpos, b.world.data.qpos), f"tick {i}"
        assert np.array_equal(a.world.data.qvel, b.world.data.qvel), f"tick {i}"
        if i % full_every == 0:
            b.sync()
            for fa, fb in zip(a.fingers, b.fingers):
                assert _finger_state(fa) == _finger_state(fb), f"tick {i}"
    assert a.faults == b.faults


@pytest.mark.parametrize("scene_name", ["two_finger_grasp", "corner", "thin_plate", "friction_ramp", "knob",
                                        "shapes_tour"])
def test_every_primitive_scene_runs_the_same_compiled(scene_name):
    """Each shipped primitive scene, whole: forces, torques, bodies and MuJoCo's state equal
    every tick, and every attribute of every finger equal every 50th tick."""
    loops, n = _twins(scene_name)
    _assert_same_run(loops, n, full_every=50)


def test_noise_faults_and_spikes_run_the_same_compiled():
    """The grasp with a noisy device that drops samples, sends NaN, spikes and stalls (the
    read fails): the same forces, the same faults counted, the same state; never NaN to
    the device."""
    loops, _ = _twins("two_finger_grasp", dict(noise_m=2e-4, noise_rad=0.01, seed=3,
                                               faults={"nan": 0.02, "drop": 0.02, "spike": 0.02, "stall": 0.005}))
    _assert_same_run(loops, 3000, full_every=25)
    a, b = loops
    assert b.device.injected["nan"] > 0 and b.device.injected["spike"] > 0
    assert b.faults["invalid_sample"] > 0 and b.faults["device_error"] > 0
    assert b.device.nan_sends == 0


def test_the_watchdog_zero_force_tick_runs_the_same_compiled():
    """A tick after an overrun renders zero force in both engines, the proxy still moving."""
    loops, _ = _twins("two_finger_grasp")
    a, b = loops
    for _ in range(800):
        a.tick()
        b.tick()
    for lp in loops:
        lp._safe_next = True
    _assert_same_run(loops, 3)
    assert b.device.last_force[0] != (0.0, 0.0, 0.0)  # rendering again after the one safe tick


def test_sensing_channels_read_the_compiled_fingers():
    """A scene with contact sensing (seed 003) inside the tick: the channels see the same
    fingers, so they estimate the same contacts."""
    loops, _ = _twins("sensing_grasp")
    _assert_same_run(loops, 1500, full_every=100)
    ha = [ch.history for ch in loops[0].sensors]
    hb = [ch.history for ch in loops[1].sensors]
    assert ha == hb and any(ha)


GEOMS = (
    '<geom type="plane" size="1 1 .01"/>',
    '<geom type="box" size=".03 .02 .015" pos="{p}" quat="{q}"/>',
    '<geom type="sphere" size=".02" pos="{p}"/>',
    '<geom type="capsule" size=".012 .025" pos="{p}" quat="{q}"/>',
    '<geom type="cylinder" size=".02 .012" pos="{p}" quat="{q}"/>',
    '<geom type="ellipsoid" size=".03 .02 .012" pos="{p}" quat="{q}"/>',
)
coord = st.floats(-0.05, 0.05)
unit_quat = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: sum(v * v for v in q) > 0.1)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 5), st.tuples(coord, coord, st.floats(0.0, 0.04)), unit_quat),
                min_size=1, max_size=4),
       st.booleans(),
       st.lists(st.tuples(coord, coord, st.floats(-0.02, 0.08)), min_size=2, max_size=12),
       st.floats(0.0, 1.0), st.floats(0.0, 0.01))
def test_the_compiled_god_object_is_the_python_one(geoms, floor, path, mu, radius):
    """Random primitives (overlapping: creases, corners), random device paths in small steps
    and large jumps: every field of the compiled god-object equals the Python one's, tick
    by tick, whatever the solver does (warm starts, holds, slides, lifts, cold restarts)."""
    body = "".join(GEOMS[k].format(p=" ".join(map(str, p)), q=" ".join(map(str, q))) for k, p, q in geoms)
    if floor:
        body = GEOMS[0] + body
    m = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{body}</worldbody></mujoco>")
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    shapes = shapes_of(m, d)
    S, T, C = shape_tables(shapes)
    god = GodObject(shapes, radius, mu, 0.8 * mu, (0.0, 0.0, 0.12))
    g = np.zeros(L.F_COLUMNS)
    near = np.zeros(len(shapes), dtype=np.int64)
    # the compiled state starts from the Python one, as CompiledFingers.pack does it
    g[L.G_X], g[L.G_Y], g[L.G_Z] = god.x, god.y, god.z
    g[L.G_RADIUS], g[L.G_MU_S], g[L.G_MU_D], g[L.G_ROOM] = radius, mu, 0.8 * mu, math.inf
    g[L.G_NNEAR] = len(shapes)
    near[:] = range(len(shapes))
    work = godobject.scratch()
    steps = []
    for p in path:  # each target in five steps, then once more in one jump back
        sx, sy, sz = god.x, god.y, god.z
        steps += [tuple(a + (b - a) * k / 5 for a, b in zip((sx, sy, sz), p)) for k in range(1, 6)]
        steps.append((sx, sy, sz))
    for q in steps:
        ok_py = god.update(*q)
        ok_c = godobject.update(S, T, C, d.geom_xpos, d.geom_xmat, g, near, *q, work[0], work[1], work[2], work[3])
        assert ok_py == ok_c
        assert (g[L.G_X], g[L.G_Y], g[L.G_Z]) == (god.x, god.y, god.z)
        assert bool(g[L.G_CONTACT]) == god.contact and bool(g[L.G_STICKING]) == god.sticking
        planes = g[L.G_PLANES:L.G_PLANES + L.PLANE_WIDTH * int(g[L.G_NPLANES])].reshape(-1, L.PLANE_WIDTH)
        assert [(*p[:4], shapes[int(p[4])]) for p in planes.tolist()] == god.planes
        if god.contact:
            assert (g[L.G_NX], g[L.G_NY], g[L.G_NZ], g[L.G_DEPTH]) == (god.nx, god.ny, god.nz, god.depth)
            assert shapes[int(g[L.G_SHAPE])] is god.shape
        assert [shapes[k] for k in near[:int(g[L.G_NNEAR])]] == god.near


def test_the_mesh_scene_runs_compiled_as_in_python():
    """mesh_object (a finger stroking the inside of a 7200-triangle bowl) run by both engines:
    where two triangles are equally near either may answer, so the engines agree to rounding,
    not to the bit; over the whole stroke the forces stay within 1e-6 N and the proxies within
    1e-9 m, the proxy never goes inside, and the friction slips are the same."""
    loops, ticks = _twins("mesh_object")
    a, b = loops
    worst_force = worst_proxy = 0.0
    for i in range(ticks):
        a.tick()
        b.tick()
        fa, fb = a.fingers[0], b.fingers[0]
        worst_force = max(worst_force, abs(fa.fx - fb.fx), abs(fa.fy - fb.fy), abs(fa.fz - fb.fz))
        if i % 10 == 0:
            b.sync()
            worst_proxy = max(worst_proxy, abs(fa.god.x - fb.god.x), abs(fa.god.y - fb.god.y),
                              abs(fa.god.z - fb.god.z))
    b.sync()
    fa, fb = a.fingers[0], b.fingers[0]
    assert fa.max_force_seen > 1.0  # the finger pressed into the bowl
    assert worst_force < 1e-6 and worst_proxy < 1e-9, (worst_force, worst_proxy)
    assert fb.penetration_max < 1e-6
    assert fb.slide_events == fa.slide_events > 0


def test_stop_clears_the_compiled_wrenches_and_sends_zero():
    """Stopping a compiled loop mid-grasp: no finger wrench left on the box, zero force sent,
    and the Python objects hold the state the compiled tick reached."""
    loops, _ = _twins("two_finger_grasp")
    b = loops[1]
    b.run(800)  # run() ends with stop()
    box = b.world.body_id("box")
    assert not b.world.data.xfrc_applied[box].any()
    assert b.device.last_force == [(0.0, 0.0, 0.0)] * 2
    a = loops[0]
    a.run(800)
    assert [f.god.x for f in a.fingers] == [f.god.x for f in b.fingers]
    # and the compiled loop carries on from there like the Python one
    _assert_same_run(loops, 200, full_every=20)
