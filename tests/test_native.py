"""`softproxy.compiled.native`: MuJoCo's half-steps and CLOCK_MONOTONIC from numba kernels and from Python,
and the emergency exit when MuJoCo errors inside such a call."""

import importlib.util
import json
import os
import subprocess
import sys
import textwrap
import threading
import time

import mujoco
import numpy as np
import pytest
from numba import njit

from softproxy.compiled import native

TICKS = 400

KERNEL_MODULE = '''
"""A servo-like kernel on a free box: half-step, spring force into xfrc_applied, half-step."""
import json
import sys

import mujoco
import numpy as np
from numba import config, njit

from softproxy.compiled.native import addresses, mj_step1, mj_step2

XML = """<mujoco><option timestep="0.002"/><worldbody><geom type="plane" size="1 1 .1"/>
<body name="box" pos="0 0 .06"><freejoint/><geom type="box" size=".05 .05 .05" friction=".4"/></body>
</worldbody></mujoco>"""
K, C = 300.0, 5.0  # N/m, N·s/m


def targets(n):
    """Where the spring pulls the box each tick (m): round a circle of radius 5 cm, 2 cm into the plane."""
    a = np.linspace(0.0, 3.0, n)
    return np.stack([0.05 * np.sin(a), 0.05 * (1.0 - np.cos(a)), np.full(n, 0.03)], axis=1)


@njit(cache=True, nogil=True)
def servo(m_addr, d_addr, samples, xpos, qvel, xfrc, box, k, c, n):
    for i in range(n):
        mj_step1(m_addr, d_addr)
        for j in range(3):
            xfrc[box, j] = k * (samples[i, j] - xpos[box, j]) - c * qvel[j]
        mj_step2(m_addr, d_addr)
    return n


def run(n, kernel=servo):
    """qpos, qvel, xfrc_applied and the number of contacts after n ticks of `kernel`."""
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    box = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "box")
    kernel(*addresses(m, d), targets(n), d.xpos, d.qvel, d.xfrc_applied, box, K, C, n)
    return {"qpos": d.qpos.tolist(), "qvel": d.qvel.tolist(), "xfrc": d.xfrc_applied.tolist(), "ncon": int(d.ncon)}


if __name__ == "__main__":
    out = run(int(sys.argv[1]))
    if not config.DISABLE_JIT:
        stats = servo.stats
        out["cache_hits"] = sum(stats.cache_hits.values())
        out["cache_misses"] = sum(stats.cache_misses.values())
    print(json.dumps(out))
'''


@pytest.fixture(scope="module")
def kernel_dir(tmp_path_factory):
    """A temp folder holding the kernel module (and numba's cache for it, in `cache/`)."""
    where = tmp_path_factory.mktemp("native_kernel")
    (where / "box_kernel.py").write_text(KERNEL_MODULE)
    return where


@pytest.fixture(scope="module")
def box_kernel(kernel_dir):
    """The kernel module imported here (its cached kernel is never called in this process)."""
    spec = importlib.util.spec_from_file_location("box_kernel", kernel_dir / "box_kernel.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def bindings_result(box_kernel):
    """The kernel's loop written in Python with mujoco's own bindings: the reference."""
    m = mujoco.MjModel.from_xml_string(box_kernel.XML)
    d = mujoco.MjData(m)
    box = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "box")
    samples, k, c = box_kernel.targets(TICKS), box_kernel.K, box_kernel.C
    for i in range(TICKS):
        mujoco.mj_step1(m, d)
        for j in range(3):
            d.xfrc_applied[box, j] = k * (samples[i, j] - d.xpos[box, j]) - c * d.qvel[j]
        mujoco.mj_step2(m, d)
    return {"qpos": d.qpos.tolist(), "qvel": d.qvel.tolist(), "xfrc": d.xfrc_applied.tolist(), "ncon": int(d.ncon)}


def _run_kernel_process(kernel_dir, **env):
    """Run the kernel module in a new process with numba's cache in kernel_dir/cache; its JSON."""
    environment = dict(os.environ)
    environment.pop("NUMBA_DISABLE_JIT", None)
    path = os.pathsep.join(filter(None, (str(kernel_dir), environment.get("PYTHONPATH"))))
    environment.update(NUMBA_CACHE_DIR=str(kernel_dir / "cache"), PYTHONPATH=path, **env)
    done = subprocess.run([sys.executable, str(kernel_dir / "box_kernel.py"), str(TICKS)], cwd=kernel_dir,
                          env=environment, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def _physics(result):
    return {key: result[key] for key in ("qpos", "qvel", "xfrc", "ncon")}


def test_compiled_half_steps_match_the_bindings_bit_for_bit(box_kernel, bindings_result):
    """step1 / force into xfrc_applied / step2 in an @njit kernel leaves qpos, qvel and xfrc_applied equal to
    the last bit to the same loop through mujoco.mj_step1/2, on a box pushed about with contacts."""
    compiled = box_kernel.run(TICKS, kernel=njit(nogil=True)(box_kernel.servo.py_func))
    assert compiled == bindings_result
    # the scene exercises what it should: the box rests on the plane and the spring dragged it
    assert bindings_result["ncon"] > 0
    assert np.hypot(*bindings_result["qpos"][:2]) > 0.01
    assert np.abs(bindings_result["xfrc"][1][:3]).max() > 0.0


def test_the_python_path_of_the_same_names_matches_the_bindings(box_kernel, bindings_result):
    """Called from plain Python, mj_step1/mj_step2 go through ctypes to the same C functions: bit-identical."""
    assert box_kernel.run(TICKS, kernel=box_kernel.servo.py_func) == bindings_result


def test_mj_step_matches_the_bindings(box_kernel):
    """native.mj_step in a kernel is mujoco.mj_step: same state after 200 steps of a falling box."""
    @njit(nogil=True)
    def steps(m_addr, d_addr, n):
        for _ in range(n):
            native.mj_step(m_addr, d_addr)

    m = mujoco.MjModel.from_xml_string(box_kernel.XML)
    ours, theirs = mujoco.MjData(m), mujoco.MjData(m)
    ours.qvel[:3] = theirs.qvel[:3] = (0.3, -0.2, 0.5)
    steps(*native.addresses(m, ours), 200)
    mujoco.mj_step(m, theirs, 200)
    assert ours.time == theirs.time > 0.0
    assert np.array_equal(ours.qpos, theirs.qpos) and np.array_equal(ours.qvel, theirs.qvel)


def test_kernel_loads_from_numba_cache_in_a_second_process(kernel_dir, bindings_result):
    """A cached kernel calling the half-steps is saved by one process and loaded by the next (no address is
    baked into it), and both give the bindings' numbers."""
    first = _run_kernel_process(kernel_dir)
    second = _run_kernel_process(kernel_dir)
    assert (first["cache_hits"], second["cache_hits"], second["cache_misses"]) == (0, 1, 0)
    assert _physics(first) == _physics(second) == bindings_result


def test_same_kernel_source_under_disable_jit(kernel_dir, bindings_result):
    """Under NUMBA_DISABLE_JIT=1 the kernel source runs as Python (ctypes calls) and gives the same numbers."""
    interpreted = _run_kernel_process(kernel_dir, NUMBA_DISABLE_JIT="1")
    assert "cache_hits" not in interpreted  # it really ran without numba compiling
    assert _physics(interpreted) == bindings_result


def test_addresses_refuse_data_of_another_model(box_kernel):
    """addresses() gives the live pointers, and refuses an MjData made for another MjModel in one line."""
    m = mujoco.MjModel.from_xml_string(box_kernel.XML)
    d = mujoco.MjData(m)
    assert native.addresses(m, d) == (m._address, d._address)
    other = mujoco.MjModel.from_xml_string(box_kernel.XML)
    with pytest.raises(RuntimeError, match="another MjModel") as e:
        native.addresses(other, d)
    assert "\n" not in str(e.value)
    with pytest.raises(RuntimeError, match=f"mujoco {mujoco.__version__} gives no MjModel._address"):
        native.addresses(object(), d)


@njit(nogil=True)
def _clock_readings(n):
    out = np.empty(n, np.int64)
    for i in range(n):
        out[i] = native.monotonic_ns()
    return out


@njit(nogil=True)
def _spin_until(deadline_ns):
    """Spin on the clock until deadline_ns; (first reading, readings taken, last reading)."""
    first = now = native.monotonic_ns()
    readings = 1
    while now < deadline_ns:
        now = native.monotonic_ns()
        readings += 1
    return first, readings, now


def test_monotonic_ns_is_pythons_monotonic_clock():
    """A kernel's monotonic_ns and Python's time.monotonic_ns read one clock: a kernel's readings fall between
    Python's readings taken around the call, and never go back."""
    assert time.get_clock_info("monotonic").implementation == "clock_gettime(CLOCK_MONOTONIC)"
    _clock_readings(1)  # compile
    for _ in range(5):
        before = time.monotonic_ns()
        readings = _clock_readings(1000)
        after = time.monotonic_ns()
        assert before <= readings[0] and readings[-1] <= after
        assert np.all(np.diff(readings) >= 0) and readings[-1] > readings[0]
    assert before <= native.monotonic_ns() <= time.monotonic_ns()  # the Python path too
    # CLOCK_BOOTTIME would pass the above on a machine never suspended: name the clock read
    assert f"@clock_gettime(i32 {time.CLOCK_MONOTONIC}," in _clock_readings.inspect_llvm(_clock_readings.signatures[0])


def test_a_kernel_paces_itself_without_the_gil():
    """A kernel spinning on monotonic_ns until a deadline stops there (its last reading the first at or past
    it), and Python threads keep running meanwhile (the clock takes no GIL): the main thread reads the
    clock between the kernel's first and last readings, which it could not while the kernel held the GIL."""
    _spin_until(0)  # compile
    result = []
    start = time.monotonic_ns()
    deadline = start + 300_000_000  # 300 ms: long enough for a shared, busy 2-core machine to schedule both
    spinner = threading.Thread(target=lambda: result.append(_spin_until(deadline)))
    spinner.start()
    seen = []
    while spinner.is_alive():
        seen.append(time.monotonic_ns())
    spinner.join()
    first, readings, last = result[0]
    assert deadline <= last and readings > 1
    assert any(first < t < last for t in seen), "Python stood still while the kernel spun"


ERROR_SCRIPT = '''
import os, sys, threading
import mujoco
from numba import njit
from softproxy.compiled import native

XML = """<mujoco><size memory="8K"/><worldbody><geom type="plane" size="1 1 .1"/>
<body pos="0 0 .049"><freejoint/><geom type="box" size=".05 .05 .05"/></body></worldbody></mujoco>"""
PATH = sys.argv[1]


def boom():
    raise RuntimeError("device gone")


def zero_force():
    with open("marker.txt", "a") as f:
        f.write("zero force\\n")


def unregistered():
    with open("marker.txt", "a") as f:
        f.write("should not run\\n")


if "failing" in sys.argv:
    native.on_fatal(boom)
native.on_fatal(zero_force)
native.on_fatal(unregistered)()
native.install_error_handler()  # a second install changes nothing
m = mujoco.MjModel.from_xml_string(XML)
d = mujoco.MjData(m)
try:
    mujoco.mj_step(m, d, 10)
except mujoco.FatalError:
    print("bindings raised FatalError", flush=True)


@njit(nogil=True)
def steps(m_addr, d_addr, n):
    for _ in range(n):
        native.mj_step1(m_addr, d_addr)
        native.mj_step2(m_addr, d_addr)


d = mujoco.MjData(m)
kernel = steps if PATH == "compiled" else steps.py_func
servo = threading.Thread(target=kernel, args=(*native.addresses(m, d), 10), name="servo")
servo.start()
servo.join()
print("returned from the error", flush=True)
'''


@pytest.mark.parametrize("path, failing", [("compiled", False), ("ctypes", True)])
def test_a_mujoco_error_in_a_direct_call_runs_the_emergency_path(tmp_path, path, failing):
    """MuJoCo running out of memory inside a compiled (or ctypes) step on a servo thread runs every registered
    callback (one that raises does not stop the others), prints one line and exits with 3, instead of
    MuJoCo's exit(1) that runs no cleanup; the bindings' own calls still raise mujoco.FatalError."""
    (tmp_path / "error_script.py").write_text(ERROR_SCRIPT)
    environment = dict(os.environ)
    environment.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run([sys.executable, "error_script.py", path] + (["failing"] if failing else []),
                          cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=120)
    assert done.returncode == native.EXIT_CODE, done.stderr
    assert done.stdout == "bindings raised FatalError\n"
    assert (tmp_path / "marker.txt").read_text() == "zero force\n"
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()  # MuJoCo's own handler never ran
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    prefix = "softproxy: MuJoCo error inside the compiled tick: mj_stackAlloc: out of memory"
    assert lines[0].startswith(prefix) and "increase <size memory" in lines[0]
    if failing:
        assert lines[0].endswith("; emergency callback failed (boom: RuntimeError: device gone), exiting")
    else:
        assert lines[0].endswith("; zero force sent, exiting")


def test_error_handler_is_process_wide_and_installed_once():
    """install_error_handler sets MuJoCo's global mju_user_error to this module's handler, and again is a no-op."""
    code = textwrap.dedent("""
        import ctypes
        from softproxy.compiled import native
        slot = ctypes.c_void_p.in_dll(native._lib, "mju_user_error")
        assert slot.value is None, slot.value
        native.install_error_handler()
        first = slot.value
        native.install_error_handler()
        assert first == slot.value == ctypes.cast(native._ERROR_HANDLER, ctypes.c_void_p).value
        print("ok")
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.stdout == "ok\n", done.stderr
