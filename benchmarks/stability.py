"""`softproxy bench stability`: where the virtual coupling is stable on real devices, and what happens at the extremes.

1. **Stiff wall on four device models** (`device_models.PROFILES`: 3D Systems Touch, Novint
   Falcon, Force Dimension omega.3 and sigma.7: moving mass, damping, encoder resolution, force
   clamp and the vendor's maximum stiffness, each figure with its source), wall stiffness K ×
   virtual damping B × servo rate (250 Hz – 10 kHz). The handle is held by a hand (300 N/m,
   2 N·s/m) that presses it on a plane with a push building to 1.5 N over 0.05 s from rest on
   the surface; the force the servo loop sends is held over the period and the handle
   integrated exactly between ticks (`device_models.HandHeldHandle`: the sampled-data loop
   Colgate analysed). At 0.06 s a tap sets the handle ringing
   (20 % of its depth in the wall) and each cell is classed from what follows:
   - **unstable**: NaN, the device's force clamp reached, the handle leaving the wall's
     surface (a separation), or an oscillation that grows: the handle's oscillation energy about its
     rest point, E = ½mv² + ½(K + K_h)(z − z_eq)², fitted as E ∝ e^{2σt} with σ > 0;
   - **buzzing**: bounded (σ ≤ 0, in contact) but ringing: the ring decays at less than half
     the rate its damping alone would give, (b + b_h + B)/2m (the hold's lag has eaten over
     half the damping: K above about half the boundary), or the encoder's share of the force
     (the force sent less the one the true positions would give) has a peak-to-peak over the
     last 20 % of the run above 5 % of the mean force (quantisation noise through K and B/T);
   - **stable**: otherwise.
   Unstable is exactly "a closed-loop pole outside the unit circle", so the **measured
   boundary** (the K where a cell turns unstable, bisected to 2 % for B of the grid) is
   compared with the **analytic** one (`sampled_wall.stability_boundary`: the exact
   discrete-time poles), measured with a perfect encoder (the model's assumption) and with the
   device's. The chart also draws Colgate & Schenkel's passivity bound b > KT/2 + |B| (b the
   device's own damping) and the vendors' stiffness figures. When the engine's `ServoLoop`
   takes `passivity=`, every wall cell and boundary runs with the passivity controller on and
   off.
2. **Grasp**, K × torsional stiffness k_τ × rate on `two_finger_grasp`: stable if the box is
   held (not dropped, turned < 2°) with grip-force ripple < 20 % in the last 0.5 s.
3. **Extremes** — P → 0, P ≫ 1e3 N, μ = 0, μ_s = μ_d, k_τ huge, 10 kHz, a device jumping 1 m
   in one tick, garbage from the device: each must send only finite forces within the clamp.

Every wall, boundary, grasp and extreme run is one cell of `softproxy.cells`: serial by
default, a pool with `--workers N`, Ray with `--ray [ADDRESS]`; the result is the same whichever
ran it. A cell that fails is listed with its parameters under "failed" (exit status 1); the
rest complete. Writes stability.json and stability.png.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import textwrap

import mujoco
import numpy as np

from .device_models import PROFILES, Hand, HandHeldHandle
from .report import Progress, figure, publish
from .sampled_wall import colgate_boundary, small_period_boundary, stability_boundary
from softproxy.cells import Backend, run_cells
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.servo import ServoLoop
from softproxy.world import World

WALL_XML = '<mujoco><worldbody><geom name="wall" type="plane" size="1 1 .1"/></worldbody></mujoco>'
HAND = Hand()
KICK_S = 0.06        # s: the tap, once the hand's push has built (over 0.05 s)
DAMPING_LEFT = 0.5   # a bounded ring decaying slower than this share of its damping's rate is buzzing
KICK_DEPTH = 0.2     # the tap's ring, as a fraction of the handle's rest depth in the wall
RIPPLE = 0.05        # the encoder's late peak-to-peak share of the force, over its mean, above which a cell buzzes
BOUNDARY_RTOL = 0.02  # the measured boundary is bisected until its bracket is this narrow
WITHIN = 0.10        # the measured boundary's target: within 10 % of the analytic one


@functools.cache
def passivity_modes() -> tuple:
    """The passivity controller settings each wall cell runs with: (True, False) when the
    engine's ServoLoop takes `passivity=`, else (None,): the engine as it is."""
    return (True, False) if "passivity" in inspect.signature(ServoLoop).parameters else (None,)


def wall_duration(rate: float) -> float:
    """Servo time (s) of one wall run at `rate` Hz: the tap, then 300 ticks of ringing, at
    least 0.15 s and at most 0.5 s (several periods of the slowest mode near the boundary)."""
    return KICK_S + min(0.5, max(0.15, 300.0 / rate))


def wall_run(device: str, K: float, B: float, rate: float, encoder: bool = True, passivity: bool | None = None,
             duration: float | None = None) -> dict:
    """One run of the engine's servo loop rendering a wall (K N/m, B N·s/m) to the device's
    hand-held handle at `rate` Hz; its measures and class (the module docstring)."""
    profile = PROFILES[device]
    period = 1.0 / rate
    kh = HAND.stiffness_Npm
    z_eq = HAND.rest(K)
    omega = math.sqrt((K + kh) / profile.mass_kg)
    ring = KICK_DEPTH * abs(z_eq)
    handle = HandHeldHandle(profile, period, HAND, encoder, KICK_S, ring * omega, start_m=0.0)
    world = World(mujoco.MjModel.from_xml_string(WALL_XML))
    # the handle starts at rest on the wall's surface and the hand's push builds smoothly, so
    # the run measures the wall in contact, not an approach's bounce; the soft start, which
    # only shapes a contact's first 0.1 s, is off for the same reason
    params = FingerParams(radius=0.0, stiffness=K, damping=B, model="point", max_force=profile.max_force_N,
                          soft_start=0.0)
    finger = SoftFingerProxy(params, world.shapes, model("point"))
    options = {} if passivity is None else {"passivity": passivity}
    loop = ServoLoop(world, [finger], handle, rate, overrun_watchdog=False, handle_signals=False, **options)
    try:
        loop.run(int(round((duration or wall_duration(rate)) * rate)))
    finally:
        loop.close()
    t = np.array(handle.times)
    z, v = np.array(handle.positions), np.array(handle.velocities)
    F = np.array(handle.forces[:len(t)])  # (the close's zero comes after)
    after = t >= KICK_S
    finite = bool(np.all(np.isfinite(F)) and np.all(np.isfinite(z)))
    clamped = finite and bool(np.abs(F).max() >= profile.max_force_N * (1 - 1e-9))
    za = z[after]  # the handle's true position: a separation is the handle leaving the surface
    separations = int(np.count_nonzero((za[:-1] <= 0.0) & (za[1:] > 0.0))) if finite else 0
    sigma = None
    if finite:
        E = 0.5 * profile.mass_kg * v[after] ** 2 + 0.5 * (K + kh) * (z[after] - z_eq) ** 2
        floor = 0.5 * (K + kh) * profile.resolution_m ** 2 if encoder else 1e-30  # a ring of one count
        above = E > floor
        if above.sum() >= max(8, 0.25 * above.size):
            sigma = float(np.polyfit(t[after][above], np.log(E[above]), 1)[0] / 2.0)
    grows = sigma is not None and sigma > 0.0
    bounded = finite and not clamped and not separations and not grows
    tail = slice(int(0.8 * len(F)), None)
    late = F[tail]
    mean = float(np.mean(late)) if finite else math.nan
    ripple = float(np.ptp(late) / mean) if finite and mean > 0 else math.inf
    # what the encoder adds: the force sent against the one the true positions would give
    true_F = np.clip(-K * z[1:] - B * rate * (z[1:] - z[:-1]), 0.0, profile.max_force_N)
    quantised = float(np.ptp((F[1:] - true_F)[tail]) / mean) if finite and mean > 0 else math.inf
    # the ring's own decay rate, were the wall rendered without the hold's lag: (b + b_h + B)/2m
    undelayed = (profile.damping_Nspm + HAND.damping_Nspm + B) / (2.0 * profile.mass_kg)
    ringing = (sigma is not None and sigma > -DAMPING_LEFT * undelayed) or quantised > RIPPLE
    cls = "unstable" if not bounded else "buzzing" if ringing else "stable"
    window = t[-1] - KICK_S
    work_after = float(np.sum(F[after][:-1] * np.diff(z[after]))) if finite else math.nan
    return {"class": cls, "bounded": bounded, "growth_per_s": None if sigma is None else round(sigma, 4),
            "separations": separations, "clamped": clamped, "late_ripple": round(ripple, 4) if finite else None,
            "encoder_ripple": round(quantised, 4) if finite else None,
            "energy_in_J": round(handle.work, 9) if finite else None,
            "power_in_after_tap_W": round(work_after / window, 6) if finite else None,
            "peak_force_N": round(float(np.abs(F).max()), 4) if finite else None}


def wall_cell(device: str, K: float, B: float, rate: float, passivity: bool | None = None,
              duration: float | None = None) -> dict:
    """One cell of the Z-width chart: the device with its encoder, and where the cell lies
    against the analytic bounds."""
    p = PROFILES[device]
    period = 1.0 / rate
    b_all = p.damping_Nspm + HAND.damping_Nspm
    analytic = stability_boundary(B, period, p.mass_kg, p.damping_Nspm, HAND.stiffness_Npm, HAND.damping_Nspm)
    return {"device": device, "K": K, "B": B, "rate_hz": rate, "passivity": passivity,
            **wall_run(device, K, B, rate, True, passivity, duration),
            "passive_by_colgate": K < colgate_boundary(B, p.damping_Nspm, period),
            "stable_by_analysis": K < analytic, "analytic_K": analytic,
            "closed_form_K": small_period_boundary(B, b_all, period)}


def boundary_cell(device: str, rate: float, B: float, encoder: bool, passivity: bool | None = None,
                  duration: float | None = None) -> dict:
    """The measured boundary for one (device, rate, B): the K where the servo loop's wall turns
    unstable, bracketed then bisected to BOUNDARY_RTOL; with the analytic one beside it.
    The bracket starts ±25 % around the analytic K and is widened (×2) until its ends really
    are bounded and unstable, so the analysis only seeds the search."""
    p = PROFILES[device]
    period = 1.0 / rate
    analytic = stability_boundary(B, period, p.mass_kg, p.damping_Nspm, HAND.stiffness_Npm, HAND.damping_Nspm)
    runs = 0

    def bounded(K):
        nonlocal runs
        runs += 1
        return wall_run(device, K, B, rate, encoder, passivity, duration)["bounded"]

    K_MIN, K_MAX = 10.0, 1e7
    seed = analytic if 0.0 < analytic < math.inf else 1e3
    lo, hi = seed / 1.25, seed * 1.25
    below = above = False  # the measured boundary lies below K_MIN / above K_MAX
    while not bounded(lo):
        hi, lo = lo, lo / 2.0
        if lo < K_MIN:
            below = True
            break
    while not below and bounded(hi):
        lo, hi = hi, hi * 2.0
        if hi > K_MAX:
            above = True
            break
    while not (below or above) and hi / lo > 1.0 + BOUNDARY_RTOL:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if bounded(mid) else (lo, mid)
    measured = None if below or above else math.sqrt(lo * hi)
    ratio = measured / analytic if measured and 0.0 < analytic < math.inf else None
    return {"device": device, "rate_hz": rate, "B": B, "encoder": encoder, "passivity": passivity,
            "measured_K": measured, "measured_bracket": [lo, hi], "measured_beyond": "above" if above else
            "below" if below else None, "analytic_K": analytic,
            "closed_form_K": small_period_boundary(B, p.damping_Nspm + HAND.damping_Nspm, period),
            "colgate_K": colgate_boundary(B, p.damping_Nspm, period),
            "ratio": None if ratio is None else round(ratio, 4),
            "within_10pct": None if ratio is None else abs(ratio - 1.0) <= WITHIN, "runs": runs}


def grasp_cell(K: float, k_tau: float, rate: float, duration: float) -> dict:
    scene = load_scene("two_finger_grasp")
    for f in scene.fingers:
        f.stiffness, f.torsion_stiffness = K, k_tau
    grip_depth = 3.0 / K  # keep 3 N of grip whatever the stiffness
    for finger in scene.device["finger"]:
        for key in finger["keyframes"][1:]:
            key[1] = math.copysign(0.02 + scene.fingers[0].radius - grip_depth, key[1])
    loop = build(scene, open_device("sim", scene), rate_hz=rate, audit=False, realtime=False)
    body = loop.world.body_id("box")
    grips = []

    def on_tick(lp):
        grips.append(lp.fingers[0].normal_force)

    q0 = None
    ticks = int(duration * rate)
    for i in range(ticks):
        loop.tick()
        on_tick(loop)
        if q0 is None and loop.t >= 0.8:
            q0 = loop.world.data.xquat[body].copy()
    loop.stop()
    from softproxy.run import _rotation_about

    turned = abs(_rotation_about(q0, loop.world.data.xquat[body], (1.0, 0.0, 0.0)))
    height = float(loop.world.data.xpos[body][2])
    late = np.array(grips[-int(0.5 * rate):])
    ripple = float(np.ptp(late) / max(np.mean(late), 1e-9)) if late.size else math.inf
    finite = bool(np.all(np.isfinite(grips)))
    if not finite:
        cls = "unstable"
    elif height < 0.05 or turned > 2.0:
        cls = "dropped"
    elif ripple > 0.2:
        cls = "buzzing"
    else:
        cls = "stable"
    return {"K": K, "k_tau": k_tau, "rate_hz": rate, "class": cls, "turned_deg": round(turned, 3),
            "grip_ripple": round(ripple, 4), "height_m": round(height, 4)}


def _depth(scene, d: float) -> None:
    """Both fingers' device `d` m past the box faces from the squeeze on."""
    for finger in scene.device["finger"]:
        for key in finger["keyframes"][1:]:
            key[1] = math.copysign(0.028 - d, key[1])


def _fingers(scene, **settings) -> None:
    for f in scene.fingers:
        for k, v in settings.items():
            setattr(f, k, v)


def _jump(scene) -> None:
    """The device leaves the grasp and jumps 1 m in one tick at 0.3 s."""
    for finger in scene.device["finger"]:
        k = finger["keyframes"]
        finger["keyframes"] = [k[0], [0.3, k[0][1], k[0][2], k[0][3], 0.0], [0.3001, k[0][1] * -20, k[0][2], -1.0, 0.0]]


def _huge_grip(scene) -> None:
    _depth(scene, 1.0)
    _fingers(scene, max_force=1e4)
    scene.device.update(max_force_N=1e4)


EXTREMES = {  # case: (edit of the grasp scene, servo rate (None: the scene's), duration s)
    "P -> 0 (grip 1 µN)": (lambda s: _depth(s, 5e-10), None, 1.0),
    "P >> 1e3 N (device 1 m deep, clamp 1e4 N)": (_huge_grip, None, 1.0),
    "mu = 0 (translational and torsional)":
        (lambda s: _fingers(s, mu_s=0.0, mu_d=0.0, torsion_mu_s=0.0, torsion_mu_d=0.0), None, 1.0),
    "mu_s = mu_d": (lambda s: _fingers(s, mu_d=1.0, torsion_mu_s=0.0081489, torsion_mu_d=0.0081489), None, 1.0),
    "k_tau huge (1e6 N·m/rad)": (lambda s: _fingers(s, torsion_stiffness=1e6), None, 1.0),
    "10 kHz": (None, 10000.0, 0.5),
    "device jumps 1 m in one tick": (_jump, None, 1.0),
    "garbage from the device (position noise 1e300 m)": (lambda s: s.device.update(noise_m=1e300), None, 1.0),
}
"""The extremes, by name (a cell names its case; the edits stay here, so cells pickle)."""


def extreme_cell(case: str) -> dict:
    """One extreme on the grasp: every force sent finite and within the clamp, the proxy outside."""
    edit, rate, duration = EXTREMES[case]
    scene = load_scene("two_finger_grasp")
    if edit:
        edit(scene)
    device = open_device("sim", scene)
    sent = []
    original = device.send

    def send(finger, *w):
        sent.append(w)
        original(finger, *w)

    device.send = send
    loop = build(scene, device, rate_hz=rate, audit=True, realtime=False)
    loop.run(int(duration * loop.rate_hz))
    finite = all(all(math.isfinite(v) for v in w) for w in sent)
    clamped = all(math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2) <= device.max_force * (1 + 1e-9) for w in sent)
    pen = max(f.penetration_max for f in loop.fingers)
    return {"case": case, "finite": finite, "clamped": clamped, "penetration_max_m": pen,
            "faults": sum(loop.faults.values()), "ok": finite and clamped and pen <= 1e-6}


def extremes() -> list[dict]:
    """Each named extreme: every force sent finite and within the clamp."""
    return [extreme_cell(case) for case in EXTREMES]


CELLS = {"wall": wall_cell, "boundary": boundary_cell, "grasp": grasp_cell, "extreme": extreme_cell}


def cell(kind: str, **params) -> dict:
    """One cell of the benchmark by kind (wall, boundary, grasp, extreme): what `softproxy.cells` runs."""
    return CELLS[kind](**params)


def grid(full: bool = False, devices: tuple | None = None) -> list[dict]:
    """The benchmark's cells, in the order of its result: the wall grid (device, passivity,
    rate, B, K), the measured boundaries (device, passivity, rate, B, encoder off then on),
    the grasp grid (rate, k_τ, K), then the extremes."""
    devices = tuple(devices or PROFILES)
    Ks = [300.0, 1e3, 3e3, 1e4, 3e4, 1e5, 3e5] if full else [300.0, 1e3, 3e3, 1e4, 3e4, 1e5]
    Bs = [0.0, 0.5, 2.0, 5.0, 10.0] if full else [0.0, 2.0, 10.0]
    rates = [250.0, 1000.0, 4000.0, 10000.0]
    modes = passivity_modes()
    cells = [{"kind": "wall", "device": d, "K": K, "B": B, "rate": rate, "passivity": p}
             for d in devices for p in modes for rate in rates for B in Bs for K in Ks]
    cells += [{"kind": "boundary", "device": d, "rate": rate, "B": B, "encoder": enc, "passivity": p}
              for d in devices for p in modes for rate in rates for B in Bs for enc in (False, True)]
    gK = [500.0, 2000.0, 1e4, 5e4] if full else [500.0, 2000.0, 1e4]
    gkt = [0.2, 2.0, 20.0, 200.0] if full else [0.2, 2.0, 50.0]
    grates = [1000.0, 4000.0] if full else [1000.0]
    cells += [{"kind": "grasp", "K": K, "k_tau": kt, "rate": rate, "duration": 2.2}
              for rate in grates for kt in gkt for K in gK]
    cells += [{"kind": "extreme", "case": case} for case in EXTREMES]
    return cells


def measure(full: bool = False, progress=None, backend: Backend = Backend(), devices: tuple | None = None) -> dict:
    """Run the grid's cells on `backend` (softproxy.cells: serial, a pool, or Ray; the result
    is the same); a cell that fails is listed in "failed" with its parameters."""
    cells = grid(full, devices)

    def report(done: int, total: int, outcome) -> None:
        if progress:
            progress(f"{done}/{total} cells ({outcome.params['kind']} done), {backend.describe()}")

    outcomes = run_cells(cell, cells, backend, report)
    found = {"wall": [], "boundary": [], "grasp": [], "extreme": []}
    failed = []
    for o in outcomes:
        if o.ok:
            found[o.params["kind"]].append(o.value)
        else:
            failed.append({"cell": o.params, "error": o.error})
    compared = [b for b in found["boundary"] if not b["encoder"] and b["passivity"] is not True]
    agree = [b for b in compared if b["within_10pct"]]
    return {"wall": found["wall"], "boundaries": found["boundary"], "grasp": found["grasp"],
            "extremes": found["extreme"], "failed": failed,
            "passivity_controller": "available: every wall cell and boundary runs on and off"
                                    if passivity_modes() != (None,) else "not available",
            "boundary_agreement": {"within_10pct": len(agree), "compared": len(compared),
                                   "worst_ratio": max((b["ratio"] for b in compared if b["ratio"]),
                                                      key=lambda r: abs(r - 1.0), default=None)},
            "devices": {name: dataclasses.asdict(p) for name, p in PROFILES.items() if name in
                        (devices or PROFILES)},
            "hand": {**dataclasses.asdict(HAND), "push_N": HAND.push_N},
            "tap": {"at_s": KICK_S, "ring_of_rest_depth": KICK_DEPTH}}


COLOURS = {"stable": "#2ca02c", "buzzing": "#ff7f0e", "unstable": "#d62728", "dropped": "#7f7f7f"}
MARKERS = {None: "o", True: "o", False: "s"}


def chart(result: dict):
    """Per device (rows) and rate (columns): the wall cells' classes on B × K (Z-width), the
    analytic stability boundary, Colgate's passivity bound, the measured boundaries and the
    vendor's stiffness; a last row for the grasp classes on K × k_τ."""
    devices = list(result["devices"])
    rates = sorted({c["rate_hz"] for c in result["wall"]})
    fig, axes = figure(len(devices) + 1, len(rates), (4.2 * len(rates), 3.8 * (len(devices) + 1)), squeeze=False)
    for row, name in zip(axes, devices):
        p = PROFILES[name]
        for ax, rate in zip(row, rates):
            period = 1.0 / rate
            cells = [c for c in result["wall"] if c["device"] == name and c["rate_hz"] == rate]
            for c in cells:
                ax.scatter(c["B"] + (0.15 if c["passivity"] is False else 0.0), c["K"],
                           color=COLOURS[c["class"]], s=70, marker=MARKERS[c["passivity"]], zorder=3)
            Bmax = max([c["B"] for c in cells] + [1.0]) * 1.05
            Bs = np.linspace(0.0, Bmax, 60)
            ana = [stability_boundary(B, period, p.mass_kg, p.damping_Nspm, HAND.stiffness_Npm,
                                      HAND.damping_Nspm) for B in Bs]
            ax.plot(Bs, ana, "k-", lw=1.2, label="stable below: exact sampled-wall poles")
            ax.plot(Bs, [small_period_boundary(B, p.damping_Nspm + HAND.damping_Nspm, period) for B in Bs], "k:",
                    lw=1, label="2(b + b_h + B)/T (small T)")
            Bc = np.linspace(0.0, p.damping_Nspm, 20)
            ax.plot(Bc, [max(colgate_boundary(B, p.damping_Nspm, period), 1.0) for B in Bc], "b--", lw=1.2,
                    label="passive below: b > KT/2 + |B| (device b)")
            b_all = p.damping_Nspm + HAND.damping_Nspm
            Bh = np.linspace(0.0, b_all, 20)
            ax.plot(Bh, [max(colgate_boundary(B, b_all, period), 1.0) for B in Bh], color="lightblue", ls="--",
                    lw=1.2, label="the same, the hand's damping counted")
            for b in result["boundaries"]:
                if b["device"] == name and b["rate_hz"] == rate and b["measured_K"] and b["passivity"] is not True:
                    ax.errorbar(b["B"] + (0.3 if b["encoder"] else -0.3), b["measured_K"],
                                yerr=[[b["measured_K"] - b["measured_bracket"][0]],
                                      [b["measured_bracket"][1] - b["measured_K"]]],
                                fmt="v" if b["encoder"] else "^", color="purple" if b["encoder"] else "black",
                                ms=6, zorder=4)
            if p.vendor_stiffness_Npm:
                ax.axhline(p.vendor_stiffness_Npm, color="teal", lw=1, ls="-.", label="vendor's max stiffness")
            ax.axhline(p.driver_stiffness_Npm, color="grey", lw=1, ls="-.", label="CHAI3D driver's max stiffness")
            ax.set_yscale("log")
            ax.set_ylim(50.0, 2e6)
            ax.set_xlabel("B (N·s/m)")
            ax.set_ylabel("K (N/m)")
            ax.set_title(f"{p.name} at {rate:g} Hz", fontsize=9)
        row[0].legend(fontsize=6, loc="upper left")
    row = axes[-1]
    ax = row[0]
    for c in result["grasp"]:
        ax.scatter(c["K"], c["k_tau"], color=COLOURS[c["class"]], s=120)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("K (N/m)")
    ax.set_ylabel("k_tau (N·m/rad)")
    ax.set_title("grasp", fontsize=9)
    note = ("green stable, orange buzzing, red unstable; circles: passivity controller on (or not available), "
            "squares: off; ^ measured boundary (perfect encoder), v (device's encoder)")
    row[1].axis("off")
    row[1].text(0.0, 0.5, textwrap.fill(note, 50), fontsize=8, va="center")
    for ax in row[2:]:
        ax.axis("off")
    return fig


def _k(K) -> str:
    return "—" if K is None else "inf" if K == math.inf else f"{K:.0f}" if K < 1e4 else f"{K:.3g}"


def main(args) -> int:
    progress = Progress("stability")
    result = measure(getattr(args, "full", False), progress, getattr(args, "backend", None) or Backend())
    progress.done()
    publish(args, "stability", result, chart(result), print_report)
    return 0 if args.json or (all(c["ok"] for c in result["extremes"]) and not result["failed"]) else 1


def print_report(result: dict) -> None:
    """What `softproxy bench stability` prints: the result as a table."""
    print(f"stability: a hand-held device (hand {HAND.stiffness_Npm:g} N/m, {HAND.damping_Nspm:g} N·s/m, pushing "
          f"{HAND.push_N:g} N) on a wall, tapped at {KICK_S:g} s; the force held over each period (ZOH), the "
          "handle integrated exactly between ticks")
    print(f"  passivity controller: {result['passivity_controller']}")
    print("  class per cell (device's encoder; * = passive by Colgate's bound with the device's own damping, "
          "! = stable by the exact sampled-wall analysis)")
    for name in result["devices"]:
        p = PROFILES[name]
        print(f"  {p.name}: m {p.mass_kg:g} kg, b {p.damping_Nspm:g} N·s/m, encoder {p.resolution_m * 1e3:g} mm, "
              f"clamp {p.max_force_N:g} N, vendor K {_k(p.vendor_stiffness_Npm)} N/m, "
              f"CHAI3D K {_k(p.driver_stiffness_Npm)} N/m")
        for mode in passivity_modes():
            cells = [c for c in result["wall"] if c["device"] == name and c["passivity"] == mode]
            if mode is not None:
                print(f"    passivity controller {'on' if mode else 'off'}")
            for rate in sorted({c["rate_hz"] for c in cells}):
                at = [c for c in cells if c["rate_hz"] == rate]
                Ks = sorted({c["K"] for c in at})
                print(f"    {rate:6g} Hz  B \\ K " + "".join(f"{K:>11g}" for K in Ks))
                for B in sorted({c["B"] for c in at}):
                    row = {c["K"]: c for c in at if c["B"] == B}
                    print(f"    {'':9s}{B:7g} " + "".join(
                        f"{row[K]['class'] + ('*' if row[K]['passive_by_colgate'] else '') + ('!' if row[K]['stable_by_analysis'] else ''):>11s}"
                        for K in Ks))
    print("  boundary: the K (N/m) above which the wall turns unstable, measured (bisected to "
          f"{BOUNDARY_RTOL:.0%}) against the exact sampled-wall analysis")
    print(f"    {'device':9s} {'passivity':>9s} {'rate Hz':>8s} {'B':>5s} {'analytic':>9s} {'2(b+B)/T':>9s} "
          f"{'measured':>9s} {'ratio':>6s} {'w/ encoder':>10s} {'Colgate':>8s}")
    rows = {}
    for b in result["boundaries"]:
        rows.setdefault((b["device"], b["passivity"], b["rate_hz"], b["B"]), {})[b["encoder"]] = b
    for (name, mode, rate, B), pair in rows.items():
        ideal, enc = pair.get(False), pair.get(True)
        if ideal is None:
            continue

        def shown(b):
            if b is None:
                return "—"
            return {"above": "> 1e7", "below": "< 10"}.get(b["measured_beyond"]) or _k(b["measured_K"])

        mode_s = "—" if mode is None else "on" if mode else "off"
        ratio = f"{ideal['ratio']:.3f}" if ideal["ratio"] else "—"
        print(f"    {name:9s} {mode_s:>9s} {rate:8g} {B:5g} {_k(ideal['analytic_K']):>9s} "
              f"{_k(ideal['closed_form_K']):>9s} {shown(ideal):>9s} {ratio:>6s} {shown(enc):>10s} "
              f"{_k(ideal['colgate_K']):>8s}")
    agree = result["boundary_agreement"]
    print(f"  measured boundary within 10 % of the analytic one (perfect encoder, controller off or absent): "
          f"{agree['within_10pct']}/{agree['compared']} (worst ratio {agree['worst_ratio']})")
    print("  grasp (3 N grip):")
    for c in result["grasp"]:
        print(f"    K {c['K']:>8g}  k_tau {c['k_tau']:>6g}  {c['rate_hz']:>6g} Hz  {c['class']:9s} "
              f"turned {c['turned_deg']:.3f} deg, grip ripple {c['grip_ripple'] * 100:.1f} %")
    print("  extremes (finite and clamped forces, proxy never > 1 µm inside):")
    for c in result["extremes"]:
        print(f"    {'ok  ' if c['ok'] else 'FAIL'} {c['case']}")
    for f in result["failed"]:
        print(f"  FAILED cell {f['cell']}: {f['error']}")
