"""Small 3-vector helpers for the kernels, on the records' vector fields (`pos`, `normal`, …:
float64 arrays of 3). numba inlines them; they spell out nothing the caller could get wrong."""

from __future__ import annotations

from softproxy.compiled.kernel import kernel


@kernel(inline="always")
def dot3(a, b):
    """a·b of two 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel(inline="always")
def dist2(a, b):
    """|a - b|² of two 3-vectors."""
    x, y, z = a[0] - b[0], a[1] - b[1], a[2] - b[2]
    return x * x + y * y + z * z
