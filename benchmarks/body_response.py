"""Cost of `softproxy.compiled.body_response.mobility` (µs per call): `python -m benchmarks.body_response`.

Timed inside a compiled loop (what the servo tick pays) and as one call from Python, on the
grasp's free box (nv = 6), a 20-hinge chain (nv = 20, its tip against its tip and against its
root) and 20 free boxes (nv = 120: mj_jac clears 6·nv entries, so the cost grows with the
model, not with the touched body's tree). Median of 7 runs; prints a table, asserts nothing.
"""

from __future__ import annotations

import time
from pathlib import Path

import mujoco
import numpy as np

from softproxy.compiled import native
from softproxy.compiled.body_response import mobility, workspace
from softproxy.compiled.kernel import kernel


CALLS = 20_000
"""Calls per timed run."""


def _chain(n: int) -> str:
    """MJCF of an n-link chain of hinges with alternating axes, 5 cm, 20 g links."""
    xml = ""
    for i in reversed(range(n)):
        axis = ("0 1 0", "0 0 1", "1 0 0")[i % 3]
        xml = (f'<body name="l{i}" pos="{0.05 if i else 0}  0 {0 if i else 0.5}">'
               f'<joint type="hinge" axis="{axis}"/><geom type="capsule" fromto="0 0 0 .05 0 0" size=".01" mass=".02"/>'
               f'{xml}</body>')
    return f"<mujoco><worldbody>{xml}</worldbody></mujoco>"


def _boxes(n: int) -> str:
    bodies = "".join(f'<body name="b{i}" pos="{0.1 * i} 0 .1"><freejoint/><geom type="box" size=".02 .02 .02"/></body>'
                     for i in range(n))
    return f"<mujoco><worldbody>{bodies}</worldbody></mujoco>"


@kernel(cache=False)
def _loop(m, d, a, pa, b, pb, out, jac_a, jac_b, work, n):
    for _ in range(n):
        mobility(m, d, a, pa, b, pb, out, jac_a, jac_b, work)


def _case(model: mujoco.MjModel, a: str, b: str) -> tuple[float, float]:
    """(µs per call in a compiled loop, µs per call from Python), medians of 7 runs."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ia, ib = (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in (a, b))
    pa, pb = data.xipos[ia] + 0.01, data.xipos[ib] + 0.01
    out, jac_a, jac_b, work = workspace(model.nv)
    m, d = native.addresses(model, data)
    args = (m, d, ia, pa, ib, pb, out, jac_a, jac_b, work)
    _loop(*args, 1)
    compiled, python = [], []
    for _ in range(7):
        t = time.perf_counter_ns()
        _loop(*args, CALLS)
        compiled.append((time.perf_counter_ns() - t) / CALLS / 1e3)
        t = time.perf_counter_ns()
        for _ in range(CALLS // 10):
            mobility(*args)
        python.append((time.perf_counter_ns() - t) / (CALLS // 10) / 1e3)
    return float(np.median(compiled)), float(np.median(python))


def main() -> None:
    grasp = mujoco.MjModel.from_xml_path(str(Path(__file__).resolve().parent.parent / "scenes" / "two_finger_grasp.xml"))
    chain = mujoco.MjModel.from_xml_string(_chain(20))
    boxes = mujoco.MjModel.from_xml_string(_boxes(20))
    cases = [("grasp box (nv 6)", grasp, "box", "box"), ("20-hinge chain, tip-tip (nv 20)", chain, "l19", "l19"),
             ("20-hinge chain, tip-root (nv 20)", chain, "l19", "l0"), ("20 free boxes, one box (nv 120)", boxes, "b7", "b7")]
    print(f"{'case':36s} {'in kernel µs':>13s} {'from Python µs':>15s}")
    for name, model, a, b in cases:
        compiled, python = _case(model, a, b)
        print(f"{name:36s} {compiled:13.2f} {python:15.2f}")


if __name__ == "__main__":
    main()
