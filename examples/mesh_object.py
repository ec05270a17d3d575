"""A mesh object from a file: a mug made with trimesh, written to OBJ, touched by a finger.

The proxy stops on the mesh's true triangles (non-convex: the inside of the mug is
reachable). Run: python examples/mesh_object.py [seconds]
"""

import sys
import tempfile
from pathlib import Path

import mujoco
import trimesh

import softproxy

MJCF = """<mujoco><option gravity="0 0 -9.81" timestep="0.001"/>
  <asset><mesh name="mug" file="{obj}"/></asset>
  <worldbody>
    <geom name="table" type="plane" size="0.5 0.5 0.01"/>
    <body name="mug" pos="0 0 0"><geom type="mesh" mesh="mug" mass="0.3"/></body>
  </worldbody></mujoco>"""


class DipDevice:
    """One finger going down into the mug and pressing sideways on its inner wall."""

    fingers, max_force, max_torque = 1, 10.0, 0.5

    def read(self, t, samples):
        s = samples[0]
        down = min(t / 0.5, 1.0)  # 0.5 s down the middle, then out toward the wall
        out = min(max(t - 0.5, 0.0) / 0.5, 1.0)
        s.x, s.y, s.z = 0.034 * out, 0.0, 0.15 - 0.08 * down
        s.twist, s.valid = 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.force = (fx, fy, fz)

    def close(self):
        pass


def mug_obj(folder: Path) -> Path:
    """A 9 cm tall mug (a thick-walled tube on a base plate), centred on the z axis, as OBJ (m)."""
    wall = trimesh.creation.annulus(r_min=0.035, r_max=0.04, height=0.09)
    base = trimesh.creation.cylinder(radius=0.04, height=0.01)
    base.apply_translation((0, 0, -0.045))
    mug = trimesh.util.concatenate([wall, base])
    mug.apply_translation((0, 0, 0.05))
    path = folder / "mug.obj"
    mug.export(path)
    return path


def main(seconds: float = 1.5) -> None:
    with tempfile.TemporaryDirectory() as folder:
        obj = mug_obj(Path(folder))
        model = mujoco.MjModel.from_xml_string(MJCF.format(obj=obj))
    world = softproxy.World(model)
    finger = softproxy.SoftFingerProxy(softproxy.FingerParams(radius=0.006, stiffness=800.0), world.shapes,
                                       softproxy.model("CH"))
    device = DipDevice()
    with softproxy.ServoLoop(world, [finger], device, audit=True) as loop:
        pressed = []  # a run ends with zero force: read the force on the way, every 100 ticks
        loop.run(int(seconds * loop.rate_hz), on_tick=lambda lp: pressed.append(finger.normal_force), every=100)
        god = finger.god
        print(f"proxy at ({god.x * 1e3:.1f}, {god.y * 1e3:.1f}, {god.z * 1e3:.1f}) mm, device at x = "
              f"{finger.xd * 1e3:.1f} mm: held by the inner wall (r = 35 mm) with {pressed[-1]:.2f} N")
        print(f"deepest the proxy went inside the mesh: {finger.penetration_max:.1e} m; "
              f"faults: {sum(loop.faults.values())}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 1.5)
