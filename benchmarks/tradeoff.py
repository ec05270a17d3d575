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
Pareto front.

The fingertip sensors (softproxy.fingertip_sensors) are measured on the grasp at 1 kHz (CH):
both off (twice: the second is the noise floor of the comparison), the tactile image on both
fingers at 100 Hz, contact sensing on both at 100 Hz and at 1 kHz, and both at 100 Hz. The
configurations run side by side, one tick of each in turn, and only their ticks from first
contact on are counted; each reports tick p50 / mean / p99 as a ratio to "off" in the same run (the
mean carries a decimated channel's cost, the p99 its working ticks), the cost of one frame
(µs: the mean tick's excess over "off" spread over the frames) and what it measured (sensing location error, tactile force). The cost of "off" itself is
one loop over an empty list, timed alone. Writes tradeoff.json and tradeoff.png.

Each configuration of the grid is one cell of `softproxy.cells` (serial by default, a pool with
`--workers N`, Ray with `--ray [ADDRESS]`), which also re-measures the bare mj_step where it
ran; the errors are the same whichever backend ran them. The fingertip sensors are compared
side by side, so they run in this process.
"""

from __future__ import annotations

import time
import timeit

import mujoco
import numpy as np

from .report import Progress, figure, publish
from softproxy.cells import Backend, run_cells
from softproxy.fingertip_sensors import SensingSpec, TactileSpec
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
        "mj_step_us": bare_step_us(500),  # the unit of cost, re-measured in the process that ran the config
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


def pareto(points: list[tuple[float, ...]]) -> list[int]:
    """Indices of the points no other point beats: at least as good on every criterion (cost
    first, then errors, each in its own unit) and better on one; sorted by cost."""
    front = []
    for i, p in enumerate(points):
        if not any(all(a <= b for a, b in zip(q, p)) and q != p for q in points):
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


FIDELITY = {  # name: (tactile spec, sensing spec) on both fingers of the grasp
    "off": (None, None),
    "off (again)": (None, None),
    "tactile 100 Hz": (TactileSpec(rate_hz=100.0), None),
    "sensing 100 Hz": (None, SensingSpec(rate_hz=100.0)),
    "sensing 1 kHz": (None, SensingSpec(rate_hz=1000.0)),
    "tactile + sensing 100 Hz": (TactileSpec(rate_hz=100.0), SensingSpec(rate_hz=100.0)),
}
FIDELITY_RATE = 1000.0
CONTACT_S = 0.5  # the grasp's fingers touch the box at ~0.48 s: ticks before are not counted


def fidelity_loop(name: str):
    """The grasp at 1 kHz (CH) with the fingertip sensors of FIDELITY[name] on both fingers."""
    tactile, sensing = FIDELITY[name]
    scene = load_scene(SCENE)
    scene.tactile = [tactile] * len(scene.fingers)
    scene.sensing = [sensing] * len(scene.fingers)
    return build(scene, open_device("sim", scene), rate_hz=FIDELITY_RATE, finger_model="CH", audit=False,
                 realtime=False)


def measure_fidelity(duration: float, rounds: int = 2, progress=None) -> dict:
    """Tick cost of the fingertip sensors on the grasp, as ratios to both off in the same run.

    Every round builds one loop per configuration and ticks them in turn, one tick each, so a
    slow spell of the machine lands on all of them alike.
    """
    ticks = int(round(duration * FIDELITY_RATE))
    skip = int(CONTACT_S * FIDELITY_RATE)
    runs = {name: [] for name in FIDELITY}
    for r in range(rounds):
        if progress:
            progress(f"fingertip sensors: {len(FIDELITY)} configurations side by side, round {r + 1}/{rounds}")
        loops = {name: fidelity_loop(name) for name in FIDELITY}
        order = list(loops.values())
        for i in range(ticks):
            for lp in (order if i % 2 else order[::-1]):  # neither first nor last always
                lp.tick()
        for name, lp in loops.items():
            lp.stop()
            runs[name].append({"durations": lp.stats.durations()[skip:], "frames": sum(ch.frames for ch in lp.sensors),
                               "summaries": [ch.summary() for ch in lp.sensors]})
    stats = {}
    for name, rs in runs.items():
        d = np.concatenate([x["durations"] for x in rs])
        stats[name] = {"p50": float(np.median(d)), "mean": float(d.mean()), "p99": float(np.percentile(d, 99)),
                       "ticks": int(d.size), "frames": sum(x["frames"] for x in rs), "runs": rs}
    off = stats["off"]
    rows = []
    for name, st in stats.items():
        last = st["runs"][-1]["summaries"]
        sensing = [s for s in last if "sensed" in s]
        tactile = [s for s in last if "last_total_force_N" in s]
        # µs of channel work per frame: the mean tick's excess over "off", spread over the frames
        per_frame = ((st["mean"] - off["mean"]) * st["ticks"] / st["frames"] * 1e6) if st["frames"] else None
        rows.append({
            "config": name, "tick_us_p50": round(st["p50"] * 1e6, 2), "tick_us_mean": round(st["mean"] * 1e6, 2),
            "tick_us_p99": round(st["p99"] * 1e6, 2), "p50_x_off": round(st["p50"] / off["p50"], 3),
            "mean_x_off": round(st["mean"] / off["mean"], 3), "p99_x_off": round(st["p99"] / off["p99"], 3),
            "frames": st["frames"], "us_per_frame": None if per_frame is None else round(per_frame, 1),
            "sensing_location_max_m": max((s["error"]["location_max_m"] or 0.0) for s in sensing) if sensing else None,
            "sensing_refused": sum(s["refused"] for s in sensing) if sensing else None,
            "tactile_last_force_N": [s["last_total_force_N"] for s in tactile] if tactile else None,
        })
    n = 200_000  # the servo's `for ch in self.sensors: ch.tick(self)` on an empty list, less timeit's own loop
    empty = min(timeit.repeat("for ch in sensors:\n    ch.tick(loop)", setup="sensors = []; loop = None",
                              number=n, repeat=5))
    bare = min(timeit.repeat("pass", number=n, repeat=5))
    empty_ns = max(empty - bare, 0.0) / n * 1e9
    return {"scene": SCENE, "rate_hz": FIDELITY_RATE, "model": "CH", "duration_s": duration, "rounds": rounds,
            "counted_from_s": CONTACT_S, "empty_sensor_list_ns": round(empty_ns, 1), "rows": rows}


def measure(full: bool = False, progress=None, duration: float | None = None, backend: Backend = Backend()) -> dict:
    """The scene × rate × model grid, each configuration one cell of `softproxy.cells` run on
    `backend` (the errors are the same whichever ran them; the costs are timings), then the
    fingertip sensors side by side in this process. A configuration that fails is listed in
    "failed" with its parameters; a scene whose reference failed has no rows."""
    rates = [250.0, 500.0, 1000.0, 2000.0, 4000.0, 10000.0] if full else [250.0, 1000.0, 4000.0, 10000.0]
    models = ["point", "CH", "MH", "VS", "LFM"]
    duration = duration or (3.0 if full else 2.2)
    step_us = bare_step_us()
    cells = [{"scene_name": scene_name, "model": m, "rate": rate, "duration": duration}
             for scene_name in SCENES for rate in rates for m in models]

    def report(done: int, total: int, outcome) -> None:
        if progress:
            p = outcome.params
            progress(f"{p['scene_name']}: {p['model']} at {p['rate']:g} Hz done ({done}/{total}), {backend.describe()}")

    outcomes = run_cells(run_config, cells, backend, report)
    failed = [{"cell": o.params, "error": o.error} for o in outcomes if not o.ok]
    rows = []
    for scene_name in SCENES:
        runs = [o.value for o in outcomes if o.ok and o.params["scene_name"] == scene_name]
        step_us = min([step_us] + [r["mj_step_us"] for r in runs])  # the least-disturbed value
        ref = next((r for r in runs if r["model"] == "LFM" and r["rate_hz"] == max(rates)), None)
        if ref is None:
            continue
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
        front = pareto([(row["tick_us_p50"], row["force_rms_error_N"], row["torque_rms_error_Nmm"])
                        for row in scene_rows])
        for i, row in enumerate(scene_rows):
            row["pareto"] = i in front
        rows.extend(scene_rows)
    for row in rows:
        row["cost_x_mj_step"] = round(row["tick_us_p50"] / step_us, 2)
    fidelity = measure_fidelity(duration, 3 if full else 2, progress)
    return {"scenes": list(SCENES), "reference": {"model": "LFM", "rate_hz": max(rates)},
            "mj_step_us_p50": round(step_us, 2), "duration_s": duration, "rows": rows,
            "fingertip_sensors": fidelity, "failed": failed}


def chart(result: dict):
    """Per scene: cost against error with the Pareto front, and outcome error against rate."""
    scenes = result["scenes"]
    fig, axes = figure(4, len(scenes), (6 * len(scenes), 16.5), squeeze=False)
    fid = result.get("fingertip_sensors")
    for col, key in enumerate(("mean_x_off", "p99_x_off")[:len(scenes)]):
        c = axes[3][col]
        if not fid:
            c.set_axis_off()
            continue
        names = [r["config"] for r in fid["rows"]]
        c.barh(names, [r[key] for r in fid["rows"]])
        c.axvline(1.0, color="k", lw=0.8)
        c.set_xlabel(f"tick {key.split('_')[0]} ÷ sensors off (same run)")
        c.set_title(f"fingertip sensors on the grasp at {fid['rate_hz']:g} Hz", fontsize=9)
        c.tick_params(labelsize=7)
    for col in range(2, len(scenes)):
        axes[3][col].set_axis_off()
    for col, scene in enumerate(scenes):
        a, t, b = axes[0][col], axes[1][col], axes[2][col]
        rows = [r for r in result["rows"] if r["scene"] == scene]
        front = [r for r in rows if r["pareto"]]
        for ax, key, unit in ((a, "force_rms_error_N", "force RMS error (N)"),
                              (t, "torque_rms_error_Nmm", "torque RMS error (N·mm)")):
            for model in dict.fromkeys(r["model"] for r in rows):
                pts = [r for r in rows if r["model"] == model]
                ax.plot([r["cost_x_mj_step"] for r in pts], [max(r[key], 1e-7) for r in pts], "o-", label=model)
            ax.plot([r["cost_x_mj_step"] for r in front], [max(r[key], 1e-7) for r in front], "ks", mfc="none",
                    ms=9, label="Pareto front (cost, force, torque)")
            ax.set_xlabel("cost per tick (× bare mj_step)")
            ax.set_ylabel(unit)
            ax.set_yscale("log")
            ax.legend(fontsize=7)
        a.set_title(f"{scene}: speed vs accuracy (ref. LFM, highest rate)", fontsize=9)
        for model in dict.fromkeys(r["model"] for r in rows):
            pts = [r for r in rows if r["model"] == model]
            b.plot([r["rate_hz"] for r in pts], [r["outcome_error_deg"] for r in pts], "o-", label=model)
        b.set_xscale("log")
        b.set_xlabel("servo rate (Hz)")
        b.set_ylabel("outcome error: object turn (deg)")
        b.legend(fontsize=7)
    return fig


def main(args) -> int:
    progress = Progress("tradeoff")
    result = measure(getattr(args, "full", False), progress, min(args.duration, 2.2),
                     getattr(args, "backend", None) or Backend())
    progress.done()
    publish(args, "tradeoff", result, chart(result), print_report)
    return 0 if args.json or not result["failed"] else 1


def print_report(result: dict) -> None:
    """What `softproxy bench tradeoff` prints: the result as a table."""
    print(f"tradeoff: reference LFM at {result['reference']['rate_hz']:g} Hz; bare mj_step p50 "
          f"{result['mj_step_us_p50']} µs (grasp scene model)")
    print(f"  {'scene':17s}{'model':6s}{'rate (Hz)':>10s}{'tick p50 (µs)':>15s}{'× mj_step':>11s}{'force RMS (N)':>15s}"
          f"{'torque RMS (N·mm)':>19s}{'pos err (m)':>13s}{'turned (°)':>12s}  pareto")
    for r in result["rows"]:
        print(f"  {r['scene']:17s}{r['model']:6s}{r['rate_hz']:10g}{r['tick_us_p50']:15.1f}{r['cost_x_mj_step']:11.2f}"
              f"{r['force_rms_error_N']:15.4f}{r['torque_rms_error_Nmm']:19.4f}{r['position_error_m']:13.2e}"
              f"{r['turned_deg']:12.3f}  {'*' if r['pareto'] else ''}")
    fid = result["fingertip_sensors"]
    print(f"fingertip sensors on {fid['scene']} at {fid['rate_hz']:g} Hz ({fid['model']}, both fingers, ticks from "
          f"{fid['counted_from_s']} s, {fid['rounds']} rounds side by side); sensors off cost one loop over an "
          f"empty list: {fid['empty_sensor_list_ns']} ns")
    print(f"  {'config':26s}{'p50 (µs)':>10s}{'mean (µs)':>11s}{'p99 (µs)':>10s}{'p50 ×off':>10s}{'mean ×off':>11s}"
          f"{'p99 ×off':>10s}{'frames':>8s}{'µs/frame':>10s}  measured")
    for r in fid["rows"]:
        got = []
        if r["sensing_location_max_m"] is not None:
            got.append(f"location err ≤ {r['sensing_location_max_m']:.1e} m, refused {r['sensing_refused']}")
        if r["tactile_last_force_N"] is not None:
            got.append("tactile F " + ", ".join(f"{v:.3f}" for v in r["tactile_last_force_N"]) + " N")
        pf = "-" if r["us_per_frame"] is None else f"{r['us_per_frame']:.1f}"
        print(f"  {r['config']:26s}{r['tick_us_p50']:10.1f}{r['tick_us_mean']:11.1f}{r['tick_us_p99']:10.1f}"
              f"{r['p50_x_off']:10.3f}{r['mean_x_off']:11.3f}{r['p99_x_off']:10.3f}{r['frames']:8d}{pf:>10s}  "
              f"{'; '.join(got)}")
    for f in result["failed"]:
        print(f"  FAILED cell {f['cell']}: {f['error']}")
