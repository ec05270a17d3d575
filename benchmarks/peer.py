"""`softproxy bench peer`: the two-finger grasp as a MuJoCo user would build it without softproxy.

The peer: two 8 mm sphere fingers that can translate but not turn (three slide joints),
squeezing the box with a constant 3 N motor force and following the same scripted device
path in y and z through position servos (kp = 2000 N/m, kv = 5 N·s/m, the same coupling as
softproxy's fingers); MuJoCo's own soft-finger contact, `condim="4"` with a torsional
coefficient of 0.0118 m, so that its torsion limit at 3 N (0.0354 N·m) equals the CH
fingertip's (seed 002 Table 1). Run with an elliptic cone at impratio 10 and 100 and a
pyramidal cone, against softproxy with CH fingers and with point fingers, all in one run.

Reported: how far the box turns about the grasp axis after the squeeze and how fast it
creeps at the end (°/s), its height, the cost per tick; and, in zero gravity under a rising
external torque, the largest torque the two contacts transmit for grips of 0.5–8 N —
softproxy's limit grows as |P|^γ, MuJoCo's linearly — with the fitted exponent. Writes
peer.json and peer.png.
"""

from __future__ import annotations

import json
import math
import time

import mujoco
import numpy as np

from .report import Progress, figure, save
from softproxy.device import DeviceSample
from softproxy.run import _rotation_about, build, open_device
from softproxy.scene import load_scene

SCENE = "two_finger_grasp"
TORSION_COEFFICIENT = 0.0118  # m: MuJoCo's linear torsion coefficient matching CH at 3 N
GRIP_N = 3.0
AXIS = (1.0, 0.0, 0.0)
SQUEEZE_END_S = 0.8


def peer_xml(cone: str, impratio: float, gravity: bool = True) -> str:
    """The grasp scene rebuilt with MuJoCo fingers (condim 4) instead of softproxy proxies."""
    friction = f'condim="4" friction="1 {TORSION_COEFFICIENT} 0.0001"'
    bodies, actuators = "", ""
    for name, x in (("right", 0.06), ("left", -0.06)):
        bodies += (
            f'<body name="{name}" pos="{x} 0.02 0.03" gravcomp="1">'
            f'<joint name="{name}_x" type="slide" axis="1 0 0" damping="5"/>'
            f'<joint name="{name}_y" type="slide" axis="0 1 0"/><joint name="{name}_z" type="slide" axis="0 0 1"/>'
            f'<geom type="sphere" size="0.008" mass="0.01" {friction}/></body>'
        )
        actuators += (f'<motor joint="{name}_x"/><position joint="{name}_y" kp="2000" kv="5"/>'
                      f'<position joint="{name}_z" kp="2000" kv="5"/>')
    # without gravity the floor is out of play: no contact, so only the fingers hold the box
    g, floor = ("0 0 -9.81", "") if gravity else ("0 0 0", ' contype="0" conaffinity="0"')
    return (
        f'<mujoco><option timestep="0.001" cone="{cone}" impratio="{impratio}" integrator="implicitfast" gravity="{g}"/>'
        f'<worldbody><geom name="floor" type="plane" size=".4 .4 .01"{floor}/>'
        f'<body name="box" pos="0 0 0.03"><freejoint/><geom name="box" type="box" size="0.02 0.05 0.03" mass="0.1" {friction}/></body>'
        f"{bodies}</worldbody><actuator>{actuators}</actuator></mujoco>"
    )


def _grip_ramp(t: float, grip: float) -> float:
    return grip * min(max((t - 0.2) / 0.3, 0.0), 1.0)


def run_peer(cone: str, impratio: float, duration: float) -> dict:
    """The MuJoCo-only grasp: rotation trace (s, deg), height, mj_step cost."""
    scene = load_scene(SCENE)
    device = open_device("sim", scene)
    m = mujoco.MjModel.from_xml_string(peer_xml(cone, impratio))
    d = mujoco.MjData(m)
    box = m.body("box").id
    samples = [DeviceSample(), DeviceSample()]
    q0, trace, cost = None, [], []
    dt = m.opt.timestep
    for i in range(int(duration / dt)):
        t = i * dt
        device.read(t, samples)
        r, l = samples
        grip = _grip_ramp(t, GRIP_N)
        d.ctrl[:] = (-grip, r.y - 0.02, r.z - 0.03, grip, l.y - 0.02, l.z - 0.03)
        start = time.perf_counter()
        mujoco.mj_step(m, d)
        cost.append(time.perf_counter() - start)
        if q0 is None and t >= SQUEEZE_END_S:
            q0 = d.xquat[box].copy()
        if q0 is not None and i % 10 == 0:
            trace.append((t, _rotation_about(q0, d.xquat[box], AXIS), float(d.xpos[box][2])))
    return {"trace": trace, "tick_us_p50": float(np.median(cost)) * 1e6}


def run_softproxy(model: str, duration: float) -> dict:
    scene = load_scene(SCENE)
    loop = build(scene, open_device("sim", scene), finger_model=model, audit=False, realtime=False)
    body = loop.world.body_id("box")
    xquat, xpos = loop.world.data.xquat, loop.world.data.xpos
    state = {"q0": None, "trace": []}

    def on_tick(lp):
        t = lp.t
        if state["q0"] is None and t >= SQUEEZE_END_S:
            state["q0"] = xquat[body].copy()
        if state["q0"] is not None and lp.ticks % 10 == 0:
            state["trace"].append((t, _rotation_about(state["q0"], xquat[body], AXIS), float(xpos[body][2])))

    loop.run(int(duration * loop.rate_hz), on_tick=on_tick)
    return {"trace": state["trace"], "tick_us_p50": loop.stats.summary_us()["p50"]}


def summarise(trace: list) -> dict:
    t = np.array([p[0] for p in trace])
    a = np.array([p[1] for p in trace])
    last = t >= t[-1] - 2.0  # creep over the last 2 s
    creep = float(np.polyfit(t[last], a[last], 1)[0]) if last.sum() > 2 else 0.0
    return {"rotation_end_deg": round(float(a[-1]), 3), "rotation_max_deg": round(float(np.abs(a).max()), 3),
            "creep_deg_per_s": round(creep, 3), "height_end_m": round(trace[-1][2], 4)}


# ---------------------------------------------------------------------------------
# Torsion limit against grip: zero gravity, an external torque ramp about the grasp axis,
# and the largest torque the two contacts ever transmit (the limit, once they slip).
# A speed criterion would not do: MuJoCo's contact creeps at a speed that grows with the
# torque whatever the grip (a soft constraint), so "lets go" has no sharp meaning there.
# ---------------------------------------------------------------------------------
TORQUE_RATE = 0.1  # N·m/s
SPUN_OUT = math.radians(200.0)  # rad/s: the box spins freely, stop the ramp


def _peak_torque(step, transmitted, spin, apply_torque, t_start: float, limit_s: float, dt: float) -> float:
    """Ramp an external torque from t_start; the peak torque the contacts transmitted (N·m)."""
    t, peak = 0.0, 0.0
    while t < t_start + limit_s:
        apply_torque(max(t - t_start, 0.0) * TORQUE_RATE)
        step(t)
        peak = max(peak, transmitted())
        if abs(spin()) > SPUN_OUT:
            break
        t += dt
    return peak


def _zero_gravity_grasp_keyframes(scene, grip: float) -> None:
    f0 = scene.fingers[0]
    depth = grip / f0.stiffness
    for finger in scene.device["finger"]:
        sign = 1.0 if finger["keyframes"][0][1] > 0 else -1.0
        x = sign * (0.02 + f0.radius - depth)
        finger["keyframes"] = [[0.0, sign * 0.06, 0.02, 0.03, 0.0], [0.5, x, 0.02, 0.03, 0.0]]


def peak_torque_softproxy(grip: float) -> float:
    scene = load_scene(SCENE)
    _zero_gravity_grasp_keyframes(scene, grip)
    loop = build(scene, open_device("sim", scene), audit=False, realtime=False)
    world = loop.world
    world.model.opt.gravity[:] = 0.0
    floor = world.model.geom("floor").id
    world.model.geom_contype[floor] = world.model.geom_conaffinity[floor] = 0  # only the fingers hold it
    box = world.body_id("box")
    dof = world.model.body_dofadr[box] + 3  # the free joint's rotation about the box's x axis
    qfrc, qvel = world.data.qfrc_applied, world.data.qvel
    fingers = loop.fingers

    def apply(torque):
        qfrc[dof] = torque

    return _peak_torque(lambda t: loop.tick(), lambda: sum(abs(f.torque) for f in fingers),
                        lambda: qvel[dof], apply, 0.8, 10.0, loop.period)


def peak_torque_mujoco(grip: float, cone: str = "elliptic", impratio: float = 100.0) -> float:
    m = mujoco.MjModel.from_xml_string(peer_xml(cone, impratio, gravity=False))
    d = mujoco.MjData(m)
    box = m.body("box").id
    dof = m.body_dofadr[box] + 3
    force = np.zeros(6)

    def step(t):
        g = _grip_ramp(t, grip)
        d.ctrl[:] = (-g, 0.0, 0.0, g, 0.0, 0.0)
        mujoco.mj_step(m, d)

    def transmitted():
        total = 0.0
        for c in range(d.ncon):
            mujoco.mj_contactForce(m, d, c, force)
            total += abs(force[3])  # the torsional component, about the contact normal
        return total

    def apply(torque):
        d.qfrc_applied[dof] = torque

    return _peak_torque(step, transmitted, lambda: d.qvel[dof], apply, 0.8, 10.0, m.opt.timestep)


def measure(duration: float = 8.0, grips=(0.5, 1.0, 2.0, 4.0, 8.0), progress=None) -> dict:
    runs = {
        "softproxy CH": lambda: run_softproxy("CH", duration),
        "softproxy point": lambda: run_softproxy("point", duration),
        "mujoco elliptic impratio 10": lambda: run_peer("elliptic", 10.0, duration),
        "mujoco elliptic impratio 100": lambda: run_peer("elliptic", 100.0, duration),
        "mujoco pyramidal impratio 10": lambda: run_peer("pyramidal", 10.0, duration),
    }
    out = {"duration_s": duration, "grip_N": GRIP_N, "hold": {}, "traces": {}}
    for i, (name, fn) in enumerate(runs.items()):
        if progress:
            progress(f"grasp {i + 1}/{len(runs)}: {name}")
        r = fn()
        out["hold"][name] = {**summarise(r["trace"]), "tick_us_p50": round(r["tick_us_p50"], 2)}
        out["traces"][name] = r["trace"]
    limits = {"softproxy CH": [], "mujoco elliptic impratio 100": []}
    for j, grip in enumerate(grips):
        if progress:
            progress(f"torsion limit {j + 1}/{len(grips)}: grip {grip} N")
        limits["softproxy CH"].append(peak_torque_softproxy(grip))
        limits["mujoco elliptic impratio 100"].append(peak_torque_mujoco(grip))
    out["slip_torque_Nm"] = {"grip_N": list(grips), **{k: [round(v, 5) for v in vals] for k, vals in limits.items()}}
    out["slip_torque_exponent"] = {
        k: round(float(np.polyfit(np.log(grips), np.log(vals), 1)[0]), 3) for k, vals in limits.items()
        if all(v > 0 for v in vals)
    }
    return out


def chart(result: dict):
    """Box rotation over the hold for every configuration, and torsion limit against grip."""
    fig, (a, b) = figure(1, 2, (12, 4.5))
    for name, trace in result["traces"].items():
        a.plot([p[0] for p in trace], [p[1] for p in trace], label=name)
    a.set_xlabel("time (s)")
    a.set_ylabel("box rotation about the grasp axis (deg)")
    a.set_title("grasp hold: 0.1 kg box, 3 N per finger, 2 cm off the centre of mass")
    a.legend(fontsize=8)
    st = result["slip_torque_Nm"]
    for name in ("softproxy CH", "mujoco elliptic impratio 100"):
        exp = result["slip_torque_exponent"].get(name)
        b.loglog(st["grip_N"], st[name], "o-", label=f"{name} (exponent {exp})")
    b.set_xlabel("grip per finger (N)")
    b.set_ylabel("largest torque transmitted (N·m)")
    b.set_title("torsion limit vs grip")
    b.legend(fontsize=8)
    return fig


def main(args) -> int:
    duration = 20.0 if getattr(args, "full", False) else min(args.duration * 2, 20.0)
    progress = Progress("peer")
    result = measure(duration, progress=progress)
    progress.done()
    json_path, png_path = save(args.out, "peer", result, chart(result))
    if args.json:
        print(json.dumps({k: v for k, v in result.items() if k != "traces"}, indent=2))
        return 0
    print(f"peer: two-finger grasp held {result['duration_s']:g} s (box 0.1 kg, 3 N per finger, 2 cm off the CoM)")
    print(f"  {'':32s}{'turned (deg)':>13s}{'max (deg)':>11s}{'creep (deg/s)':>15s}{'height (m)':>12s}{'tick p50 (us)':>15s}")
    for name, h in result["hold"].items():
        print(f"  {name:32s}{h['rotation_end_deg']:13.3f}{h['rotation_max_deg']:11.3f}{h['creep_deg_per_s']:15.3f}"
              f"{h['height_end_m']:12.4f}{h['tick_us_p50']:15.2f}")
    st = result["slip_torque_Nm"]
    print("  largest torque the two contacts transmit (N·m), zero gravity, rising torque:")
    print("  " + f"{'grip (N)':32s}" + "".join(f"{g:>10g}" for g in st["grip_N"]) + "   exponent")
    for name in ("softproxy CH", "mujoco elliptic impratio 100"):
        print("  " + f"{name:32s}" + "".join(f"{v:10.4f}" for v in st[name])
              + f"   {result['slip_torque_exponent'].get(name)}")
    print(f"  wrote {json_path} and {png_path}")
    return 0
