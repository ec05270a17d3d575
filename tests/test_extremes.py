"""Stability at the extremes: garbage from the device, huge stiffness, jumps — never NaN to a motor."""

import math

import mujoco
import pytest
from hypothesis import given, settings, strategies as st

from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.servo import ServoLoop
from softproxy.world import World

XML = """<mujoco><option timestep="0.001"/><worldbody>
  <geom type="plane" size="1 1 .1"/>
  <body name="box" pos="0 0 0.03"><freejoint/><geom type="box" size=".03 .03 .03" mass="0.1"/></body>
  <geom type="sphere" pos="0.1 0 0.02" size="0.02"/>
</worldbody></mujoco>"""

anything = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-0.2, 0.2))


class Replay:
    """A one-finger device replaying the given samples, then holding the last."""

    fingers, max_force, max_torque = 1, 15.0, 0.2

    def __init__(self, samples):
        self.samples, self.i, self.sent = samples, 0, []

    def read(self, t, out):
        x, y, z, twist, valid = self.samples[min(self.i, len(self.samples) - 1)]
        self.i += 1
        s = out[0]
        s.x, s.y, s.z, s.twist, s.valid = x, y, z, twist, valid

    def send(self, finger, *wrench):
        self.sent.append(wrench)

    def close(self):
        pass


def make_loop(device, **params):
    world = World(mujoco.MjModel.from_xml_string(XML))
    p = FingerParams(**{"radius": 0.008, "stiffness": 2000.0, "max_force": 30.0, **params})
    # lockstep: no wall-clock watchdog, so a slow tick on a busy machine cannot change the result
    return ServoLoop(world, [SoftFingerProxy(p, world.shapes, model("CH"))], device, 1000.0, overrun_watchdog=False)


def assert_safe(device):
    for w in device.sent:
        assert all(math.isfinite(v) for v in w), w
        assert math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2) <= device.max_force * (1 + 1e-12)
        assert math.sqrt(w[3] ** 2 + w[4] ** 2 + w[5] ** 2) <= device.max_torque * (1 + 1e-12)


@pytest.mark.filterwarnings("ignore::softproxy.input_error.UnitWarning")  # (metres away: garbage on purpose)
@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(anything, anything, anything, anything, st.booleans()), min_size=1, max_size=60))
def test_garbage_device_never_sends_nan_or_unclamped_force(samples):
    """NaN, Inf, 1e308 or wild jumps from the device: every force sent is finite and within the clamps."""
    dev = Replay(samples)
    loop = make_loop(dev)
    loop.run(len(samples) + 5)
    assert_safe(dev)
    assert all(math.isfinite(v) for v in loop.world.data.qpos)


@pytest.mark.parametrize("k, b, k_tau", [(1e7, 0.0, 1e6), (10.0, 0.0, 1e-3), (2000.0, 1e3, 2.0)])
def test_extreme_gains_stay_finite(k, b, k_tau):
    """Very stiff or very soft couplings, huge damping: finite, clamped output (it may buzz, never NaN)."""
    press = [(0.0, 0.0, 0.07 - 0.0005 * i, 0.01 * i, True) for i in range(40)]
    dev = Replay(press)
    loop = make_loop(dev, stiffness=k, damping=b, torsion_stiffness=k_tau)
    loop.run(400)
    assert_safe(dev)


def test_one_metre_jump_in_one_tick():
    """The device jumps 1 m through the box and the table in one tick: the proxy stays on top, force clamped."""
    dev = Replay([(0.0, 0.0, 0.2, 0.0, True)] * 5 + [(0.0, 0.0, -0.8, 0.0, True)] * 20)
    loop = make_loop(dev, soft_start=0.0)
    loop.run(25)
    f = loop.fingers[0]
    box_top = loop.world.data.body("box").xpos[2] + 0.03
    assert f.god.z >= box_top + 0.008 - 1e-6  # on the box top (pressed a little into the table), not through it
    assert_safe(dev)
    assert dev.sent[-2][2] == pytest.approx(15.0)  # clamped to the device's 15 N


def test_soft_start_no_kick_when_starting_inside():
    """A finger whose device starts 2 cm inside the box: the force ramps in over soft_start, no
    kick: every tick within the ramp's envelope (1 % of the clamp per ms), and no step up of
    more than 2 % (the box's implicit coupling renders a little less than the envelope on the
    first ticks, then catches up with it)."""
    dev = Replay([(0.0, 0.0, 0.04, 0.0, True)] * 300)  # box top at 0.06: 2 cm deep
    loop = make_loop(dev, soft_start=0.1, max_force=30.0)
    loop.run(300)
    fz = [w[2] for w in dev.sent[:-1]]
    assert all(f <= 30.0 * 0.01 * (i + 1) + 1e-9 for i, f in enumerate(fz))  # the ramp's envelope
    assert all(b - a <= 30.0 * 0.02 for a, b in zip(fz, fz[1:]))  # never more than 2 %/ms up
    assert fz[-1] == pytest.approx(15.0)  # then the full force (device clamp 15 N)
