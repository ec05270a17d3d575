"""What several test files share: a stepped clock, the box-on-a-floor world and a loop pressing
a finger into it, an open haptic
input report, a scripted device's do-nothing send and close, a hand held still, and a
world's kinetic energy after a nudge.

The test files import these by name (`from conftest import Clock`): pytest puts this folder
on the import path, as it does for the fakes beside it (`fake_dhd`, `mesh_oracle`).
"""

import struct

import mujoco
import numpy as np

BOX_ON_PLANE_XML = """<mujoco><option timestep="0.001"/><worldbody>
  <geom type="plane" size="1 1 .1"/>
  <body name="box" pos="0 0 0.03"><freejoint/><geom type="box" size=".03 .03 .03" mass="0.1"/></body>
</worldbody></mujoco>"""
"""A floor and a free 6 cm box resting on it (top face at z = 0.06 m), 1 ms steps."""


def box_loop(device):
    """A 1 kHz ServoLoop over BOX_ON_PLANE_XML with one finger on `device` (radius 8 mm, 1000 N/m,
    the CH fingertip), its overrun watchdog off: where the adapters' tests press a finger."""
    import mujoco

    from softproxy.finger import FingerParams, SoftFingerProxy
    from softproxy.fingertip import model
    from softproxy.servo import ServoLoop
    from softproxy.world import World

    world = World(mujoco.MjModel.from_xml_string(BOX_ON_PLANE_XML))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=1000.0), world.shapes, model("CH"))
    return ServoLoop(world, [finger], device, 1000.0, overrun_watchdog=False)


class Clock:
    """A device's clock, stepped by the test: `clock.now += dt` (s)."""

    def __init__(self, start: float = 100.0):
        self.now = start

    def __call__(self):
        return self.now


def oh_state(seq, status=0x01, x_um=0, y_um=0, z_um=0, twist_urad=0, buttons=0):
    """An open haptic input report (id 1): sequence, status bits, buttons, position (µm), twist (µrad)."""
    return bytes([1]) + struct.pack("<HBBiiii", seq & 0xFFFF, status, buttons, x_um, y_um, z_um, twist_urad)


class ScriptedDevice:
    """A device whose `read` the test writes; what the loop sends is dropped, closing is a no-op."""

    fingers, max_force, max_torque = 1, 10.0, 0.0

    def read(self, t, samples):
        raise NotImplementedError

    def send(self, finger, *wrench):
        pass

    def close(self):
        pass


class Holding(ScriptedDevice):
    """Fingers held still at given device positions (m), no twist: a hand that does not move."""

    max_force, max_torque = 40.0, 1.0

    def __init__(self, positions):
        self.positions = positions
        self.fingers = len(positions)

    def read(self, t, samples):
        for s, (x, y, z) in zip(samples, self.positions):
            s.x, s.y, s.z, s.twist, s.valid = x, y, z, 0.0, True


def kinetic_energy(world) -> float:
    """½ q̇ᵀ M q̇ of the whole world (J)."""
    m, d = world.model, world.data
    Mv = np.zeros(m.nv)
    mujoco.mj_mulM(m, d, Mv, d.qvel)
    return 0.5 * float(d.qvel @ Mv)


def nudged(world, loop, qvel, seconds):
    """Settle, stop every body, nudge (qvel), then tick for `seconds`: the kinetic energy after
    the nudge and at every tick after it (J)."""
    for _ in range(int(0.3 * loop.rate_hz)):
        loop.tick()
    world.data.qvel[:] = qvel
    start = kinetic_energy(world)
    energy = []
    for _ in range(int(seconds * loop.rate_hz)):
        loop.tick()
        energy.append(kinetic_energy(world))
    return start, np.array(energy)
