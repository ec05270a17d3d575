"""Two rates: the local model of the world the haptic ticks render against between MuJoCo's steps.

`ServoLoop(physics_rate_hz=...)` steps MuJoCo once every `every` haptic ticks; in between,
the fingers touch the shapes at poses carried forward from MuJoCo's last state with their
bodies' velocities and their answer to the fingers' own wrenches
(`softproxy.compiled.carry`), and MuJoCo integrates each finger's wrench averaged over the
step. `LocalModel` holds that model's arrays: what the compiled tick takes as
`layout.Carried`, and the `Shapes` bundle the fingers' queries read (the shape table of the
world, the carried poses).
"""

from __future__ import annotations

import math
import time

import mujoco
import numpy as np

from softproxy.compiled.handoff import CTL_SIZE
from softproxy.compiled.layout import Carried, Handoff, MjArrays, Shapes

MAX_EVERY = 1000
"""The most haptic ticks per MuJoCo step (a MuJoCo step of 1 s at 1 kHz)."""


AUTO = "auto"
"""`physics_rate_hz="auto"`: MuJoCo as fast as the world lets it (`every_for_cost`)."""
PHYSICS_SHARE = 0.5
"""The share of a core MuJoCo's steps may take at the rate "auto" picks: the rest is margin
for a step that costs more than the measured one (contacts come and go) and for the
machine's other work."""
COARSE_STEP_S = 0.01
"""A MuJoCo step longer than this (s; 100 Hz) is warned of: contacts resolved that coarsely
let fast objects pass through thin ones and stiff ones ring."""


def every_for_cost(rate_hz: float, step_cost_s: float, share: float = PHYSICS_SHARE) -> int:
    """Haptic ticks per MuJoCo step "as fast as it goes": the fewest for which a step costing
    `step_cost_s` (s) takes at most `share` of its period, at most MAX_EVERY."""
    every = max(1, math.ceil(step_cost_s * rate_hz / share - 1e-9))
    return min(every, MAX_EVERY)


def step_cost(model: mujoco.MjModel, data: mujoco.MjData, steps: int = 30) -> float:
    """What one mj_step of the world costs (s): the median of `steps` on a copy of its state,
    what "auto" picks its rate from."""
    d = mujoco.MjData(model)
    mujoco.mj_copyData(d, model, data)
    costs = []
    for _ in range(steps):
        t0 = time.perf_counter()
        mujoco.mj_step(model, d)
        costs.append(time.perf_counter() - t0)
    return float(np.median(costs))


def physics_every(rate_hz: float, physics_rate_hz: float | None) -> int:
    """Haptic ticks per MuJoCo step for a physics rate (Hz) under a servo rate (Hz): 1 for
    None (one rate). ValueError unless the physics rate divides the servo rate, at most it
    ("auto" is resolved by the loop, which has the world: `every_for_cost`)."""
    if physics_rate_hz is None:
        return 1
    if not (isinstance(physics_rate_hz, (int, float)) and math.isfinite(physics_rate_hz) and physics_rate_hz > 0):
        raise ValueError(f"physics_rate_hz must be a rate in Hz > 0, got {physics_rate_hz!r}")
    if physics_rate_hz > rate_hz * (1 + 1e-9):
        raise ValueError(f"physics_rate_hz ({physics_rate_hz:g} Hz) must be at most the servo rate ({rate_hz:g} Hz): "
                         "MuJoCo steps once every whole number of haptic ticks")
    every = int(round(rate_hz / physics_rate_hz))
    if abs(rate_hz / every - physics_rate_hz) > 1e-6 * physics_rate_hz or every > MAX_EVERY:
        below, above = max(1, min(MAX_EVERY, every)), max(1, min(MAX_EVERY, every + 1))
        raise ValueError(f"physics_rate_hz ({physics_rate_hz:g} Hz) must divide the servo rate ({rate_hz:g} Hz) "
                         f"a whole number of times, at most {MAX_EVERY}: try {rate_hz / below:g} or {rate_hz / above:g} Hz")
    return every


def movers(S) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The shapes that can move (rows of the SHAPE table `S` not static), as `carry` walks
    them: their geoms, bodies and bounding radii (m; inf for a plane), apart from the SHAPE
    records (whose hint slots make each ~3 kB)."""
    moving = ~S["static"]
    return (S["geom"][moving].astype(np.int64), S["body"][moving].astype(np.int64),
            S["rbound"][moving].astype(np.float64))


def mj_arrays(data) -> MjArrays:
    """The arrays of an mjData the servo side reads of MuJoCo's state (views)."""
    return MjArrays(data.geom_xpos, data.geom_xmat, data.cvel, data.xipos, data.ximat, data.subtree_com,
                    data.qvel, data.qacc, data.cdof, data.qLD, data.qLDiagInv)


def _copies(arrays: MjArrays) -> MjArrays:
    return MjArrays(*(np.array(a) for a in arrays))


class LocalModel:
    """The carried copies of a world's poses and the per-body state of `softproxy.compiled.carry`,
    in two bundles: `carried` over the world's mjData (lockstep: MuJoCo steps in the servo
    thread) and `threaded` over `mirror`, an mjData of the servo side's own that MuJoCo's
    thread publishes its state into (`softproxy.compiled.handoff`). Both carry the same poses."""

    def __init__(self, world) -> None:
        model, data, shapes = world.model, world.data, world.shapes
        nbody, ngeom, nv = model.nbody, model.ngeom, model.nv
        self.geom_xpos = np.array(data.geom_xpos)  # the carried poses (m), what the fingers read
        self.geom_xmat = np.array(data.geom_xmat)
        self.cvel = np.array(data.cvel)
        shapes_moving = movers(shapes.S)
        self.moving = np.unique(shapes_moving[1])
        """The bodies of the shapes that can move (each once, ascending): those the fingers push."""
        self.mirror = mujoco.MjData(model)
        """The servo side's copy of MuJoCo's state in a threaded run (what the handoff fills)."""
        state = mj_arrays(data)
        self.handoff = Handoff(np.zeros(1, np.int64), np.zeros(1, np.int64), _copies(state), mj_arrays(self.mirror),
                               np.zeros(1, np.int64), np.zeros((nbody, 6)), np.zeros(1, np.int64),
                               np.zeros(CTL_SIZE, np.int64))
        """The two threads' handoff (`softproxy.compiled.layout.Handoff`)."""
        own = (self.geom_xpos, self.geom_xmat, self.cvel,
               np.zeros((ngeom, 3)), np.zeros((ngeom, 9)),
               np.zeros((nbody, 3)), np.zeros((nbody, 9)), np.zeros((nbody, 6)), np.zeros((nbody, 6)),
               np.zeros((nbody, 6)), np.zeros((nbody, 6)), np.zeros((nbody, 2)), np.zeros(nbody, dtype=np.bool_),
               np.zeros(nbody, dtype=np.bool_),
               np.zeros(nv), np.zeros(nv), np.zeros(nv), np.zeros(nv), np.zeros(9), self.handoff)

        def over(d):
            return Carried(d.geom_xpos, d.geom_xmat, d.cvel, d.qvel, d.qacc, d.xipos, d.ximat, d.subtree_com,
                           model.body_rootid, self.moving, *shapes_moving, *own)

        self.carried = over(data)
        """The bundle the compiled tick takes in lockstep (`softproxy.compiled.layout.Carried`)."""
        self.threaded = over(self.mirror)
        """... and with MuJoCo in its own thread: MuJoCo's state read from `mirror`."""
        t = shapes.tables
        self.shapes = Shapes(t.S, t.T, t.C, self.geom_xpos, self.geom_xmat, self.cvel)
        """The world's shapes at the carried poses: what the haptic ticks' queries read."""
