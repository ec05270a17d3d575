"""Your own device behind softproxy's `Device` protocol: a finger pressing on a puck.

A device is any object with `fingers`, `max_force`, `max_torque`, `read(t, samples)`,
`send(finger, fx, fy, fz, tx, ty, tz)` and `close()`. Here it draws a circle on a puck and
prints what it would drive its motors with. Run: python examples/custom_device.py [seconds]
"""

import math
import sys

import mujoco

import softproxy

XML = """<mujoco><option gravity="0 0 -9.81"/><worldbody>
  <geom name="table" type="plane" size="0.5 0.5 0.01"/>
  <body name="puck" pos="0 0 0.01"><freejoint/><geom type="cylinder" size="0.03 0.01" mass="0.05"/></body>
</worldbody></mujoco>"""


class CircleDevice:
    """One finger drawing a 2 cm circle, sinking 2 mm into the puck over the first 0.5 s."""

    fingers, max_force, max_torque = 1, 10.0, 0.0  # N, N·m: this device renders no torque

    def __init__(self) -> None:
        self.last_force = (0.0, 0.0, 0.0)

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z = 0.02 * math.cos(t), 0.02 * math.sin(t), 0.028 - min(t, 0.5) * 0.004
        s.twist, s.valid = 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.last_force = (fx, fy, fz)  # drive your motors here (N)

    def close(self):
        self.last_force = (0.0, 0.0, 0.0)  # switch your motors off here


def main(seconds: float = 1.0) -> None:
    world = softproxy.World(mujoco.MjModel.from_xml_string(XML))
    finger = softproxy.SoftFingerProxy(softproxy.FingerParams(radius=0.008, stiffness=1000.0),
                                       world.shapes, softproxy.model("LFM"))
    device = CircleDevice()
    with softproxy.ServoLoop(world, [finger], device, rate_hz=1000.0) as loop:
        for _ in range(int(seconds * loop.rate_hz)):
            loop.tick()  # device -> proxy -> world -> device
        print(f"pressing with {finger.normal_force:.2f} N, proxy at z = {finger.god.z * 1e3:.2f} mm; "
              f"puck at {world.data.body('puck').xpos.round(4)}")
        print(f"force sent last tick: ({', '.join(f'{v:.2f}' for v in device.last_force)}) N; "
              f"faults: {sum(loop.faults.values())}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 1.0)
