"""How every kernel is compiled: `@kernel` is numba's `njit` with the engine's options.

- **numpy's error model**: a division by zero gives Inf or NaN, which the device guard turns
  into zero force, never an exception out of a tick;
- **cached on disk** (`compiled.cache` keeps the cache in step with the sources);
- **one machine code per argument types.** numba types a constant argument by its value
  (`Literal[int](0)`, `Literal[bool](False)`) and, called from another kernel, compiles the
  callee once more for every distinct constant. A kernel's callers see it with plain types
  instead: `_move(..., 0, False)` and `_move(..., n, follow)` share one machine code; a
  branch on such an argument is taken at run time (a nanosecond's test) where numba pruned it.
- **no Python wrapper where Python never calls.** numba gives every compiled function a
  wrapper that unboxes its arguments from Python objects and another for C callers, and
  compiles both to machine code. The tick's kernels take records and named tuples of arrays,
  whose unboxing code is long, and most are called only from other kernels. So a kernel is
  compiled twice over, on demand: without wrappers for kernels (`Kernel.jit`), and with them,
  cached apart, for Python (`Kernel.python`, built the first time Python calls it). A kernel
  that Python calls in every run (a loop's entry points) says `entry=True` and is one plain
  numba function for both. Not a kernel that many kernels call, though Python calls it too
  (the shape queries behind the library's `Shape`): numba links a callee's wrappers into
  every caller's code and compiles them again there (the grasp: +3 s of CPU with the four
  shape queries as entry points).

The grasp's first compile (`softproxy compile two_finger_grasp`, a fresh cache) took 99 s of
CPU with the constants' copies and the wrappers, 73 s without the copies, 56–59 s without either.
"""

from __future__ import annotations

import functools
import importlib
import types as pytypes

from numba import config, njit, types
from numba.core.dispatcher import Dispatcher


def _typed_by_type(dispatcher: Dispatcher) -> Dispatcher:
    """Make calls from other kernels compile `dispatcher` for their arguments' types alone,
    never for a constant's value (numba's `Literal` types)."""
    by_value = dispatcher.get_call_template

    def get_call_template(args, kws):
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
        return by_value(args, kws)

    dispatcher.get_call_template = get_call_template
    return dispatcher


def _named(module: str, qualname: str):
    """The kernel `qualname` of `module` (how a `Kernel` is pickled: by name)."""
    found = importlib.import_module(module)
    for part in qualname.split("."):
        found = getattr(found, part)
    return found


class Kernel:
    """A compiled function called from kernels as bare machine code and from Python through
    numba's wrapper: `jit` is what kernels call, `python` what Python calls."""

    def __init__(self, f, options: dict) -> None:
        functools.update_wrapper(self, f)
        self._f = f
        self._options = options
        self.jit = _typed_by_type(njit(no_cpython_wrapper=True, no_cfunc_wrapper=True, **options)(f))
        self._python = None

    @property
    def _numba_type_(self):
        """How numba types this object where a kernel names it: as the wrapper-less twin."""
        return types.Dispatcher(self.jit)

    @property
    def python(self) -> Dispatcher:
        """The twin with numba's Python wrapper, cached under its own name (`NAME.python`)."""
        if self._python is None:
            f = self._f
            twin = pytypes.FunctionType(f.__code__, f.__globals__, f.__name__, f.__defaults__, f.__closure__)
            twin.__qualname__ = f"{f.__qualname__}.python"
            twin.__module__ = f.__module__
            twin.__kwdefaults__ = f.__kwdefaults__
            self._python = njit(**self._options)(twin)
        return self._python

    @property
    def targetoptions(self) -> dict:
        """numba's options of the kernel (read by numba's inliner, so never the twin's)."""
        return self.jit.targetoptions

    @property
    def py_func(self):
        """The Python function itself (run uncompiled)."""
        return self._f

    def __call__(self, *args, **kwargs):
        return self.python(*args, **kwargs)

    def __getattr__(self, name: str):
        # numba's public attributes (signatures, overloads, inspect_llvm, ...) are the Python twin's
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.python, name)

    def __reduce__(self):
        return _named, (self._f.__module__, self._f.__qualname__)

    def __repr__(self) -> str:
        return f"<kernel {self._f.__module__}.{self._f.__qualname__}>"


def kernel(fn=None, *, inline: str = "never", nogil: bool = False, cache: bool = True, entry: bool = False):
    """Compile `fn` as an engine kernel; used bare (`@kernel`) or with options:
    `inline="always"` (numba inlines it where it is called), `nogil=True`, `cache=False`
    (a function built at run time), `entry=True` (called from Python in every run: one plain
    numba function, wrappers and all)."""

    def build(f):
        options = dict(cache=cache, nogil=nogil, inline=inline, error_model="numpy")
        if config.DISABLE_JIT:  # NUMBA_DISABLE_JIT=1: the Python function itself
            return f
        if entry or inline == "always":  # (inlined where called: no machine code of its own for kernels)
            return _typed_by_type(njit(**options)(f))
        return Kernel(f, options)

    return build if fn is None else build(fn)
