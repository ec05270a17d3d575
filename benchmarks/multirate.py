"""`softproxy bench multirate`: two rates, what they cost and what they change.

For the heavy `bin_pick` (60 free objects) and the light `two_finger_grasp`, lockstep runs on
the simulated device at haptic rates of 1, 4 and 10 kHz, each with MuJoCo at 100, 250 and
500 Hz and at one step per tick (one rate). Per run: the haptic tick's p50 / p99 (timed by the
compiled tick itself, `loop.stats`), over every tick and over the ticks between MuJoCo's
steps alone (what the haptic loop costs once MuJoCo runs elsewhere); the force sent to the
device, how much it changes from one tick to the next on the first tick after a MuJoCo step
("update" ticks) against the other ticks (p99 and max of |ΔF| over every finger); how far
a tracked body (the pushed box, the grasped box) strays from where a one-rate lockstep run at
MuJoCo's rate has it; and the trade: the RMS, over the run and every finger, of the difference between the force sent and
the force a one-rate lockstep run at 10 kHz sends at the same instant. Beside them, the cost
of one bare `mj_step` of each world at each physics step (from compiled code, on a copy of
the scene's start state). Then each haptic rate paced in real time, MuJoCo at 250 Hz and per
tick: deadline misses and overruns beside the pacer's alone around an empty tick. Prints a
table, writes multirate.json and multirate.png.
"""

from __future__ import annotations

import numpy as np

from .latency import _bare_step_ns, _empty_misses
from .report import Progress, figure, publish
from softproxy.compiled import native
from softproxy.run import build, open_device
from softproxy.scene import load_scene

SCENES = ("bin_pick", "two_finger_grasp")
HAPTIC_HZ = (1000.0, 4000.0, 10000.0)
PHYSICS_HZ = (100.0, 250.0, 500.0)
REFERENCE_HZ = 10000.0
"""The one-rate lockstep run every run's force is compared with (Hz)."""
TRACKED = {"bin_pick": "pushed", "two_finger_grasp": "box"}
"""The body whose trajectory a run compares with a one-rate run at MuJoCo's rate."""
QUICK_S = 1.0
"""Seconds of each run with --quick (the grasp's squeeze, the bin's first push)."""
PACED_PHYSICS_HZ = 250.0
"""MuJoCo's rate in the paced runs, beside one step per tick."""
QUICK_PACED_S = 0.5
STEPS_TIMED = 200


def _percentiles(values: np.ndarray) -> dict:
    if values.size == 0:
        return {"p50": None, "p99": None, "max": None}
    p50, p99 = np.percentile(values, [50, 99])
    return {"p50": round(float(p50), 4), "p99": round(float(p99), 4), "max": round(float(values.max()), 4)}


def step_cost_us(scene_name: str, physics_hz: float) -> dict:
    """p50 / p99 (µs) of a bare mj_step of the scene's world, from its start state, at a timestep
    of 1 / physics_hz: STEPS_TIMED steps on a copy, each timed from compiled code."""
    scene = load_scene(scene_name)
    model = scene.load_model()
    data = scene.start_data(model)
    model.opt.timestep = 1.0 / physics_hz
    m_at, d_at = native.addresses(model, data)
    _bare_step_ns(m_at, d_at)  # compiled outside the timing
    ns = np.array([_bare_step_ns(m_at, d_at) for _ in range(STEPS_TIMED)], dtype=float)
    return _percentiles(ns * 1e-3)


def run(scene_name: str, haptic_hz: float, physics_hz: float, seconds: float) -> dict:
    """One lockstep run: per tick the force sent to each finger's device (N), the tick durations
    (µs) and which ticks began or ended a MuJoCo step, and per MuJoCo step the position of the
    scene's TRACKED body (m); `physics_hz` equal to `haptic_hz` is one rate."""
    scene = load_scene(scene_name)
    loop = build(scene, open_device("sim", scene), rate_hz=haptic_hz, audit=False, realtime=False,
                 physics_rate_hz=physics_hz)
    ticks = int(round(seconds * loop.rate_hz))
    if ticks > loop.stats.capacity:
        raise ValueError(f"{seconds:g} s at {haptic_hz:g} Hz is more ticks than the loop's statistics keep "
                         f"({loop.stats.capacity}): ask for a shorter --duration")
    forces = np.empty((ticks, len(loop.fingers), 3))
    sent = loop.rows.data["sent_force"]
    body, xpos, state = loop.world.body_id(TRACKED[scene_name]), loop.world.data.xpos, loop.state[0]
    track = []

    def on_tick(lp):
        forces[lp.ticks - 1] = sent
        if state.phase == 0:  # MuJoCo has just taken a step
            track.append(xpos[body].copy())

    loop.run(ticks, on_tick=on_tick, every=1)
    every = loop.physics_every
    durations = loop.stats.durations() * 1e6
    loop.close()
    k = np.arange(ticks)
    stepping = (k % every == 0) | (k % every == every - 1)  # mj_step1 on a step's first tick, mj_step2 on its last
    return {"forces": forces, "tick_us": durations, "between_us": durations[~stepping], "every": every,
            "track": np.array(track)}


def paced(scene_name: str, haptic_hz: float, physics_hz: float, seconds: float) -> dict:
    """Deadline misses of a run paced in real time (ordinary scheduling, the overrun watchdog
    on: a tick over 3 periods makes the next render zero), then of the pacer alone around an
    empty tick for as long (`softproxy bench latency`'s)."""
    scene = load_scene(scene_name)
    loop = build(scene, open_device("sim", scene), rate_hz=haptic_hz, audit=False, physics_rate_hz=physics_hz)
    ticks = int(round(seconds * loop.rate_hz))
    loop.run(ticks, realtime=True)
    row = {"haptic_hz": haptic_hz, "physics_hz": physics_hz, "one_rate": physics_hz == haptic_hz, "ticks": loop.ticks,
           "misses": loop.stats.misses, "overruns": int(loop.faults["overrun"]), "tick_us": loop.stats.summary_us()}
    loop.close()
    row["pacer_alone_misses"] = _empty_misses(haptic_hz, ticks)
    return row


def compare(result: dict, reference: np.ndarray, haptic_hz: float, one_rate_track: np.ndarray | None) -> dict:
    """A run's figures: force jumps at updates and elsewhere, its force error (RMS, N) against
    the reference run's force at the same instants, and how far (mm) its tracked body strays
    from where a one-rate run at MuJoCo's rate has it, step by step (None: no such run)."""
    forces, every = result["forces"], result["every"]
    jump = np.linalg.norm(np.diff(forces, axis=0), axis=2)  # tick k-1 -> tick k, per finger
    updated = np.arange(1, len(forces)) % every == 0  # tick k the first against MuJoCo's new state
    # the reference's force at this run's instants (tick k renders at k / haptic_hz), linear
    # between its own ticks: 4 kHz falls between 10 kHz ticks every other tick
    t = np.arange(len(forces)) / haptic_hz
    t_ref = np.arange(len(reference)) / REFERENCE_HZ
    n = int(np.searchsorted(t, t_ref[-1], side="right"))
    flat = reference.reshape(len(reference), -1)
    at = np.stack([np.interp(t[:n], t_ref, flat[:, j]) for j in range(flat.shape[1])], axis=1)
    error = forces[:n] - at.reshape(n, *reference.shape[1:])
    return {
        "tick_us": _percentiles(result["tick_us"]),
        "between_steps_tick_us": _percentiles(result["between_us"]),
        "jump_at_updates_N": _percentiles(jump[updated].ravel()),
        "jump_elsewhere_N": _percentiles(jump[~updated].ravel()),
        "force_error_rms_N": round(float(np.sqrt(np.mean(np.sum(error ** 2, axis=2)))), 5),
        "force_rms_N": round(float(np.sqrt(np.mean(np.sum(reference ** 2, axis=2)))), 5),
        "track_vs_one_rate_mm": None if one_rate_track is None else
        round(float(np.linalg.norm(result["track"] - one_rate_track, axis=1).max()) * 1e3, 4),
    }


def measure(seconds: float, paced_s: float, scenes=SCENES, haptic=HAPTIC_HZ, physics=PHYSICS_HZ,
            progress=None) -> dict:
    """Every (scene, haptic rate, physics rate) run, the step costs and the figures (see the
    module docstring); `seconds` of each run (at most the scene's duration); then, `paced_s`
    long, each haptic rate paced in real time with MuJoCo at PACED_PHYSICS_HZ and per tick."""
    out = {"haptic_hz": list(haptic), "physics_hz": list(physics) + ["per tick"], "reference_hz": REFERENCE_HZ,
           "scenes": {}}
    for name in scenes:
        scene = load_scene(name)
        span = min(seconds, scene.duration_s)
        if progress is not None:
            progress(f"{name}: one rate at {REFERENCE_HZ:g} Hz")
        reference_run = run(name, REFERENCE_HZ, REFERENCE_HZ, span)
        reference = reference_run["forces"]
        one_rate = {}  # MuJoCo's rate -> the tracked body's trajectory in a one-rate run at that rate
        for p in physics:
            if progress is not None:
                progress(f"{name}: one rate at {p:g} Hz")
            one_rate[p] = run(name, p, p, span)["track"]
        rows = []
        for h in haptic:
            for p in list(physics) + [h]:
                if progress is not None:
                    progress(f"{name}: {h:g} Hz, MuJoCo at {p:g} Hz")
                r = reference_run if (h == REFERENCE_HZ and p == REFERENCE_HZ) else run(name, h, p, span)
                rows.append({"haptic_hz": h, "physics_hz": p, "one_rate": p == h,
                             **compare(r, reference, h, None if p == h else one_rate[p])})
        costs = {f"{p:g}": step_cost_us(name, p) for p in sorted({*physics, *haptic})}
        pacing = []
        for h in haptic:
            for p in (PACED_PHYSICS_HZ, h):
                if progress is not None:
                    progress(f"{name}: paced at {h:g} Hz, MuJoCo at {p:g} Hz")
                pacing.append(paced(name, h, p, min(paced_s, scene.duration_s)))
        out["scenes"][name] = {"seconds": span, "tracked": TRACKED[name], "mj_step_us": costs, "runs": rows,
                               "paced": pacing}
    return out


def chart(result: dict):
    """Per scene: the force error against the physics rate (one line per haptic rate), the tick
    p99 (every tick and between steps), and the largest jumps at updates against elsewhere."""
    names = list(result["scenes"])
    fig, axes = figure(len(names), 3, (15, 4 * len(names)), squeeze=False)
    for row, name in zip(axes, names):
        runs = result["scenes"][name]["runs"]
        err, cost, jumps = row
        for h in result["haptic_hz"]:
            mine = [r for r in runs if r["haptic_hz"] == h]
            x = [r["physics_hz"] for r in mine]
            label = f"{h / 1000:g} kHz haptic"
            # the reference run's own error (0) has no place on a log axis
            line, = err.plot(x, [r["force_error_rms_N"] or np.nan for r in mine], "o-", label=label)
            cost.plot(x, [r["tick_us"]["p99"] for r in mine], "o-", color=line.get_color(), label=f"{label}: every tick")
            cost.plot(x, [r["between_steps_tick_us"]["p99"] or np.nan for r in mine], "s--", color=line.get_color(),
                      label=f"{label}: between steps")
            jumps.plot(x, [r["jump_at_updates_N"]["max"] for r in mine], "o-", color=line.get_color(),
                       label=f"{label}: at updates")
            jumps.plot(x, [r["jump_elsewhere_N"]["max"] if r["jump_elsewhere_N"]["max"] is not None else np.nan
                           for r in mine], "s--", color=line.get_color(), label=f"{label}: elsewhere")
        step = result["scenes"][name]["mj_step_us"]
        for ax in row:
            ax.set_xscale("log")
            ax.set_xlabel("MuJoCo rate (Hz; the last point of a line: one step per tick)")
        err.set_yscale("log")
        err.set_ylabel(f"force error RMS (N) vs one rate at {result['reference_hz'] / 1000:g} kHz")
        err.set_title(f"{name}: the trade (mj_step {step['250']['p50']:.0f} µs at 4 ms)")
        cost.set_yscale("log")
        cost.set_ylabel("haptic tick p99 (µs), lockstep")
        cost.set_title(f"{name}: tick cost")
        jumps.axhline(0.2, color="k", ls=":", lw=1, label="0.2 N (issue target)")
        jumps.set_ylabel("largest |ΔF| from one tick to the next (N)")
        jumps.set_title(f"{name}: force jumps")
        for ax in row:
            ax.legend(fontsize=7)
    return fig


def print_report(result: dict) -> None:
    """What `softproxy bench multirate` prints: one table per scene."""
    print(f"multirate: lockstep runs; force error against one rate at {result['reference_hz']:g} Hz")
    for name, s in result["scenes"].items():
        costs = ", ".join(f"{k} Hz {v['p50']:.1f}" for k, v in s["mj_step_us"].items())
        print(f"\n{name} ({s['seconds']:g} s per run); bare mj_step p50 (µs) at each rate's step: {costs}")
        print(f"  {'haptic':>8s} {'MuJoCo':>9s} {'tick p50':>9s} {'p99':>8s} {'between p50':>12s} {'p99':>8s} "
              f"{'jump@upd p99':>13s} {'max':>7s} {'elsewhere p99':>14s} {'max':>7s} {'F err RMS':>10s} {'track mm':>9s}")
        for r in s["runs"]:
            t, b, u, e = r["tick_us"], r["between_steps_tick_us"], r["jump_at_updates_N"], r["jump_elsewhere_N"]
            mu = "per tick" if r["one_rate"] else f"{r['physics_hz']:g} Hz"
            track = f"{r['track_vs_one_rate_mm']:9.3f}" if r["track_vs_one_rate_mm"] is not None else f"{'-':>9s}"
            between = f"{b['p50']:12.2f} {b['p99']:8.2f}" if b["p99"] is not None else f"{'-':>12s} {'-':>8s}"
            elsewhere = (f"{e['p99']:14.4f} {e['max']:7.4f}" if e["p99"] is not None else f"{'-':>14s} {'-':>7s}")
            print(f"  {r['haptic_hz']:8g} {mu:>9s} {t['p50']:9.2f} {t['p99']:8.2f} {between} {u['p99']:13.4f} "
                  f"{u['max']:7.4f} {elsewhere} {r['force_error_rms_N']:10.5f} {track}")
        print(f"  (times in µs, forces in N; 'between': ticks that neither begin nor end a MuJoCo step; "
              f"the reference's force RMS {s['runs'][0]['force_rms_N']:.3f} N; track: the farthest "
              f"{s['tracked']!r} gets from a one-rate run at MuJoCo's rate)")
        for r in s["paced"]:
            mu = "per tick" if r["one_rate"] else f"at {r['physics_hz']:g} Hz"
            print(f"  paced at {r['haptic_hz']:g} Hz, MuJoCo {mu}: {r['misses']} of {r['ticks']} deadlines missed, "
                  f"{r['overruns']} overruns (zero force), tick p99 {r['tick_us']['p99']} µs; "
                  f"the pacer alone: {r['pacer_alone_misses']}")


def main(args) -> int:
    progress = Progress("multirate")
    quick = getattr(args, "quick", False)
    seconds = QUICK_S if quick else args.duration
    paced_s = QUICK_PACED_S if quick else (args.paced if args.paced is not None else seconds)
    result = measure(seconds, paced_s, progress=progress)
    progress.done()
    result["quick"] = bool(getattr(args, "quick", False))
    publish(args, "multirate", result, chart(result), print_report)
    return 0
