"""How a MuJoCo body answers an impulse: the operational-space inverse inertia between two points.

`mobility` fills a 6×6 matrix A = J_a M⁻¹ J_bᵀ, J = [jacp; jacr] the 6×nv Jacobian of a body at
a world point: the change of body a's velocity at point pa (linear m/s, angular rad/s, world
frame) per unit impulse applied to body b at point pb (linear N·s, angular N·m·s, world frame).
Its blocks are in 1/kg (linear per linear), 1/(kg·m) (cross) and 1/(kg·m²) (angular per
angular). An implicit coupling needs it: a wrench W held over a tick h changes the body's
velocity at the contact by h·A·W, so W can be solved together with that change (e.g.
W = (I + (h²K + hB)A)⁻¹ W_pred) instead of from the body's last velocity, which injects energy
into a light body. A is M⁻¹ of the free (unconstrained) tree: contacts, limits and equalities that
stiffen the body are not in it, and neither are the damping terms MuJoCo's Euler and implicit
integrators add to M in mj_step2.

Valid after mj_step1 or mj_forward at the current qpos (both compute xpos, cdof, subtree_com and
the factorisation qLD of M), so in the servo tick between mj_step1 and mj_step2. The kernel
calls MuJoCo by symbol (`softproxy.compiled.native`); the same source runs as Python through
ctypes (`mobility.py_func`, or under NUMBA_DISABLE_JIT=1).
"""

from __future__ import annotations

import numpy as np

from softproxy.compiled.kernel import kernel
from softproxy.compiled.native import mj_jac, mj_solveLD, mj_solveM

_F64 = 8
"""Bytes per float64 (mjtNum)."""


def workspace(nv: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(out, jac_a, jac_b, work) for `mobility` on a model with `nv` degrees of freedom."""
    nv = int(nv)
    if nv < 0:
        raise ValueError(f"nv must be >= 0, got {nv}")
    return np.zeros((6, 6)), np.zeros((6, nv)), np.zeros((6, nv)), np.zeros((6, nv))


@kernel
def point_jacobian(m, d, body, point, jac):
    """jac (C-contiguous 6×nv) = [jacp; jacr] of `body` at the world point whose 3 float64 are at
    address `point` (np.uintp): MuJoCo's mj_jac."""
    nv = jac.shape[1]
    base = np.uintp(jac.ctypes.data)
    mj_jac(m, d, base, base + np.uintp(3 * nv * _F64), point, body)  # (uintp + int64 would be a float)


@kernel
def response(m, d, jac, work):
    """work (C-contiguous 6×nv) = the rows of (M⁻¹ Jᵀ)ᵀ: the 6 rows of J are 6 vectors of nv,
    one mj_solveM over the factorisation mj_step1 left."""
    mj_solveM(m, d, np.uintp(work.ctypes.data), np.uintp(jac.ctypes.data), 6)


@kernel
def response_in_tree(mass, jac, work, lo, hi):
    """`response` over the dofs lo..hi of one kinematic tree (the rows of jac zero outside
    them, as a body's Jacobian is): work[:, lo:hi] = the rows of (M⁻¹ Jᵀ)ᵀ there, bit for bit
    mj_solveM's, at that tree's cost; work outside lo..hi is left as it was. `mass`: a
    `layout.MassMatrix` of the mjData the factorisation is read from."""
    idx = mass.dof_index + np.uintp(4 * lo)
    for r in range(6):
        for k in range(lo, hi):
            work[r, k] = jac[r, k]
        mj_solveLD(np.uintp(work[r].ctypes.data), mass.qLD, mass.qLDiagInv, hi - lo, mass.rownnz, mass.rowadr,
                   mass.colind, idx)


@kernel
def mobility(m, d, body_a, pa, body_b, pb, out, jac_a, jac_b, work):
    """out (6×6) = J_a M⁻¹ J_bᵀ: body a's (v, ω) at world point pa (m) per unit (linear,
    angular) impulse on body b at world point pb, world frame (see the module docstring).

    m, d: the mjModel and mjData addresses (`native.addresses`); body_a, body_b: body ids
    (< nbody; <= 0, the world or none, gives zero); pa, pb: 3 float64. out: a C-contiguous
    6×6 float64 array; jac_a, jac_b, work: C-contiguous 6×nv float64 scratch (`workspace(nv)`),
    nv that of the model (not checkable here: a smaller array is overwritten past its end).
    A body welded to the world, or bodies in different kinematic trees, give exact zeros.
    Allocates nothing. Raises ValueError on arrays of the wrong shape or layout."""
    nv = jac_a.shape[1]
    if (out.shape[0] != 6 or out.shape[1] != 6 or out.strides[0] != 6 * _F64 or out.strides[1] != _F64
            or jac_a.shape[0] != 6 or jac_b.shape[0] != 6 or work.shape[0] != 6
            or jac_b.shape[1] != nv or work.shape[1] != nv
            or jac_a.strides[0] != nv * _F64 or jac_b.strides[0] != nv * _F64 or work.strides[0] != nv * _F64
            or jac_a.strides[1] != _F64 or jac_b.strides[1] != _F64 or work.strides[1] != _F64
            or pa.shape[0] != 3 or pb.shape[0] != 3):
        raise ValueError("mobility: out must be a C-contiguous 6x6 float64 array, jac_a, jac_b and work "
                         "C-contiguous 6 x nv, pa and pb of 3")
    out[:, :] = 0.0
    if body_a <= 0 or body_b <= 0 or nv == 0:
        return
    # The points go to MuJoCo as addresses of 3 contiguous doubles: copy them into out's first
    # row (any stride in, overwritten below) rather than trust the caller's layout.
    out[0, 0], out[0, 1], out[0, 2] = pa[0], pa[1], pa[2]
    out[0, 3], out[0, 4], out[0, 5] = pb[0], pb[1], pb[2]
    point_a = np.uintp(out.ctypes.data)
    point_b = point_a + np.uintp(3 * _F64)
    point_jacobian(m, d, body_a, point_a, jac_a)
    point_jacobian(m, d, body_b, point_b, jac_b)
    response(m, d, jac_b, work)
    out[0, :] = 0.0
    # out = J_a (M⁻¹ J_bᵀ), over the dofs that move body a only (its chain to the world: the
    # columns of J_a that are not zero), which is a few of nv in a model of many bodies
    for k in range(nv):
        if (jac_a[0, k] == 0.0 and jac_a[1, k] == 0.0 and jac_a[2, k] == 0.0 and jac_a[3, k] == 0.0
                and jac_a[4, k] == 0.0 and jac_a[5, k] == 0.0):
            continue
        for i in range(6):
            jik = jac_a[i, k]
            for j in range(6):
                out[i, j] += jik * work[j, k]
