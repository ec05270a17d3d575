"""The Python side of a device whose `read` and `send` are `@njit` kernels over its state arrays
(`softproxy.device_kernel`): the plain protocol's `read` and `close`, its `closed` flag and its
`compiled_io`, the same for every such device (the simulated and replay devices).

A subclass holds `_ints` (its int64 state, the closed flag at I_CLOSED), `_arrays` (the read
kernel's arguments after t: the state arrays, then the SAMPLE rows it fills), `_buffer` (the
`SampleBuffer` of those rows) and `fingers`; it names its read kernel (`_read_kernel`) and its
cfuncs (`_cfuncs`), and says what an error code means (`_raise`, `read_error`). Its kernels
stay in its own module, where numba caches them and `drop_stale_kernels` watches them.
"""

from __future__ import annotations

from softproxy import device_kernel as dk
from softproxy.device import DeviceSample

I_CLOSED = 0
"""The closed flag's place in a kernel device's int64 state (its read kernel refuses once set)."""


class KernelDevice:
    """`read`, `close`, `closed` and `compiled_io` over a device's kernels and state arrays."""

    _read_kernel = None
    """The `@njit` read kernel: (t, *_arrays) -> 0 or an error code (a staticmethod)."""
    _cfuncs = None
    """() -> the (read, send) cfuncs over the same state (`device_kernel.build_cfuncs`; a staticmethod)."""

    @property
    def closed(self) -> bool:
        return bool(self._ints[I_CLOSED])

    @closed.setter
    def closed(self, value: bool) -> None:
        self._ints[I_CLOSED] = bool(value)

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        """Run the read kernel into the device's SAMPLE rows, then copy them into `samples`."""
        code = self._read_kernel(t, *self._arrays)
        if code:
            self._raise(code)
        self._buffer.copy_into(samples)

    def close(self) -> None:
        self.closed = True

    def _raise(self, code: int) -> None:
        """Raise the error a read's non-zero `code` stands for."""
        raise NotImplementedError

    def read_error(self, code: int) -> str:
        """The one-line message for an error code of read or send."""
        raise NotImplementedError

    def _compiled_io_extras(self) -> tuple:
        """What `device_io` takes after read_error: (stall code, stall s, limits), or fewer."""
        return ()

    def compiled_io(self) -> dk.CompiledIO | None:
        """read and send as cfuncs over this device's state (softproxy.device_kernel); None
        under NUMBA_DISABLE_JIT=1."""
        if not dk.JIT:
            return None
        return dk.device_io(self._cfuncs(), self._arrays, self.fingers, self.read_error,
                            *self._compiled_io_extras())
