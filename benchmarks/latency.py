"""`softproxy bench latency`: the full servo tick against a bare mj_step of the same scene.

Two soft fingers hold the box of `two_finger_grasp` (device read + two god-objects +
torsion + coupling + MuJoCo). Each tick is timed, the Python engine's, then the compiled
one's (`ServoLoop(compiled=True)`), and after each tick a bare `mj_step` is timed on a copy
of the very same MuJoCo state, so each ratio compares like with like on a shared, noisy
machine. The Python tick's stage times come from timing subclasses swapped in for the
god-object and torsion (one extra call each). A paced run of each engine at the scene's
rate gives its deadline-miss rate. Prints a table, writes latency.json and latency.png.
"""

from __future__ import annotations

import json
import time

import mujoco
import numpy as np

from benchmarks.report import Progress, figure, save
from softproxy.proxy import GodObject
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.torsion import TorsionalFriction

_clock = time.perf_counter


class _TimedGodObject(GodObject):
    __slots__ = ()
    spent = [0.0]

    def update(self, xd, yd, zd):
        t = _clock()
        ok = GodObject.update(self, xd, yd, zd)
        _TimedGodObject.spent[0] += _clock() - t
        return ok


class _TimedTorsion(TorsionalFriction):
    __slots__ = ()
    spent = [0.0]

    def step(self, alpha_s, P):
        t = _clock()
        M = TorsionalFriction.step(self, alpha_s, P)
        _TimedTorsion.spent[0] += _clock() - t
        return M


def _percentiles(us: np.ndarray) -> dict:
    return {"p50": round(float(np.percentile(us, 50)), 2), "p99": round(float(np.percentile(us, 99)), 2),
            "max": round(float(us.max()), 2)}


def _compiled_loop(scene):
    """The same scene's loop with compiled fingers, or the reason there is none."""
    try:
        return build(scene, open_device("sim", scene), audit=False, realtime=False, compiled=True), ""
    except (ImportError, ValueError) as exc:
        return None, str(exc)


def _paced(scene, seconds: float, compiled: bool) -> dict:
    """Deadline misses of a loop paced in real time at the scene's rate."""
    paced = build(scene, open_device("sim", scene), audit=False, compiled=compiled)
    paced.run(int(seconds * paced.rate_hz), realtime=True)
    return {"ticks": paced.ticks, "misses": paced.stats.misses,
            "miss_rate": paced.stats.misses / max(paced.ticks, 1), "tick_us": paced.stats.summary_us()}


def _timed_pass(loop, ticks: int, scratch, progress, done: float):
    """Time `ticks` ticks of `loop`, each followed by a bare mj_step on a copy of its state
    (into scratch): tick, mj_step, god-object and torsion times (µs, the last two only where
    the timing subclasses are swapped in). `done`: the progress fraction at the start."""
    tick_us, step_us, god_us, torsion_us = (np.empty(ticks) for _ in range(4))
    m, d = loop.world.model, loop.world.data
    for i in range(ticks):
        _TimedGodObject.spent[0] = _TimedTorsion.spent[0] = 0.0
        t0 = _clock()
        loop.tick()
        tick_us[i] = (_clock() - t0) * 1e6
        god_us[i] = _TimedGodObject.spent[0] * 1e6
        torsion_us[i] = _TimedTorsion.spent[0] * 1e6
        mujoco.mj_copyData(scratch, m, d)
        t0 = _clock()
        mujoco.mj_step(m, scratch)
        step_us[i] = (_clock() - t0) * 1e6
        if progress is not None and i % 500 == 0:
            progress(done + 0.5 * i / ticks)
    return tick_us, step_us, god_us, torsion_us


def measure(duration_s: float = 5.0, paced_s: float = 5.0, scene_name: str = "two_finger_grasp",
            progress=None) -> dict:
    """Run the benchmark and return the result dict (times in µs).

    The Python tick, then the compiled tick (`ServoLoop(compiled=True)`), each followed by a
    bare `mj_step` of the same state, in one process: each ratio compares like with like."""
    scene = load_scene(scene_name)
    loop = build(scene, open_device("sim", scene), audit=False, realtime=False)
    fast, why_not = _compiled_loop(scene)
    ticks = int(duration_s * loop.rate_hz)
    scratch = mujoco.MjData(loop.world.model)
    warm = min(int(1.0 * loop.rate_hz), ticks // 4)  # squeeze and lift first: time the hold
    loop.run(warm)
    loop._started = True
    if fast is not None:
        fast.run(warm)
        fast._started = True
    for f in loop.fingers:
        f.god.__class__ = _TimedGodObject
        if f.torsion is not None:
            f.torsion.__class__ = _TimedTorsion
    # each engine in a pass of its own: a tick of the other engine in between would evict
    # this one's working set
    tick_us, step_us, god_us, torsion_us = _timed_pass(loop, ticks, scratch, progress, 0.0)
    if fast is not None:
        fast_us, fast_step_us, _, _ = _timed_pass(fast, ticks, scratch, progress, 0.5)
    # stage costs of the device and MuJoCo's two halves, timed alone on the same state
    device, samples = loop.device, loop.samples
    t_dev = np.empty(2000)
    for i in range(t_dev.size):
        t0 = _clock()
        device.read(loop.t, samples)
        t_dev[i] = (_clock() - t0) * 1e6
    loop.stop()
    if fast is not None:
        fast.stop()

    tick = _percentiles(tick_us)
    step = _percentiles(step_us)
    stages = {
        "device": round(float(np.median(t_dev)), 2),
        "god_object": round(float(np.median(god_us)), 2),
        "torsion": round(float(np.median(torsion_us)), 2),
        "mj_step": step["p50"],
    }
    stages["coupling_and_loop"] = round(tick["p50"] - sum(stages.values()), 2)
    result = {
        "scene": scene_name,
        "fingers": len(loop.fingers),
        "rate_hz": loop.rate_hz,
        "ticks_timed": ticks,
        "tick_us": tick,
        "mj_step_us": step,
        "ratio_p50": round(tick["p50"] / step["p50"], 2),
        "stages_us_p50": stages,
        "paced": _paced(scene, paced_s, False),
        "targets": {"ratio_p50": 3.0, "tick_p99_us": 50.0, "deadline_miss_rate": 1e-4},
        "_samples": {"tick_us": tick_us, "mj_step_us": step_us},
    }
    if fast is None:
        result["compiled"] = {"unavailable": why_not}
    else:
        ftick, fstep = _percentiles(fast_us), _percentiles(fast_step_us)
        result["compiled"] = {"tick_us": ftick, "mj_step_us": fstep, "ratio_p50": round(ftick["p50"] / fstep["p50"], 2),
                              "paced": _paced(scene, paced_s, True)}
        result["_samples"]["compiled_tick_us"] = fast_us
    return result


def chart(result: dict):
    """Histogram of tick and mj_step times, and where a tick goes."""
    fig, (a, b) = figure(1, 2, (11, 4))
    s = result["_samples"]
    hi = float(np.percentile(s["tick_us"], 99.5)) * 1.2
    bins = np.linspace(0, hi, 80)
    a.hist(s["mj_step_us"], bins=bins, alpha=0.7, label="bare mj_step")
    a.hist(s["tick_us"], bins=bins, alpha=0.7, label="softproxy tick, Python (2 fingers)")
    if "compiled_tick_us" in s:
        a.hist(s["compiled_tick_us"], bins=bins, alpha=0.7, label="softproxy tick, compiled")
    a.axvline(result["mj_step_us"]["p50"] * 3, color="k", ls="--", lw=1, label="target: 3 x mj_step p50")
    a.set_xlabel("µs per tick")
    a.set_ylabel("ticks")
    a.legend()
    title = f"Python tick p50 = {result['ratio_p50']} x mj_step"
    if "ratio_p50" in result["compiled"]:
        title += f", compiled {result['compiled']['ratio_p50']} x"
    a.set_title(title)
    st = result["stages_us_p50"]
    b.barh(list(st), list(st.values()))
    b.set_xlabel("µs (median per tick)")
    b.set_title("where a Python tick goes")
    return fig


def main(args) -> int:
    progress = Progress("latency")
    result = measure(args.duration, args.paced if args.paced is not None else args.duration,
                     progress=lambda frac: progress(f"{frac * 100:5.1f} %"))
    progress.done()
    fig = chart(result)
    del result["_samples"]
    json_path, png_path = save(args.out, "latency", result, fig)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    t, s, c = result["tick_us"], result["mj_step_us"], result["compiled"]
    print(f"latency on {result['scene']} ({result['fingers']} fingers, {result['ticks_timed']} ticks timed)")
    print(f"  {'':22s}{'p50':>9s}{'p99':>9s}{'max':>9s}{'/ mj_step':>11s}   (µs)")
    print(f"  {'tick, Python':22s}{t['p50']:9.2f}{t['p99']:9.2f}{t['max']:9.2f}{result['ratio_p50']:11.2f}")
    if "tick_us" in c:
        ct = c["tick_us"]
        print(f"  {'tick, compiled':22s}{ct['p50']:9.2f}{ct['p99']:9.2f}{ct['max']:9.2f}{c['ratio_p50']:11.2f}")
    else:
        print(f"  tick, compiled: unavailable ({c['unavailable']})")
    print(f"  {'bare mj_step':22s}{s['p50']:9.2f}{s['p99']:9.2f}{s['max']:9.2f}   (after each Python tick)")
    if "mj_step_us" in c:
        cs = c["mj_step_us"]
        print(f"  {'bare mj_step':22s}{cs['p50']:9.2f}{cs['p99']:9.2f}{cs['max']:9.2f}   (after each compiled tick)")
    print("  targets: ratio p50 <= 3 (floor <= 5), tick p99 < 50 µs (floor < 100), deadline misses < 1e-4")
    for name, paced in (("Python", result["paced"]), ("compiled", c.get("paced"))):
        if paced is not None:
            print(f"  deadline misses paced at {result['rate_hz']:g} Hz, {name}: {paced['misses']} of "
                  f"{paced['ticks']} ({paced['miss_rate']:.2e})")
    print("  Python tick's stages (µs, median): " + ", ".join(f"{k} {v}" for k, v in result["stages_us_p50"].items()))
    print(f"  wrote {json_path} and {png_path}")
    return 0
