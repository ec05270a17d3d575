"""`softproxy bench stability`: where the virtual coupling is stable, and what happens at the extremes.

1. **Stiff wall**, stiffness K × virtual damping B × servo rate. A scripted device cannot go
   unstable (nothing feeds back), so the wall is pushed by a simulated *hand-held* device:
   a 0.1 kg handle with 0.5 N·s/m of its own friction, held by a hand modelled as a
   300 N/m, 2 N·s/m spring-damper pulling it 1 cm into the wall. The rendered force acts on
   the handle (zero-order hold), exactly the sampled-data loop Colgate analysed. Each cell is
   classed from the force in the last 40 % of the run:
   - **unstable**: NaN, the force clamp reached, or an oscillation that grows;
   - **buzzing**: a sustained oscillation, peak-to-peak > 5 % of the mean force;
   - **stable**: otherwise.
   It also reports the energy the coupling put into the handle (Σ F·Δx) and Colgate's
   passivity bound b > KT/2 + |B| (b: the physical damping on the handle, its own plus the
   hand's, 2.5 N·s/m; T: the servo period), to show where the measured region and the
   bound differ: passivity is sufficient, not necessary, so stable cells outside the bound
   are expected (the hand's stiffness and the handle's mass help too).
2. **Grasp**, K × torsional stiffness k_τ × rate on `two_finger_grasp`: stable if the box is
   held (not dropped, turned < 2°) with grip-force ripple < 20 % in the last 0.5 s.
3. **Extremes** — P → 0, P ≫ 1e3 N, μ = 0, μ_s = μ_d, k_τ huge, 10 kHz, a device jumping 1 m
   in one tick, garbage from the device: each must send only finite forces within the clamp.

Every wall, grasp and extreme run is one cell of `softproxy.cells`: serial by default, a pool
with `--workers N`, Ray with `--ray [ADDRESS]`; the result is the same whichever ran it. A cell
that fails is listed with its parameters under "failed" (exit status 1); the rest complete.
Writes stability.json and stability.png.
"""

from __future__ import annotations

import json
import math

import mujoco
import numpy as np

from .report import Progress, figure, save
from softproxy.cells import Backend, run_cells
from softproxy.device import DeviceSample
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.servo import ServoLoop
from softproxy.world import World

WALL_XML = '<mujoco><worldbody><geom name="wall" type="plane" size="1 1 .1"/></worldbody></mujoco>'
HANDLE_MASS = 0.1       # kg
HANDLE_DAMPING = 0.5    # N·s/m, the device's own friction (b in Colgate's bound)
HAND_STIFFNESS = 300.0  # N/m
HAND_DAMPING = 2.0      # N·s/m
HAND_DEPTH = 0.01       # m: where the hand pulls the handle to, below the wall surface
PHYSICAL_DAMPING = HANDLE_DAMPING + HAND_DAMPING  # b in Colgate's bound: all real damping on the handle
WALL_CLAMP = 200.0      # N


class HandHeldDevice:
    """A one-axis (z) haptic handle with mass, held by a spring-damper hand; Device protocol.

    The force sent in one tick acts over the next period (zero-order hold), integrated with
    semi-implicit Euler at the servo rate.
    """

    fingers, max_torque = 1, 0.0

    def __init__(self, period: float, max_force: float = WALL_CLAMP) -> None:
        self.period = period
        self.max_force = max_force
        self.z, self.v, self.force = 0.02, 0.0, 0.0
        self.work = 0.0  # energy the rendered force put into the handle, J
        self.forces: list[float] = []

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        hand_target = 0.02 - min(t / 0.2, 1.0) * (0.02 + HAND_DEPTH)
        a = (self.force + HAND_STIFFNESS * (hand_target - self.z) - (HAND_DAMPING + HANDLE_DAMPING) * self.v) / HANDLE_MASS
        self.v += a * self.period
        dz = self.v * self.period
        self.work += self.force * dz
        self.z += dz
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, self.z, 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz) -> None:
        self.force = fz
        self.forces.append(fz)

    def close(self) -> None:
        pass


def classify(forces: np.ndarray, clamp: float) -> str:
    if not np.all(np.isfinite(forces)) or np.abs(forces).max() >= clamp * (1 - 1e-9):
        return "unstable"
    n = len(forces)
    late, earlier = forces[int(0.8 * n):], forces[int(0.6 * n):int(0.8 * n)]
    p2p_late, p2p_earlier = np.ptp(late), np.ptp(earlier)
    mean = abs(float(np.mean(late))) or 1e-12
    if p2p_late > 0.05 * mean and p2p_late > 1.5 * p2p_earlier:
        return "unstable"
    if p2p_late > 0.05 * mean:
        return "buzzing"
    return "stable"


def wall_cell(K: float, B: float, rate: float, duration: float) -> dict:
    world = World(mujoco.MjModel.from_xml_string(WALL_XML))
    params = FingerParams(radius=0.0, stiffness=K, damping=B, model="point", max_force=WALL_CLAMP)
    finger = SoftFingerProxy(params, world.shapes, model("point"))
    device = HandHeldDevice(1.0 / rate)
    loop = ServoLoop(world, [finger], device, rate, overrun_watchdog=False)
    loop.run(int(duration * rate))
    forces = np.array(device.forces[:-1])  # the last send is the stop's zero
    T = 1.0 / rate
    return {"K": K, "B": B, "rate_hz": rate, "class": classify(forces, WALL_CLAMP),
            "energy_in_J": round(device.work, 6), "passive_by_colgate": PHYSICAL_DAMPING > K * T / 2 + abs(B)}


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


CELLS = {"wall": wall_cell, "grasp": grasp_cell, "extreme": extreme_cell}


def cell(kind: str, **params) -> dict:
    """One cell of the benchmark by kind (wall, grasp, extreme): what `softproxy.cells` runs."""
    return CELLS[kind](**params)


def grid(full: bool = False) -> list[dict]:
    """The benchmark's cells, in the order of its result: the wall grid (rate, B, K), the
    grasp grid (rate, k_τ, K), then the extremes."""
    Ks = [300.0, 1e3, 3e3, 1e4, 3e4, 1e5] if full else [300.0, 1e3, 3e3, 1e4, 3e4]
    Bs = [0.0, 0.5, 2.0, 10.0] if full else [0.0, 2.0, 10.0]
    rates = [250.0, 1000.0, 4000.0, 10000.0] if full else [250.0, 1000.0, 4000.0]
    cells = [{"kind": "wall", "K": K, "B": B, "rate": rate, "duration": 0.6}
             for rate in rates for B in Bs for K in Ks]
    gK = [500.0, 2000.0, 1e4, 5e4] if full else [500.0, 2000.0, 1e4]
    gkt = [0.2, 2.0, 20.0, 200.0] if full else [0.2, 2.0, 50.0]
    grates = [1000.0, 4000.0] if full else [1000.0]
    cells += [{"kind": "grasp", "K": K, "k_tau": kt, "rate": rate, "duration": 2.2}
              for rate in grates for kt in gkt for K in gK]
    cells += [{"kind": "extreme", "case": case} for case in EXTREMES]
    return cells


def measure(full: bool = False, progress=None, backend: Backend = Backend()) -> dict:
    """Run the grid's cells on `backend` (softproxy.cells: serial, a pool, or Ray; the result
    is the same); a cell that fails is listed in "failed" with its parameters."""
    cells = grid(full)

    def report(done: int, total: int, outcome) -> None:
        if progress:
            progress(f"{done}/{total} cells ({outcome.params['kind']} done), {backend.describe()}")

    outcomes = run_cells(cell, cells, backend, report)
    found = {"wall": [], "grasp": [], "extreme": []}
    failed = []
    for o in outcomes:
        if o.ok:
            found[o.params["kind"]].append(o.value)
        else:
            failed.append({"cell": o.params, "error": o.error})
    return {"wall": found["wall"], "grasp": found["grasp"], "extremes": found["extreme"], "failed": failed,
            "handle": {"mass_kg": HANDLE_MASS, "damping_Nspm": HANDLE_DAMPING, "hand_stiffness_Npm": HAND_STIFFNESS,
                       "colgate_b_Nspm": PHYSICAL_DAMPING,
                       "hand_damping_Nspm": HAND_DAMPING}}


COLOURS = {"stable": "#2ca02c", "buzzing": "#ff7f0e", "unstable": "#d62728", "dropped": "#7f7f7f"}


def chart(result: dict):
    """Wall classes per rate on K × B with Colgate's bound, and the grasp classes on K × k_τ."""
    rates = sorted({c["rate_hz"] for c in result["wall"]})
    fig, axes = figure(1, len(rates) + 1, (4.2 * (len(rates) + 1), 4))
    for ax, rate in zip(axes, rates):
        cells = [c for c in result["wall"] if c["rate_hz"] == rate]
        for c in cells:
            ax.scatter(c["K"], c["B"] + 0.05, color=COLOURS[c["class"]], s=120,
                       marker="o" if c["passive_by_colgate"] else "s")
        Ks = np.logspace(np.log10(min(c["K"] for c in cells)), np.log10(max(c["K"] for c in cells)), 50)
        ax.plot(Ks, np.maximum(PHYSICAL_DAMPING - Ks / (2 * rate), 0) + 0.05, "k--", lw=1, label="Colgate: b = KT/2 + |B|")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("K (N/m)")
        ax.set_ylabel("B (N·s/m) + 0.05")
        ax.set_title(f"wall at {rate:g} Hz")
    axes[0].legend(fontsize=7)
    ax = axes[-1]
    for c in result["grasp"]:
        ax.scatter(c["K"], c["k_tau"], color=COLOURS[c["class"]], s=120)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("K (N/m)")
    ax.set_ylabel("k_tau (N·m/rad)")
    ax.set_title("grasp (green stable, orange buzzing, red unstable, grey dropped)", fontsize=8)
    return fig


def main(args) -> int:
    progress = Progress("stability")
    result = measure(getattr(args, "full", False), progress, getattr(args, "backend", None) or Backend())
    progress.done()
    json_path, png_path = save(args.out, "stability", result, chart(result))
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    print("stability: hand-held handle against a stiff wall (class; * = passive by Colgate's bound)")
    for rate in sorted({c["rate_hz"] for c in result["wall"]}):
        cells = [c for c in result["wall"] if c["rate_hz"] == rate]
        Ks = sorted({c["K"] for c in cells})
        print(f"  {rate:6g} Hz   B \\ K " + "".join(f"{K:>11g}" for K in Ks))
        for B in sorted({c["B"] for c in cells}):
            row = {c["K"]: c for c in cells if c["B"] == B}
            print(f"  {'':9s}{B:8g} " + "".join(
                f"{row[K]['class'] + ('*' if row[K]['passive_by_colgate'] else ' '):>11s}" for K in Ks))
    agree = sum((c["class"] == "stable") == c["passive_by_colgate"] for c in result["wall"])
    stable_not_passive = sum(c["class"] == "stable" and not c["passive_by_colgate"] for c in result["wall"])
    passive_unstable = sum(c["class"] != "stable" and c["passive_by_colgate"] for c in result["wall"])
    print(f"  Colgate's bound agrees with the measured class in {agree}/{len(result['wall'])} cells; "
          f"{stable_not_passive} cells are stable though not passive (the bound is sufficient, not necessary); "
          f"{passive_unstable} passive cells are not stable")
    print("  grasp (3 N grip):")
    for c in result["grasp"]:
        print(f"    K {c['K']:>8g}  k_tau {c['k_tau']:>6g}  {c['rate_hz']:>6g} Hz  {c['class']:9s} "
              f"turned {c['turned_deg']:.3f} deg, grip ripple {c['grip_ripple'] * 100:.1f} %")
    print("  extremes (finite and clamped forces, proxy never > 1 µm inside):")
    for c in result["extremes"]:
        print(f"    {'ok  ' if c['ok'] else 'FAIL'} {c['case']}")
    for f in result["failed"]:
        print(f"  FAILED cell {f['cell']}: {f['error']}")
    print(f"  wrote {json_path} and {png_path}")
    return 0 if all(c["ok"] for c in result["extremes"]) and not result["failed"] else 1
