"""Models like a user's, driven by the simulated device: the fingers never sink into what they touch.

Each model in tests/models/ (a jointed hand of capsules and boxes, a gripper with sliver-meshed
grooved pads, a height-field terrain with a stone on it, a trampoline membrane) runs a few
hundred servo ticks of the simulated device pressing and sliding fingers over it. After every
tick an independent check asks MuJoCo itself how far a sphere of the finger's radius at the
proxy is from each geom (`mj_geomDistance`, in the poses the tick solved against), and every
force is finite and within the finger's clamp, and the device got no NaN.
"""

import math
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from softproxy import FingerParams, ServoLoop, SoftFingerProxy, World
from softproxy.devices.simulated import SimulatedDevice
from softproxy.geometry import FlexWarning

MODELS = Path(__file__).resolve().parent / "models"
TOL = 1e-6
"""How far (m) a proxy may be inside a geom by MuJoCo's own distance (rounding, float32 mesh vertices)."""


def load(name: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_path(str(MODELS / f"{name}.xml"))


class Clearance:
    """MuJoCo's distance (m) from the model's probe sphere (radius = the finger's) placed at a
    proxy to each geom, in the poses of `world.data` (mj_step2 leaves the geom poses mj_step1
    computed, which the tick's proxies were solved against). Worst (smallest) per geom kept."""

    def __init__(self, world: World, geoms: list[str]) -> None:
        m = world.model
        self.world = world
        self.check = mujoco.MjData(m)
        self.probe = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "probe")
        self.geoms = {name: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name) for name in geoms}
        self.worst = {name: math.inf for name in geoms}
        self.fromto = np.zeros(6)

    def distance(self, geom: int, x: float, y: float, z: float) -> float:
        c = self.check
        c.geom_xpos[:] = self.world.data.geom_xpos
        c.geom_xmat[:] = self.world.data.geom_xmat
        c.geom_xpos[self.probe] = (x, y, z)
        c.geom_xmat[self.probe] = np.eye(3).ravel()
        return mujoco.mj_geomDistance(self.world.model, c, self.probe, geom, 0.05, self.fromto)

    def record(self, x: float, y: float, z: float) -> None:
        for name, g in self.geoms.items():
            self.worst[name] = min(self.worst[name], self.distance(g, x, y, z))


def drive(world: World, params: list[FingerParams], keyframes, ticks: int, on_tick=None):
    """Run `ticks` ticks of the simulated device over `world`; per tick check every finger's force
    (finite, within its clamp) and call `on_tick(fingers)`. Returns (fingers, device, largest |F|)."""
    fingers = [SoftFingerProxy(p, world.shapes) for p in params]
    device = SimulatedDevice(keyframes, max_force=20.0)
    largest = [0.0]

    def each(loop: ServoLoop) -> None:
        for f in fingers:
            force = math.sqrt(f.fx * f.fx + f.fy * f.fy + f.fz * f.fz)
            assert math.isfinite(force) and force <= f.params.max_force * (1 + 1e-9), (f.params.name, force)
            assert all(map(math.isfinite, (f.god.x, f.god.y, f.god.z)))
            largest[0] = max(largest[0], force)
        if on_tick is not None:
            on_tick(fingers)

    with ServoLoop(world, fingers, device, rate_hz=1000.0, overrun_watchdog=False) as loop:
        loop.run(ticks, on_tick=each, every=1)
        assert sum(loop.faults.values()) == 0, loop.faults
    assert device.nan_sends == 0 and math.isfinite(device.max_force_sent)
    return fingers, device, largest[0]


def test_a_hand_of_capsules_and_boxes_on_jointed_fingers():
    """Two fingers on a sprung, jointed hand: one presses the index fingertip down (its hinges
    give) and strokes it; one presses the palm and slides over the knuckles, between the
    capsules. No proxy is ever inside any of the hand's 22 geoms by MuJoCo's distance; both
    fingers feel a push (> 1 N) and the pressed fingertip moves."""
    world = World(load("hand"))
    geoms = [mujoco.mj_id2name(world.model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(world.model.ngeom)]
    clearance = Clearance(world, [g for g in geoms if g not in ("probe", "table")])
    tip = world.body_id("index2")
    tip_start = world.data.xpos[tip].copy()
    r = 0.006
    params = [FingerParams(name="presser", radius=r, stiffness=800.0, damping=2.0, device_finger=0, soft_start=0.0),
              FingerParams(name="stroker", radius=r, stiffness=800.0, damping=2.0, device_finger=1, soft_start=0.0)]
    keys = [[(0.0, -0.027, 0.125, 0.04, 0.0), (0.15, -0.027, 0.125, 0.004, 0.0), (0.3, -0.027, 0.105, 0.0, 0.0),
             (0.45, -0.027, 0.125, 0.0, 0.0)],
            [(0.0, 0.0, -0.02, 0.04, 0.0), (0.1, 0.0, -0.02, 0.014, 0.0), (0.3, 0.0, 0.07, 0.012, 0.0),
             (0.45, 0.0, 0.10, 0.010, 0.0)]]
    pressed = []

    def check(fingers):
        for f in fingers:
            clearance.record(f.god.x, f.god.y, f.god.z)
        pressed.append([math.sqrt(f.fx ** 2 + f.fy ** 2 + f.fz ** 2) for f in fingers])

    drive(world, params, keys, 450, check)
    assert min(clearance.worst.values()) >= -TOL, sorted(clearance.worst.items(), key=lambda kv: kv[1])[:3]
    felt = np.max(pressed, axis=0)
    assert (felt > 1.0).all(), felt
    assert np.linalg.norm(world.data.xpos[tip] - tip_start) > 0.002, "the pressed fingertip gave way"


@pytest.mark.parametrize("surface", ["hull", "true"])
def test_a_gripper_with_sliver_meshed_grooved_pads(surface):
    """A finger pressed into the grooved inner face of a gripper pad (a CAD-like mesh of sliver
    triangles): with mesh_surface="hull" it stops on the convex hull MuJoCo collides with, so
    MuJoCo finds it never inside the pad (nor the other pad); with the true surface it sinks
    into the groove, past the hull's face by more than a millimetre, yet never through a true
    triangle (a brute-force distance to every triangle of the pad). The pressed jaw slides."""
    world = World(load("gripper"), mesh_surface=surface)
    clearance = Clearance(world, ["left_pad", "right_pad"])
    m = world.model
    pad = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "right_pad")
    mesh = int(m.geom_dataid[pad])
    verts = np.array(m.mesh_vert[m.mesh_vertadr[mesh]:m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]], dtype=np.float64)
    faces = np.array(m.mesh_face[m.mesh_faceadr[mesh]:m.mesh_faceadr[mesh] + m.mesh_facenum[mesh]])
    jaw = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "right")]
    r = 0.005
    true_clear = [math.inf]
    slid = [0.0]

    def check(fingers):
        f = fingers[0]
        clearance.record(f.god.x, f.god.y, f.god.z)
        slid[0] = max(slid[0], abs(float(world.data.qpos[jaw])))
        local = (np.array([f.god.x, f.god.y, f.god.z]) - world.data.geom_xpos[pad]) @ \
            world.data.geom_xmat[pad].reshape(3, 3)
        true_clear[0] = min(true_clear[0], triangles_distance(local, verts, faces) - r)

    params = [FingerParams(name="f", radius=r, stiffness=600.0, damping=2.0, soft_start=0.0)]
    # from the gripper's middle into the right pad's groove (inner face at x = 30 mm), then up its face
    keys = [[(0.0, 0.0, 0.0, 0.12, 0.0), (0.15, 0.031, 0.0, 0.12, 0.0), (0.3, 0.031, 0.0, 0.135, 0.0),
             (0.4, 0.02, 0.0, 0.135, 0.0)]]
    drive(world, params, keys, 400, check)
    assert clearance.worst["left_pad"] >= -TOL
    assert true_clear[0] >= -TOL, true_clear
    if surface == "hull":
        assert clearance.worst["right_pad"] >= -TOL, clearance.worst
    else:  # inside the hull MuJoCo collides with: the groove is felt
        assert clearance.worst["right_pad"] < -0.001, clearance.worst
    assert slid[0] > 1e-3, "the pressed jaw slid"


def triangles_distance(p, vertices, faces) -> float:
    """Unsigned distance (m) from point p to the nearest triangle (Ericson's closest point, every triangle)."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        q = a + ab * (vb / denom)[:, None] + ac * (vc / denom)[:, None]
        regions = [
            ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * (d1 / (d1 - d3))[:, None]),
            ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * (d2 / (d2 - d6))[:, None]),
            ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None]),
            ((d1 <= 0) & (d2 <= 0), a), ((d3 >= 0) & (d4 <= d3), b), ((d6 >= 0) & (d5 <= d6), c),
        ]
    for mask, point in regions:
        q[mask] = point[mask]
    return float(np.sqrt(((p - q) ** 2).sum(1)).min())


def test_a_height_field_terrain_with_a_stone():
    """One finger strokes the rolling terrain (a height field) over its bumps, pressing 4 mm into
    it; another pushes the stone (a free box) resting on it. MuJoCo finds neither proxy ever
    inside the terrain or the stone, and a ray straight down from each proxy centre meets the
    terrain below it (not inside the solid, where MuJoCo's distance would not say so); the
    stroking finger feels the terrain (> 1 N) and the stone moves."""
    world = World(load("terrain"))
    m, d = world.model, world.data
    clearance = Clearance(world, ["ground", "stone"])
    ground = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "ground")
    stone = world.body_id("stone")
    settle = 300  # the stone settles on the terrain first
    for _ in range(settle):
        mujoco.mj_step(m, d)
    stone_start = d.xpos[stone].copy()
    r = 0.006
    below = [math.inf]
    geomid = np.zeros(1, dtype=np.int32)

    def surface_z(x, y) -> float:
        dist = mujoco.mj_ray(m, d, np.array([x, y, 1.0]), np.array([0.0, 0.0, -1.0]), None, 1, -1, geomid)
        return 1.0 - dist if int(geomid[0]) == ground else -math.inf

    def check(fingers):
        for f in fingers:
            clearance.record(f.god.x, f.god.y, f.god.z)
            below[0] = min(below[0], f.god.z - surface_z(f.god.x, f.god.y))

    top = lambda x, y: surface_z(x, y) + r  # noqa: E731 (where a finger resting on the terrain is)
    sx, sy = float(stone_start[0]), float(stone_start[1])
    keys = [[(0.0, -0.08, -0.02, top(-0.08, -0.02) + 0.01, 0.0), (0.1, -0.08, -0.02, top(-0.08, -0.02) - 0.004, 0.0),
             (0.4, 0.04, -0.02, top(0.04, -0.02) - 0.004, 0.0)],
            [(0.0, sx - 0.04, sy, stone_start[2] + 0.003, 0.0), (0.4, sx - 0.005, sy, stone_start[2] + 0.003, 0.0)]]
    params = [FingerParams(name="stroke", radius=r, stiffness=800.0, damping=2.0, device_finger=0, soft_start=0.0),
              FingerParams(name="push", radius=r, stiffness=800.0, damping=2.0, device_finger=1, soft_start=0.0)]
    _, _, largest = drive(world, params, keys, 400, check)
    assert min(clearance.worst.values()) >= -TOL, clearance.worst
    assert below[0] > 0.0, below
    assert largest > 1.0
    assert np.linalg.norm(d.xpos[stone][:2] - stone_start[:2]) > 0.002, "the pushed stone moved"


def test_a_flex_membrane_is_named_and_not_felt():
    """A trampoline: its membrane (a flex) collides in MuJoCo but not with the fingers. Loading it
    warns once, one line naming the membrane; a finger lowered through it feels nothing until it
    rests on the block below (its proxy then one radius over the block's top). Excluded by name,
    the membrane loads without a warning."""
    with pytest.warns(FlexWarning) as caught:
        world = World(load("trampoline"))
    messages = [str(w.message) for w in caught if issubclass(w.category, FlexWarning)]
    assert len(messages) == 1 and "\n" not in messages[0] and "'membrane'" in messages[0]
    r = 0.006
    block_top = 0.04
    through = []

    def check(fingers):
        f = fingers[0]
        if f.god.z > block_top + r + 0.002:
            through.append(math.sqrt(f.fx ** 2 + f.fy ** 2 + f.fz ** 2))

    keys = [[(0.0, 0.0, 0.0, 0.12, 0.0), (0.3, 0.0, 0.0, block_top + r - 0.003, 0.0),
             (0.35, 0.0, 0.0, block_top + r - 0.003, 0.0)]]
    fingers, _, largest = drive(world, [FingerParams(name="f", radius=r, stiffness=800.0, soft_start=0.0)], keys, 350,
                                check)
    assert len(through) > 100 and max(through) == 0.0, "the membrane is not felt"
    assert abs(fingers[0].god.z - (block_top + r)) < 1e-4 and largest > 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexWarning)
        World(load("trampoline"), exclude=["membrane"])
