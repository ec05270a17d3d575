"""The tick as compiled blocks: the same results as the per-tick Python path, the GIL left to
other threads, a stop from outside, pacing, and the zero-force path for a MuJoCo error."""

import threading
import time

import numpy as np
import pytest

from softproxy.compiled import native
from softproxy.device_kernel import JIT
from softproxy.run import build, open_device
from softproxy.servo import BLOCK_S
from softproxy.scene import load_scene

pytestmark = pytest.mark.skipif(not JIT, reason="compiled blocks need the device's cfuncs (no NUMBA_DISABLE_JIT)")

FAULTY = {"nan": 0.01, "drop": 0.01, "spike": 0.005, "stall": 0.002}


def _loop(python_device: bool, faults: dict | None = None, scene_name: str = "two_finger_grasp"):
    scene = load_scene(scene_name)
    config = dict(scene.device)
    if faults:
        config.update(faults=faults, seed=7)
    device = open_device("sim", scene, config)
    if python_device:
        device.read = device.read  # replaced on the instance: the loop calls it from Python
    return build(scene, device, realtime=False), device


@pytest.mark.parametrize("faults", [None, FAULTY], ids=["clean", "faulty"])
def test_compiled_blocks_equal_the_python_path_bit_for_bit(faults):
    """One compiled block of 1500 ticks and 1500 ticks with the device called from Python give
    the same finger records, MuJoCo state, fault counts, device messages and rendered
    forces, bit for bit: the two paths share every line of the tick but the device I/O."""
    (fast, fast_device), (slow, slow_device) = _loop(False, faults), _loop(True, faults)
    assert fast.compiled_block and not slow.compiled_block
    fast.run(1500)
    slow.run(1500)
    assert fast.ticks == slow.ticks == 1500 and fast.t == slow.t
    assert fast.faults == slow.faults
    if faults:
        assert fast.faults["device_error"] > 0 and fast.faults["invalid_sample"] > 0  # the faults were exercised
        assert fast.last_device_error == slow.last_device_error != ""
    assert fast.rows.data.tobytes() == slow.rows.data.tobytes()
    for name in ("qpos", "qvel", "xfrc_applied"):
        assert np.array_equal(getattr(fast.world.data, name), getattr(slow.world.data, name)), name
    assert fast_device.injected == slow_device.injected and fast_device.sends == slow_device.sends
    assert fast_device.max_force_sent == slow_device.max_force_sent > 1.0
    assert [s.x for s in fast.samples] == [s.x for s in slow.samples]  # the last samples, as DeviceSamples


def test_a_background_run_leaves_the_gil_to_other_threads():
    """A paced run in its own thread runs its ticks without the GIL: the main thread runs Python
    while a block is under way, and sees the loop's tick count between two blocks' ends (with
    the GIL held through a block it could read the count only between blocks, at their ends)."""
    loop, _ = _loop(False)
    loop.run(10)
    block = int(BLOCK_S * loop.rate_hz)  # ticks per block of a run without on_tick
    thread = loop.run_in_thread(3 * block, realtime=True)
    seen = set()
    while thread.is_alive():
        seen.add(loop.ticks)
    thread.join()
    assert loop.error is None and loop.ticks == 10 + 3 * block
    mid_block = sorted(seen - {10 + k * block for k in range(4)})
    print(f"\n{len(seen)} tick counts seen by the main thread, {len(mid_block)} of them mid-block")
    assert mid_block


def test_request_stop_ends_a_background_run_with_zero_force():
    """request_stop() from another thread ends a long paced run after the tick in progress; the
    run then sends zero force to every finger, as any run does when it ends."""
    loop, device = _loop(False)
    loop.run(1200)  # squeezing the box
    seen = []
    thread = loop.run_in_thread(60_000, realtime=True, every=50,
                                on_tick=lambda lp: seen.append(min(abs(f[0]) for f in device.last_force)))
    while not seen and thread.is_alive():  # until the run has had a block
        time.sleep(0.01)
    loop.request_stop()
    thread.join(60.0)
    assert not thread.is_alive() and loop.error is None
    assert seen and min(seen) > 0.1  # both fingers squeezed throughout the run
    assert 1200 < loop.ticks < 1200 + 60_000  # it ended before its ticks were done
    assert device.last_force == [(0.0, 0.0, 0.0)] * 2
    ticks = loop.ticks
    loop.run(5)  # the flag was cleared: the next run runs
    assert loop.ticks == ticks + 5


@pytest.mark.slow
def test_a_paced_block_takes_its_real_time():
    """A paced compiled run of 200 ticks at 1 kHz lasts at least until its last tick's deadline,
    199 periods after it began (a lockstep one of the same ticks far less): the kernel waits
    for each deadline. A loaded machine can only make it longer."""
    loop, _ = _loop(False)
    loop.run(10)
    begun = time.monotonic_ns()
    loop.run(200, realtime=True)
    assert time.monotonic_ns() - begun >= 199 * loop.state[0].period_ns
    assert loop.stats.count == 210


def test_every_stage_of_a_profiled_tick_is_timed():
    """With profiling on, the five stages of a compiled tick are each timed (> 0 ns) and add up
    to no more than the tick's own duration."""
    loop, _ = _loop(False)
    loop.run(100)
    loop.state[0].profile = True
    loop.tick()
    stages = loop.state[0].stage_ns.copy()
    duration_ns = loop.stats.duration[(loop.stats.count - 1) % loop.stats.capacity] * 1e9
    assert (stages > 0).all(), stages
    assert stages.sum() <= duration_ns + 1.0


def test_the_loop_sends_zero_force_if_mujoco_errors_inside_the_tick():
    """A started loop has registered its zero force on the emergency path of a MuJoCo error in
    a direct call (softproxy.compiled.native; test_native runs the path itself), and closing
    the loop unregisters it."""
    loop, device = _loop(False)
    before = len(native._callbacks)
    loop.run(1200)  # squeezing the box; the run ends with zero force
    loop.start()
    assert len(native._callbacks) == before + 1
    loop.tick()
    assert all(abs(f[0]) > 0.1 for f in device.last_force)
    native._callbacks[-1][1]()  # what the emergency path runs
    assert device.last_force == [(0.0, 0.0, 0.0)] * 2
    loop.close()
    assert len(native._callbacks) == before


def test_a_device_without_compiled_io_is_called_every_tick():
    """A device whose read was replaced (or one written in Python) is read from Python every
    tick, inside a compiled run too."""
    loop, device = _loop(True)
    reads = []
    inner = device.read
    device.read = lambda t, samples: (reads.append(t), inner(t, samples))
    loop.run(50)
    assert len(reads) == 50 + 1  # start() reads once to place the proxies


def test_a_replay_runs_compiled_and_equals_its_python_path(tmp_path):
    """A recording replayed through the compiled replay device and through its Python read gives
    the same run bit for bit (the replay device runs as compiled blocks)."""
    from softproxy.run import run_scene

    scene = load_scene("two_finger_grasp")
    path = tmp_path / "grasp.rec"
    run_scene(scene, open_device("sim", scene), duration_s=0.6, record=str(path))
    loops = []
    for python_device in (False, True):
        device = open_device(f"replay:{path}", scene)
        if python_device:
            device.read = device.read
        loop = build(scene, device, realtime=False)
        loop.run(550)
        loops.append(loop)
    fast, slow = loops
    assert fast.compiled_block and not slow.compiled_block
    assert fast.faults == slow.faults and fast.ticks == slow.ticks == 550
    assert fast.rows.data.tobytes() == slow.rows.data.tobytes()
    assert np.array_equal(fast.world.data.qpos, slow.world.data.qpos)
    assert max(f.max_force_seen for f in fast.fingers) > 1.0


def test_fast_loops_return_to_python_ten_times_less_often():
    """A return to Python between blocks costs ~50 µs: blocks are 0.1 s of ticks at 1 kHz and
    1 s above 2 kHz, where that is half a period (an on_tick's `every` still sets them)."""
    scene = load_scene("two_finger_grasp")
    for rate, expected in ((1000.0, [100, 100, 50]), (10_000.0, [10_000, 10_000, 5000])):
        with build(scene, open_device("sim", scene), rate_hz=rate, realtime=False) as loop:
            blocks = []
            run_block = loop._run_block
            loop._run_block = lambda n, paced: blocks.append(n) or run_block(n, paced)
            loop.run(sum(expected))
            assert blocks == expected and loop.ticks == sum(expected)
            blocks.clear()
            loop.run(30, on_tick=lambda _: None, every=20)
            assert blocks == [20, 10]
