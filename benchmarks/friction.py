"""`softproxy bench friction`: what the friction laws render under a steady twist and a steady slide.

Both laws are run twice on the same motion: with the slip state (the default; a slipping
contact stays in dynamic friction until the motion stops or reverses) and with
`restick_time = 0`, the static limit re-tested every tick (seed 002's eq 39 and the proxy
literature's cone as printed). docs/friction.md explains the choice and holds the figures.

- steady twist: a soft finger (CH) pressed on a floor at P = 1 N (k = 1000 N/m, 1 mm), its
  device turning at a steady rate, k_τ = 2 N·m/rad, through the finger's own tick (the
  torsional damping b_τ included). Torque ripple = max - min of the torque from 20 ms after
  the first slip (N·m, and as a fraction of μ_d|P|^γ).
- steady slide: a 5 mm god-object 2 mm into a box face, μ_s = 0.5, μ_d = 0.4, the device
  sliding at a steady speed for 2500 ticks, the situation TARGETS.md measured CHAI3D's
  finger proxy in (a steady 0.80 mm lag, 2 switches). Lag = device - proxy along the slide;
  lag ripple = its max - min from 20 ms after the first slip (mm).

Transitions are changes of the stick/slip state, both ways, per second of the run.
"""

from __future__ import annotations


import mujoco
import numpy as np

from .report import Progress, figure, publish
from softproxy.compiled.godobject import RESTICK_FRACTION, RESTICK_TIME, RESTICK_TRAVEL
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.geometry import shapes_of
from softproxy.proxy import GodObject

DT = 1e-3                       # s, 1 kHz
K_TAU = 2.0                     # N·m/rad
PRESS = 0.001                   # m: the finger 1 mm into the floor at 1000 N/m, P = 1 N
TWIST_RATES = (0.02, 0.1)       # rad/s (from ~0.8 rad/s on, eq 39 slips every tick and renders steadily too)
RADIUS, DEPTH = 0.005, 0.002    # m: CHAI3D's 5 mm proxy, 2 mm deep
CONE_S, CONE_D = 0.5, 0.4
SLIDE_SPEEDS = (0.02, 0.1)      # m/s (from 0.2 m/s on, the per-tick cone slips every tick too)
SLIDE_TICKS = 2500
BOX_HALF = 0.2                  # m: a box face long enough for 25 cm of slide
OPTIONS = (("slip state", RESTICK_TIME), ("per tick (seed)", 0.0))
CHAI3D_SLIDE = {"switches": 2, "ticks": 2500, "lag_mm": 0.80}
"""CHAI3D 3.3.0's cAlgorithmFingerProxy on the same slide (TARGETS.md): a reference, not run here."""


SETTLE = 20
"""Ticks after the first slip left out of the ripple: the breakaway itself (the torsional
damping's kick as the torque drops from μ_s to μ_d|P|^γ) is not the steady state."""


def _steady(values: np.ndarray, states: np.ndarray) -> np.ndarray:
    """The values from SETTLE ticks after the first slip on (all of them if it never slipped)."""
    slipped = np.flatnonzero(states)
    return values[slipped[0] + SETTLE:] if len(slipped) else values


def _transitions(states: np.ndarray) -> int:
    """Changes of the stick/slip state, from stuck."""
    return int(np.count_nonzero(np.diff(np.concatenate(([False], states)).astype(np.int8))))


def twist_run(rate: float, restick_time: float, seconds: float) -> dict:
    """A finger pressed at P = 1 N on a floor, its device twisting at `rate` rad/s for `seconds`."""
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    params = FingerParams(radius=RADIUS, stiffness=1000.0, damping=0.0, torsion_stiffness=K_TAU,
                          soft_start=0.0, restick_time=restick_time)
    ch = model("CH")
    f = SoftFingerProxy(params, shapes_of(m, d), ch, (0.0, 0.0, 0.02))
    f.place(0.0, 0.0, 0.02)
    ticks = int(round(seconds / DT))
    torque = np.empty(ticks)
    states = np.empty(ticks, dtype=bool)
    for k in range(ticks):
        f.update(0.0, 0.0, RADIUS - PRESS, rate * k * DT, DT)
        torque[k] = f.torque
        states[k] = f.torsion.slipping
    P = f.normal_force
    dynamic = f.torsion.mu_d * P ** ch.gamma
    steady = _steady(torque, states)
    ripple = float(steady.max() - steady.min())
    return {"law": "torsion", "motion": f"twist {rate:g} rad/s", "rate": rate, "restick_time_s": restick_time,
            "seconds": seconds, "P_N": P, "dynamic_Nm": dynamic, "static_Nm": f.torsion.mu_s * P ** ch.gamma,
            "mean": float(steady.mean()), "ripple": ripple, "ripple_fraction": ripple / dynamic,
            "transitions": _transitions(states), "transitions_per_s": _transitions(states) / seconds,
            "slips": f.torsion.slip_events, "_trace": torque}


def slide_run(speed: float, restick_time: float) -> dict:
    """A 5 mm god-object 2 mm into a box face, the device sliding at `speed` m/s for SLIDE_TICKS ticks."""
    m = mujoco.MjModel.from_xml_string(f'<mujoco><worldbody><geom type="box" size="{BOX_HALF} {BOX_HALF} .05"/>'
                                       '</worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    level = 0.05 + RADIUS - DEPTH
    x0 = -0.15
    god = GodObject(shapes_of(m, d), RADIUS, CONE_S, CONE_D, (x0, 0.0, 0.07), restick_time=restick_time)
    god.update(x0, 0.0, level, DT)
    lag = np.empty(SLIDE_TICKS)
    states = np.empty(SLIDE_TICKS, dtype=bool)
    for k in range(SLIDE_TICKS):
        x = x0 + speed * (k + 1) * DT
        god.update(x, 0.0, level, DT)
        lag[k] = x - god.x
        states[k] = not god.sticking
    steady = _steady(lag, states)
    seconds = SLIDE_TICKS * DT
    return {"law": "friction cone", "motion": f"slide {speed * 1e3:g} mm/s", "rate": speed,
            "restick_time_s": restick_time, "seconds": seconds, "dynamic_mm": CONE_D * DEPTH * 1e3,
            "static_mm": CONE_S * DEPTH * 1e3, "mean": float(steady.mean() * 1e3),
            "ripple": float((steady.max() - steady.min()) * 1e3),
            "ripple_fraction": float((steady.max() - steady.min()) / (CONE_D * DEPTH)),
            "transitions": _transitions(states), "transitions_per_s": _transitions(states) / seconds,
            "_trace": lag * 1e3}


def measure(twist_seconds: float = 5.0, progress=None) -> dict:
    """Every row: both motions at both rates, with the slip state and per tick."""
    rows = []
    jobs = [(twist_run, rate, (twist_seconds,)) for rate in TWIST_RATES] + \
           [(slide_run, speed, ()) for speed in SLIDE_SPEEDS]
    for k, (run, rate, extra) in enumerate(jobs):
        for name, restick_time in OPTIONS:
            if progress is not None:
                progress(f"{run.__name__.split('_')[0]} {rate:g}, {name} ({len(rows) + 1}/{2 * len(jobs)})")
            row = run(rate, restick_time, *extra)
            row["option"] = name
            rows.append(row)
    return {"constants": {"restick_time_s": RESTICK_TIME, "restick_fraction": RESTICK_FRACTION,
                          "restick_travel": RESTICK_TRAVEL},
            "twist_setup": {"model": "CH", "P_N": 1.0, "k_tau_Nm_per_rad": K_TAU, "dt_s": DT, "seconds": twist_seconds},
            "slide_setup": {"radius_m": RADIUS, "depth_m": DEPTH, "mu_s": CONE_S, "mu_d": CONE_D,
                            "ticks": SLIDE_TICKS, "dt_s": DT},
            "chai3d_slide": CHAI3D_SLIDE, "rows": rows}


def chart(result: dict):
    fig, axes = figure(1, 3, (15, 4.2))
    rows = result["rows"]
    colours = {"slip state": "#4a7ab8", "per tick (seed)": "#c03030"}
    for ax, law, motion, unit in ((axes[0], "torsion", f"twist {TWIST_RATES[1]:g} rad/s", "torque (N·m)"),
                                  (axes[1], "friction cone", f"slide {SLIDE_SPEEDS[1] * 1e3:g} mm/s", "lag (mm)")):
        for r in sorted(rows, key=lambda r: r["option"] == "slip state"):  # the slip state drawn on top
            if r["law"] == law and r["motion"] == motion:
                trace = r["_trace"]
                start = max(int(np.argmax(np.abs(trace) > 0.5 * np.abs(trace).max())) - 20, 0)
                window = trace[start:start + 300]
                ax.plot(np.arange(len(window)) * DT * 1e3, window, color=colours[r["option"]], label=r["option"],
                        lw=2.0 if r["option"] == "slip state" else 1.0)
        ax.set_xlabel("ms")
        ax.set_ylabel(unit)
        ax.set_title(f"{law}: {motion}")
        ax.legend(fontsize=8)
    ax = axes[2]
    labels = [f"{r['motion']}\n{r['option']}" for r in rows]
    y = np.arange(len(rows))
    ax.barh(y, [max(r["transitions_per_s"], 0.1) for r in rows], color=[colours[r["option"]] for r in rows])
    ax.set_yticks(y, labels, fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("stick/slip transitions per second")
    ax.set_title("transitions (log)")
    return fig


def main(args) -> int:
    progress = Progress("friction")
    seconds = 20.0 if getattr(args, "full", False) else min(float(getattr(args, "duration", 5.0) or 5.0), 20.0)
    result = measure(seconds, progress)
    progress.done()
    fig = chart(result)
    for r in result["rows"]:
        del r["_trace"]
    publish(args, "friction", result, fig, print_report)
    return 0


def print_report(result: dict) -> None:
    """What `softproxy bench friction` prints: the result as a table."""
    c = result["constants"]
    print(f"friction under steady motion: slip state (re-stick when stopped {c['restick_time_s']:g} s or turned back "
          f"to {c['restick_fraction']:g} of the dynamic limit) vs per tick (restick_time 0)")
    print(f"  {'motion':22s}{'option':18s}{'mean':>10s}{'ripple':>10s}{'ripple/dyn':>12s}{'trans/s':>10s}{'trans':>8s}")
    for r in result["rows"]:
        unit = "N·m" if r["law"] == "torsion" else "mm"
        print(f"  {r['motion']:22s}{r['option']:18s}{r['mean']:10.5f}{r['ripple']:10.5f}{r['ripple_fraction']:11.1%} "
              f"{r['transitions_per_s']:10.2f}{r['transitions']:8d}  {unit}")
    chai, seconds = result["chai3d_slide"], result["twist_setup"]["seconds"]
    print(f"  twist: CH at P = 1 N, k_τ = {K_TAU:g}, {seconds:g} s; slide: {RADIUS * 1e3:g} mm proxy {DEPTH * 1e3:g} mm "
          f"deep, μ {CONE_S}/{CONE_D}, {SLIDE_TICKS} ticks (CHAI3D's finger proxy there: {chai['switches']} switches, "
          f"{chai['lag_mm']:.2f} mm steady lag)")

