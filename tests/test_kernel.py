"""`softproxy.compiled.kernel`: how every kernel is compiled (one machine code per argument
types, numba's Python wrapper only where Python calls)."""

import pickle

import pytest
from numba import config
from numba.core.dispatcher import Dispatcher

from softproxy.compiled import finite as finite_module
from softproxy.compiled.kernel import Kernel, kernel

pytestmark = pytest.mark.skipif(config.DISABLE_JIT, reason="what numba compiles: nothing under NUMBA_DISABLE_JIT")


def _scaled(x, k, flip):
    return -k * x if flip else k * x


scaled = kernel(cache=False)(_scaled)


@kernel(cache=False)
def _with_constants(x):
    """Calls `scaled` with three different constants and one variable."""
    n = int(x)
    return scaled(x, 0, False) + scaled(x, 2, True) + scaled(x, 3, False) + scaled(x, n, n > 1)


@kernel(cache=False, entry=True)
def _entry(x):
    return scaled(x, 4, False)


def test_constants_share_one_machine_code():
    """Four calls with constants (0, 2, 3; False, True) and one with variables compile `scaled`
    once, for (float64, int64, bool); the results are those of the Python function."""
    x = 2.0
    assert _with_constants(x) == _scaled(x, 0, False) + _scaled(x, 2, True) + _scaled(x, 3, False) + _scaled(x, 2, True)
    assert [str(s) for s in scaled.jit.signatures] == ["(float64, int64, bool)"]


def test_kernels_call_the_wrapperless_compile_and_python_the_twin():
    """Kernels call `jit` (compiled without numba's Python and C wrappers); a call from Python
    compiles the twin (`python`, with them) and returns what the kernel computes."""
    assert scaled.jit.targetoptions.get("no_cpython_wrapper") is True
    assert scaled.jit.targetoptions.get("no_cfunc_wrapper") is True
    assert "no_cpython_wrapper" not in scaled.python.targetoptions
    assert _entry(1.5) == 6.0  # through `scaled.jit`
    assert len(scaled.python.signatures) == 0  # Python has not called it yet
    assert scaled(1.5, 4, False) == 6.0 and scaled(1.5, 4, True) == -6.0
    assert [str(s) for s in scaled.python.signatures] == ["(float64, int64, bool)"]
    assert scaled.py_func is _scaled and scaled.__name__ == "_scaled"
    assert scaled.targetoptions is scaled.jit.targetoptions  # what numba's inliner reads


def test_entry_points_and_inlined_kernels_are_plain_numba_functions():
    """`entry=True` and `inline="always"`: one numba function, wrappers and all."""
    assert isinstance(_entry, Dispatcher) and not isinstance(_entry, Kernel)
    inlined = kernel(inline="always", cache=False)(_scaled)
    assert isinstance(inlined, Dispatcher) and inlined.targetoptions["inline"] == "always"


def test_a_kernel_pickles_by_name():
    """A kernel of a module pickles as its name (for worker processes), not as compiled code."""
    assert isinstance(finite_module.finite, Kernel)
    assert pickle.loads(pickle.dumps(finite_module.finite)) is finite_module.finite
