"""Calling kernels from Python: the entry point without per-call dispatch, compile progress,
and the compile cache keyed on every file the kernels are built from."""

import io
import time

import numpy as np
from numba import njit

from softproxy.compiled import cache
from softproxy.compiled.dispatch import announced, entry
from softproxy.compiled.layout import FINGER_DATA


@njit
def _sum_x(F, k):
    s = 0.0
    for i in range(F.shape[0]):
        s += F[i].pos[0] * k
    return s


def test_entry_point_gives_the_kernels_answer_and_writes_in_place():
    """The entry point computes what the dispatcher does, on the same record array."""
    F = np.zeros(3, FINGER_DATA).view(np.recarray)
    F.pos[:, 0] = [1.0, 2.0, 3.5]
    call = entry(_sum_x, (F, 2.0))
    assert call is not _sum_x
    assert call(F, 2.0) == _sum_x(F, 2.0) == 13.0
    F.pos[1, 0] = 10.0  # the same array, changed: the entry point reads it live
    assert call(F, 1.0) == 14.5


def _fresh_kernel():
    """A kernel numba has never compiled (a new function object each call; not cached)."""
    @njit
    def kernel(a):
        return a * 2.0 + 1.0
    return kernel


def test_a_slow_compile_is_announced_and_a_quick_one_is_not():
    """A compile longer than `after_s`: a line saying what compiles, and how long it took; a
    compile quicker than that: nothing."""
    out = io.StringIO()
    with announced("the test kernel", stream=out, after_s=0.05):
        _fresh_kernel()(1.0)
        time.sleep(0.2)  # (however quick the compile was, the block outlasts after_s)
    text = out.getvalue()
    assert "compiling the test kernel" in text and "compiled the test kernel in" in text
    quiet = io.StringIO()
    with announced("the test kernel", stream=quiet, after_s=60.0):
        _fresh_kernel()(1.0)
    assert quiet.getvalue() == ""


def test_a_slow_block_that_compiles_nothing_is_not_announced():
    """A load from the cache that a busy machine makes slow is no compile: nothing is said
    (the block here compiles nothing and outlasts `after_s`)."""
    kernel = _fresh_kernel()
    kernel(1.0)  # compiled before the block
    out = io.StringIO()
    with announced("the test kernel", stream=out, after_s=0.05):
        kernel(2.0)
        time.sleep(0.3)
    assert out.getvalue() == ""


def test_the_cache_is_keyed_on_every_module_the_kernels_import():
    """The digest covers the kernel package, found from its imports: every module whose
    constants and functions it compiles in (a constant changed there must drop the cache). The
    kernels import nothing above their package, so that is all of it."""
    names = {str(p.relative_to(cache._ROOT)) for p in cache.sources()}
    assert {"compiled/tolerances.py", "compiled/godobject.py", "compiled/finger.py", "compiled/mesh.py",
            "compiled/guard.py", "compiled/triangle.py", "compiled/box_tree.py", "compiled/patch.py"} <= names
    assert all(name.startswith("compiled/") for name in names), sorted(names)
