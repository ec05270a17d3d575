"""A set of example recordings, made by the simulated device, for batch replays to chew on.

`generate(folder, count, duration_s, seed)` writes `count` recordings (`NNN_SCENE.rec`, the
format of `softproxy run --record`) and a `recordings.json` saying how each was made. They
differ the way a lab's trials do: two-finger grasps of the box at different places beside its
centre of mass, with different grips, lifts and sways, some released at the end, and light
twists of the knob around its torsion limit; with and without sensor noise, and some with
device faults (NaN coordinates, invalid samples, spikes, stalls). The same arguments give the
same files, byte for byte: every choice comes from a seeded stream, the runs are lockstep, and
the recorder's buffer holds the whole run (a lockstep run outpaces the writer thread).

    python -m softproxy.example_recordings FOLDER [--count 8] [--duration 5] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
from pathlib import Path

from softproxy.recording import RecordingDevice
from softproxy.run import open_device, run_scene
from softproxy.scene import load_scene

RATE_HZ = 1000.0
MIN_DURATION_S = 1.5
"""Shortest recording (s): the grasp needs it to squeeze, lift and hold."""
MAX_COUNT = 10_000
NOISE_M = (0.0, 1e-5, 3e-5)  # position noise std choices, m
FAULTS = ({}, {"nan": 0.001, "drop": 0.002}, {"spike": 0.0005, "drop": 0.001}, {"stall": 0.0005, "nan": 0.0005})
"""Fault rates per read, cycled through the recordings (the first: none)."""


def _grasp(rng: random.Random, duration: float) -> tuple[list, dict]:
    """Two fingers' keyframes squeezing the box up to 3 cm beside its centre of mass, lifting it
    and holding it with a sway (and a twist of the device), maybe opening at the end; and what was chosen."""
    y = rng.uniform(-0.03, 0.03)  # along the box, m from the centre of mass
    z = rng.uniform(0.02, 0.04)  # grasp height, m
    grip_mm = rng.uniform(0.8, 2.5)  # device past the proxy: 2000 N/m × 1 mm = 2 N
    lift = rng.uniform(0.02, 0.06)
    twist = rng.uniform(-0.3, 0.3)  # rad of device twist while holding
    contact, lifted = rng.uniform(0.4, 0.55), rng.uniform(1.0, 1.3)
    release = rng.random() < 0.3 and duration - 0.2 > lifted + 0.1  # open the hand 0.2 s before the end
    end_hold = duration - 0.2 if release else duration
    hold = []  # (t, dy, dz, twist) every 0.6 s while holding: the same for both fingers
    t = lifted
    while t + 0.6 < end_hold:
        t += 0.6
        hold.append((t, rng.uniform(-0.01, 0.01), rng.uniform(-0.005, 0.005), twist * rng.choice((-1.0, 1.0))))
    x_in = 0.02 + 0.008 - grip_mm * 1e-3
    fingers = []
    for side in (1.0, -1.0):
        keys = [[0.0, side * 0.06, y, z, 0.0], [contact, side * x_in, y, z, 0.0],
                [contact + 0.2, side * x_in, y, z, 0.0], [lifted, side * x_in, y, z + lift, 0.0]]
        keys += [[t, side * x_in, y + dy, z + lift + dz, w] for t, dy, dz, w in hold]
        if release:
            keys.append([end_hold, *keys[-1][1:]])
            keys.append([duration, side * 0.06, *keys[-1][2:]])
        elif keys[-1][0] < duration:
            keys.append([duration, *keys[-1][1:]])
        fingers.append({"keyframes": keys})
    return fingers, {"beside_com_m": round(y, 4), "grip_mm": round(grip_mm, 3), "lift_m": round(lift, 4),
                     "twist_rad": round(twist, 3), "released": release}


def _knob(rng: random.Random, duration: float) -> tuple[list, dict]:
    """One finger pressing the knob with 0.3-1.2 N (its torsion limit is near 0.59 N) and twisting."""
    force = rng.uniform(0.3, 1.2)
    x, y = rng.uniform(-0.003, 0.003), rng.uniform(-0.003, 0.003)
    turn = rng.choice((-1.0, 1.0)) * rng.uniform(0.5, 2.0)
    z = 0.048 - force / 1000.0  # the scene's stiffness is 1000 N/m
    pressed = rng.uniform(0.35, 0.5)
    keys = [[0.0, x, y, 0.07, 0.0], [pressed, x, y, z, 0.0], [pressed + 0.1, x, y, z, 0.0],
            [pressed + 0.1 + 0.6 * (duration - pressed - 0.1), x, y, z, turn], [duration, x, y, z, turn]]
    return [{"keyframes": keys}], {"press_N": round(force, 3), "turn_rad": round(turn, 3)}


SCRIPTS = {"two_finger_grasp": _grasp, "knob": _knob}
ORDER = ("two_finger_grasp", "two_finger_grasp", "knob")  # scenes cycled through the recordings


def generate(folder: str | Path, count: int = 8, duration_s: float = 5.0, seed: int = 0) -> list[Path]:
    """Write `count` recordings of `duration_s` s each into `folder` (made if missing), plus
    recordings.json; returns their paths. ValueError (one line) for a count or duration out of range."""
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_COUNT:
        raise ValueError(f"--count must be a number of recordings from 1 to {MAX_COUNT}, got {count!r}")
    if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and MIN_DURATION_S <= duration_s <= 600):
        raise ValueError(f"--duration must be a number of seconds from {MIN_DURATION_S:g} to 600, got {duration_s!r}")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = random.Random(seed)
    scenes = {name: load_scene(name) for name in SCRIPTS}
    paths, manifest = [], []
    for i in range(count):
        name = ORDER[i % len(ORDER)]
        scene = scenes[name]
        fingers, chosen = SCRIPTS[name](rng, float(duration_s))
        config = {**scene.device, "finger": fingers, "seed": seed * 100_003 + i,
                  "noise_m": NOISE_M[i % len(NOISE_M)], "faults": FAULTS[i % len(FAULTS)]}
        path = folder / f"{i:03d}_{name}.rec"
        device = open_device("sim", scene, config, source=f"example recording {i}")
        # The whole run fits the ring, so no read is ever dropped, however fast the run goes.
        recorder = RecordingDevice(device, path, buffer_s=duration_s + 1.0, scene=scene.name, rate_hz=RATE_HZ)
        try:
            run_scene(scene, recorder, duration_s=float(duration_s), rate_hz=RATE_HZ)
        finally:
            recorder.close()
        if recorder.dropped or recorder.error:
            raise RuntimeError(f"{path}: the recorder dropped {recorder.dropped} reads ({recorder.error or 'no error'})")
        paths.append(path)
        manifest.append({"file": path.name, "scene": name, "duration_s": float(duration_s),
                         "noise_m": config["noise_m"], "faults": config["faults"], "seed": config["seed"], **chosen})
    (folder / "recordings.json").write_text(json.dumps({"seed": seed, "recordings": manifest}, indent=1) + "\n")
    return paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m softproxy.example_recordings", description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", help="where to write the recordings (made if missing)")
    parser.add_argument("--count", type=int, default=8, help="how many (default 8)")
    parser.add_argument("--duration", type=float, default=5.0, help="seconds each (default 5)")
    parser.add_argument("--seed", type=int, default=0, help="seed of every choice (default 0)")
    args = parser.parse_args(argv)
    try:
        paths = generate(args.folder, args.count, args.duration, args.seed)
    except (ValueError, OSError) as exc:
        print(f"{parser.prog}: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {len(paths)} recordings of {args.duration:g} s and recordings.json to {args.folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
