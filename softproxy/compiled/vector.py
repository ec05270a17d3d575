"""Small 3-vector helpers for the kernels, on the records' vector fields (`pos`, `normal`, …:
float64 arrays of 3) and MuJoCo's geom frames (`geom_xmat`, row-major). numba inlines them;
they spell out nothing the caller could get wrong."""

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


@kernel(inline="always")
def to_geom_frame(xmat, g, x, y, z):
    """The world vector (x, y, z) in geom g's frame: Rᵀv, R = xmat[g] (MuJoCo's geom_xmat)."""
    return (xmat[g, 0] * x + xmat[g, 3] * y + xmat[g, 6] * z,
            xmat[g, 1] * x + xmat[g, 4] * y + xmat[g, 7] * z,
            xmat[g, 2] * x + xmat[g, 5] * y + xmat[g, 8] * z)


@kernel(inline="always")
def point_in_geom_frame(xpos, xmat, g, x, y, z):
    """The world point (x, y, z) (m) in geom g's frame (m): Rᵀ(p - geom_xpos[g])."""
    return to_geom_frame(xmat, g, x - xpos[g, 0], y - xpos[g, 1], z - xpos[g, 2])


@kernel(inline="always")
def to_world_frame(xmat, g, x, y, z):
    """The geom-frame vector (x, y, z) of geom g in the world frame: Rv, R = xmat[g]."""
    return (xmat[g, 0] * x + xmat[g, 1] * y + xmat[g, 2] * z,
            xmat[g, 3] * x + xmat[g, 4] * y + xmat[g, 5] * z,
            xmat[g, 6] * x + xmat[g, 7] * y + xmat[g, 8] * z)
