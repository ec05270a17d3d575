"""Two rates: MuJoCo stepping once every few haptic ticks, the ticks between rendering against
the shapes carried forward (`softproxy.local_model`, `softproxy.compiled.carry`)."""

import math

import mujoco
import numpy as np
import pytest
from conftest import BOX_ON_PLANE_XML

from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.local_model import physics_every
from softproxy.servo import ServoLoop
from softproxy.world import World

FREE_BOX_XML = """<mujoco><option gravity="0 0 0" timestep="0.001"/><worldbody>
  <body name="box" pos="0 0 0.1"><freejoint/><geom type="box" size=".03 .03 .03" mass="0.1"/></body>
</worldbody></mujoco>"""
"""A free 6 cm box of 100 g in a world without gravity."""


class PathDevice:
    """One finger following `path(t) -> (x, y, z)` (m, device frame); sends are kept."""

    fingers, max_force, max_torque = 1, 10.0, 0.0

    def __init__(self, path):
        self.path = path
        self.sent = []

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z = self.path(t)
        s.qw, s.qx, s.qy, s.qz, s.twist, s.valid = 1.0, 0.0, 0.0, 0.0, 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.sent.append((fx, fy, fz))

    def close(self):
        pass


def _loop(xml, path, physics_rate_hz, stiffness=1000.0):
    world = World(mujoco.MjModel.from_xml_string(xml))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=stiffness), world.shapes, model("CH"))
    return ServoLoop(world, [finger], PathDevice(path), 1000.0, overrun_watchdog=False, physics_rate_hz=physics_rate_hz)


def test_the_physics_rate_is_a_whole_fraction_of_the_servo_rate():
    assert physics_every(1000.0, None) == 1
    assert physics_every(1000.0, 1000.0) == 1
    assert physics_every(1000.0, 250.0) == 4
    assert physics_every(4000.0, 100.0) == 40
    with pytest.raises(ValueError, match="must divide the servo rate.*try 333.333 or 250 Hz"):
        physics_every(1000.0, 300.0)
    with pytest.raises(ValueError, match="at most the servo rate"):
        physics_every(1000.0, 2000.0)
    for bad in (0.0, -5.0, math.nan, math.inf, "100"):
        with pytest.raises(ValueError, match="physics_rate_hz must be a rate in Hz"):
            physics_every(1000.0, bad)


def test_mujoco_steps_at_the_physics_rate_with_the_wrenches_averaged():
    """Every 4th tick MuJoCo takes one step of 4 ms, and the box gets minus the mean of what the
    device was sent over those 4 ticks: a finger pressing 5 mm into a box on a floor."""
    loop = _loop(BOX_ON_PLANE_XML, lambda t: (0.0, 0.0, 0.068 - 0.005 * min(1.0, t / 0.05)), 250.0)
    world, dev = loop.world, loop.device
    box = world.body_id("box")
    assert world.timestep == pytest.approx(0.004)
    for step in range(30):
        before = len(dev.sent)
        for _ in range(4):
            time_before = world.data.time
            loop.tick()
        assert world.data.time == pytest.approx(time_before + 0.004)  # one step, on the 4th tick
        mean = -np.mean(np.array(dev.sent[before:before + 4]), axis=0)
        np.testing.assert_allclose(world.data.xfrc_applied[box, :3], mean, rtol=1e-12, atol=1e-15)
    assert np.linalg.norm(mean) > 1.0  # the finger was pressing
    loop.close()


def test_a_shape_near_a_finger_is_carried_with_its_velocity():
    """A free box drifting at 5 cm/s and turning at 2 rad/s about z, a finger hovering just
    above it: at every haptic tick the pose the finger's queries read is the box's at that
    tick's time (constant velocity: x₀ + v t, R(ω t) R₀), not MuJoCo's last step's."""
    loop = _loop(FREE_BOX_XML, lambda t: (0.0, 0.0, 0.145), 100.0)
    world = loop.world
    world.data.qvel[:] = [0.05, 0.0, 0.0, 0.0, 0.0, 2.0]
    g = int(np.where(world.model.geom_bodyid == world.body_id("box"))[0][0])
    x0 = world.data.geom_xpos[g].copy()
    for i in range(35):
        loop.tick()
        t = i * 0.001  # the time of the pose tick i rendered against
        np.testing.assert_allclose(loop.local.geom_xpos[g], x0 + [0.05 * t, 0.0, 0.0], atol=1e-12)
        R = loop.local.geom_xmat[g].reshape(3, 3)
        c, s = math.cos(2.0 * t), math.sin(2.0 * t)
        np.testing.assert_allclose(R, [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], atol=1e-12)
        if i % 10 == 9:  # MuJoCo's own pose after its step: where the carried one arrives
            np.testing.assert_allclose(world.data.qpos[:3], x0 + [0.05 * (i + 1) * 0.001, 0.0, 0.0], atol=1e-12)
    # MuJoCo's pose itself moved only at its steps: the finger was not reading it
    assert world.data.time == pytest.approx(0.03)
    loop.close()


@pytest.mark.parametrize("physics_rate_hz", [None, 250.0, 100.0])
def test_pushing_a_free_box_creates_no_energy(physics_rate_hz):
    """A finger pushes a free 100 g box (no gravity) at 10 cm/s for 0.3 s, then pulls back:
    the box's kinetic energy is at most the work the hand did against the rendered force
    (an energy balance: the averaged wrench must not hand the box more than the hand put in)."""
    speed = 0.1

    def path(t):
        x = -0.05 + speed * min(t, 0.3) - speed * max(0.0, t - 0.3)
        return (x, 0.0, 0.1)

    loop = _loop(FREE_BOX_XML, path, physics_rate_hz)
    dev, world = loop.device, loop.world
    work, xd_prev = 0.0, None
    for i in range(600):
        loop.tick()
        xd = path(i * 0.001)[0]
        if xd_prev is not None:
            work += -dev.sent[-2][0] * (xd - xd_prev)  # last tick's force over this tick's motion
        xd_prev = xd
    v = world.data.qvel
    inertia = world.model.body_inertia[1]
    kinetic = 0.5 * 0.1 * float(np.dot(v[:3], v[:3])) + 0.5 * float(np.dot(inertia, v[3:] ** 2))
    assert kinetic > 1e-4  # it was pushed
    assert kinetic <= work * 1.001 + 1e-7
    loop.close()


def _grasp(physics_rate_hz):
    """The shipped grasp on its simulated device: per tick the right finger's force; the box."""
    from softproxy.devices.simulated import SimulatedDevice
    from softproxy.run import build
    from softproxy.scene import load_scene

    scene = load_scene("two_finger_grasp")
    loop = build(scene, SimulatedDevice.from_config(scene.device), realtime=False, physics_rate_hz=physics_rate_hz)
    forces = []
    loop.run(4000, on_tick=lambda lp: forces.append(lp.rows.data[0]["force"].copy()), every=1)
    box = loop.world.body_id(scene.measure.object)
    pose = loop.world.data.xpos[box].copy(), loop.world.data.xquat[box].copy()
    loop.close()
    return np.array(forces), pose


@pytest.fixture(scope="module")
def one_rate_grasp():
    return _grasp(None)


@pytest.mark.parametrize("physics_rate_hz", [250.0, 50.0])
def test_the_grasp_holds_with_mujoco_at_a_lower_rate(one_rate_grasp, physics_rate_hz):
    """The shipped grasp with MuJoCo at 250 or 50 Hz under the 1 kHz loop: the box ends where
    the one-rate run leaves it (within 0.5 mm and 0.5°), still squeezed, and the force never
    steps more than the one-rate run's own largest step (at first touch) plus 0.15 N."""
    one, (x1, q1) = one_rate_grasp
    two, (x2, q2) = _grasp(physics_rate_hz)
    assert np.linalg.norm(x2 - x1) < 5e-4
    turn = 2.0 * math.degrees(math.acos(min(1.0, abs(float(np.dot(q1, q2))))))
    assert turn < 0.5
    assert np.abs(np.diff(two, axis=0)).max() <= np.abs(np.diff(one, axis=0)).max() + 0.15
    assert np.abs(two[2000:, 0]).min() > 2.5  # still squeezing at the end: the box was held


def test_two_rates_in_lockstep_repeat_exactly():
    """Two runs of the grasp with MuJoCo at 100 Hz give the same forces bit for bit."""
    first, _ = _grasp(100.0)
    again, _ = _grasp(100.0)
    np.testing.assert_array_equal(first, again)


def test_a_real_time_run_steps_mujoco_in_its_own_thread():
    """`run(realtime=True)` with two rates: MuJoCo steps in its own thread (about one step per
    4 ticks of real time), the finger presses the box on the floor through it, and when the
    run ends the thread has stopped and left no wrench in xfrc_applied."""
    loop = _loop(BOX_ON_PLANE_XML, lambda t: (0.0, 0.0, 0.068 - 0.005 * min(1.0, t / 0.05)), 250.0)
    world = loop.world
    box = world.body_id("box")
    time_before = world.data.time
    loop.run(300, realtime=True)
    physics = loop.physics
    assert physics.steps >= 10  # at 250 Hz over ~0.3 s: ~75, fewer on a loaded machine
    assert world.data.time == pytest.approx(time_before + physics.steps * 0.004)
    assert not world.data.xfrc_applied[box].any()
    assert max(abs(f[2]) for f in loop.device.sent) > 1.0  # the finger pressed the box
    assert not loop.state[0].threaded and loop.state[0].phase == 0
    # lockstep ticks go on from MuJoCo's last step
    loop.tick()
    assert world.data.time == pytest.approx(time_before + physics.steps * 0.004)
    loop.close()


def test_pushing_a_free_box_in_two_threads_creates_no_energy():
    """The energy balance of `test_pushing_a_free_box_creates_no_energy` with MuJoCo in its own
    thread at 250 Hz, in real time: the box gets at most the work the hand did."""
    speed = 0.1

    def path(t):
        return (-0.05 + speed * min(t, 0.3) - speed * max(0.0, t - 0.3), 0.0, 0.1)

    loop = _loop(FREE_BOX_XML, path, 250.0)
    xs = []
    loop.run(500, realtime=True, on_tick=lambda lp: xs.append(path(lp.t - lp.period)[0]), every=1)
    sent = np.array(loop.device.sent)[:, 0]
    work = float(np.sum(-sent[:len(xs) - 1] * np.diff(xs)))  # (then the zero sent at the end)
    v = loop.world.data.qvel
    inertia = loop.world.model.body_inertia[1]
    kinetic = 0.5 * 0.1 * float(np.dot(v[:3], v[:3])) + 0.5 * float(np.dot(inertia, v[3:] ** 2))
    assert kinetic > 1e-4
    assert kinetic <= work * 1.001 + 1e-7
    loop.close()


def test_auto_picks_the_fewest_ticks_per_step_the_step_cost_allows():
    """"auto": the highest physics rate at which a step takes at most half a core: a 1.3 ms
    step under 1 kHz needs 3 ticks (333 Hz), a 2.5 µs one runs every tick, one of 10 s the
    most ticks a step may span."""
    from softproxy.local_model import MAX_EVERY, every_for_cost

    assert every_for_cost(1000.0, 1.3e-3) == 3
    assert every_for_cost(4000.0, 1.3e-3) == 11
    assert every_for_cost(1000.0, 2.5e-6) == 1
    assert every_for_cost(1000.0, 10.0) == MAX_EVERY


def test_auto_on_a_light_world_is_one_rate_and_says_its_rate():
    """A box on a floor costs microseconds a step, far under half a 1 ms period even on a
    loaded machine: "auto" keeps a step every tick, and the loop says the rate it chose."""
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_PLANE_XML))
    finger = SoftFingerProxy(FingerParams(radius=0.008), world.shapes, model("CH"))
    with ServoLoop(world, [finger], PathDevice(lambda t: (0.0, 0.0, 0.1)), 1000.0, physics_rate_hz="auto") as loop:
        assert loop.physics_every == 1 and loop.physics_rate_hz == 1000.0


def test_a_coarse_physics_step_is_warned_of():
    """MuJoCo at 50 Hz under 1 kHz (a 20 ms step): the run's warnings say so, once."""
    from softproxy.run import run_warnings

    world = World(mujoco.MjModel.from_xml_string(BOX_ON_PLANE_XML))
    finger = SoftFingerProxy(FingerParams(radius=0.008), world.shapes, model("CH"))
    with ServoLoop(world, [finger], PathDevice(lambda t: (0.0, 0.0, 0.061)), 1000.0, physics_rate_hz=50.0) as loop:
        for _ in range(100):
            loop.tick()
        said = [w for w in run_warnings(loop) if "MuJoCo stepped every 20 ms (50 Hz)" in w]
    assert len(said) == 1


def test_physics_rate_auto_from_the_command_line(tmp_path):
    """`--physics-rate auto` runs (the grasp's world: a step every tick); a word that is
    neither a rate nor auto is refused in one line, status 2."""
    import subprocess
    import sys

    ok = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", "two_finger_grasp", "--headless", "--duration",
                         "0.2", "--physics-rate", "auto", "--json"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert '"physics_rate_hz": 1000.0' in ok.stdout
    bad = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", "two_finger_grasp", "--headless",
                          "--physics-rate", "fast"], capture_output=True, text=True)
    assert bad.returncode == 2 and "a rate in Hz or 'auto', got 'fast'" in bad.stderr
