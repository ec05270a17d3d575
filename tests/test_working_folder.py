"""Nothing from the working folder runs (softproxy.working_folder): a `ctypes.py`, `numpy.py`
and `sitecustomize.py` in the folder where `softproxy run` is started are never imported, by
the command, by the Pythons it starts, or by those a library starts (MuJoCo's GLFW probe ran
`python -c` with the folder first on its path and executed a folder's `ctypes.py`)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

PLANTED = ("ctypes", "numpy", "sitecustomize", "argparse", "struct")
SOFTPROXY = Path(sys.executable).parent / "softproxy"  # the console script, as a user types it


@pytest.fixture
def hostile_folder(tmp_path):
    """A working folder whose modules, if imported, leave a marker file in `marks`."""
    folder, marks = tmp_path / "work", tmp_path / "marks"
    folder.mkdir()
    marks.mkdir()
    for name in PLANTED:
        (folder / f"{name}.py").write_text(
            f"import os\nopen(os.path.join({str(marks)!r}, '{name}-' + str(os.getpid())), 'w').close()\n")
    return folder, marks


def clean_env():
    """This environment without PYTHONSAFEPATH: what a user's shell hands the command."""
    return {k: v for k, v in os.environ.items() if k != "PYTHONSAFEPATH"}


def run_in(folder, argv, timeout=600):
    return subprocess.run(argv, cwd=folder, capture_output=True, text=True, timeout=timeout, env=clean_env())


@pytest.mark.parametrize("command", ["script", "module"])
def test_softproxy_run_imports_nothing_from_the_working_folder(hostile_folder, command):
    """`softproxy run two_finger_grasp --headless --duration 0.2` (the console script, and
    `python -m softproxy.cli`) from the folder: the run completes, and no planted module ran in
    the command or in any Python it or MuJoCo started."""
    folder, marks = hostile_folder
    start = [str(SOFTPROXY)] if command == "script" else [sys.executable, "-m", "softproxy.cli"]
    done = run_in(folder, [*start, "run", "two_finger_grasp", "--headless", "--duration", "0.2", "--json"])
    assert done.returncode == 0, done.stderr[-2000:]
    assert '"scene": "two_finger_grasp"' in done.stdout
    assert sorted(os.listdir(marks)) == []


@pytest.mark.slow
def test_a_snapshot_and_a_pool_import_nothing_from_the_working_folder(hostile_folder, tmp_path):
    """The offscreen snapshot and a replay batch in two worker processes, from the folder: no
    planted module ran."""
    folder, marks = hostile_folder
    recording = tmp_path / "run.rec"
    done = run_in(folder, [str(SOFTPROXY), "run", "two_finger_grasp", "--headless", "--duration", "0.2",
                           "--snapshot", str(tmp_path / "shot.png"), "--record", str(recording)])
    assert done.returncode == 0 or "EGL" in done.stderr, done.stderr[-2000:]
    if done.returncode:  # no EGL here: the run and its recording without the snapshot
        done = run_in(folder, [str(SOFTPROXY), "run", "two_finger_grasp", "--headless", "--duration", "0.2",
                               "--record", str(recording)])
    done = run_in(folder, [str(SOFTPROXY), "replay-batch", str(recording), "--vary", "model=point", "--workers", "2",
                           "--out", str(tmp_path / "batch")])
    assert done.returncode == 0, done.stderr[-2000:]
    assert sorted(os.listdir(marks)) == []


def test_the_viewer_process_imports_nothing_from_the_working_folder(hostile_folder):
    """The viewer's command line (as `ViewerProcess` starts it, here with --help) from the
    folder, without PYTHONSAFEPATH: it runs this softproxy and nothing planted."""
    from softproxy.viewer.launch import viewer_command

    folder, marks = hostile_folder
    done = run_in(folder, viewer_command(["--help"]), timeout=300)
    assert done.returncode == 0 and "usage" in done.stdout, done.stderr[-2000:]
    assert sorted(os.listdir(marks)) == []


def test_the_viewer_process_and_its_children_get_a_safe_path(monkeypatch):
    """`ViewerProcess` starts the viewer with -P and PYTHONSAFEPATH=1 in its environment, so
    the Pythons the viewer starts (GLFW's probe) are safe too."""
    from softproxy.viewer import launch

    seen = {}

    class Popen:
        def __init__(self, argv, **kwargs):
            seen.update(argv=argv, env=kwargs.get("env"))

    monkeypatch.delenv("PYTHONSAFEPATH", raising=False)
    monkeypatch.setattr(launch.subprocess, "Popen", Popen)
    launch.ViewerProcess("scene.toml", "shm-name")
    assert seen["argv"][1] == "-P" and seen["env"]["PYTHONSAFEPATH"] == "1"


def test_importing_softproxy_leaves_the_applications_environment_as_it_was(hostile_folder):
    """An application importing softproxy (its own folder safe: -P) finds PYTHONSAFEPATH as it
    left it, unset, and MuJoCo's probe still imported nothing planted."""
    folder, marks = hostile_folder
    done = run_in(folder, [sys.executable, "-P", "-c",
                           "import os, softproxy; print(os.environ.get('PYTHONSAFEPATH'))"], timeout=300)
    assert done.returncode == 0 and done.stdout.strip() == "None", done.stderr[-2000:]
    assert sorted(os.listdir(marks)) == []
