"""An application embedding the engine loads only what the tick needs: numpy, MuJoCo, numba
and scipy. GL, HID, matplotlib, trimesh (meshes only), tqdm (progress on a terminal) and the
optional extras are imported when a feature that needs them is used, never before."""

import subprocess
import sys

SCRIPT = """
import sys, mujoco, softproxy
XML = '<mujoco><worldbody><geom name="t" type="plane" size="0.5 0.5 0.01"/></worldbody></mujoco>'
class Device:
    fingers, max_force, max_torque = 1, 10.0, 0.0
    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z, s.valid = 0.0, 0.0, max(0.005, 0.02 - 0.1 * t), True  # down onto the table, 3 mm in
    def send(self, *wrench): pass
    def close(self): pass
world = softproxy.World(mujoco.MjModel.from_xml_string(XML))
finger = softproxy.SoftFingerProxy(softproxy.FingerParams(radius=0.008, stiffness=1000.0), world.shapes)
with softproxy.ServoLoop(world, [finger], Device()) as loop:
    for _ in range(400):  # down in 0.15 s, then past the soft start (0.1 s)
        loop.tick()
    assert finger.normal_force > 0.5, finger.normal_force  # it rendered: the tick ran, not a no-op
print(" ".join(sorted({m.split(".")[0] for m in sys.modules})))
"""

NOT_FOR_THE_TICK = ("matplotlib", "glfw", "moderngl", "hid", "trimesh", "tqdm", "ray", "pybullet",
                    "imageio_ffmpeg", "networkx", "forcedimension_core", "pyOpenHaptics", "HaplyHardwareAPI")


def test_an_embedded_loop_imports_nothing_it_does_not_use():
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300,
                         env={**__import__("os").environ, "MUJOCO_GL": "egl"})
    assert out.returncode == 0, out.stderr
    loaded = set(out.stdout.split())
    assert {"numpy", "mujoco", "numba", "softproxy"} <= loaded
    assert not loaded & set(NOT_FOR_THE_TICK), sorted(loaded & set(NOT_FOR_THE_TICK))
