"""A device's frame seen from the engine's workspace frame (z up, the operator looking along +y).

Every vendor SDK reports its device's frame in its own axes; the adapter's DEVICE_TO_ENGINE is the
constant rotation M whose rows are the engine's x, y, z in the device's axes, so a vector v reads
M v in the engine and a device rotation R reads M R Mᵀ. Plain scalar lists: this runs every
servo tick, on 3x3 matrices, where numpy's per-call cost would dominate.
"""

from __future__ import annotations


def is_rotation(r) -> bool:
    """True when `r` (3x3, rows) is a rotation: orthonormal within 1e-3 and no reflection.
    Garbage from a device (NaN fails too) must not become an orientation."""
    for i in range(3):
        for j in range(3):
            d = sum(r[k][i] * r[k][j] for k in range(3)) - (1.0 if i == j else 0.0)
            if not abs(d) < 1e-3:  # NaN fails too
                return False
    det = (r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
           + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]))
    return det > 0.0


def frame_in_engine(m, r) -> tuple[list, list]:
    """(M R, M R Mᵀ) of a device rotation `r` under DEVICE_TO_ENGINE `m` (both rows): M R Mᵀ is the
    rotation in the engine frame; the columns of M R are the device frame's axes in engine
    coordinates (e.g. a gripper's opening axis)."""
    mr = [[sum(m[a][k] * r[k][b] for k in range(3)) for b in range(3)] for a in range(3)]
    return mr, [[sum(mr[a][k] * m[b][k] for k in range(3)) for b in range(3)] for a in range(3)]
