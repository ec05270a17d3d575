"""`softproxy bench sensing`: contact sensing (seed 003) — rate per solve and accuracy under the
seed's sensor noise, against the paper's Table 1 and against other ways of solving it.

Speed: random pushing contacts all over the upper half of the skin (friction ratio ≤ 1, local
torque ≤ 10 N·mm, normal force 0.1–10 N), each a distinct wrench, solved one call at a time;
the mean per solve is the best of 5 passes over the set, p50/p99 come from timing every call.
Rows: `ContactSensor.sense` (ellipsoid frame, cold start), the same in the sensor frame, warm
started along a sliding contact sampled at 1 kHz, `sense_main` (the CLI's dict), and the same
two-unknown system through scipy.optimize (least_squares 'lm' and root 'hybr'), and the
paper's own five-unknown LM (eq 10, Algorithm 1) with the share of pulling roots it returns.

Accuracy: Table 1's three conditions (f_n, f_t, q ranges), contacts at location A (the
central top, where the paper measured) and all over the upper half; the wrench is quantised
to the Nano17's resolution (1/160 N, 1/32 N·mm, error uniform in ±½ LSB) or given Gaussian
noise of σ = 1 LSB. Friction is capped at μ = 1 (the envelope the paper calls reliable) and
f_n starts at 0.2 N (Table 1's ranges start at 0, where any location is noise).

Prints a table, writes sensing.json and sensing.png to the output folder.
"""

from __future__ import annotations

import json
import math
import random
import sys
import time
from pathlib import Path

import numpy as np

from softproxy import sensing as S
from softproxy import units

_clock = time.perf_counter


# ---------------------------------------------------------------------------
# Synthetic contacts and noise
# ---------------------------------------------------------------------------
def sample_contact(rng: random.Random, tip: S.Fingertip, *, fn_range=(0.1, 10.0), ft_max=math.inf, mu_max=1.0,
                   q_range=(units.nmm(-10.0), units.nmm(10.0)), placement: str = "upper") -> dict:
    """A random pushing contact and the wrench it makes (ellipsoid frame).

    placement "upper": outward normal uniform over the upper hemisphere (z ≥ 0 on the skin);
    "top": location A, the central top (0, 0, c) of Algorithm 1 / §4.3.
    """
    if placement == "top":
        n = (0.0, 0.0, 1.0)
    else:
        th = rng.uniform(0.0, 2.0 * math.pi)
        sz = rng.uniform(0.0, 1.0)
        cz = math.sqrt(1.0 - sz * sz)
        n = (cz * math.cos(th), cz * math.sin(th), sz)
    fn = rng.uniform(*fn_range)
    t = (rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 1))
    tn = t[0] * n[0] + t[1] * n[1] + t[2] * n[2]
    t = (t[0] - tn * n[0], t[1] - tn * n[1], t[2] - tn * n[2])
    tl = math.sqrt(t[0] ** 2 + t[1] ** 2 + t[2] ** 2)
    ft = rng.uniform(0.0, min(ft_max, mu_max * fn))
    fr = (t[0] / tl * ft, t[1] / tl * ft, t[2] / tl * ft)
    tau = rng.uniform(*q_range)
    F, M, p, dd = S.wrench_from_contact(n, fn, fr, tau, tip)
    return {"F": F, "M": M, "point": p, "normal": n, "fn": fn, "friction": fr, "ft": ft, "tau": tau, "dd": dd}


def add_noise(F, M, noise: str, rng: random.Random) -> tuple:
    """The wrench as the seed's Nano17 would report it: 'quantise' (round to 1/160 N, 1/32 N·mm),
    'gauss' (σ = 1 LSB per channel) or 'none'."""
    fl, tl = S.FORCE_LSB, S.TORQUE_LSB
    if noise == "quantise":
        return tuple(round(v / fl) * fl for v in F), tuple(round(v / tl) * tl for v in M)
    if noise == "gauss":
        return tuple(v + rng.gauss(0, fl) for v in F), tuple(v + rng.gauss(0, tl) for v in M)
    if noise == "none":
        return tuple(F), tuple(M)
    raise ValueError(f"noise must be quantise, gauss or none, got {noise!r}")


def _stats(xs) -> dict:
    xs = np.asarray(xs, float)
    if xs.size == 0:
        return {"mean": None, "max": None}
    return {"mean": float(xs.mean()), "max": float(xs.max())}


def accuracy(condition: str, noise: str, placement: str, n: int, seed: int = 0,
             sensor: S.ContactSensor | None = None) -> dict:
    """Errors of f_n, f_t (magnitude, as the paper's benchmark sensor measured), q, location and
    normal over `n` contacts of a Table 1 condition, with the given noise."""
    sensor = S.ContactSensor() if sensor is None else sensor
    tip = sensor.tip
    cond = S.TABLE_1[condition]
    rng = random.Random(seed)
    e_fn, e_ft, e_q, e_loc, e_ang, e_dd = [], [], [], [], [], []
    refused = 0
    for _ in range(n):
        c = sample_contact(rng, tip, fn_range=(max(0.2, cond["fn_N"][0]), cond["fn_N"][1]),
                           ft_max=cond["ft_N"][1], q_range=cond["q_Nm"], placement=placement)
        F, M = add_noise(c["F"], c["M"], noise, rng)
        est = sensor.sense(F, M, checked=True)
        if not est.explained:
            refused += 1
            continue
        e_fn.append(abs(est.normal_force - c["fn"]))
        e_ft.append(abs(math.sqrt(sum(v * v for v in est.friction)) - c["ft"]))
        e_q.append(abs(est.local_torque - c["tau"]))
        e_loc.append(math.dist(est.point, c["point"]))
        cosang = sum(a * b for a, b in zip(est.normal, c["normal"]))
        e_ang.append(math.acos(max(-1.0, min(1.0, cosang))))
        e_dd.append(abs(est.deformation - c["dd"]))
    loc = np.asarray(e_loc)
    out = {
        "condition": condition, "noise": noise, "placement": placement, "samples": n, "refused": refused,
        "error_fn_N": _stats(e_fn), "error_ft_N": _stats(e_ft), "error_q_Nm": _stats(e_q),
        "error_location_m": _stats(e_loc), "location_rmse_m": float(np.sqrt((loc**2).mean())) if loc.size else None,
        "error_normal_rad": _stats(e_ang), "error_deformation_m": _stats(e_dd),
    }
    paper = {k: cond[k] for k in ("error_fn_N", "error_ft_N", "error_q_Nm")}
    out["within_table_1"] = bool(refused == 0 and all(
        out[k]["mean"] <= paper[k][0] and out[k]["max"] <= paper[k][1] for k in paper))
    out["location_within_paper_rmse"] = bool(loc.size and out["location_rmse_m"] <= S.LOCATION_RMSE)
    return out


# ---------------------------------------------------------------------------
# Speed
# ---------------------------------------------------------------------------
def _time_calls(fn, args_list, passes: int = 5) -> dict:
    """Best-of-`passes` mean over the set, and p50/p99 from timing every call of one pass (µs)."""
    best = math.inf
    for _ in range(passes):
        t0 = _clock()
        for a in args_list:
            fn(*a)
        best = min(best, (_clock() - t0) / len(args_list))
    per = np.empty(len(args_list))
    for i, a in enumerate(args_list):
        t0 = _clock()
        fn(*a)
        per[i] = _clock() - t0
    mean_us = best * 1e6
    return {"mean_us": round(mean_us, 2), "p50_us": round(float(np.percentile(per, 50)) * 1e6, 2),
            "p99_us": round(float(np.percentile(per, 99)) * 1e6, 2), "rate_hz": round(1e6 / mean_us)}


def _chart_system(F, M, tip: S.Fingertip):
    """The same two-unknown system as ContactSensor (g1, g2 and Jacobian), in numpy, for scipy."""
    F = np.asarray(F, float)
    M = np.asarray(M, float)
    f2 = float(F @ F)
    f = math.sqrt(f2)
    e = F / f
    k = np.eye(3)[int(np.argmin(np.abs(e)))]
    u = np.cross(e, k)
    u /= np.linalg.norm(u)
    v = np.cross(e, u)
    h = float(F @ M) / f2
    q = np.cross(F, M) / f2
    qu, qv = float(q @ u), float(q @ v)
    ax = np.array([tip.a, tip.b, tip.c])
    inv = 1.0 / tip.E1

    def parts(y):
        m = -e + y[0] * u + y[1] * v
        mm2 = 1.0 + y[0] ** 2 + y[1] ** 2
        dd = f * inv / math.sqrt(mm2)
        A = ax - dd
        B = A * A
        bm = B * m
        s = math.sqrt(float(m @ bm))
        p = bm / s
        return m, mm2, dd, A, B, s, p

    def fun(y):
        m, mm2, dd, A, B, s, p = parts(y)
        return np.array([p @ u - qu + h * y[1], p @ v - qv - h * y[0]])

    def jac(y):
        m, mm2, dd, A, B, s, p = parts(y)
        P = np.stack([u, v], axis=1)
        G = (P.T @ (np.diag(B) - np.outer(p, p)) @ P) / s
        dB = -2.0 * A * m
        dp = (dB - p * float(m @ dB) / (2.0 * s)) / s
        ddy = -dd / mm2 * np.asarray(y)
        return G + np.array([[0.0, h], [-h, 0.0]]) + np.outer(P.T @ dp, ddy)

    return fun, jac


def _sliding_track(tip: S.Fingertip, n: int) -> list:
    """A contact sliding over the upper skin at ~20 mm/s, sampled at 1 kHz, with varying load."""
    out = []
    for i in range(n):
        t = i * 1e-3
        th = 0.7 * t
        ph = 0.6 + 0.4 * math.sin(0.9 * t)
        nrm = (math.cos(th) * math.cos(ph), math.sin(th) * math.cos(ph), math.sin(ph))
        fn = 2.0 + 1.5 * math.sin(2.0 * t)
        tvec = (-math.sin(th), math.cos(th), 0.0)
        F, M, p, dd = S.wrench_from_contact(nrm, fn, tuple(0.5 * fn * x for x in tvec), units.nmm(3.0 * math.cos(t)),
                                            tip)
        out.append((F, M))
    return out


def speed(n: int = 2000, n_paper: int = 200, seed: int = 1) -> dict:
    """Per-solve time of each way of solving the same wrenches."""
    from scipy import optimize

    sensor = S.ContactSensor()
    tip = sensor.tip
    mount = sensor.mount
    rng = random.Random(seed)
    cases = [sample_contact(rng, tip) for _ in range(n)]
    wrenches = [(c["F"], c["M"]) for c in cases]
    rows = {}

    its = [sensor.sense(F, M).iterations for F, M in wrenches]
    rows["ContactSensor.sense (cold start)"] = {**_time_calls(sensor.sense, wrenches),
                                                "iterations_mean": round(float(np.mean(its)), 2),
                                                "iterations_max": int(max(its))}
    sensor_frame = [mount.wrench_to_sensor(F, M) for F, M in wrenches]

    def sense_sensor(F, M):
        return sensor.sense(F, M, sensor_frame=True)

    rows["ContactSensor.sense (sensor frame)"] = _time_calls(sense_sensor, sensor_frame)

    track = _sliding_track(tip, n)
    warm = S.ContactSensor(warm_start=True)
    its = [warm.sense(F, M).iterations for F, M in track]
    warm.reset()
    rows["ContactSensor.sense (warm start, sliding 1 kHz)"] = {
        **_time_calls(warm.sense, track), "iterations_mean": round(float(np.mean(its)), 2),
        "iterations_max": int(max(its))}
    cold_track = _time_calls(sensor.sense, track)
    rows["ContactSensor.sense (cold start, same sliding track)"] = cold_track

    six = [(list(F) + list(M),) for F, M in wrenches]
    rows["sense_main (CLI dict)"] = _time_calls(S.sense_main, six)

    def scipy_lm(F, M):
        fun, jac = _chart_system(F, M, tip)
        return optimize.least_squares(fun, np.zeros(2), jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)

    def scipy_hybr(F, M):
        fun, jac = _chart_system(F, M, tip)
        return optimize.root(fun, np.zeros(2), jac=jac, method="hybr", tol=1e-14)

    sub = wrenches[: max(50, n // 4)]
    for name, fn in (("scipy least_squares lm (same 2 unknowns)", scipy_lm),
                     ("scipy root hybr (same 2 unknowns)", scipy_hybr)):
        worst = 0.0
        for (F, M), c in zip(sub, cases):
            res = fn(F, M)
            worst = max(worst, abs(res.x @ res.x - sum(v * v for v in c["friction"]) / c["fn"] ** 2))
        rows[name] = {**_time_calls(fn, sub, passes=2), "friction_ratio_sq_max_error": worst}

    paper = wrenches[:n_paper]
    pulling = wrong = 0
    its = []
    for (F, M), c in zip(paper, cases):
        r = S.solve_algorithm1(F, M)
        its.append(r["iterations"])
        if not r["pushing"]:
            pulling += 1
        elif not r["converged"] or math.dist(r["point"], c["point"]) > 1e-6:
            wrong += 1
    rows["paper Algorithm 1 (5 unknowns, numpy LM, eq 10-13)"] = {
        **_time_calls(S.solve_algorithm1, paper, passes=1), "iterations_mean": round(float(np.mean(its)), 2),
        "iterations_max": int(max(its)), "pulling_root_share": pulling / len(paper),
        "wrong_or_unconverged_share": wrong / len(paper)}
    return {"contacts": n, "rows": rows}


# ---------------------------------------------------------------------------
def measure(full: bool = False, progress=None) -> dict:
    n_acc = 2000 if full else 400
    n_speed = 4000 if full else 1500
    acc = []
    sensor = S.ContactSensor()
    combos = [(cond, noise, place) for cond in S.TABLE_1 for noise in ("quantise", "gauss")
              for place in ("top", "upper")]
    for i, (cond, noise, place) in enumerate(combos):
        if progress:
            progress(f"accuracy {cond} {noise} {place}")
        acc.append(accuracy(cond, noise, place, n_acc, seed=100 + i, sensor=sensor))
    if progress:
        progress("noise-free recovery")
    exact = accuracy("condition-3", "none", "upper", n_acc, seed=7, sensor=sensor)
    if progress:
        progress("speed")
    sp = speed(n_speed, n_paper=300 if full else 120)
    return {
        "machine_note": "single-threaded CPython, one call per solve",
        "speed": sp,
        "accuracy": acc,
        "noise_free": {"location_max_m": exact["error_location_m"]["max"], "error_fn_max_N": exact["error_fn_N"]["max"],
                       "error_q_max_Nm": exact["error_q_Nm"]["max"], "refused": exact["refused"]},
        "paper": {"table_1": S.TABLE_1, "location_rmse_m": S.LOCATION_RMSE, "rate_hz": [158, 242]},
        "targets": {"rate_hz": 10_000, "noise_free_location_m": 1e-6},
    }


def chart(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.5))
    rows = result["speed"]["rows"]
    names = list(rows)
    a.barh(names, [rows[k]["mean_us"] for k in names], color="tab:blue")
    a.axvline(100.0, color="k", ls="--", lw=1, label="10 kHz (100 µs)")
    a.set_xscale("log")
    a.set_xlabel("µs per solve (log)")
    a.tick_params(axis="y", labelsize=7)
    a.legend(fontsize=8)
    a.set_title("contact sensing: time per solve")
    acc = [r for r in result["accuracy"] if r["noise"] == "quantise" and r["placement"] == "upper"]
    labels, ours, paper = [], [], []
    for r in acc:
        t1 = S.TABLE_1[r["condition"]]
        for key, unit in (("error_fn_N", "fn"), ("error_ft_N", "ft"), ("error_q_Nm", "q")):
            labels.append(f"{r['condition'][-1]}:{unit}")
            ours.append(r[key]["mean"])
            paper.append(t1[key][0])
    x = np.arange(len(labels))
    b.bar(x, np.asarray(ours) / np.asarray(paper), 0.6, label="ours (quantised wrench) / Table 1 mean")
    b.axhline(1.0, color="k", lw=1)
    b.set_yscale("log")
    b.set_xticks(x)
    b.set_xticklabels(labels, fontsize=7)
    b.set_ylabel("mean error / paper's mean error")
    b.legend(fontsize=8)
    b.set_title("accuracy vs the contact-sensing paper's Table 1 (upper half)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _fmt(x, scale=1.0, spec=".4f"):
    return "-" if x is None else format(x * scale, spec)


def main(args) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    def progress(msg):
        print(f"\r  sensing: {msg:60s}", end="", file=sys.stderr, flush=True)

    result = measure(getattr(args, "full", False), progress=progress)
    print("\r" + " " * 72 + "\r", end="", file=sys.stderr)
    try:
        chart(result, out / "sensing.png")
    except ImportError:  # pragma: no cover - matplotlib is a dependency
        pass
    (out / "sensing.json").write_text(json.dumps(result, indent=1))
    if getattr(args, "json", False):
        print(json.dumps(result, indent=2))
        return 0
    sp = result["speed"]
    print(f"contact sensing (Liu et al.): time per solve, {sp['contacts']} distinct upper-half contacts")
    print(f"  {'':52s}{'mean':>9s}{'p50':>9s}{'p99':>9s}{'rate':>10s}{'iter':>7s}")
    for name, r in sp["rows"].items():
        it = r.get("iterations_mean")
        print(f"  {name:52s}{r['mean_us']:9.1f}{r['p50_us']:9.1f}{r['p99_us']:9.1f}{r['rate_hz']:8d}Hz"
              f"{'' if it is None else format(it, '7.2f')}")
    pa = sp["rows"]["paper Algorithm 1 (5 unknowns, numpy LM, eq 10-13)"]
    print(f"  paper's Algorithm 1 returns the pulling root for {pa['pulling_root_share'] * 100:.0f} % of contacts, "
          f"another wrong/unconverged answer for {pa['wrong_or_unconverged_share'] * 100:.0f} %")
    nf = result["noise_free"]
    print(f"  noise-free: largest location error {nf['location_max_m']:.2e} m (target < 1e-6), refused {nf['refused']}")
    print("accuracy: mean (max) errors; Table 1 = the paper's hardware")
    print(f"  {'condition':12s}{'noise':9s}{'where':7s}{'f_n (N)':>18s}{'f_t (N)':>18s}{'q (N·mm)':>18s}"
          f"{'loc RMSE (mm)':>15s}{'refused':>9s}")
    for cond, t1 in S.TABLE_1.items():
        print(f"  {cond:12s}{'Table 1':16s}"
              f"{t1['error_fn_N'][0]:>10.3f} ({t1['error_fn_N'][1]:.3f})"
              f"{t1['error_ft_N'][0]:>10.3f} ({t1['error_ft_N'][1]:.3f})"
              f"{units.to_nmm(t1['error_q_Nm'][0]):>10.3f} ({units.to_nmm(t1['error_q_Nm'][1]):.3f})"
              f"{units.to_mm(S.LOCATION_RMSE):>15.2f}")
        for r in result["accuracy"]:
            if r["condition"] != cond:
                continue
            print(f"  {'':12s}{r['noise']:9s}{r['placement']:7s}"
                  f"{_fmt(r['error_fn_N']['mean']):>10s} ({_fmt(r['error_fn_N']['max'])})"
                  f"{_fmt(r['error_ft_N']['mean']):>10s} ({_fmt(r['error_ft_N']['max'])})"
                  f"{_fmt(r['error_q_Nm']['mean'], 1e3):>10s} ({_fmt(r['error_q_Nm']['max'], 1e3)})"
                  f"{_fmt(r['location_rmse_m'], 1e3):>15s}{r['refused']:>9d}")
    ok = all(r["within_table_1"] for r in result["accuracy"])
    print(f"  all conditions within Table 1's mean and max: {ok}")
    print(f"  wrote {out / 'sensing.json'} and {out / 'sensing.png'}")
    return 0


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench-out")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--full", action="store_true")
    raise SystemExit(main(ap.parse_args()))
