"""Draw the world in your own loop while the servo runs in its own thread.

The servo loop runs paced at 1 kHz in a thread (`ServoLoop.run_in_thread`): with the
simulated device its ticks run as compiled blocks without the GIL, so this thread renders
with `mujoco.Renderer` at 30 frames a second meanwhile. MuJoCo steps the loop's `MjData`
inside the blocks, so the servo thread copies the state out in `on_tick` (between blocks)
and this thread draws the copy. Run: python examples/servo_thread_render.py [seconds] [frame.png]
Headless machines render through EGL (MUJOCO_GL=egl, set here when there is no display).
"""

import os
import sys
import threading
import time

if not os.environ.get("DISPLAY"):
    os.environ.setdefault("MUJOCO_GL", "egl")
    os.environ.setdefault("LP_NUM_THREADS", "1")  # software GL: one render thread, the other core for the servo

import matplotlib.image
import mujoco
import numpy as np

import softproxy


def main(seconds: float = 2.0, png: str | None = None) -> None:
    scene = softproxy.load_scene("two_finger_grasp")
    loop = softproxy.build(scene, softproxy.open_device("sim", scene))
    model = loop.world.model
    shown = mujoco.MjData(model)  # what this thread draws: a copy, never the servo's MjData
    qpos = loop.world.data.qpos.copy()
    proxies = np.zeros((len(loop.fingers), 3))  # the proxies' centres (m): drawn as spheres
    lock = threading.Lock()
    copies = [0]

    def copy_state(lp):  # on the servo thread, between blocks of ticks
        with lock:
            qpos[:] = lp.world.data.qpos
            for i, f in enumerate(lp.fingers):
                proxies[i] = f.god.x, f.god.y, f.god.z
            copies[0] += 1

    camera = mujoco.MjvCamera()
    camera.lookat[:], camera.distance, camera.azimuth, camera.elevation = (0, 0, 0.06), 0.35, 60.0, -20.0
    radius = [f.params.radius for f in loop.fingers]

    with loop, mujoco.Renderer(model, 240, 320) as renderer:
        servo = loop.run_in_thread(int(seconds * loop.rate_hz), realtime=True, on_tick=copy_state, every=16)
        frames, next_frame = 0, time.perf_counter()
        while servo.is_alive():
            with lock:
                shown.qpos[:] = qpos
                centres = proxies.copy()
            mujoco.mj_forward(model, shown)
            renderer.update_scene(shown, camera)
            for centre, r in zip(centres, radius):  # the proxies are no MuJoCo bodies: add them to the scene
                scn = renderer.scene
                if scn.ngeom < scn.maxgeom:
                    mujoco.mjv_initGeom(scn.geoms[scn.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([r, 0, 0]),
                                        centre, np.eye(3).ravel(), np.array([0.3, 0.5, 0.9, 1.0], dtype=np.float32))
                    scn.ngeom += 1
            image = renderer.render()
            frames += 1
            next_frame += 1 / 30
            time.sleep(max(0.0, next_frame - time.perf_counter()))
        servo.join()
        if loop.error is not None:
            raise loop.error
        print(f"servo: {loop.ticks} ticks paced at {loop.rate_hz:g} Hz, {loop.stats.misses} deadline misses, "
              f"tick p99 {loop.stats.summary_us()['p99']} µs; drawn meanwhile: {frames} frames from {copies[0]} "
              f"state copies")
        if png:
            matplotlib.image.imsave(png, image)
            print(f"last frame written to {png}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 2.0, sys.argv[2] if len(sys.argv) > 2 else None)
