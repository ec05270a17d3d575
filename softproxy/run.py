"""Run a scene headless: build world, fingers, device and servo loop, run, and report.

This is what `softproxy run SCENE --headless --json` does; it is also the simplest way to
embed the engine: `build(load_scene(...), device)` returns a `ServoLoop` whose `tick()`
another application can call from its own loop.
"""

from __future__ import annotations

import math
from dataclasses import replace
from importlib.metadata import entry_points

import mujoco
import numpy as np

from softproxy.device import Device
from softproxy.device_group import DeviceGroup
from softproxy.finger import SoftFingerProxy
from softproxy.fingertip_sensors import attach as attach_sensors
from softproxy.fingertip_sensors import summaries as sensor_summaries
from softproxy.local_model import COARSE_STEP_S
from softproxy.recording import RecordingDevice
from softproxy.scheduling import realtime_thread
from softproxy.scene import Scene, SceneError
from softproxy.servo import MAX_RATE_HZ, MIN_RATE_HZ, ServoLoop
from softproxy.stiffness_cap import cap_fingers
from softproxy.world import World


def device_types() -> list[str]:
    """Names of the device implementations registered under `softproxy.devices`."""
    return sorted(ep.name for ep in entry_points(group="softproxy.devices"))


def device_table(scene: Scene, index: int = 0) -> dict:
    """The scene's table of device `index` ([device], or the index-th [[device]]); {} if none."""
    if index == 0:
        return scene.device  # (what a caller may have replaced since loading)
    return scene.devices[index] if index < len(scene.devices) else {}


def open_device(kind: str, scene: Scene, config: dict | None = None, source: str | None = None,
                index: int = 0) -> Device:
    """Open a device: "sim" (configured by the scene's [device] table, the `index`-th of its
    [[device]] tables, or by `config`, whose errors then name `source` instead of the scene
    file) or "NAME:ARGUMENT" (e.g. "replay:run.rec"), whose argument replaces the scene's
    configuration."""
    name, _, argument = kind.partition(":")
    for ep in entry_points(group="softproxy.devices"):
        if ep.name == name:
            cls = ep.load()
            if argument:
                if not hasattr(cls, "from_argument"):
                    raise SceneError(f"device type {name!r} takes no argument (got {argument!r})")
                # the argument overrides the fields of this device's own table, not the first's
                own = scene if index == 0 else replace(scene, device=device_table(scene, index))
                return cls.from_argument(argument, own)
            where = str(scene.path) if index == 0 else f"{scene.path}: device[{index}]"
            return cls.from_config(device_table(scene, index) if config is None else config, source=source or where)
    raise SceneError(f"no device type {name!r}; installed: {', '.join(device_types()) or 'none'}")


def check_device_fingers(scene: Scene, device: Device, label: str, index: int = 0) -> None:
    """SceneError (one line naming the device `label` and the scene) when a finger of the
    scene on device `index` is driven by a device finger the device does not have: it would
    get no samples."""
    for params in scene.fingers:
        if params.device == index and params.device_finger >= device.fingers:
            raise SceneError(f"{label} drives {device.fingers} finger(s), but scene {scene.name!r} ({scene.path}) has "
                             f"finger {params.name!r} on device finger {params.device_finger}: use a device (or a "
                             f"recording) with at least {params.device_finger + 1}, or a scene with fewer fingers")
    header = getattr(device, "header", None)  # a recording: every recorded finger must drive one of the scene's
    if isinstance(header, dict):
        used = {params.device_finger for params in scene.fingers if params.device == index}
        unused = [i for i in range(device.fingers) if i not in used]
        if unused:
            made = f" (recorded in scene {header['scene']!r})" if isinstance(header.get("scene"), str) else ""
            raise SceneError(f"{label} holds {device.fingers} finger(s){made}, but scene {scene.name!r} "
                             f"({scene.path}) drives none from recorded finger(s) {', '.join(map(str, unused))}: "
                             f"replay it into a scene with a finger on each")


def replay_notes(scene: Scene, device: Device, rate_hz: float) -> list[str]:
    """What differs between a recording and the scene and rate it is replayed at (one line
    each; empty for a device that is no recording): a replay into another scene or at another
    rate is allowed, it only replays a different experiment."""
    header = getattr(device, "header", None)
    if not isinstance(header, dict):
        return []
    notes = []
    made_in = header.get("scene")
    if isinstance(made_in, str) and made_in != scene.name:
        notes.append(f"the recording was made in scene {made_in!r}, replayed into {scene.name!r}")
    made_at = header.get("rate_hz")
    if isinstance(made_at, (int, float)) and made_at != rate_hz:
        notes.append(f"the recording was made at {made_at:g} Hz, replayed at {rate_hz:g} Hz: one recorded read per tick")
    return notes


def check_run(duration_s: float, rate_hz: float) -> None:
    """ValueError unless `duration_s` is a finite number of seconds > 0 and `rate_hz` a rate
    the servo loop runs (`softproxy.servo.MIN_RATE_HZ`..`MAX_RATE_HZ`). Nothing in a run is
    sized by its duration, so an embedding application may plan any length; scene files and
    `softproxy run --duration` keep to `softproxy.schema.MAX_DURATION_S` to catch typos."""
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f"duration must be a finite number of seconds > 0, got {duration_s!r}")
    if not (math.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
        raise ValueError(f"rate must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g} Hz, got {rate_hz!r}")


def build(scene: Scene, device: Device | list[Device], rate_hz: float | None = None, finger_model: str | None = None,
          audit: bool | None = None, realtime: bool = True, passivity: bool = True, allow_stiffer: bool = False,
          notes: list | None = None, physics_rate_hz: float | None = None) -> ServoLoop:
    """World + fingers + servo loop for `scene`, driven by `device` (or a list of devices, or
    a `DeviceGroup`: finger i by device `scene.fingers[i].device`).

    A finger stiffer (or more damped) than its device renders stably is capped to the device's
    figure, one line for `notes` (a list, if given) saying so; `allow_stiffer` keeps the
    scene's figures (`softproxy.stiffness_cap`).

    `realtime=False` builds a loop for lockstep runs in simulated time: no overrun watchdog;
    otherwise the watchdog watches while `run(realtime=True)` paces the ticks, and an
    application calling `tick()` itself gets lockstep results (`ServoLoop.overrun_watchdog`).
    The fingers whose scene entry asks for `tactile` or `sensing` get their channels in
    `loop.sensors` (softproxy.fingertip_sensors); no other finger costs the tick anything.
    `passivity=False` switches the passivity controller off (`ServoLoop.passivity`).
    `physics_rate_hz` (default: the scene's) steps MuJoCo at that rate, two rates
    (`ServoLoop`).
    """
    model = scene.load_model()
    world = World(model, scene.start_data(model), **scene.world_options())
    members = list(device) if isinstance(device, (list, tuple)) else (
        device.devices if isinstance(device, DeviceGroup) else [device])
    chosen = [replace(p, model=finger_model) if finger_model is not None else p  # the params name the model run
              for p in scene.fingers]
    try:
        chosen, said = cap_fingers(chosen, members, allow_stiffer)
    except ValueError as exc:
        raise SceneError(f"{scene.path}: {exc}") from None
    if notes is not None:
        notes.extend(said)
    fingers = [SoftFingerProxy(params, world.shapes) for params in chosen]
    try:
        loop = ServoLoop(world, fingers, device, scene.rate_hz if rate_hz is None else rate_hz,
                         audit=scene.audit if audit is None else audit, overrun_watchdog=None if realtime else False,
                         passivity=passivity,
                         physics_rate_hz=scene.physics_rate_hz if physics_rate_hz is None else physics_rate_hz)
    except ValueError as exc:
        raise SceneError(f"{scene.path}: {exc}") from None
    try:
        attach_sensors(loop, scene.tactile, scene.sensing)
    except ValueError as exc:
        raise SceneError(f"{scene.path}: {exc}") from None
    return loop


MOSTLY = 0.5
"""A run whose samples were invalid (or whose reads failed) this often is said to have mostly failed."""


def run_warnings(loop: ServoLoop) -> list[str]:
    """One line for each thing a run's figures say went wrong though it ended cleanly: most
    samples invalid or most reads failed (a device in other units, outside the workspace, or
    unplugged), every send failed, a finger that never touched anything, a MuJoCo step coarser
    than COARSE_STEP_S (two rates)."""
    ticks, n = loop.ticks, len(loop.fingers)
    if ticks == 0:
        return []
    faults = loop.faults
    said = []
    if faults["device_error"] > MOSTLY * ticks:
        said.append(f"the device's reads failed on {faults['device_error']} of {ticks} ticks: the fingers rendered "
                    "nothing then")
    if faults["invalid_sample"] > MOSTLY * ticks * n:
        said.append(f"{faults['invalid_sample']} of {ticks * n} samples were invalid or refused (positions in m, "
                    "within ±1 km; a twist in rad): check the device's units")
    if faults["send_error"] >= ticks * n:
        said.append(f"every send to the device failed ({faults['send_error']}): {loop.last_send_error or 'no reason given'}")
    step = loop.period * loop.physics_every
    if step > COARSE_STEP_S:
        said.append(f"MuJoCo stepped every {step * 1e3:g} ms ({loop.physics_rate_hz:g} Hz): contacts resolved that "
                    "coarsely let fast objects pass through thin ones and stiff ones ring; try a higher physics rate")
    for f in loop.fingers:
        if f.max_force_seen == 0.0:
            said.append(f"finger {f.params.name!r} never touched anything: are its device positions in m, and its "
                        "offset and scale those of the scene?")
    return said


def _rotation_about(q_from: np.ndarray, q_to: np.ndarray, axis: tuple) -> float:
    """Signed rotation (deg) about a world axis taking orientation q_from to q_to (w, x, y, z)."""
    inverse = np.zeros(4)
    relative = np.zeros(4)
    rotvec = np.zeros(3)
    mujoco.mju_negQuat(inverse, q_from)
    mujoco.mju_mulQuat(relative, q_to, inverse)  # world-frame rotation from q_from to q_to
    mujoco.mju_quat2Vel(rotvec, relative, 1.0)
    return float(np.degrees(np.dot(rotvec, axis)))


def run_scene(scene: Scene, device: Device, duration_s: float | None = None, rate_hz: float | None = None,
              finger_model: str | None = None, realtime: bool = False, on_tick=None, on_built=None,
              record: str | None = None, every: int = 10, priority: int | None = None, passivity: bool = True,
              allow_stiffer: bool = False, physics_rate_hz: float | None = None) -> dict:
    """Run the scene and return the result dict that `softproxy run --json` prints.

    `priority` (1–99) runs a real-time run's ticks under SCHED_FIFO at that priority
    (`softproxy.scheduling`; what the OS granted is in the result's "scheduling").

    `on_built(loop)` is called once the loop exists (e.g. to attach a viewer publisher);
    `on_tick(loop)` after every `every` ticks (and the last), outside the timed region; the
    ticks between run as one compiled block where the device allows (`ServoLoop.run`). `record` streams every device
    sample to that file as the run goes (see `softproxy.recording`). ValueError, before anything is built, for a
    duration or a rate out of bounds (`check_run`).
    """
    check_run(scene.duration_s if duration_s is None else duration_s, scene.rate_hz if rate_hz is None else rate_hz)
    if isinstance(device, (list, tuple)):
        device = device[0] if len(device) == 1 else DeviceGroup(device)
    if record is not None and isinstance(device, DeviceGroup):
        raise SceneError("--record records one device: run with one --device to record")
    original = device
    notes: list = []
    recorder = None
    if record is not None:  # opened before the run: an unwritable path fails now, naming it
        try:
            device = recorder = RecordingDevice(device, record, scene=scene.name, rate_hz=float(rate_hz or scene.rate_hz))
        except ValueError as exc:
            raise SceneError(f"--record {exc}") from None
    try:  # the recording is finished however this ends, building the loop included
        loop = build(scene, device, rate_hz, finger_model, realtime=realtime, passivity=passivity,
                     allow_stiffer=allow_stiffer, notes=notes, physics_rate_hz=physics_rate_hz)
        if on_built is not None:
            on_built(loop)
        user_on_tick = on_tick
        duration = duration_s if duration_s is not None else scene.duration_s
        ticks = int(round(duration * loop.rate_hz))
        measure = scene.measure
        track: dict = {}
        if measure is not None:
            body = loop.world.body_id(measure.object)
            xquat = loop.world.data.xquat
            start_tick = int(round(measure.start_s * loop.rate_hz))
            track.update(q0=None, max_deg=0.0)

            def on_tick(lp: ServoLoop) -> None:
                if lp.ticks == start_tick or (track["q0"] is None and lp.ticks > start_tick):
                    track["q0"] = xquat[body].copy()
                elif track["q0"] is not None:
                    track["max_deg"] = max(track["max_deg"], abs(_rotation_about(track["q0"], xquat[body], measure.axis)))
                if user_on_tick is not None:
                    user_on_tick(lp)
        else:
            on_tick = user_on_tick
        with realtime_thread(priority if realtime else None) as granted:
            loop.run(ticks, realtime=realtime, on_tick=on_tick, every=every)
    finally:
        if recorder is not None:
            recorder.finish()  # drain and close the file however the run ends (the caller closes the device)
    if recorder is not None and recorder.error:
        raise SceneError(f"--record {record}: {recorder.error}")

    result = {
        "scene": scene.name,
        "rate_hz": loop.rate_hz,
        "physics_rate_hz": loop.physics_rate_hz,
        "ticks": loop.ticks,
        "duration_s": loop.ticks * loop.period,
        "realtime": realtime,
        "scheduling": str(granted),
    }
    if measure is not None:
        mujoco_data = loop.world.data
        q0 = track["q0"] if track["q0"] is not None else mujoco_data.xquat[body].copy()
        rotation = _rotation_about(q0, mujoco_data.xquat[body], measure.axis)
        result["object"] = measure.object
        result["object_rotation_deg"] = round(rotation, 4)
        result["object_rotation_max_deg"] = round(max(track["max_deg"], abs(rotation)), 4)
        result["object_height_m"] = round(float(mujoco_data.xpos[body][2]), 5)
    result["fingers"] = [
        {
            "name": f.params.name,
            "model": f.model.name,
            "max_force_N": round(f.max_force_seen, 4),
            "proxy_penetration_max_m": f.penetration_max if loop.audit else None,
            "slip_events": f.slip_events,
            # the passivity observer and controller (softproxy.compiled.passivity)
            "energy_in_J": float(f.energy_in),
            "energy_owed_max_J": max(0.0, -float(f.energy_min)),
            "passivity_ticks": f.pc_ticks,
            "passivity_dissipated_J": float(f.pc_energy),
        }
        for f in loop.fingers
    ]
    result["passivity_controller"] = loop.passivity
    for i, channels in sensor_summaries(loop).items():  # only the fingers whose scene asked
        result["fingers"][i].update(channels)
    result["warnings"] = run_warnings(loop)
    result["notes"] = notes
    if isinstance(original, DeviceGroup):  # each device's own read failures (its fingers held meanwhile)
        result["devices"] = [{"device": type(d).__name__, "read_failures": n, "last_error": e}
                             for d, n, e in zip(original.devices, original.read_failures, original.last_errors)]
    result["tick_us"] = loop.stats.summary_us()
    result["deadline_misses"] = loop.stats.misses if realtime else None
    physics = loop.physics
    result["physics_thread"] = None if not (realtime and physics is not None) else {
        "steps": physics.steps, "late_steps": physics.late, "max_step_ms": physics.max_cost_s * 1e3}
    result["faults"] = dict(loop.faults)
    if loop.last_device_error:
        result["device_error"] = loop.last_device_error
    if getattr(original, "faults", None):  # a device injecting faults reports what it did
        result["device"] = {
            "faults_injected": dict(original.injected),
            "max_force_sent_N": round(getattr(original, "max_force_sent", 0.0), 4),
            "nan_sends": getattr(original, "nan_sends", 0),
            "force_clamp_N": original.max_force,
        }
    return result
