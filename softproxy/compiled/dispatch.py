"""`entry`: a kernel's compiled machine code for given argument types, called without dispatch.

numba resolves the types of every argument on every call. For a numpy record array that
costs ~3 µs (its dtype is walked field by field), more than a finger's whole tick, so the
servo loop resolves the types once, when it is built, and then calls the compiled entry
point straight (~0.1 µs). The caller promises to pass arguments of exactly those types (the
same arrays every tick): the entry point does not check them.
"""

from __future__ import annotations


def entry(kernel, args: tuple):
    """The compiled `kernel` for the types of `args` (compiling it if needed), as a plain
    callable; `kernel` itself where nothing is compiled (NUMBA_DISABLE_JIT=1)."""
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return kernel
    types = tuple(kernel.typeof_pyval(a) for a in args)
    if types not in overloads:
        kernel.compile(types)
    return overloads[types].entry_point
