"""Each benchmark runs briefly and writes well-formed JSON and a PNG (no timing assertions)."""

import pytest
import json
import subprocess
import sys

from softproxy.compiled.servo import STAGES


pytestmark = pytest.mark.slow  # benchmarks


def bench(tmp_path, name, *extra):
    out = subprocess.run([sys.executable, "-m", "softproxy.cli", "bench", name, "--out", str(tmp_path), *extra],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    data = json.loads((tmp_path / f"{name}.json").read_text())
    png = (tmp_path / f"{name}.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    return data, out.stdout


def test_latency_bench(tmp_path):
    """The latency figures agree with each other: ordered percentiles, the ratio of the two
    medians, as many ticks as the durations ask for, miss rates of the counts, and no stage's
    median longer than the tick's that holds it."""
    data, text = bench(tmp_path, "latency", "--duration", "0.5", "--paced", "0.3", "--realtime")
    for key in ("tick_us", "mj_step_us"):
        t = data[key]
        assert set(t) == {"p50", "p99", "max"} and 0 < t["p50"] <= t["p99"] <= t["max"], (key, t)
    assert data["ratio_p50"] == round(data["tick_us"]["p50"] / data["mj_step_us"]["p50"], 2)
    assert data["ticks_timed"] == int(0.5 * data["rate_hz"])
    assert [p["rate_hz"] for p in data["paced"]] == [1000.0, 1000.0, 10000.0, 10000.0]
    assert "SCHED_FIFO" not in data["paced"][0]["scheduling"] and "SCHED_FIFO" in data["paced"][1]["scheduling"]
    for p in data["paced"]:
        assert p["ticks"] == int(0.3 * p["rate_hz"]), p
        assert 0 <= p["misses"] <= p["ticks"] and p["miss_rate"] == p["misses"] / p["ticks"], p
        assert 0 <= p["pacer_alone_misses"] <= p["ticks"], p
        assert p["pacer_alone_miss_rate"] == p["pacer_alone_misses"] / p["ticks"], p
        assert 0 < p["tick_us"]["p50"] <= p["tick_us"]["p99"] <= p["tick_us"]["max"], p
    stages = data["stages_us_p50"]
    assert list(STAGES) == list(stages)
    # each stage is timed inside its tick, so its median is at most the tick's (+ rounding)
    assert all(0 < v <= data["tick_us"]["p50"] + 0.01 for v in stages.values()), (stages, data["tick_us"])
    assert "/ mj_step" in text and "stages" in text


def test_latency_bench_leaves_the_scheduling_alone_unless_asked(tmp_path):
    """Without --realtime no paced run asks for SCHED_FIFO (a priority-80 busy loop would starve
    the machine's other work), and the report says how to ask."""
    data, text = bench(tmp_path, "latency", "--duration", "0.2", "--paced", "0.1")
    assert [p["rate_hz"] for p in data["paced"]] == [1000.0, 10000.0]
    assert not any("SCHED_FIFO" in p["scheduling"] for p in data["paced"]) and data["realtime"] is False
    assert "add --realtime" in text


def test_the_pacer_alone_counts_what_it_misses():
    """The empty paced loop the latency bench compares with counts a tick as missed exactly when
    it ends after the next deadline. Each tick is bracketed by the test's own readings of the
    same clock: one that began past the next deadline must be counted, one that returned
    before it must not; started ten periods late the first nine are certain misses, and
    paced from now (on an idle machine) none is."""
    import time

    import numpy as np

    from softproxy.benchmarks.latency import _pacer_alone
    from softproxy.compiled.servo import LOOP

    period_ns = 1_000_000
    loop = np.zeros(1, dtype=LOOP)
    loop["period_ns"], loop["spin_ns"] = period_ns, 1_500_000
    counters = np.zeros(2, dtype=np.int64)
    _pacer_alone(loop, counters, 1)  # compiled outside the count
    for late in (10, 0):
        counters[:] = 0
        loop["next_ns"] = time.monotonic_ns() - late * period_ns
        certain = possible = 0
        for k in range(20):
            deadline = int(loop["next_ns"][0]) + period_ns  # a tick ending after this missed
            counted = int(counters[1])
            before = time.monotonic_ns()  # the clock the pacer reads (test_native)
            _pacer_alone(loop, counters, 1)
            after = time.monotonic_ns()
            missed = int(counters[1]) - counted
            if before > deadline:
                assert missed == 1, (late, k)
            elif after <= deadline:
                assert missed == 0, (late, k)
            certain += before > deadline
            possible += after > deadline
        print(f"\nstarted {late} periods late: {certain} certain misses, {possible} possible, "
              f"{int(counters[1])} counted")
        if late:
            assert certain >= 9  # ticks 0-8 began past their next deadline


def test_peer_bench(tmp_path):
    """The peer comparison's physics is checked too (tests/test_peer.py checks its parts):
    softproxy holds, point contacts spin, MuJoCo's limit is linear, the power law's |P|^γ."""
    data, text = bench(tmp_path, "peer", "--duration", "1.5")
    hold = data["hold"]
    assert abs(hold["softproxy saturating law"]["rotation_end_deg"]) < 2.0
    assert abs(hold["softproxy point"]["rotation_max_deg"]) > 20.0
    exps = data["limit_exponent"]
    assert abs(exps["softproxy power law"]["0.5-8 N"] - 4 / 3) < 0.05  # seed 002 eq 29: M ∝ P^(4/3) for CH
    assert abs(exps["mujoco best condim 4"]["0.5-8 N"] - 1.0) < 0.1
    assert "torsional limit per contact vs the measured fingertip" in text


def test_stability_bench(tmp_path):
    data, text = bench(tmp_path, "stability")
    classes = {c["class"] for c in data["wall"]}
    assert classes <= {"stable", "buzzing", "unstable"} and "stable" in classes and "unstable" in classes
    assert {c["device"] for c in data["wall"]} == set(data["devices"]) and len(data["devices"]) == 4
    # Colgate's passivity bound is sufficient: no passive cell may be found unstable
    assert not [c for c in data["wall"] if c["passive_by_colgate"] and c["class"] == "unstable"]
    # the measured boundary (perfect encoder, no passivity controller) within 10 % of the analysis
    agree = data["boundary_agreement"]
    assert agree["compared"] > 0 and agree["within_10pct"] == agree["compared"], data["boundaries"]
    assert all(c["ok"] for c in data["extremes"]), data["extremes"]
    assert "passivity controller: " in text and "boundary:" in text


def test_the_measured_wall_boundary_lies_between_stable_and_unstable_cells():
    """A small grid of the stability bench on the Falcon model at 1 kHz and 250 Hz: a wall at
    half the analytic boundary is bounded, one at twice it (and the issue's K = 1e4 N/m,
    B = 0 at 1 kHz, which the old Euler-integrated handle called stable) is unstable, and
    the bisected boundary lies between them, within 10 % of the exact sampled-wall poles'
    (Colgate & Schenkel 1997's loop; Gil et al. 2004's small-period form 2(b + B)/T). The
    analysis is of the wall alone: the passivity controller is off."""
    from softproxy.benchmarks.stability import boundary_cell, wall_run

    assert wall_run("Falcon", 1e4, 0.0, 1000.0, encoder=False, passivity=False)["class"] == "unstable"
    for rate, B in ((1000.0, 2.0), (250.0, 0.0)):
        b = boundary_cell("Falcon", rate, B, encoder=False, passivity=False)
        K = b["analytic_K"]
        assert wall_run("Falcon", 0.5 * K, B, rate, encoder=False, passivity=False)["bounded"]
        assert wall_run("Falcon", 2.0 * K, B, rate, encoder=False, passivity=False)["class"] == "unstable"
        assert 0.5 * K < b["measured_bracket"][0] < b["measured_K"] < b["measured_bracket"][1] < 2.0 * K
        assert abs(b["measured_K"] / K - 1.0) <= 0.10, b


def test_tradeoff_bench(tmp_path):
    data, text = bench(tmp_path, "tradeoff", "--duration", "0.9")
    rows = data["rows"]
    assert {r["model"] for r in rows} == {"point", "CH", "MH", "VS", "LFM"}
    ref = [r for r in rows if r["model"] == "LFM" and r["rate_hz"] == data["reference"]["rate_hz"]]
    assert ref and all(r["force_rms_error_N"] == r["torque_rms_error_Nmm"] == r["outcome_error_deg"] == 0.0
                       for r in ref)  # the reference against itself
    step = data["mj_step_us_p50"]
    for scene in data["scenes"]:
        ours = [r for r in rows if r["scene"] == scene]
        assert len({(r["model"], r["rate_hz"]) for r in ours}) == len(ours)  # one row a configuration
        key = [(r["tick_us_p50"], r["force_rms_error_N"], r["torque_rms_error_Nmm"]) for r in ours]
        for r, k in zip(ours, key):
            # on the Pareto front exactly when no other configuration is as good on every
            # criterion and better on one (computed here again, from the rows)
            beaten = any(all(o <= m for o, m in zip(other, k)) and other != k for other in key)
            assert r["pareto"] == (not beaten), r
            assert abs(r["cost_x_mj_step"] - r["tick_us_p50"] / step) <= 0.01 + 1e-3 * r["cost_x_mj_step"], r
    fid = {r["config"]: r for r in data["fingertip_sensors"]["rows"]}
    assert set(fid) == {"off", "off (again)", "tactile 100 Hz", "sensing 100 Hz", "sensing 1 kHz",
                        "tactile + sensing 100 Hz"}
    assert fid["off"]["frames"] == fid["off (again)"]["frames"] == 0 and fid["off"]["mean_x_off"] == 1.0
    assert fid["sensing 1 kHz"]["frames"] == 10 * fid["sensing 100 Hz"]["frames"] > 0
    assert fid["sensing 100 Hz"]["sensing_location_max_m"] < 1e-6 and fid["sensing 100 Hz"]["sensing_refused"] == 0
    assert all(abs(f - 3.0) < 0.1 for f in fid["tactile 100 Hz"]["tactile_last_force_N"])  # the 3 N grip
    assert "fingertip sensors on two_finger_grasp" in text


def test_godobject_bench_times_every_situation_without_penetration():
    """`softproxy bench godobject` in miniature: every situation is timed, the proxy touches
    what it should (free space never, the pressed ones always) and never goes inside."""
    from softproxy.benchmarks import godobject

    result = godobject.measure(updates=40, warm=40)
    rows = {r["situation"]: r for r in result["rows"]}
    assert len(rows) == len(godobject.situations())
    assert rows["free space"]["contact_fraction"] == 0.0
    for name, row in rows.items():
        assert row["p50_us"] > 0.0 and row["penetration_max_m"] <= 1e-6, name
        if name != "free space":
            assert row["contact_fraction"] == 1.0, name


def test_friction_bench(tmp_path):
    """Steady twist and slide rows for both options; on every motion the slip state has fewer
    transitions and no more ripple than the per-tick option (docs/friction.md)."""
    data, text = bench(tmp_path, "friction", "--duration", "2")
    rows = data["rows"]
    motions = sorted({r["motion"] for r in rows})
    assert any(m.startswith("twist") for m in motions) and any(m.startswith("slide") for m in motions)
    for motion in motions:
        state = [r for r in rows if r["motion"] == motion and r["option"] == "slip state"]
        tick = [r for r in rows if r["motion"] == motion and r["option"].startswith("per tick")]
        assert len(state) == len(tick) == 1, motion
        assert state[0]["transitions"] < tick[0]["transitions"] and state[0]["ripple"] <= tick[0]["ripple"], motion
    assert "trans/s" in text


def test_multirate_bench(tmp_path):
    """`softproxy bench multirate --quick`: every (scene, haptic rate, MuJoCo rate) once, the
    one-rate 10 kHz run its own reference (no error), every other run's force off it and
    less so with MuJoCo at 500 Hz than at 100 Hz (lockstep runs: deterministic), ordered
    percentiles, no ticks "between steps" when a step spans at most two ticks, and a paced
    run of 0.5 s for each haptic rate with MuJoCo at 250 Hz and per tick, its counts in range."""
    data, text = bench(tmp_path, "multirate", "--quick")
    assert data["quick"] is True and set(data["scenes"]) == {"bin_pick", "two_finger_grasp"}
    for name, scene in data["scenes"].items():
        assert scene["seconds"] == 1.0 and scene["tracked"] in {"pushed", "box"}
        assert set(scene["mj_step_us"]) == {"100", "250", "500", "1000", "4000", "10000"}
        runs = {(r["haptic_hz"], r["physics_hz"]): r for r in scene["runs"]}
        assert set(runs) == {(h, p) for h in (1000.0, 4000.0, 10000.0) for p in (100.0, 250.0, 500.0, h)}
        for (h, p), r in runs.items():
            assert r["one_rate"] == (p == h)
            for key in ("tick_us", "jump_at_updates_N"):
                assert 0 <= r[key]["p50"] <= r[key]["p99"] <= r[key]["max"], (name, h, p, key)
            assert (r["between_steps_tick_us"]["p50"] is None) == (h / p <= 2), (name, h, p)
            assert (r["jump_elsewhere_N"]["p50"] is None) == (p == h), (name, h, p)
            assert (r["force_error_rms_N"] == 0.0) == (h == p == 10000.0), (name, h, p)
            assert r["force_rms_N"] > 1.0  # the fingers squeezed: there was force to get wrong
            assert (r["track_vs_one_rate_mm"] is None) == (p == h), (name, h, p)
        for h in (1000.0, 4000.0, 10000.0):
            assert runs[(h, 100.0)]["force_error_rms_N"] > runs[(h, 500.0)]["force_error_rms_N"], (name, h)
        paced = scene["paced"]
        assert [(r["haptic_hz"], r["physics_hz"]) for r in paced] == [
            (h, p) for h in (1000.0, 4000.0, 10000.0) for p in (250.0, h)]
        for r in paced:
            assert r["ticks"] == int(0.5 * r["haptic_hz"]) and r["one_rate"] == (r["physics_hz"] == r["haptic_hz"])
            assert 0 <= r["misses"] <= r["ticks"] and 0 <= r["overruns"] <= r["ticks"], r
            assert 0 <= r["pacer_alone_misses"] <= r["ticks"], r
    assert "F err RMS" in text and "bare mj_step" in text and "the pacer alone" in text
