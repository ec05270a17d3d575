"""A proxy that jumps renders no kick: when the god-object's proxy moves millimetres in one
tick (breaking free of static friction, dropping off a box's edge onto the floor) the force
on the finger stays within its spring force plus the damper's bound, b times the device's
speed relative to the touched surface (static here, so the device's speed): the damper acts
on the device's velocity, never on the proxy's jump (docs/coupling.md). Run on the simulated
device in a servo loop."""

import math

import mujoco
import pytest

from softproxy.devices.simulated import SimulatedDevice
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.servo import ServoLoop
from softproxy.world import World

RADIUS = 0.005    # m
K = 2000.0        # N/m
B = 5.0           # N·s/m, the shipped damping
DT = 1e-3         # s
JUMP = 0.003
"""A proxy moving this far in one tick (m) is a jump: b·JUMP/dt = 15 N of damping, had the
damper seen it."""

SCENES = {
    # a floor of high static and low dynamic friction: the stuck proxy trails the device by
    # up to μ_s·depth, then breaks free to μ_d·depth behind it in one tick
    "breaking free": dict(
        xml='<geom type="plane" size=".2 .2 .01"/>',
        mu=(1.5, 0.3),
        keys=[(0.0, 0.0, 0.0, 0.02, 0.0), (0.2, 0.0, 0.0, RADIUS - 0.004, 0.0),
              (0.3, 0.0, 0.0, RADIUS - 0.004, 0.0), (0.9, 0.03, 0.0, RADIUS - 0.004, 0.0)]),
    # a 3 mm step (a static box on the floor): pressed on its top 2 mm from the edge and slid
    # off it, the proxy is held on the top by friction until it breaks free, then drops onto
    # the floor toward the device in one tick
    "dropping off an edge": dict(
        xml='<geom type="plane" size=".2 .2 .01"/><geom type="box" size=".02 .02 .0015" pos="0 0 .0015"/>',
        mu=(1.5, 0.3),
        keys=[(0.0, 0.018, 0.0, 0.03, 0.0), (0.2, 0.018, 0.0, 0.003 + RADIUS - 0.004, 0.0),
              (0.3, 0.018, 0.0, 0.003 + RADIUS - 0.004, 0.0), (0.7, 0.04, 0.0, 0.003 + RADIUS - 0.004, 0.0)]),
}


@pytest.mark.parametrize("name", sorted(SCENES))
def test_a_proxy_jump_renders_no_damping_kick(name):
    """On every tick in contact: |F| <= k|x_p - x_d| + b|v_d| (v_d the device's velocity over
    the tick; the scene is static), and at least one tick sees the proxy jump >= JUMP."""
    scene = SCENES[name]
    world = World(mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{scene['xml']}</worldbody></mujoco>"))
    mu_s, mu_d = scene["mu"]
    finger = SoftFingerProxy(FingerParams(radius=RADIUS, stiffness=K, damping=B, mu_s=mu_s, mu_d=mu_d,
                                          model="point", soft_start=0.0), world.shapes)
    device = SimulatedDevice([scene["keys"]], max_force=40.0)
    ticks = int(scene["keys"][-1][0] / DT) + 50
    worst = {"excess": -math.inf, "jump": 0.0}
    last = {}

    def check(loop):
        proxy, dev = (finger.god.x, finger.god.y, finger.god.z), (finger.xd, finger.yd, finger.zd)
        if finger.body >= 0 and last:
            spring = K * math.dist(proxy, dev)
            damper = B * math.dist(dev, last["device"]) / DT
            force = math.hypot(finger.fx, finger.fy, finger.fz)
            worst["excess"] = max(worst["excess"], force - (spring + damper))
            if last["contact"]:
                worst["jump"] = max(worst["jump"], math.dist(proxy, last["proxy"]))
            assert force <= spring + damper + 1e-9, (
                f"{name}: |F| = {force:.2f} N > spring {spring:.2f} N + damper bound {damper:.2f} N "
                f"at t = {loop.t:.3f} s, proxy moved {math.dist(proxy, last['proxy']) * 1e3:.1f} mm")
        last.update(proxy=proxy, device=dev, contact=finger.body >= 0)

    with ServoLoop(world, [finger], device, 1000.0, overrun_watchdog=False, handle_signals=False) as loop:
        loop.run(ticks, on_tick=check)
    print(f"{name}: largest proxy move in contact {worst['jump'] * 1e3:.1f} mm, |F| - bound at most "
          f"{worst['excess']:.2f} N")
    assert worst["jump"] >= JUMP, f"{name}: the proxy never jumped (largest move in contact {worst['jump']} m)"
