"""Nothing from the working folder runs: no module there is imported by softproxy, by a
Python that softproxy starts, or by one a library starts on its behalf.

A Python started as `python -c CODE` (or `-m MODULE`) puts the folder it was started in
first on its module path, so a `ctypes.py`, `numpy.py` or `argparse.py` lying in the folder
where `softproxy run` was typed would be imported in its place and run. MuJoCo's import does
exactly that: its GLFW library probe starts `python -c` to try each libglfw it finds.

- `import softproxy` imports MuJoCo here first, with PYTHONSAFEPATH=1 in the environment
  while it does (Python >= 3.11: nothing is put before the module path), then puts the
  environment back: an application embedding the engine keeps its own environment.
- The command line (`softproxy.cli.main`) sets PYTHONSAFEPATH=1 for the whole command, so
  every Python it starts inherits it: the viewer (also started with `-P`), a pool's workers,
  Ray's workers, and whatever those start. `python -m softproxy.cli` from a folder puts that
  folder first on its own path by Python's rule; `dropped_from_path` takes it off again
  before anything else is imported (the `softproxy` console script never puts it there).

`sitecustomize.py` and `usercustomize.py` are imported at start-up from the module path as
it is before the working folder is added (`site` runs first), so a folder's copy is never
imported by `python -c` or `-m`; they matter only in a folder on PYTHONPATH, which is the
user's own setting.
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager

SAFE_PATH = "PYTHONSAFEPATH"


@contextmanager
def safe_path_for_children():
    """PYTHONSAFEPATH=1 in the environment while the block runs, as it was afterwards."""
    before = os.environ.get(SAFE_PATH)
    os.environ[SAFE_PATH] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(SAFE_PATH, None)
        else:
            os.environ[SAFE_PATH] = before


def dropped_from_path() -> bool:
    """Take the working folder off the front of `sys.path` when this process is
    `python -m softproxy...` (which put it there); True if it was. Any other program's path
    is its own."""
    argv = getattr(sys, "orig_argv", [])
    try:
        module = argv[argv.index("-m") + 1]
    except (ValueError, IndexError):
        return False
    if sys.flags.safe_path or not (module == "softproxy" or module.startswith("softproxy.")) or not sys.path:
        return False
    try:
        first = os.path.realpath(sys.path[0] or os.curdir)
        here = os.path.realpath(os.getcwd())
    except OSError:
        return False
    if first != here:
        return False
    del sys.path[0]
    return True


dropped_from_path()
with safe_path_for_children():
    import mujoco  # noqa: E402,F401  (its GLFW probe starts `python -c`)
