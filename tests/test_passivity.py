"""Passive by construction: the coupling renders no energy a hand or a body did not put in.

What is tested here: the friction laws' slip state under steady slow motion (a steady
dynamic torque or lag, not a saw-tooth that pumps the hand), the torsional damper on the
relative twist rate (a slip renders no reversal), and one wrench for both sides of the
coupling (the body gets the reaction of exactly what the device is sent).
"""

import math

import mujoco
import numpy as np
import pytest

from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.servo import ServoLoop
from softproxy.world import World

FLOOR = '<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>'
DT = 1e-3
RUN_S = 5.0


def finger_on_floor(**params):
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    params = {"radius": 0.008, "soft_start": 0.0, **params}
    f = SoftFingerProxy(FingerParams(**params), world.shapes, model("CH"))
    f.place(0.0, 0.0, 0.02)
    return f


def transitions(flags) -> int:
    """How many times a boolean series changes value."""
    flags = np.asarray(flags, dtype=bool)
    return int(np.count_nonzero(flags[1:] != flags[:-1]))


@pytest.mark.parametrize("grip", [0.3, 1.0, 3.0, 10.0])
@pytest.mark.parametrize("rate", [0.02, 0.1, 1.0])
def test_a_steady_twist_slips_steadily(grip, rate):
    """A finger pressing with a steady grip P while the device twists at a steady rate: after
    the break-away it slips at the dynamic limit μ_d·L(P) (soft-finger proxy paper, eq 40 with
    its sign) for the 5 s that follow: at most 2 stick-slip transitions and a torque ripple within
    5 % of the dynamic limit, from 0.3 to 10 N and 0.02 to 1 rad/s."""
    f = finger_on_floor()
    k = f.params.stiffness
    depth = grip / k
    slipping, torque = [], []
    i, end = 0, 10 ** 6
    while i < end:  # until 5 s after the break-away
        assert f.update(0.0, 0.0, f.params.radius - depth, rate * i * DT, DT)
        slipping.append(f.torsion.slipping)
        torque.append(f.torque)
        if f.torsion.slipping and end == 10 ** 6:
            end = i + int(RUN_S / DT)
        i += 1
    assert f.normal_force == pytest.approx(grip, rel=1e-6)
    dynamic = f.torsion.limit * 0.8  # μ_d = 0.8 μ_s, the default
    first = slipping.index(True)
    tail = np.array(torque[first + 10:])
    ripple = (tail.max() - tail.min()) / dynamic
    print(f"P {grip} N, {rate} rad/s: slips at tick {first}, {transitions(slipping)} transitions, "
          f"torque {tail.mean():.4g} N·m (dynamic limit {dynamic:.4g}), ripple {ripple:.2%}")
    assert transitions(slipping) <= 2
    assert ripple <= 0.05
    assert tail.mean() == pytest.approx(-dynamic, rel=0.05)  # the twist's way, at the dynamic limit


@pytest.mark.parametrize("grip", [0.3, 1.0, 3.0, 10.0])
@pytest.mark.parametrize("speed", [0.001, 0.01, 0.1])
def test_a_steady_slide_slips_steadily(grip, speed):
    """A finger pressing with a steady grip while the device slides along the floor at 1 to
    100 mm/s: after the break-away the proxy trails at the dynamic cone's edge (tangential
    force μ_d·P) for the 5 s that follow, with at most 2 stick-slip transitions and a ripple
    within 5 % of μ_d·P."""
    f = finger_on_floor()
    depth = grip / f.params.stiffness
    sticking, lateral = [], []
    i, end = 0, 10 ** 6
    while i < end:  # until 5 s after the break-away
        assert f.update(speed * i * DT, 0.0, f.params.radius - depth, 0.0, DT)
        sticking.append(f.god.sticking)
        lateral.append(f.fx)
        if not f.god.sticking and end == 10 ** 6:
            end = i + int(RUN_S / DT)
        i += 1
    first = sticking.index(False)
    tail = np.array(lateral[first + 10:])
    dynamic = f.params.mu_d * grip
    print(f"P {grip} N, {speed * 1e3:g} mm/s: slides at tick {first}, {transitions(sticking)} transitions, "
          f"Fx {tail.mean():.4g} N (μ_d P {dynamic:.4g}), ripple {(tail.max() - tail.min()) / dynamic:.2%}")
    assert transitions(sticking) <= 2
    assert (tail.max() - tail.min()) / dynamic <= 0.05
    assert tail.mean() == pytest.approx(-dynamic, rel=0.05)  # the proxy trails: the finger is pulled back (-x)


def test_a_slip_renders_no_torque_reversal():
    """Eq 39 re-tested every tick (restick_time 0), a steady twist slips again and again: the
    torsional damper acts on the device's twist rate relative to the touched body, never on
    the proxy's jump at a slip, so the torque keeps the twist's sign on every tick (it
    flipped to -0.2× the static limit for a tick at every slip when the damper saw the jump)."""
    f = finger_on_floor(restick_time=0.0, torsion_damping=0.01)
    depth = 1.0 / f.params.stiffness
    torque = []
    for i in range(2000):
        f.update(0.0, 0.0, f.params.radius - depth, 0.1 * i * DT, DT)
        torque.append(f.torque)
    torque = np.array(torque)
    print(f"{f.torsion.slip_events} slips, torque from {torque.min():.4g} to {torque.max():.4g} N·m")
    assert f.torsion.slip_events > 20  # the per-tick law slips often
    assert torque.max() <= 0.0  # never against the twist


BOX = """<mujoco><option gravity="0 0 0"/><worldbody><geom type="plane" size="1 1 .1"/>
<body name="box" pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.05 0.05" mass="10"/></body>
</worldbody></mujoco>"""


class Pressing:
    fingers, max_force, max_torque = 1, 20.0, 0.05

    def __init__(self):
        self.sent = []

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.01, 0.0, 0.12 - min(t, 0.05) * 0.8, 2.0 * t, True

    def send(self, finger, *w):
        self.sent.append(w)

    def close(self):
        pass


def test_the_body_gets_the_reaction_of_exactly_what_the_device_is_sent():
    """A finger whose own clamp (40 N, 1 N·m) is above the device's (20 N, 0.05 N·m) presses
    and twists on a free box: each tick the box's applied wrench is the reaction of the wrench
    the device was sent, after every clamp, so both sides exchange the same energy."""
    world = World(mujoco.MjModel.from_xml_string(BOX))
    finger = SoftFingerProxy(FingerParams(radius=0.008, soft_start=0.0), world.shapes, model("CH"))
    device = Pressing()
    body = world.model.body("box").id
    compared = 0
    with ServoLoop(world, [finger], device, 1000.0) as loop:
        for _ in range(150):
            loop.tick()
            xfrc = world.data.xfrc_applied[body]
            if not finger.valid or finger.body != body:
                continue
            w = np.array(device.sent[-1])
            assert np.allclose(xfrc[:3], -w[:3], rtol=1e-12, atol=1e-12)
            # the torque about the box's centre: the pure torque -M·n plus the lever of -F at the contact
            lever = np.array([finger.px, finger.py, finger.pz]) - world.data.xipos[body]
            assert np.allclose(xfrc[3:], -w[3:] + np.cross(lever, -w[:3]), rtol=1e-9, atol=1e-12)
            compared += 1
        assert max(np.linalg.norm(np.array(device.sent)[:, :3], axis=1)) == pytest.approx(20.0)
        assert math.hypot(finger.fx, finger.fy, finger.fz) > 20.0  # the finger's own force is past the device's
    assert compared > 100
