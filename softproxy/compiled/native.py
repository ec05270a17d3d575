"""MuJoCo's step and a monotonic clock, callable from compiled (numba) kernels and from Python.

The compiled tick runs a block of servo ticks, MuJoCo's half-steps included, in one
`@njit(cache=True, nogil=True)` call. This module gives it:

- `mj_step1`, `mj_step2`, `mj_step` on the raw addresses of an mjModel and an mjData (ints,
  from `addresses(model, data)`). In a kernel each is an LLVM call to the C symbol by name
  (numba `ExternalFunction`), resolved when the kernel is linked or loaded from cache, so a
  cached kernel holds no process address. From plain Python, and under `NUMBA_DISABLE_JIT=1`,
  the same names call the same C functions through ctypes: one kernel source for both modes,
  bit-identical to `mujoco.mj_step1/2` on the same model and data.
- `mj_jac` and `mj_solveM` the same way, their arrays passed as addresses: a body's
  Jacobian at a world point, and x = M⁻¹ y with the factorisation of M (`qLD`) that
  mj_step1 (its mj_fwdPosition) and mj_forward leave in the mjData.
- `monotonic_ns()`: CLOCK_MONOTONIC in ns, the clock of `time.monotonic_ns()` on Linux, so a
  kernel and Python compare times. In a kernel it calls libc's `clock_gettime` on the stack
  (no allocation, no GIL), so a kernel can spin until a deadline; `sleep_until_ns(deadline)`
  sleeps until one (clock_nanosleep, absolute), so a paced kernel need not spin a whole period.
- `install_error_handler()` and `on_fatal(callback)`: the emergency path when MuJoCo raises an
  error inside one of these direct calls (see 1 below).

What a caller must know (measured and reproduced in docs/compiled-mujoco.md):

1. A MuJoCo error inside a direct call (compiled or ctypes) is not `mujoco.FatalError`: the
   bindings only catch errors around their own calls. Without a handler MuJoCo calls
   `exit(1)` and no `finally` runs, so no zero force reaches the device. The handler installed
   here runs every `on_fatal` callback, prints one line to stderr and ends the process with
   `os._exit(3)`; it never returns, because MuJoCo would carry on with a NULL allocation. The
   bindings' own calls still raise `mujoco.FatalError`.
2. Load order: this module loads libmujoco into LLVM's symbol table at import. A kernel module
   must import it (it does, to name `mj_step1`) before any kernel is compiled or loaded from
   numba's cache; otherwise the call resolves to nothing and segfaults.
3. Lifetime: a kernel holds raw addresses, and the numpy views (`d.qpos`, ...) do not keep the
   MjData alive. Whoever runs the kernel keeps `model` and `data` alive for the whole call. A
   new MjData (copy, reload) has a new address and new views.
4. No concurrent access: while a nogil kernel steps `data`, no other thread may touch it (the
   viewer, `mujoco.*` calls, reading its views). Hand copies over between blocks of ticks.
5. Pointers travel as 64-bit unsigned integers (x86-64, aarch64); the import refuses other ABIs.
   The void C functions are declared as returning a pointer whose value is never used.
6. This module has no cached kernel of its own: its overloads compile into their callers.
   Changing it changes `softproxy.compiled.cache`'s digest, which drops the kernels built on it.
"""

from __future__ import annotations

import ctypes
import glob
import os
import sys
import threading
import time
from collections.abc import Callable

import llvmlite.binding as llvm
import mujoco
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

if ctypes.sizeof(ctypes.c_void_p) != 8 or ctypes.sizeof(ctypes.c_long) != 8:
    raise RuntimeError("softproxy.compiled.native needs a 64-bit platform (pointers and C long of 8 bytes); "
                       "run without the compiled tick")


def _library_path() -> str:
    """The wheel's own libmujoco, the one its extension modules load (RUNPATH $ORIGIN)."""
    found = sorted(glob.glob(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so*")))
    if not found:
        raise RuntimeError(f"no libmujoco.so* beside mujoco {mujoco.__version__} in {os.path.dirname(mujoco.__file__)}; "
                           "the compiled tick needs the Linux mujoco wheel")
    return found[0]


LIB_PATH = _library_path()
# dlopen of the path the bindings loaded returns their handle: one libmujoco, one set of
# globals (mju_user_error included) shared by the bindings, ctypes and the kernels.
llvm.load_library_permanently(LIB_PATH)
_lib = ctypes.CDLL(LIB_PATH)

_STEP_SIGNATURE = types.void(types.uintp, types.uintp)
"""void f(const mjModel*, mjData*), the pointers as 64-bit unsigned integers."""


def _c_step(name: str):
    """`name(m_addr, d_addr)`: ctypes from Python, the C symbol by name in a kernel."""
    cfunc = getattr(_lib, name)
    cfunc.argtypes = (ctypes.c_void_p, ctypes.c_void_p)
    cfunc.restype = None
    external = types.ExternalFunction(name, _STEP_SIGNATURE)

    def step(m_addr, d_addr):
        cfunc(int(m_addr), int(d_addr))  # ctypes releases the GIL for the call

    step.__name__ = step.__qualname__ = name
    step.__doc__ = f"MuJoCo's `{name}` on the mjModel at `m_addr` and the mjData at `d_addr` (ints)."

    @overload(step, inline="never")
    def _compiled(m_addr, d_addr):
        def impl(m_addr, d_addr):
            external(m_addr, d_addr)
        return impl

    return step


mj_step1 = _c_step("mj_step1")
mj_step2 = _c_step("mj_step2")
mj_step = _c_step("mj_step")


def addresses(model, data) -> tuple[int, int]:
    """(m_addr, d_addr): the mjModel* and mjData* behind `model` and `data`, for the functions here."""
    m_addr = getattr(model, "_address", None)
    d_addr = getattr(data, "_address", None)
    if not isinstance(m_addr, int) or not isinstance(d_addr, int):
        raise RuntimeError(f"mujoco {mujoco.__version__} gives no MjModel._address / MjData._address, which the "
                           "compiled tick needs; install the mujoco version pyproject.toml names or run without it")
    if data.model._address != m_addr:
        raise RuntimeError("the MjData given to softproxy.compiled.native.addresses was made for another MjModel; "
                           "pass the model the data was made from")
    return m_addr, d_addr



# -- kinematics and the mass matrix ------------------------------------------------------

_JAC_SIGNATURE = types.void(types.uintp, types.uintp, types.uintp, types.uintp, types.uintp, types.int32)
"""void mj_jac(const mjModel*, const mjData*, mjtNum* jacp, mjtNum* jacr, const mjtNum point[3], int body)."""

_mj_jac_c = _lib.mj_jac
_mj_jac_c.argtypes = (ctypes.c_void_p,) * 5 + (ctypes.c_int,)
_mj_jac_c.restype = None
_mj_jac_external = types.ExternalFunction("mj_jac", _JAC_SIGNATURE)


def mj_jac(m_addr, d_addr, jacp_addr, jacr_addr, point_addr, body):
    """MuJoCo's `mj_jac`: the 3×nv translation (`jacp`) and rotation (`jacr`) Jacobians of the
    world point at `point_addr` (3 float64, m) moving with `body`, written row-major as float64
    at `jacp_addr` and `jacr_addr` (either may be 0: not computed). Uses xpos, cdof and
    subtree_com of the mjData, so valid after mj_step1/mj_forward. Addresses are ints
    (`array.ctypes.data`); the caller owns the sizes (3·nv each) and 0 <= body < nbody."""
    _mj_jac_c(int(m_addr), int(d_addr), int(jacp_addr) or None, int(jacr_addr) or None, int(point_addr), int(body))


@overload(mj_jac, inline="never")
def _compiled_mj_jac(m_addr, d_addr, jacp_addr, jacr_addr, point_addr, body):
    def impl(m_addr, d_addr, jacp_addr, jacr_addr, point_addr, body):
        _mj_jac_external(np.uintp(m_addr), np.uintp(d_addr), np.uintp(jacp_addr), np.uintp(jacr_addr),
                         np.uintp(point_addr), np.int32(body))
    return impl


_SOLVE_M_SIGNATURE = types.void(types.uintp, types.uintp, types.uintp, types.uintp, types.int32)
"""void mj_solveM(const mjModel*, mjData*, mjtNum* x, const mjtNum* y, int n)."""

_mj_solveM_c = _lib.mj_solveM
_mj_solveM_c.argtypes = (ctypes.c_void_p,) * 4 + (ctypes.c_int,)
_mj_solveM_c.restype = None
_mj_solveM_external = types.ExternalFunction("mj_solveM", _SOLVE_M_SIGNATURE)


def mj_solveM(m_addr, d_addr, x_addr, y_addr, n):
    """MuJoCo's `mj_solveM`: x = M⁻¹ y for `n` vectors of nv float64 each, stored one after the
    other (an n×nv row-major array) at `y_addr`, written at `x_addr` (the same address solves in
    place). M⁻¹ comes from the mjData's L'DL factorisation (qLD, qLDiagInv), so this is valid
    after mj_step1/mj_forward at the current qpos. The caller owns the sizes (n·nv each)."""
    _mj_solveM_c(int(m_addr), int(d_addr), int(x_addr), int(y_addr), int(n))


@overload(mj_solveM, inline="never")
def _compiled_mj_solveM(m_addr, d_addr, x_addr, y_addr, n):
    def impl(m_addr, d_addr, x_addr, y_addr, n):
        _mj_solveM_external(np.uintp(m_addr), np.uintp(d_addr), np.uintp(x_addr), np.uintp(y_addr), np.int32(n))
    return impl


_SOLVE_LD_SIGNATURE = types.void(types.uintp, types.uintp, types.uintp, types.int32, types.int32, types.uintp,
                                 types.uintp, types.uintp, types.uintp)
"""void mj_solveLD(mjtNum* x, const mjtNum* qLD, const mjtNum* qLDiagInv, int nv, int n,
const int* rownnz, const int* rowadr, const int* colind, const int* index)."""

_mj_solveLD_c = _lib.mj_solveLD
_mj_solveLD_c.argtypes = (ctypes.c_void_p,) * 3 + (ctypes.c_int,) * 2 + (ctypes.c_void_p,) * 4
_mj_solveLD_c.restype = None
_mj_solveLD_external = types.ExternalFunction("mj_solveLD", _SOLVE_LD_SIGNATURE)


def mj_solveLD(x_addr, qLD_addr, qLDiagInv_addr, count, rownnz_addr, rowadr_addr, colind_addr, index_addr):
    """MuJoCo's `mj_solveLD` on one vector, in place: x = M⁻¹ x over the `count` dofs listed
    (int32) at `index_addr` (x: nv float64, zero outside those dofs; M's factorisation and
    sparsity: an mjData's qLD and qLDiagInv, an mjModel's M_rownnz, M_rowadr, M_colind). Over
    the dofs of one kinematic tree (M is block diagonal by tree) it gives mj_solveM's answer
    bit for bit, at the cost of that tree alone."""
    _mj_solveLD_c(int(x_addr), int(qLD_addr), int(qLDiagInv_addr), int(count), 1, int(rownnz_addr),
                  int(rowadr_addr), int(colind_addr), int(index_addr))


@overload(mj_solveLD, inline="never")
def _compiled_mj_solveLD(x_addr, qLD_addr, qLDiagInv_addr, count, rownnz_addr, rowadr_addr, colind_addr, index_addr):
    def impl(x_addr, qLD_addr, qLDiagInv_addr, count, rownnz_addr, rowadr_addr, colind_addr, index_addr):
        _mj_solveLD_external(np.uintp(x_addr), np.uintp(qLD_addr), np.uintp(qLDiagInv_addr), np.int32(count),
                             np.int32(1), np.uintp(rownnz_addr), np.uintp(rowadr_addr), np.uintp(colind_addr),
                             np.uintp(index_addr))
    return impl


# -- the monotonic clock -----------------------------------------------------------------

CLOCK_MONOTONIC = getattr(time, "CLOCK_MONOTONIC", 1)
"""The clock id `time.monotonic_ns()` reads on Linux (`time.get_clock_info("monotonic")`)."""


@intrinsic
def _clock_monotonic_ns(typingctx):
    """clock_gettime(CLOCK_MONOTONIC) into a timespec on the stack, as int64 ns."""
    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        timespec = ir.LiteralStructType([i64, i64])  # time_t tv_sec; long tv_nsec (64-bit Linux)
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(i32, [i32, timespec.as_pointer()]),
                                            "clock_gettime")
        ts = cgutils.alloca_once(builder, timespec)  # in the entry block: a loop reuses one slot
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ts])  # cannot fail for this clock
        seconds = builder.load(cgutils.gep_inbounds(builder, ts, 0, 0))
        nanoseconds = builder.load(cgutils.gep_inbounds(builder, ts, 0, 1))
        return builder.add(builder.mul(seconds, ir.Constant(i64, 1_000_000_000)), nanoseconds)

    return types.int64(), codegen


def monotonic_ns() -> int:
    """Now on CLOCK_MONOTONIC (ns): the same clock from a kernel and from Python."""
    return time.monotonic_ns()


@overload(monotonic_ns)
def _compiled_monotonic_ns():
    def impl():
        return _clock_monotonic_ns()
    return impl


TIMER_ABSTIME = 1
"""clock_nanosleep's flag for an absolute deadline (Linux)."""


@intrinsic
def _clock_sleep_until_ns(typingctx, deadline):
    """clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME) until `deadline` (int64 ns), timespec on
    the stack. A signal may end the sleep early; callers spin the rest."""
    if not isinstance(deadline, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        timespec = ir.LiteralStructType([i64, i64])
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(i32, [i32, i32, timespec.as_pointer(), timespec.as_pointer()]),
            "clock_nanosleep")
        ts = cgutils.alloca_once(builder, timespec)
        at = builder.sext(args[0], i64) if args[0].type.width < 64 else args[0]
        billion = ir.Constant(i64, 1_000_000_000)
        builder.store(builder.sdiv(at, billion), cgutils.gep_inbounds(builder, ts, 0, 0))
        builder.store(builder.srem(at, billion), cgutils.gep_inbounds(builder, ts, 0, 1))
        builder.call(fn, [ir.Constant(i32, CLOCK_MONOTONIC), ir.Constant(i32, TIMER_ABSTIME), ts,
                          ir.Constant(timespec.as_pointer(), None)])
        return context.get_dummy_value()

    return types.none(deadline), codegen


def sleep_until_ns(deadline: int) -> None:
    """Sleep until CLOCK_MONOTONIC reads `deadline` (ns); at once if it has passed. In a
    kernel the thread sleeps in the kernel, without the GIL."""
    remaining = deadline - time.monotonic_ns()
    if remaining > 0:
        time.sleep(remaining * 1e-9)


@overload(sleep_until_ns)
def _compiled_sleep_until_ns(deadline):
    def impl(deadline):
        if deadline > 0:
            _clock_sleep_until_ns(deadline)
    return impl


@intrinsic
def _fence_seq_cst(typingctx):
    """A sequentially consistent memory fence (LLVM `fence seq_cst`): neither the compiler
    nor the CPU moves a load or store across it."""
    def codegen(context, builder, signature, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return types.none(), codegen


def fence() -> None:
    """A full memory fence between a seqlock's counter and the data it guards
    (`softproxy.compiled.handoff`); in Python a no-op (the GIL orders everything)."""


@overload(fence)
def _compiled_fence():
    def impl():
        _fence_seq_cst()
    return impl


# -- the emergency path for a MuJoCo error inside a direct call --------------------------

EXIT_CODE = 3
"""The process's exit status after a MuJoCo error inside a direct call."""

_callbacks: list[tuple[object, Callable[[], object]]] = []  # (token, callback), in the order registered
_handling = threading.Lock()  # held by the thread running the emergency path
_handling_thread: int | None = None


def on_fatal(callback: Callable[[], object]) -> Callable[[], None]:
    """Run `callback()` (e.g. send zero force) if MuJoCo errors inside a direct call; installs
    the handler. Returns a function that unregisters it."""
    install_error_handler()
    token = object()
    _callbacks.append((token, callback))

    def unregister() -> None:
        _callbacks[:] = [entry for entry in _callbacks if entry[0] is not token]

    return unregister


def _emergency(message: bytes) -> None:
    """The global mju_user_error: callbacks, one line to stderr, os._exit. Never returns."""
    global _handling_thread
    try:
        if _handling_thread == threading.get_ident():  # a callback hit a MuJoCo error itself
            os._exit(EXIT_CODE)
        _handling.acquire()  # a second thread's error waits here for the first one's exit
        _handling_thread = threading.get_ident()
        # MuJoCo's message spans lines (the fix is on the second): join them into one
        text = " ".join((message or b"").decode("utf-8", "replace").split()) or "(no message)"
        failed = []
        entries = list(_callbacks)
        for _, callback in entries:
            try:
                callback()
            except BaseException as e:  # the others and the exit still run
                failed.append(" ".join(f"{getattr(callback, '__name__', callback)!s}: {type(e).__name__}: {e}".split()))
        if failed:
            outcome = "emergency callback failed (" + "; ".join(failed) + ")"
        elif entries:
            outcome = "zero force sent"
        else:
            outcome = "no emergency callback was registered"
        line = f"softproxy: MuJoCo error inside the compiled tick: {text}; {outcome}, exiting\n"
        try:
            sys.stderr.write(line)
            sys.stderr.flush()
        except BaseException:
            os.write(2, line.encode())
    finally:
        os._exit(EXIT_CODE)


_ERROR_HANDLER = ctypes.CFUNCTYPE(None, ctypes.c_char_p)(_emergency)  # MuJoCo holds only its address
_ERROR_HANDLER_ADDRESS = ctypes.cast(_ERROR_HANDLER, ctypes.c_void_p).value


def install_error_handler() -> None:
    """Make a MuJoCo error inside a direct call run the emergency path (idempotent)."""
    slot = ctypes.c_void_p.in_dll(_lib, "mju_user_error")
    if slot.value != _ERROR_HANDLER_ADDRESS:
        slot.value = _ERROR_HANDLER_ADDRESS
