"""World coupling and servo loop: the grasp, the knob, wrench balance, determinism, watchdog."""

import math
import time

import mujoco
import numpy as np
import pytest

from softproxy.device import DeviceError
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.geometry import shapes_of
from softproxy.run import open_device, run_scene
from softproxy.scene import load_scene
from softproxy.servo import ServoLoop
from softproxy.world import World


def run(name, **kw):
    scene = load_scene(name)
    return run_scene(scene, open_device("sim", scene), **kw)


@pytest.fixture(scope="module")
def grasp_soft():
    return run("two_finger_grasp")


def test_soft_fingers_hold_the_box(grasp_soft):
    """Seed 002 Fig 1 / §7: two soft fingers fully restrain the box against the gravity torque (< 2°)."""
    r = grasp_soft
    assert r["object_height_m"] > 0.07, "the box was lifted"
    assert abs(r["object_rotation_deg"]) < 2.0
    assert r["object_rotation_max_deg"] < 2.0
    for f in r["fingers"]:
        assert 2.5 < f["max_force_N"] < 4.0  # ~3 N of grip
        assert f["proxy_penetration_max_m"] <= 1e-6
    assert not any(r["faults"].values())


def test_point_contacts_let_the_box_spin():
    """Seed 002 §1: two point contacts cannot resist torque about the grasp axis: the box swings (> 20°)."""
    r = run("two_finger_grasp", finger_model="point")
    assert r["object_height_m"] > 0.04
    assert abs(r["object_rotation_deg"]) > 20.0


def _knob_run(grip_fraction):
    scene = load_scene("knob")
    ch = model("CH")
    f = scene.fingers[0]
    f.torsion_mu_s = f.torsion_mu_d = ch.mu_prime  # one coefficient: a sharp threshold
    threshold = (0.004 / ch.mu_prime) ** (1 / ch.gamma)  # hinge friction 4 N·mm = μ'P^γ
    depth = grip_fraction * threshold / f.stiffness
    for key in scene.device["finger"][0]["keyframes"][1:]:
        key[3] = 0.048 - depth  # proxy rests at z = 0.048 on the knob top
    return run_scene(scene, open_device("sim", scene))


def test_knob_turns_only_above_the_torsional_limit():
    """Seed 002 eq 39: the finger turns a knob with 4 N·mm of hinge friction only if μ'|P|^γ exceeds it."""
    below = _knob_run(0.9)
    above = _knob_run(1.1)
    assert abs(below["object_rotation_deg"]) < 1.0 and below["fingers"][0]["slip_events"] > 0
    assert above["object_rotation_deg"] > 30.0


def test_equal_and_opposite_wrench():
    """The impulse of the finger forces on a free body equals its change of momentum (no gravity, no other contact)."""
    xml = """<mujoco><option gravity="0 0 0" timestep="0.001"/><worldbody>
      <body name="b" pos="0 0 0"><freejoint/><geom type="box" size=".02 .02 .02" mass="0.2"/></body>
      </worldbody></mujoco>"""
    world = World(mujoco.MjModel.from_xml_string(xml))
    params = FingerParams(radius=0.005, stiffness=500.0, damping=0.0)

    class Push:
        fingers, max_force, max_torque = 1, 100.0, 1.0

        def read(self, t, samples):
            s = samples[0]
            s.x, s.y, s.z, s.twist, s.valid = -0.03 + min(t, 0.05) * 0.2, 0.003, 0.004, 0.0, True

        def send(self, *a):
            pass

        def close(self):
            pass

    finger = SoftFingerProxy(params, world.shapes, model("CH"))
    loop = ServoLoop(world, [finger], Push(), 1000.0, overrun_watchdog=False)
    impulse = [0.0, 0.0, 0.0]

    def on_tick(lp):
        impulse[0] -= finger.fx * lp.period
        impulse[1] -= finger.fy * lp.period
        impulse[2] -= finger.fz * lp.period

    loop.run(300, on_tick=on_tick)
    mujoco.mj_forward(world.model, world.data)
    v = world.data.qvel[:3]
    assert abs(impulse[0]) > 1e-3, "the finger pushed the box"
    for i in range(3):
        assert 0.2 * v[i] == pytest.approx(impulse[i], rel=1e-6, abs=1e-9)


def test_pushed_wrenches_reach_the_body_about_its_centre_of_mass():
    """World.push: forces at points add up, their moment is taken about the body's centre of
    mass (off the geom here), a body pushed last tick and not this one is cleared, and a
    body welded to the world gets nothing."""
    xml = """<mujoco><option gravity="0 0 0"/><worldbody>
      <geom name="wall" type="box" pos="0 0.5 0" size=".1 .1 .1"/>
      <body name="b" pos="0.1 0.2 0.3"><freejoint/>
        <geom type="box" size=".02 .02 .02" mass="0.2"/><geom type="sphere" pos="0.05 0 0" size="0.01" mass="0.1"/>
      </body></worldbody></mujoco>"""
    world = World(mujoco.MjModel.from_xml_string(xml))
    body = world.body_id("b")
    world.begin_step()
    c = world.data.xipos[body].copy()
    assert abs(c[0] - 0.1) > 1e-3, "centre of mass off the body origin"
    pushes = [((1.0, -2.0, 0.5), (0.12, 0.21, 0.28), (0.01, 0.0, -0.02)),
              ((-0.3, 0.4, 2.0), (0.08, 0.19, 0.33), (0.0, 0.005, 0.0))]
    force, moment = [0.0] * 3, [0.0] * 3
    for f, p, t in pushes:
        world.push(body, *f, *p, *t)
        world.push(0, *f, *p, *t)  # the world body: ignored
        r = [p[i] - c[i] for i in range(3)]
        cross = (r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0])
        for i in range(3):
            force[i] += f[i]
            moment[i] += cross[i] + t[i]
    world.end_step()
    assert world.data.xfrc_applied[body].tolist() == pytest.approx(force + moment, abs=1e-12)
    assert not world.data.xfrc_applied[0].any()
    world.begin_step()
    world.end_step()  # nothing pushed this tick
    assert not world.data.xfrc_applied.any()
    world.begin_step()
    world.push(body, 1.0, 0.0, 0.0, *c, 0.0, 0.0, 0.0)
    world.end_step()
    world.clear_wrenches()
    assert not world.data.xfrc_applied.any()


def test_lockstep_is_deterministic():
    a = run("two_finger_grasp", duration_s=1.0)
    b = run("two_finger_grasp", duration_s=1.0)
    a.pop("tick_us"), b.pop("tick_us")
    assert a == b


class Scripted:
    """A one-finger device pressing down on a plane, with a fault planted at chosen ticks."""

    fingers, max_force, max_torque = 1, 50.0, 1.0

    def __init__(self, fault=None, at=()):
        self.fault, self.at, self.n = fault, set(at), 0
        self.sent = []

    def read(self, t, samples):
        self.n += 1
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, 0.005 - min(t, 0.01), 0.0, True
        if self.n in self.at:
            if self.fault == "raise":
                raise DeviceError("unplugged")
            if self.fault == "nan":
                s.z = math.nan
            if self.fault == "stall":
                time.sleep(0.02)

    def send(self, finger, *wrench):
        self.sent.append(wrench)

    def close(self):
        pass


def plane_loop(device, watchdog=False):
    xml = '<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>'
    world = World(mujoco.MjModel.from_xml_string(xml))
    finger = SoftFingerProxy(FingerParams(radius=0.005, stiffness=1000.0), world.shapes, model("CH"))
    # the overrun watchdog only where a test plants a stall (10 ms; `overran` tells which ticks tripped it)
    return ServoLoop(world, [finger], device, 1000.0, overrun_factor=10.0, overrun_watchdog=watchdog)


def overran(loop) -> set[int]:
    """The ticks (0-based, since the loop was built) that lasted longer than the watchdog's limit,
    by the watchdog's own measure: a planted stall, and any tick a loaded machine held up."""
    durations_ns = np.round(loop.stats.durations() * 1e9)
    return set(np.flatnonzero(durations_ns > loop.state[0].overrun_ns).tolist())


@pytest.mark.parametrize("fault, counter", [("raise", "device_error"), ("nan", "invalid_sample")])
def test_watchdog_zero_force_on_bad_device(fault, counter):
    """A device that raises or sends NaN: zero force that tick, a counted fault, and the loop goes on."""
    dev = Scripted(fault, at=(40,))
    loop = plane_loop(dev)
    loop.run(60)
    assert loop.faults[counter] == 1
    assert loop.ticks == 60
    # read 40 is tick 39 (the first read places the proxies): that tick sent zero, its neighbours the contact force
    assert dev.sent[37][2] > 1.0 and dev.sent[38] == (0.0,) * 6 and dev.sent[39][2] > 1.0
    assert all(all(math.isfinite(v) for v in w) for w in dev.sent)


def test_watchdog_zero_force_after_stalled_tick():
    """A tick that overruns its period badly (a 20 ms stall at 1 kHz) is followed by a zero-force
    tick, and only such a tick renders zero: exactly the ticks after those the watchdog measured
    over its limit (the planted stall, and any a loaded machine added) sent zero, each counted."""
    dev = Scripted("stall", at=(40,))
    loop = plane_loop(dev, watchdog=True)
    loop.run(60)  # lockstep, but the loop was built with the real-time watchdog on
    late = overran(loop)
    assert 38 in late  # read 40, the stalled one, is tick 38
    assert loop.faults["overrun"] == len(late)
    for k in range(10, 60):  # pressing > 1 N from tick 10 on
        zeroed = dev.sent[k] == (0.0,) * 6
        assert zeroed == (k - 1 in late), (k, dev.sent[k], sorted(late))
        assert zeroed or dev.sent[k][2] > 1.0


def test_by_default_the_overrun_watchdog_watches_only_real_time_runs():
    """An application ticking a loop in lockstep gets the same forces however loaded the machine
    is: with the default watchdog a 20 ms stall zeroes nothing there, and the next tick after
    one does in `run(realtime=True)`."""
    dev = Scripted("stall", at=(40,))
    loop = plane_loop(dev, watchdog=None)
    for _ in range(60):
        loop.tick()
    assert loop.faults["overrun"] == 0 and dev.sent[39][2] > 1.0
    dev.at, dev.n = {20}, 0
    loop.run(40, realtime=True)  # read 20 is this run's tick 19 (the loop had started)
    overruns = loop.faults["overrun"]
    assert 60 + 19 in overran(loop) and overruns == len(overran(loop) - set(range(60)))
    assert dev.sent[60 + 20] == (0.0,) * 6
    dev.at, dev.n = {10}, 0
    for _ in range(20):  # lockstep again: off again
        loop.tick()
    assert loop.faults["overrun"] == overruns and dev.sent[-10][2] > 1.0


def test_a_loop_built_for_an_application_ticks_in_lockstep():
    """`build(scene, device)` (the embedding path) and the application's own tick(): a 20 ms
    stall renders nothing different; inside run(realtime=True) the watchdog is on."""
    from softproxy.run import build

    scene = load_scene("two_finger_grasp")
    device = open_device("sim", scene)
    inner_read = device.read
    stall_at = {20}

    def stalling_read(t, samples):
        inner_read(t, samples)
        if round(t * 1000) in stall_at:
            time.sleep(0.02)

    device.read = stalling_read
    loop = build(scene, device)
    for _ in range(50):
        loop.tick()
    assert loop.faults["overrun"] == 0 and not loop.paced
    stall_at.add(60)
    loop.run(30, realtime=True)
    assert loop.faults["overrun"] >= 1 and not loop.paced


def test_run_ends_with_zero_force():
    dev = Scripted()
    loop = plane_loop(dev)
    loop.run(30)
    assert dev.sent[-2][2] > 1.0 and dev.sent[-1] == (0.0,) * 6


@pytest.mark.parametrize("rate", [250.0, 10000.0])
def test_rates(rate):
    """The loop runs from 250 Hz to 10 kHz (timestep follows the rate) and keeps the grip."""
    r = run("two_finger_grasp", rate_hz=rate, duration_s=2.0)
    assert r["rate_hz"] == rate and r["ticks"] == int(2.0 * rate)
    assert abs(r["object_rotation_deg"]) < 2.0


def test_the_pacer_starts_each_tick_at_its_deadline_and_counts_a_late_one(monkeypatch):
    """The pacer (`pace`, `paced_done`) on a clock the test steps: tick k begins at the first
    reading at or past its deadline d0 + k·period, never before; it sleeps until `spin_ns`
    before a deadline still that far off and spins the rest; a tick that ends after the next
    deadline is one miss, and the deadlines stay on the period grid (a late tick does not
    shift the ones after it: the next begins at once)."""
    from softproxy.compiled import servo as kernel

    step = 1_000  # ns the clock moves per reading, so a spin ends
    clock = [5_000_000]
    slept_to = []

    def monotonic_ns():
        clock[0] += step
        return clock[0]

    def sleep_until_ns(deadline):
        slept_to.append(deadline)
        clock[0] = max(clock[0], deadline)

    monkeypatch.setattr(kernel, "monotonic_ns", monotonic_ns)
    monkeypatch.setattr(kernel, "sleep_until_ns", sleep_until_ns)
    # the kernels' Python source, which reads the clock above (itself under NUMBA_DISABLE_JIT=1)
    pace = getattr(kernel.pace, "py_func", kernel.pace)
    paced_done = getattr(kernel.paced_done, "py_func", kernel.paced_done)
    period, spin = 1_000_000, 200_000
    loop = np.zeros(1, dtype=kernel.LOOP).view(np.recarray)
    loop.period_ns, loop.spin_ns, loop.next_ns = period, spin, clock[0]
    counters = np.zeros(2, dtype=np.int64)
    d0 = clock[0]
    work = [300_000] * 40
    work[10], work[25] = 2_500_000, 1_200_000  # two ticks too long for their period
    late = 0
    for k, w in enumerate(work):
        deadline = d0 + k * period
        due_in = deadline - (clock[0] + step)  # at the pacer's first reading
        sleeps = len(slept_to)
        pace(loop)
        begun = clock[0]
        assert begun >= deadline, (k, begun - deadline)
        if due_in > 0:  # not due yet: it begins on the first reading at or past its deadline
            assert begun < deadline + step, (k, begun - deadline)
        assert slept_to[sleeps:] == ([deadline - spin] if due_in > spin else []), k
        clock[0] += w
        late += clock[0] + step > deadline + period  # the miss check reads the clock once more
        paced_done(loop, counters)
        assert loop.next_ns[0] == deadline + period, k
    assert late >= 2 and counters[kernel.MISSES] == late


@pytest.mark.slow
def test_a_paced_tick_never_starts_before_its_deadline():
    """Paced mode on the real clock: tick k reads the device no sooner than k periods after the
    run began (a loaded machine can only make it later; how close it keeps to the period is
    `softproxy bench latency`'s to measure)."""
    dev = Scripted()
    loop = plane_loop(dev)
    loop.start()
    inner, read_ns = dev.read, []

    def timed_read(t, samples):
        read_ns.append(time.monotonic_ns())  # the clock the pacer waits on (test_native)
        inner(t, samples)

    dev.read = timed_read
    begun = time.monotonic_ns()
    loop.run(200, realtime=True)
    period_ns = loop.state[0].period_ns
    assert len(read_ns) == 200
    early = [k for k, at in enumerate(read_ns) if at < begun + k * period_ns]
    assert not early, early


def test_injected_faults_never_reach_the_motor():
    """Fault injection: NaN, dropped, spiking and stalling samples each give zero force that tick;
    the force sent never is NaN nor above the clamp, the proxy never enters the box, and the grasp holds."""
    scene = load_scene("two_finger_grasp")
    scene.device["faults"] = {"nan": 0.01, "drop": 0.002, "spike": 0.002, "stall": 0.0005}
    scene.device["seed"] = 3
    r = run_scene(scene, open_device("sim", scene))
    injected = r["device"]["faults_injected"]
    assert all(injected[k] > 0 for k in ("nan", "drop", "spike"))
    assert r["device"]["nan_sends"] == 0
    assert r["device"]["max_force_sent_N"] < 5.0  # spikes rejected: no kick
    assert r["faults"]["device_error"] == injected["stall"]
    assert r["faults"]["invalid_sample"] >= injected["nan"] + injected["drop"] + injected["spike"]
    assert all(f["proxy_penetration_max_m"] <= 1e-6 for f in r["fingers"])
    assert abs(r["object_rotation_deg"]) < 2.0 and r["object_height_m"] > 0.07


def test_bad_fault_spec_is_named():
    scene = load_scene("two_finger_grasp")
    scene.device["faults"] = {"gremlins": 0.1}
    with pytest.raises(ValueError, match="device.faults.gremlins"):
        open_device("sim", scene)


# ---------------------------------------------------------------------------------------
# The loop's table of fingers: views, stop, refusals
# ---------------------------------------------------------------------------------------

BOX_ON_FLOOR = """<mujoco><option timestep="0.001"/><worldbody>
  <geom type="plane" size="1 1 .1"/>
  <body name="box" pos="0 0 .02"><freejoint/><geom type="box" size=".02 .02 .02" mass="0.2"/></body>
</worldbody></mujoco>"""


class Pressing:
    """Two device fingers pressing down: finger 0 on the box top (z = 0.04), twisting; finger
    1 on the floor beside it, sliding along x (frictionless fingers follow it exactly)."""

    fingers, max_force, max_torque = 2, 50.0, 1.0

    def __init__(self):
        self.sent = {0: [], 1: []}
        self.stall_at = None
        self.reads = 0

    def read(self, t, samples):
        self.reads += 1
        a, b = samples
        a.x, a.y, a.z, a.twist, a.valid = 0.0, 0.0, 0.05 - min(t, 0.02) * 0.6, 0.3 * math.sin(20.0 * t), True
        b.x, b.y, b.z, b.twist, b.valid = 0.05 + 0.1 * t, 0.0, 0.008 - min(t, 0.02) * 0.2, 0.0, True
        if self.reads == self.stall_at:
            time.sleep(0.05)

    def send(self, finger, *wrench):
        self.sent[finger].append(wrench)

    def close(self):
        pass


def box_fingers(world, **params):
    """The two fingers `Pressing` drives, over the world's shapes."""
    return [SoftFingerProxy(FingerParams(name=name, radius=0.005, device_finger=i, soft_start=0.0, **params),
                            world.shapes, model("CH")) for i, name in enumerate(("top", "side"))]


VIEWED = {
    "god": ("x", "y", "z", "contact", "nx", "ny", "nz", "depth", "sticking", "lx", "ly", "lz"),
    "torsion": ("in_contact", "alpha_0", "alpha_p", "alpha_g", "torque", "limit", "slipping", "slip_events"),
    "finger": ("fx", "fy", "fz", "torque", "tx", "ty", "tz", "px", "py", "pz", "body", "normal_force", "valid",
               "placed", "ramp", "xd", "yd", "zd", "max_force_seen", "penetration_max", "slide_events",
               "spikes_rejected"),
}
RECORD = {"torsion.torque": ("spring_torque", None), "finger.torque": ("torque_n", None)}
"""Where a view reads when its name is not its data field's: (field, component)."""
for _i, _axis in enumerate("xyz"):
    RECORD.update({f"god.{_axis}": ("pos", _i), f"god.n{_axis}": ("normal", _i), f"god.l{_axis}": ("local", _i),
                   f"finger.f{_axis}": ("force", _i), f"finger.t{_axis}": ("torque", _i),
                   f"finger.p{_axis}": ("contact_pos", _i), f"finger.{_axis}d": ("device_pos", _i)})


def data_field(row, key):
    """What finger data record `row` holds for the view `key` ("part.name")."""
    field, index = RECORD.get(key, (key.split(".")[1], None))
    return row[field] if index is None else row[field][index]


def state_of(f) -> dict:
    """Every field a finger's views show, by part and name."""
    parts = {"god": f.god, "torsion": f.torsion, "finger": f}
    return {f"{part}.{name}": getattr(parts[part], name) for part, names in VIEWED.items() for name in names}


def test_the_finger_views_read_the_loops_table():
    """The fingers are views of the loop's table, never copies that could go stale: after
    every tick, finger.god.x, finger.torsion.alpha_p, finger.fx and every other field read
    through the views are what loop.rows.data holds (and they move as the tick moves them). A
    finger built and driven alone keeps its whole state when a loop takes it in."""
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_FLOOR))
    top, side = box_fingers(world)
    top.place(0.0, 0.0, 0.05)
    for z in (0.046, 0.043, 0.041):  # alone, on the box top: in contact, twisted
        assert top.update(0.0, 0.0, z, 0.05, 1e-3)
    alone = state_of(top)
    assert alone["god.contact"] and alone["torsion.in_contact"] and alone["finger.fz"] > 0.0
    loop = ServoLoop(world, [top, side], Pressing(), 1000.0, overrun_watchdog=False)
    assert state_of(top) == alone
    seen = set()
    for _ in range(60):
        loop.tick()
        for i, f in enumerate(loop.fingers):
            row = loop.rows.data[i]
            for key, value in state_of(f).items():
                assert value == data_field(row, key), key
        seen.add((top.god.x, top.god.z, top.torsion.alpha_p, top.fx, side.god.x, side.fz))
    assert len(seen) > 50  # the tick moved them, and the views moved with it
    assert top.max_force_seen >= alone["finger.max_force_seen"]  # counters carried over from alone


def test_stop_clears_the_wrenches_and_sends_zero():
    """Stopping mid-contact: zero force sent to every device finger, no finger wrench left on
    the box, every finger's output cleared; the loop then carries on from there, rendering
    and pushing again."""
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_FLOOR))
    device = Pressing()
    loop = ServoLoop(world, box_fingers(world), device, 1000.0, overrun_watchdog=False)
    box = world.body_id("box")
    pushed = []
    loop.run(60, on_tick=lambda lp: pushed.append(world.data.xfrc_applied[box].copy()))  # run() ends with stop()
    assert np.linalg.norm(pushed[-1][:3]) > 1.0 and device.sent[0][-2][2] > 1.0  # pressing on the box
    assert not world.data.xfrc_applied.any()
    assert device.sent[0][-1] == device.sent[1][-1] == (0.0,) * 6
    for f in loop.fingers:
        assert (f.fx, f.fy, f.fz, f.tx, f.ty, f.tz, f.body, f.valid) == (0.0,) * 6 + (-1, False)
    loop.tick()
    assert world.data.xfrc_applied[box, 2] < -1.0 and device.sent[0][-1][2] > 1.0


def test_the_watchdogs_zero_force_tick_still_moves_the_proxy():
    """The tick after an overrun sends zero force, yet every proxy follows its device that
    tick (the frictionless finger on the floor stays under the sliding device), and the
    next tick renders again (unless it too followed an overrun: a loaded machine may add one)."""
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_FLOOR))
    device = Pressing()
    device.stall_at = 40
    loop = ServoLoop(world, box_fingers(world, mu_s=0.0, mu_d=0.0), device, 1000.0, overrun_factor=20.0,
                     overrun_watchdog=True)
    side = loop.fingers[1]
    while device.reads < device.stall_at:
        loop.tick()
    stalled = loop.ticks - 1
    assert stalled in overran(loop)  # the 50 ms stall, over the 20 ms limit
    if stalled - 1 not in overran(loop):
        assert device.sent[1][-1][2] > 1.0  # the stalled tick itself rendered
    t = loop.t
    loop.tick()  # the zero-force tick
    assert device.sent[1][-1] == (0.0,) * 6 and device.sent[0][-1] == (0.0,) * 6
    assert side.god.contact and side.god.x == pytest.approx(0.05 + 0.1 * t, abs=1e-12)
    while loop.ticks - 1 in overran(loop):  # at most a few, on a loaded machine
        loop.tick()
    loop.tick()
    assert loop.faults["overrun"] == len(overran(loop))
    assert device.sent[1][-1][2] > 1.0 and device.sent[0][-1][2] > 1.0


def test_a_finger_over_shapes_of_its_own_is_refused():
    """A finger built over another ShapeSet than the world's would touch shapes the loop
    never moves: the loop refuses it, naming the finger and the fix."""
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_FLOOR))
    stray = SoftFingerProxy(FingerParams(name="stray"), shapes_of(world.model, world.data), model("CH"))
    with pytest.raises(ValueError, match="'stray' touches shapes of its own.*world.shapes"):
        ServoLoop(world, [*box_fingers(world)[:1], stray], Pressing(), 1000.0)


def test_a_finger_has_one_source_for_its_fingertip_model():
    """FingerParams.model alone picks the law; a law given with the default params decides and
    the finger's params name it (the caller's params unchanged); a law contradicting a model
    named in the params is refused, naming both, instead of one being silently ignored."""
    world = World(mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/>'
                                                 '</worldbody></mujoco>'))
    assert SoftFingerProxy(FingerParams(model="MH"), world.shapes).model.name == "MH"
    params = FingerParams()
    f = SoftFingerProxy(params, world.shapes, model("LFM"))
    assert f.model.name == f.params.model == "LFM" and params.model == "CH"
    with pytest.raises(ValueError, match="FingerParams.model is 'MH' but the fingertip law given is 'LFM'"):
        SoftFingerProxy(FingerParams(model="MH"), world.shapes, model("LFM"))
    # the scene path: --finger-model overrides, and the params say so
    from softproxy.run import build

    scene = load_scene("two_finger_grasp")
    loop = build(scene, open_device("sim", scene), finger_model="point")
    assert [(f.model.name, f.params.model) for f in loop.fingers] == [("point", "point")] * 2
    loop.close()
