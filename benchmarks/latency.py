"""`softproxy bench latency`: the full servo tick against a bare mj_step of the same scene.

Two soft fingers hold the box of `two_finger_grasp` (device read + two god-objects +
torsion + coupling + sends + MuJoCo), with the simulated device run compiled, as
`softproxy run` runs it. Each tick is timed by the compiled tick itself (CLOCK_MONOTONIC,
its stages too: `softproxy.compiled.servo.STAGES`), and after each tick a bare `mj_step` is
timed the same way, from compiled code, on a copy of the very same MuJoCo state, so the
ratio compares like with like on a shared, noisy machine. Paced runs at the scene's rate and
at 10 kHz, with ordinary scheduling and, asked for with `--realtime`, with real-time
scheduling (SCHED_FIFO on a CPU of its own, where the OS grants it: never by default, since a
busy loop at priority 80 starves the machine's other work), give the deadline-miss rates; each is followed by the pacer alone
(the same sleep-and-spin and miss count around an empty tick) for as long, under the same
scheduling, so a miss rate can be read against what the machine gives a loop that does
nothing. Prints a table, writes latency.json and latency.png.
"""

from __future__ import annotations

import os

import mujoco
import numpy as np
from numba import njit

from .report import Progress, figure, publish
from softproxy.compiled import native
from softproxy.compiled.servo import LOOP, STAGES, pace, paced_done
from softproxy.run import build, open_device
from softproxy.scheduling import DEFAULT_PRIORITY, realtime_thread, spin_time
from softproxy.scene import load_scene


@njit(nogil=True)  # not cached: numba's cache would not see a change in native (compiles in a second)
def _bare_step_ns(m, d):
    """One mj_step of the mjData at `d`, timed from compiled code (ns)."""
    start = native.monotonic_ns()
    native.mj_step(m, d)
    return native.monotonic_ns() - start


def _percentiles(us: np.ndarray) -> dict:
    return {"p50": round(float(np.percentile(us, 50)), 2), "p99": round(float(np.percentile(us, 99)), 2),
            "max": round(float(us.max()), 2)}


@njit(nogil=True)  # not cached, like _bare_step_ns
def _pacer_alone(loop, counters, n):
    """n paced ticks that do nothing: the servo loop's own pacing and miss count (`pace`,
    `paced_done`) around an empty tick."""
    for _ in range(n):
        pace(loop)
        paced_done(loop, counters)


def _empty_misses(rate_hz: float, ticks: int) -> int:
    """Deadline misses of `ticks` empty ticks paced at `rate_hz` in the calling thread, spinning
    as a servo loop in this thread would (`spin_time`)."""
    loop = np.zeros(1, dtype=LOOP)
    loop["period_ns"] = int(round(1e9 / rate_hz))
    loop["spin_ns"] = int(spin_time(rate_hz) * 1e9)
    counters = np.zeros(2, dtype=np.int64)
    _pacer_alone(loop, counters, 10)  # compiled outside the count
    counters[:] = 0
    loop["next_ns"] = native.monotonic_ns()
    _pacer_alone(loop, counters, ticks)
    return int(counters[1])


def _paced(scene, seconds: float, rate_hz: float, fifo: bool = False) -> dict:
    """Deadline misses of a loop paced in real time at `rate_hz`, then of the pacer alone for as
    long; with `fifo`, the thread under SCHED_FIFO pinned to the last CPU
    (`softproxy.scheduling`) where the OS grants it."""
    paced = build(scene, open_device("sim", scene), rate_hz=rate_hz, audit=False)
    cpu = max(os.sched_getaffinity(0)) if fifo and hasattr(os, "sched_getaffinity") else None
    ticks = int(seconds * paced.rate_hz)
    with realtime_thread(DEFAULT_PRIORITY if fifo else None, cpu) as granted:
        paced.run(ticks, realtime=True)
        empty = _empty_misses(paced.rate_hz, ticks)
    paced.close()
    return {"rate_hz": rate_hz, "scheduling": str(granted), "ticks": paced.ticks, "misses": paced.stats.misses,
            "miss_rate": paced.stats.misses / max(paced.ticks, 1), "tick_us": paced.stats.summary_us(),
            "pacer_alone_misses": empty, "pacer_alone_miss_rate": empty / max(ticks, 1)}


def _timed_pass(loop, ticks: int, progress):
    """`ticks` ticks of `loop`, each timed by the tick itself with its stages, then a bare
    mj_step on a copy of its state: (tick µs, mj_step µs, stages µs: ticks × stages)."""
    tick_us, step_us, stage_us = np.empty(ticks), np.empty(ticks), np.empty((ticks, len(STAGES)))
    m, d = loop.world.model, loop.world.data
    scratch = mujoco.MjData(m)
    m_at, scratch_at = native.addresses(m, scratch)
    stats, state = loop.stats, loop.state[0]
    state.profile = True
    try:
        for i in range(ticks):
            loop.tick()
            tick_us[i] = stats.duration[(stats.count - 1) % stats.capacity] * 1e6
            stage_us[i] = state.stage_ns * 1e-3
            mujoco.mj_copyData(scratch, m, d)
            step_us[i] = _bare_step_ns(m_at, scratch_at) * 1e-3
            if progress is not None and i % 500 == 0:
                progress(i / ticks)
    finally:
        state.profile = False
    return tick_us, step_us, stage_us


def measure(duration_s: float = 5.0, paced_s: float = 5.0, scene_name: str = "two_finger_grasp",
            progress=None, realtime: bool = False) -> dict:
    """Run the benchmark and return the result dict (times in µs): each tick followed by a
    bare `mj_step` of the same state, in one process, then the paced runs (with `realtime`,
    each also under SCHED_FIFO)."""
    scene = load_scene(scene_name)
    loop = build(scene, open_device("sim", scene), audit=False, realtime=False)
    if not loop.compiled_block:
        raise RuntimeError("bench latency times the compiled tick; it cannot run under NUMBA_DISABLE_JIT=1")
    ticks = int(duration_s * loop.rate_hz)
    warm = min(int(1.0 * loop.rate_hz), ticks // 4)  # squeeze and lift first: time the hold
    loop.run(warm)
    spare = mujoco.MjData(loop.world.model)  # kept alive while its address is in use
    _bare_step_ns(*native.addresses(loop.world.model, spare))  # compile it now, outside the timed pass
    tick_us, step_us, stage_us = _timed_pass(loop, ticks, progress)
    loop.close()
    tick = _percentiles(tick_us)
    step = _percentiles(step_us)
    return {
        "scene": scene_name,
        "fingers": len(loop.fingers),
        "rate_hz": loop.rate_hz,
        "ticks_timed": ticks,
        "tick_us": tick,
        "mj_step_us": step,
        "ratio_p50": round(tick["p50"] / step["p50"], 2),
        "stages_us_p50": {name: round(float(np.median(stage_us[:, k])), 2) for k, name in enumerate(STAGES)},
        # ordinary and real-time scheduling interleaved, so both see the same machine
        "paced": [_paced(scene, paced_s, rate, fifo) for rate in (loop.rate_hz, 10_000.0)
                  for fifo in ((False, True) if realtime else (False,))],
        "realtime": realtime,
        "targets": {"ratio_p50": 2.0, "tick_p99_us": 25.0, "deadline_miss_rate": 1e-4},
        "_samples": {"tick_us": tick_us, "mj_step_us": step_us},
    }


def chart(result: dict):
    """Histogram of tick and mj_step times, and where a tick goes."""
    fig, (a, b) = figure(1, 2, (11, 4))
    s = result["_samples"]
    # log-spaced bins on a log axis: the bulk (a few µs) and the rare preempted tick (ms) both show
    both = np.concatenate([s["tick_us"], s["mj_step_us"]])
    bins = np.geomspace(max(float(both.min()), 0.1) * 0.9, float(both.max()) * 1.1, 80)
    a.hist(s["mj_step_us"], bins=bins, alpha=0.7, label="bare mj_step")
    a.hist(s["tick_us"], bins=bins, alpha=0.7, label=f"softproxy tick ({result['fingers']} fingers)")
    a.axvline(result["mj_step_us"]["p50"] * result["targets"]["ratio_p50"], color="k", ls="--", lw=1,
              label=f"target: {result['targets']['ratio_p50']:g} x mj_step p50")
    a.set_xscale("log")
    a.set_xlabel("µs per tick (log scale)")
    a.set_yscale("log")  # single preempted ticks stay visible beside the thousands at a few µs
    a.set_ylabel("ticks (log scale)")
    a.legend()
    a.set_title(f"tick p50 = {result['ratio_p50']} x mj_step")
    st = result["stages_us_p50"]
    b.barh(list(st), list(st.values()))
    b.invert_yaxis()  # the stages top to bottom, in the tick's order
    b.set_xlabel("µs (median per tick)")
    b.set_title("where a tick goes")
    return fig


def main(args) -> int:
    progress = Progress("latency")
    result = measure(args.duration, args.paced if args.paced is not None else args.duration,
                     progress=lambda frac: progress(f"{frac * 100:5.1f} %"), realtime=getattr(args, "realtime", False))
    progress.done()
    fig = chart(result)
    del result["_samples"]
    publish(args, "latency", result, fig, print_report)
    return 0


def print_report(result: dict) -> None:
    """What `softproxy bench latency` prints: the result as a table."""
    t, s = result["tick_us"], result["mj_step_us"]
    print(f"latency on {result['scene']} ({result['fingers']} fingers, {result['ticks_timed']} ticks timed)")
    print(f"  {'':22s}{'p50':>9s}{'p99':>9s}{'max':>9s}{'/ mj_step':>11s}   (µs)")
    print(f"  {'tick':22s}{t['p50']:9.2f}{t['p99']:9.2f}{t['max']:9.2f}{result['ratio_p50']:11.2f}")
    print(f"  {'bare mj_step':22s}{s['p50']:9.2f}{s['p99']:9.2f}{s['max']:9.2f}   (after each tick)")
    tg = result["targets"]
    print(f"  targets: ratio p50 <= {tg['ratio_p50']:g}, tick p99 <= {tg['tick_p99_us']:g} µs, "
          f"deadline misses < {tg['deadline_miss_rate']:g}")
    for paced in result["paced"]:
        print(f"  deadline misses paced at {paced['rate_hz']:g} Hz, {paced['scheduling']}: {paced['misses']} of "
              f"{paced['ticks']} ({paced['miss_rate']:.2e}), tick p99 {paced['tick_us']['p99']} µs; "
              f"the pacer alone: {paced['pacer_alone_misses']} ({paced['pacer_alone_miss_rate']:.2e})")
    if not result.get("realtime"):
        print("  real-time scheduling (SCHED_FIFO) not tried: add --realtime")
    print("  stages (µs, median): " + ", ".join(f"{k} {v}" for k, v in result["stages_us_p50"].items()))
