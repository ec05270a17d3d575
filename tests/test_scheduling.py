"""Real-time scheduling of a servo thread (softproxy.scheduling): granted or reported, always restored."""

import os
import threading

import pytest

from softproxy.scheduling import realtime_thread

linux = pytest.mark.skipif(not hasattr(os, "sched_setscheduler"), reason="SCHED_FIFO is Linux's")


@linux
def test_the_thread_gets_what_it_asked_for_or_says_why_and_is_restored():
    """Inside the block the thread runs SCHED_FIFO on one CPU (or the refusal is reported and
    nothing changed); after it, the policy and the affinity are what they were."""
    policy, affinity = os.sched_getscheduler(0), os.sched_getaffinity(0)
    cpu = max(affinity)
    with realtime_thread(10, cpu) as granted:
        if granted.priority is not None:
            assert os.sched_getscheduler(0) == os.SCHED_FIFO and os.sched_getparam(0).sched_priority == 10
            assert "SCHED_FIFO priority 10" in str(granted)
        else:
            assert os.sched_getscheduler(0) == policy and "SCHED_FIFO refused" in str(granted)
        assert granted.cpus == {cpu} and os.sched_getaffinity(0) == {cpu}
    assert os.sched_getscheduler(0) == policy and os.sched_getaffinity(0) == affinity


@linux
def test_it_changes_only_the_calling_thread():
    """Another thread keeps its own scheduling while one thread is real-time."""
    seen = {}
    inside, done = threading.Event(), threading.Event()

    def other():
        inside.wait(5)
        seen["policy"], seen["cpus"] = os.sched_getscheduler(0), os.sched_getaffinity(0)
        done.set()

    before = os.sched_getaffinity(0)
    t = threading.Thread(target=other)
    t.start()
    with realtime_thread(10, max(before)):
        inside.set()
        done.wait(5)
    t.join()
    assert seen["policy"] == os.SCHED_OTHER and seen["cpus"] == before


@pytest.mark.parametrize("priority", [0, 100, 1.5, "80"])
def test_a_priority_out_of_range_is_named(priority):
    with pytest.raises(ValueError, match="priority must be an integer from 1 to 99"):
        with realtime_thread(priority):
            pass


def test_a_cpu_the_machine_lacks_is_reported_not_raised():
    with realtime_thread(None, 10_000) as granted:
        pass
    assert granted.cpus is None and "CPU 10000 refused" in str(granted)


@linux
def test_a_servo_thread_runs_where_it_was_asked_and_reports_it():
    """`run_in_thread(cpu=…)` pins the servo thread (not the caller) and keeps what was granted;
    the run itself is the same run."""
    from softproxy.run import build, open_device
    from softproxy.scene import load_scene

    scene = load_scene("two_finger_grasp")
    before = os.sched_getaffinity(0)
    cpu = max(before)
    with build(scene, open_device("sim", scene), realtime=False) as loop:
        thread = loop.run_in_thread(200, realtime=False, cpu=cpu)
        thread.join(60)
        assert not thread.is_alive() and loop.error is None and loop.ticks == 200
        assert loop.scheduling.cpus == {cpu} and loop.scheduling.priority is None
    assert os.sched_getaffinity(0) == before
    with pytest.raises(ValueError, match="priority"):
        loop.run_in_thread(10, priority=0)


def test_a_real_time_thread_sleeps_most_of_each_period(monkeypatch):
    """A paced tick spins up to 1.5 ms in an ordinary thread (at 1 kHz it never sleeps) but at
    most 0.2 ms, and half the period at 10 kHz, under SCHED_FIFO: a real-time thread spinning
    its whole core is throttled by Linux (stopped 50 ms every second), unless throttling is off."""
    from softproxy import scheduling
    from softproxy.run import build, open_device
    from softproxy.scene import load_scene

    assert scheduling.spin_time(1000.0) == scheduling.SPIN_ORDINARY_S or scheduling.realtime_policy()
    monkeypatch.setattr(scheduling, "realtime_policy", lambda: True)
    monkeypatch.setattr(scheduling, "rt_throttled", lambda: False)
    assert scheduling.spin_time(10_000.0) == scheduling.SPIN_ORDINARY_S  # nothing stops it: spin
    monkeypatch.setattr(scheduling, "rt_throttled", lambda: True)
    assert scheduling.spin_time(1000.0) == pytest.approx(2e-4)
    assert scheduling.spin_time(10_000.0) == pytest.approx(5e-5)
    scene = load_scene("two_finger_grasp")
    with build(scene, open_device("sim", scene), rate_hz=10_000.0, realtime=False) as loop:
        loop.run(20, realtime=True)
        assert loop.state[0].spin_ns == 50_000 and loop.ticks == 20
        loop.run(20, realtime=True, spin_s=1e-3)
        assert loop.state[0].spin_ns == 1_000_000


@linux
def test_a_fifo_thread_is_seen_as_real_time():
    from softproxy.scheduling import realtime_policy

    with realtime_thread(10) as granted:
        assert realtime_policy() == (granted.priority is not None)
    assert not realtime_policy()


def test_rt_throttling_is_read_from_the_kernel(tmp_path, monkeypatch):
    from softproxy import scheduling

    setting = tmp_path / "sched_rt_runtime_us"
    monkeypatch.setattr(scheduling, "RT_RUNTIME", str(setting))
    assert scheduling.rt_throttled()  # unknown: assume throttled
    setting.write_text("950000\n")
    assert scheduling.rt_throttled()
    setting.write_text("-1\n")
    assert not scheduling.rt_throttled()
