"""`softproxy bench tradeoff`: what each servo rate and fidelity level costs, and what it gets wrong.

Every configuration — servo rate 250 Hz → 10 kHz × fingertip model (point contact, CH, MH,
VS, LFM) — runs the same scripted device path on two scenes: `two_finger_grasp` (squeeze,
lift, hold: the soft fingers stick, so the models agree and only the rate matters) and
`knob` touched lightly, at 0.55 N, where the models' torsion limits (3.7–4.7 N·mm) straddle
the knob's 4 N·mm of hinge friction, so the model decides whether the knob turns. The
reference is the most faithful one, LFM (the model closest to all three sets of the
seed's measurements, seed 002 §6.5) at the highest rate. Against it each configuration
reports its cost per tick (p50, µs, and as a multiple of a bare mj_step timed in the same
run) and its errors: RMS of the rendered force and torque on finger 0 sampled every 4 ms
(N, N·mm), the object's final position (m) and orientation (deg), and the outcome (how far
the object turned about the scene's measured axis, deg). The chart shows cost against force error with the
Pareto front. Contact area, tactile image and contact sensing join the levels once the
tick can run them. Writes tradeoff.json and tradeoff.png.
"""

from __future__ import annotations

import json
import time

import mujoco
import numpy as np

from benchmarks.report import Progress, figure, save
from softproxy.run import _rotation_about, build, open_device
from softproxy.scene import load_scene

SCENE = "two_finger_grasp"  # the model whose bare mj_step is the unit of cost
SAMPLE_S = 0.004  # force sampled on a 250 Hz grid shared by every rate


def _light_knob_touch(scene) -> None:
    """0.55 N on the knob: near the models' torsion limits (3.7–4.7 N·mm vs 4 N·mm of hinge friction)."""
    for key in scene.device["finger"][0]["keyframes"][1:]:
        key[3] = 0.048 - 0.55 / scene.fingers[0].stiffness


SCENES = {"two_finger_grasp": None, "knob": _light_knob_touch}


def run_config(scene_name: str, model: str, rate: float, duration: float) -> dict:
    scene = load_scene(scene_name)
    if SCENES[scene_name] is not None:
        SCENES[scene_name](scene)
    loop = build(scene, open_device("sim", scene), rate_hz=rate, finger_model=model, audit=False, realtime=False)
    measure = scene.measure
    body = loop.world.body_id(measure.object)
    data = loop.world.data
    every = max(int(round(SAMPLE_S * rate)), 1)
    forces, q0 = [], None
    q_start = data.xquat[body].copy()  # used if the run ends before the measure's start
    finger = loop.fingers[0]
    for i in range(int(round(duration * rate))):
        loop.tick()
        if loop.ticks % every == 0:
            forces.append((finger.fx, finger.fy, finger.fz, finger.torque))
        if q0 is None and loop.t >= measure.start_s - 1e-9:
            q0 = data.xquat[body].copy()
    loop.stop()
    return {
        "scene": scene_name, "model": model, "rate_hz": rate, "tick_us_p50": loop.stats.summary_us()["p50"],
        "forces": np.array(forces), "position": data.xpos[body].copy(), "quat": data.xquat[body].copy(),
        "turned_deg": _rotation_about(q_start if q0 is None else q0, data.xquat[body], measure.axis),
        "axis": measure.axis,
    }


def bare_step_us(n: int = 3000) -> float:
    """p50 of a bare mj_step of the scene's model (the unit of cost)."""
    m = load_scene(SCENE).load_model()
    d = mujoco.MjData(m)
    times = np.empty(n)
    for i in range(n):
        t = time.perf_counter()
        mujoco.mj_step(m, d)
        times[i] = time.perf_counter() - t
    return float(np.median(times)) * 1e6


def pareto(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats on both cost and error."""
    front = []
    for i, (c, e) in enumerate(points):
        if not any((c2 <= c and e2 <= e) and (c2 < c or e2 < e) for c2, e2 in points):
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def measure(full: bool = False, progress=None, duration: float | None = None) -> dict:
    rates = [250.0, 500.0, 1000.0, 2000.0, 4000.0, 10000.0] if full else [250.0, 1000.0, 4000.0, 10000.0]
    models = ["point", "CH", "MH", "VS", "LFM"]
    duration = duration or (3.0 if full else 2.2)
    step_us = bare_step_us()
    rows = []
    total = len(SCENES) * len(rates) * len(models)
    for scene_name in SCENES:
        runs = []
        for rate in rates:
            for m in models:
                if progress:
                    progress(f"{scene_name}: {m} at {rate:g} Hz ({len(rows) + len(runs) + 1}/{total})")
                runs.append(run_config(scene_name, m, rate, duration))
                step_us = min(step_us, bare_step_us(500))  # re-measured as we go: the least-disturbed value
        ref = next(r for r in runs if r["model"] == "LFM" and r["rate_hz"] == max(rates))
        scene_rows = []
        for r in runs:
            n = min(len(r["forces"]), len(ref["forces"]))
            diff = r["forces"][:n] - ref["forces"][:n]
            scene_rows.append({
                "scene": scene_name, "model": r["model"], "rate_hz": r["rate_hz"], "tick_us_p50": r["tick_us_p50"],
                "force_rms_error_N": round(float(np.sqrt(np.mean(np.sum(diff[:, :3] ** 2, axis=1)))), 5),
                "torque_rms_error_Nmm": round(float(np.sqrt(np.mean(diff[:, 3] ** 2))) * 1e3, 4),
                "position_error_m": round(float(np.linalg.norm(r["position"] - ref["position"])), 7),
                "orientation_error_deg": round(abs(_rotation_about(ref["quat"], r["quat"], r["axis"])), 4),
                "turned_deg": round(r["turned_deg"], 4),
                "outcome_error_deg": round(abs(r["turned_deg"] - ref["turned_deg"]), 4),
            })
        front = pareto([(row["tick_us_p50"], row["force_rms_error_N"] + row["torque_rms_error_Nmm"] * 1e-3)
                        for row in scene_rows])
        for i, row in enumerate(scene_rows):
            row["pareto"] = i in front
        rows.extend(scene_rows)
    for row in rows:
        row["cost_x_mj_step"] = round(row["tick_us_p50"] / step_us, 2)
    return {"scenes": list(SCENES), "reference": {"model": "LFM", "rate_hz": max(rates)},
            "mj_step_us_p50": round(step_us, 2), "duration_s": duration, "rows": rows}


def chart(result: dict):
    """Per scene: cost against error with the Pareto front, and outcome error against rate."""
    scenes = result["scenes"]
    fig, axes = figure(2, len(scenes), (6 * len(scenes), 8.5), squeeze=False)
    for col, scene in enumerate(scenes):
        a, b = axes[0][col], axes[1][col]
        rows = [r for r in result["rows"] if r["scene"] == scene]
        for model in dict.fromkeys(r["model"] for r in rows):
            pts = [r for r in rows if r["model"] == model]
            err = [max(r["force_rms_error_N"] + r["torque_rms_error_Nmm"] * 1e-3, 1e-7) for r in pts]
            a.plot([r["cost_x_mj_step"] for r in pts], err, "o-", label=model)
            b.plot([r["rate_hz"] for r in pts], [r["outcome_error_deg"] for r in pts], "o-", label=model)
        front = sorted((r for r in rows if r["pareto"]), key=lambda r: r["cost_x_mj_step"])
        a.plot([r["cost_x_mj_step"] for r in front],
               [max(r["force_rms_error_N"] + r["torque_rms_error_Nmm"] * 1e-3, 1e-7) for r in front], "k--", lw=1,
               label="Pareto front")
        a.set_xlabel("cost per tick (× bare mj_step)")
        a.set_ylabel("RMS force (N) + torque (N·m) error")
        a.set_yscale("log")
        a.set_title(f"{scene}: speed vs accuracy (ref. LFM, highest rate)", fontsize=9)
        a.legend(fontsize=7)
        b.set_xscale("log")
        b.set_xlabel("servo rate (Hz)")
        b.set_ylabel("outcome error: object turn (deg)")
        b.legend(fontsize=7)
    return fig


def main(args) -> int:
    progress = Progress("tradeoff")
    result = measure(getattr(args, "full", False), progress, min(args.duration, 2.2))
    progress.done()
    json_path, png_path = save(args.out, "tradeoff", result, chart(result))
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print(f"tradeoff: reference LFM at {result['reference']['rate_hz']:g} Hz; bare mj_step p50 "
          f"{result['mj_step_us_p50']} µs (grasp scene model)")
    print(f"  {'scene':17s}{'model':6s}{'rate (Hz)':>10s}{'tick p50 (µs)':>15s}{'× mj_step':>11s}{'force RMS (N)':>15s}"
          f"{'torque RMS (N·mm)':>19s}{'pos err (m)':>13s}{'turned (°)':>12s}  pareto")
    for r in result["rows"]:
        print(f"  {r['scene']:17s}{r['model']:6s}{r['rate_hz']:10g}{r['tick_us_p50']:15.1f}{r['cost_x_mj_step']:11.2f}"
              f"{r['force_rms_error_N']:15.4f}{r['torque_rms_error_Nmm']:19.4f}{r['position_error_m']:13.2e}"
              f"{r['turned_deg']:12.3f}  {'*' if r['pareto'] else ''}")
    print(f"  wrote {json_path} and {png_path}")
    return 0
