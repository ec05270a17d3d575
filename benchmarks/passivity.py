"""`softproxy bench passivity`: what the passivity controller costs in transparency, and what it buys.

Each case runs twice, controller on and off, with everything else the same (lockstep, so
both runs see the same inputs until their forces differ), and compares what the device was
sent tick by tick:

1. **grasp**: the shipped two-finger grasp (the scripted device): the grip force, the box's
   hold; a passive setting where the controller should do nothing.
2. **wall**: an omega.3's handle (`device_models`, integrated exactly under the held force)
   pulled onto a floor by a hand, tapped, at the default finger settings and at K = 1e4 N/m
   undamped, 1 kHz and 250 Hz: the force error, and the energy the wall gave the hand.
3. **light knob**: a 5 g hinged knob under a finger that presses and twists it: the force and
   torque error.

Force error: the RMS over the run of |F_on - F_off| (N, and N·m for the torque) and its
largest value, beside the RMS force of the run off. Energy to the hand: the work the rendered
force did on the handle over the run (J; > 0: the wall gave the hand energy it never put in).
Writes passivity.json and passivity.png.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from .device_models import PROFILES, Hand, HandHeldHandle
from .report import Progress, figure, publish
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.servo import ServoLoop
from softproxy.world import World

FLOOR = '<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/></worldbody></mujoco>'
KNOB = """<mujoco><worldbody><body name="knob" pos="0 0 0.01"><joint type="hinge" axis="0 0 1"/>
<geom type="cylinder" size="0.015 0.01" mass="0.005"/></body></worldbody></mujoco>"""
WALLS = [("default k 2000, b 5", 2000.0, 5.0), ("K 1e4, B 0", 1e4, 0.0)]
RATES = (1000.0, 250.0)


class Recorder:
    """Wraps a device: keeps every wrench it is sent, per tick (fingers × 6)."""

    def __init__(self, inner):
        self.inner = inner
        self.fingers, self.max_force, self.max_torque = inner.fingers, inner.max_force, inner.max_torque
        self.sent: list[list[float]] = []

    def read(self, t, samples):
        self.inner.read(t, samples)
        self.sent.append([0.0] * (6 * self.fingers))

    def send(self, finger, *w):
        self.sent[-1][6 * finger:6 * finger + 6] = w
        self.inner.send(finger, *w)

    def close(self):
        self.inner.close()


class Twisting:
    """One finger pressing 1 N on the knob's top and twisting 0.5 rad/s after 0.2 s."""

    fingers, max_force, max_torque = 1, 20.0, 0.5

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z = 0.0, 0.0, 0.028 - 1.0 / 2000.0
        s.twist, s.valid = 0.5 * max(0.0, t - 0.2), True

    def send(self, finger, *w):
        pass

    def close(self):
        pass


def _compare(on: np.ndarray, off: np.ndarray) -> dict:
    """Force and torque error between two runs' sends (ticks × fingers·6)."""
    n = min(len(on), len(off))
    on, off = on[:n].reshape(n, -1, 6), off[:n].reshape(n, -1, 6)
    df = np.linalg.norm(on[:, :, :3] - off[:, :, :3], axis=2)
    dt = np.linalg.norm(on[:, :, 3:] - off[:, :, 3:], axis=2)
    return {"force_rms_error_N": float(np.sqrt(np.mean(df ** 2))), "force_max_error_N": float(df.max()),
            "force_rms_N": float(np.sqrt(np.mean(np.linalg.norm(off[:, :, :3], axis=2) ** 2))),
            "torque_rms_error_Nm": float(np.sqrt(np.mean(dt ** 2))), "torque_max_error_Nm": float(dt.max())}


def grasp(passivity: bool) -> tuple[np.ndarray, dict]:
    scene = load_scene("two_finger_grasp")
    device = Recorder(open_device("sim", scene))
    with build(scene, device, realtime=False, passivity=passivity) as loop:
        ticks = int(scene.duration_s * loop.rate_hz)
        loop.run(ticks)
        acted = sum(f.pc_ticks for f in loop.fingers)
        owed = max(-f.energy_min for f in loop.fingers)
    return np.array(device.sent), {"controller_ticks": acted, "owed_max_J": owed}


def wall(passivity: bool, stiffness: float, damping: float, rate: float) -> tuple[np.ndarray, dict]:
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=stiffness, damping=damping, soft_start=0.0,
                                          max_force=200.0), world.shapes, model("point"))
    # the handle starts on the floor's surface: the proxy's centre one radius above it
    handle = HandHeldHandle(PROFILES["omega.3"], 1.0 / rate, Hand(), encoder=True, kick_s=0.3, kick_mps=-0.05,
                            start_m=0.008)
    device = Recorder(handle)
    with ServoLoop(world, [finger], device, rate, passivity=passivity) as loop:
        loop.run(int(1.0 * rate))
        info = {"controller_ticks": finger.pc_ticks, "owed_max_J": -finger.energy_min,
                "work_on_hand_J": handle.work}
    return np.array(device.sent), info


def knob(passivity: bool) -> tuple[np.ndarray, dict]:
    world = World(mujoco.MjModel.from_xml_string(KNOB))
    finger = SoftFingerProxy(FingerParams(radius=0.008, soft_start=0.0), world.shapes, model("CH"))
    device = Recorder(Twisting())
    with ServoLoop(world, [finger], device, 1000.0, passivity=passivity) as loop:
        loop.run(1000)
        info = {"controller_ticks": finger.pc_ticks, "owed_max_J": -finger.energy_min,
                "knob_turn_rad": float(world.data.qpos[0])}
    return np.array(device.sent), info


def measure(progress) -> dict:
    cases = [("grasp", "two_finger_grasp, 1 kHz", grasp, ())]
    for label, k, b in WALLS:
        for rate in RATES:
            cases.append(("wall", f"omega.3 on a wall, {label}, {rate:g} Hz", wall, (k, b, rate)))
    cases.append(("light knob", "5 g knob pressed and twisted, 1 kHz", knob, ()))
    rows = []
    for i, (kind, label, run, extra) in enumerate(cases):
        progress(f"{label} ({i + 1}/{len(cases)})")
        sent_on, on = run(True, *extra)
        sent_off, off = run(False, *extra)
        row = {"case": kind, "label": label, "on": on, "off": off, **_compare(sent_on, sent_off)}
        rows.append(row)
    return {"rows": rows}


def chart(result: dict):
    fig, ax = figure(1, 1, (9, 4))
    rows = result["rows"]
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["force_rms_N"] for r in rows], 0.4, label="RMS force, controller off (N)")
    ax.bar(x + 0.2, [r["force_rms_error_N"] for r in rows], 0.4, label="RMS force change, on vs off (N)")
    ax.set_xticks(x, [r["label"].replace(", ", "\n") for r in rows], fontsize=7)
    ax.set_yscale("symlog", linthresh=1e-3)
    ax.set_title("What the passivity controller changes in what the device is sent")
    ax.legend(fontsize=8)
    return fig


def main(args) -> int:
    progress = Progress("passivity")
    result = measure(progress)
    progress.done()
    publish(args, "passivity", result, chart(result), print_report)
    return 0


def print_report(result: dict) -> None:
    """What `softproxy bench passivity` prints: the result as a table."""
    print("the passivity controller's transparency cost: what the device is sent, controller on vs off")
    print(f"  {'case':48s}{'RMS F':>9s}{'RMS dF':>10s}{'max dF':>9s}{'RMS dM':>10s}{'ticks on':>9s}"
          f"{'hand J on':>11s}{'hand J off':>11s}")
    for r in result["rows"]:
        on, off = r["on"], r["off"]
        hand_on = on.get("work_on_hand_J", math.nan)
        hand_off = off.get("work_on_hand_J", math.nan)
        print(f"  {r['label']:48s}{r['force_rms_N']:9.3f}{r['force_rms_error_N']:10.4f}{r['force_max_error_N']:9.3f}"
              f"{r['torque_rms_error_Nm']:10.2e}{on['controller_ticks']:9d}{hand_on:11.4f}{hand_off:11.4f}")
    print("  (N and N·m; 'hand J': the work the wall's force did on the hand-held handle, > 0: energy the hand never "
          "put in)")
