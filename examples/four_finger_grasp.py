"""Two hands, four soft fingers: squeeze, lift and hold a box (a scene file of your own).

The scene (`four_finger_grasp.toml` beside this file, with its MJCF) is loaded by path and
run on the simulated device, with soft fingers and with point contacts: two contacts on
each side, 6 cm apart, hold the box either way. Run: python examples/four_finger_grasp.py
"""

import sys
from pathlib import Path

import softproxy

SCENE = Path(__file__).with_name("four_finger_grasp.toml")


def main(seconds: float | None = None) -> None:
    scene = softproxy.load_scene(str(SCENE))
    for model in ("CH", "point"):
        device = softproxy.open_device("sim", scene)
        try:
            r = softproxy.run_scene(scene, device, duration_s=seconds, finger_model=model)
        finally:
            device.close()
        grips = ", ".join(f"{f['name']} {f['max_force_N']:.2f} N" for f in r["fingers"])
        print(f"{model:>5s}: box lifted to {r['object_height_m'] * 1e3:.1f} mm, turned "
              f"{r['object_rotation_deg']:+.3f} deg about the grasp axis; grip: {grips}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else None)
