"""The programs in examples/ run as a user runs them and print what they claim."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # each example is a program run in its own process


EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run(name, *args):
    env = dict(os.environ)
    env.pop("NUMBA_DISABLE_JIT", None)
    done = subprocess.run([sys.executable, str(EXAMPLES / name), *map(str, args)], capture_output=True, text=True,
                          timeout=600, env=env, cwd=EXAMPLES.parent)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_custom_device_presses_the_puck():
    """A Python device drives a finger into a puck: a grip of a few newtons reaches it, no faults."""
    out = run("custom_device.py", 1.0)
    force = float(re.search(r"pressing with ([\d.]+) N", out).group(1))
    assert 0.5 < force < 5.0 and "faults: 0" in out


def test_mesh_object_holds_the_finger_at_the_inner_wall():
    """A finger pushed 5 mm into a mug's inner wall (a non-convex mesh from an OBJ file) stops at
    the wall (proxy centre one radius inside r = 35 mm) and feels the spring: 800 N/m × 5 mm."""
    out = run("mesh_object.py", 1.5)
    x = float(re.search(r"proxy at \(([-\d.]+),", out).group(1))
    force = float(re.search(r"with ([\d.]+) N", out).group(1))
    assert abs(x - 29.0) < 0.1 and 3.5 < force < 4.5
    assert float(re.search(r"inside the mesh: ([-\d.e+]+) m", out).group(1)) <= 1e-9


def test_four_fingers_lift_and_hold_the_box():
    """Two hands lift the box ~5 cm and hold it level, with soft fingers and with point contacts."""
    out = run("four_finger_grasp.py", 2.0)
    lines = [line for line in out.splitlines() if "box lifted" in line]
    assert len(lines) == 2
    for line in lines:
        assert float(re.search(r"lifted to ([\d.]+) mm", line).group(1)) > 70.0
        assert abs(float(re.search(r"turned ([-+\d.]+) deg", line).group(1))) < 1.0


def test_the_servo_thread_leaves_the_application_free_to_draw(tmp_path):
    """The servo runs 1000 paced ticks in its thread while the main thread renders frames of the
    state it copied out (EGL offscreen); the last frame is written. (How many frames fit in the
    run's second depends on the machine's load: at least one was drawn while the servo ran.)"""
    png = tmp_path / "frame.png"
    try:
        out = run("servo_thread_render.py", 1.0, png)
    except AssertionError as exc:
        if "EGL" in str(exc) or "gladLoadGL" in str(exc):
            pytest.skip(f"no EGL here: {exc}")
        raise
    assert "servo: 1000 ticks" in out
    frames, copies = (int(v) for v in re.search(r"drawn meanwhile: (\d+) frames from (\d+) state copies", out).groups())
    assert frames >= 1 and copies >= 1000 // 16 and png.stat().st_size > 1000
