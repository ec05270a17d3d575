"""Batch replays: every recording of a folder replayed under variations of the engine, one table.

`softproxy replay-batch RECORDINGS... --vary SPEC ...` replays each recording (`softproxy run
--record` files, played by the replay device `replay:PATH`, lockstep) as it was recorded — the
unvaried replay, labelled "recorded", which reproduces a lockstep recorded run exactly — and
once per variation: a fingertip model, a servo rate, finger stiffness, damping or friction
(`--vary model=point`, `--vary rate=500`, `--vary stiffness=4000,damping=2`, `--vary
mu_s=0.5,mu_d=0.4`). Each replay is one cell of `softproxy.cells` (serial, `--workers N`, or
`--ray [ADDRESS]`). Per recording × variation the table says, against the unvaried replay of
the same recording:

- the measured object's pose error (position, m; orientation, deg: at the end and the largest),
  sampled every `SAMPLE_S` (4 ms) of replay time;
- the outcome: "held" (a finger touches the object at the end), "dropped" (touched, then let
  go: a deliberate release reads so too, in the unvaried replay as well) or "untouched", and
  whether it differs from the unvaried replay's;
- the rendered force and torque error (every finger's wrench, RMS and largest over the same
  samples; N, N·m), the slip events, the largest force, the faults the loop counted;
- the cost per tick (p50 and mean, µs, the compiled tick's own timing) and the cell's wall time.

A servo-rate variation replays the recording resampled to the new rate: each read of the new
loop takes the recorded pose at its time, interpolated linearly between two good samples; a
faulty or invalid sample (or a failed read) is held for the interval it covered. The scene is
the one named in each recording's header (`--scene` overrides it); recordings do not say which
fingertip model or settings the recorded run used, so the unvaried replay uses the scene's.

Everything but the timing columns depends only on the inputs, so it is the same bit for bit
whichever backend ran it; the summary's `outcomes_sha256` is a digest of those columns.
Writes replay_batch.csv, replay_batch.json (the summary) and replay_batch.png to `--out`.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from softproxy.cells import Backend, Outcome, each_outcome
from softproxy.device import DeviceError, DeviceSample
from softproxy.finger import FingerParams
from softproxy.fingertip import MODELS
from softproxy.recording import Recording, RecordingDevice, RecordingError, load_recording, read_header
from softproxy.run import check_device_fingers, open_device, run_scene
from softproxy.scene import SceneError, load_scene
from softproxy.servo import MAX_RATE_HZ, MIN_RATE_HZ

SAMPLE_S = 0.004
"""Replay time between two samples of the pose and the wrenches compared (s): a 250 Hz grid
every servo rate from 250 Hz up lands on."""
UNVARIED = "recorded"
"""The label of each recording's unvaried replay, the reference of its row group."""
SUFFIX = ".rec"
"""What a recording is called in a folder (files given by name may be called anything)."""
FINGER_KEYS = ("stiffness", "damping", "torsion_stiffness", "torsion_damping", "mu_s", "mu_d",
               "torsion_mu_s", "torsion_mu_d")
"""The finger settings a variation may change (FingerParams fields; units in FingerParams)."""
VARIATION_KEYS = ("model", "rate", *FINGER_KEYS)
COLUMNS = (
    "recording", "variation", "status", "error", "scene", "fingers", "rate_hz", "duration_s", "ticks",
    "object", "outcome", "outcome_changed", "turned_deg", "position_error_end_m", "position_error_max_m",
    "rotation_error_end_deg", "rotation_error_max_deg", "force_error_rms_N", "force_error_max_N",
    "torque_error_rms_Nm", "torque_error_max_Nm", "slip_events", "max_force_N", "faults",
)
"""The table's columns that depend only on the inputs (equal bit for bit across backends)."""
TIMING_COLUMNS = ("tick_us_p50", "tick_us_mean", "cell_s")
"""The measured ones, last in the table: cost per tick (µs) and the cell's wall time (s)."""
OUTCOMES = ("held", "dropped", "untouched")


class BatchError(ValueError):
    """A batch that cannot run as asked; one line naming the file, flag or field and the fix."""


# ---------------------------------------------------------------------------------------------
# inputs

def parse_variation(text: str) -> dict:
    """`--vary` "model=point,stiffness=4000" -> {"label", "model", "rate", "fingers": {...}};
    BatchError naming the flag, the item and what it takes."""
    where = f"--vary {text!r}"
    found: dict = {}
    for item in text.split(","):
        key, sep, value = (part.strip() for part in item.partition("="))
        if not sep or not key or not value:
            raise BatchError(f"{where}: {item.strip()!r} is not KEY=VALUE (e.g. --vary model=point or "
                             f"--vary stiffness=4000,damping=2)")
        if key not in VARIATION_KEYS:
            raise BatchError(f"{where}: unknown setting {key!r}; vary any of {', '.join(VARIATION_KEYS)}")
        if key in found:
            raise BatchError(f"{where}: {key} is given twice")
        if key == "model":
            if value not in MODELS:
                raise BatchError(f"{where}: model must be one of {', '.join(MODELS)}, got {value!r}")
            found[key] = value
            continue
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not math.isfinite(number):
            raise BatchError(f"{where}: {key} must be a number, got {value!r}")
        if key == "rate" and not MIN_RATE_HZ <= number <= MAX_RATE_HZ:
            raise BatchError(f"{where}: rate must be a servo rate from {MIN_RATE_HZ:g} to {MAX_RATE_HZ:g} Hz, "
                             f"got {value}")
        found[key] = number
    label = ",".join(f"{k}={v if isinstance(v, str) else format(v, 'g')}" for k, v in found.items())
    if label == UNVARIED:
        raise BatchError(f"{where}: {UNVARIED!r} is the unvaried replay's label")
    return {"label": label, "model": found.get("model"), "rate": found.get("rate"),
            "fingers": {k: v for k, v in found.items() if k in FINGER_KEYS}}


def find_recordings(inputs: list[str]) -> list[tuple[str, Path]]:
    """(name as shown, absolute path) of every recording: files as given, folders' `*.rec`
    files (in subfolders too), in name order; BatchError for a path that is neither."""
    if not inputs:
        raise BatchError("give recording files or folders of them (*.rec)")
    found: dict[Path, str] = {}
    for given in inputs:
        path = Path(given)
        if path.is_dir():
            files = sorted(p for p in path.rglob(f"*{SUFFIX}") if p.is_file())
            if not files:
                raise BatchError(f"{given}: no recordings (*{SUFFIX}) in this folder; record some with "
                                 f"softproxy run SCENE --record FILE{SUFFIX}")
            for p in files:
                found.setdefault(p.resolve(), str(path / p.relative_to(path)))
        elif path.exists():
            found.setdefault(path.resolve(), given)
        else:
            raise BatchError(f"{given}: no such file or folder; give recording files or folders of them (*{SUFFIX})")
    return sorted(((name, path) for path, name in found.items()), key=lambda item: item[0])


def _recorded_rate(header: dict, scene) -> float:
    """The rate the recording was made at (Hz): its header's, else the scene's."""
    rate = header.get("rate_hz")
    if isinstance(rate, (int, float)) and not isinstance(rate, bool) and MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
        return float(rate)
    return float(scene.rate_hz)


def _varied(scene, variation: dict, where: str):
    """The scene with the variation's finger settings (each finger re-validated); BatchError naming `where`."""
    changes = variation["fingers"]
    if not changes:
        return scene
    try:
        fingers = [dataclasses.replace(f, **changes) for f in scene.fingers]
    except ValueError as exc:
        hint = ""
        if "mu_d" in str(exc) and "mu_s" in changes and "mu_d" not in changes:
            hint = f"; give mu_d too (e.g. mu_s={changes['mu_s']:g},mu_d={0.8 * changes['mu_s']:g})"
        elif "torsion_mu_d" in str(exc) and "torsion_mu_d" not in changes:
            hint = "; give torsion_mu_d too"
        raise BatchError(f"{where}: {exc}{hint}") from None
    return dataclasses.replace(scene, fingers=fingers)


def plan(inputs: list[str], specs: list[str], scene: str | None = None) -> tuple[list[dict], list[str]]:
    """The cells of a batch (recording-major: the unvaried replay, then each variation in the
    order given) and the recordings' names; BatchError (one line) for anything that would make
    every replay of a recording fail: a path, a file that is no recording or is damaged (each
    is read whole and checked, checksums and the reads it claims included, before any replay
    starts), a scene, a variation."""
    variations = [{"label": UNVARIED, "model": None, "rate": None, "fingers": {}}]
    for spec in specs:
        v = parse_variation(spec)
        if any(v["label"] == w["label"] for w in variations):
            raise BatchError(f"--vary {spec!r}: given twice")
        variations.append(v)
    recordings = find_recordings(inputs)
    if scene is not None and Path(scene).is_file():
        scene = str(Path(scene).resolve())  # a worker may run elsewhere in the file system
    scenes: dict = {}
    cells, names = [], []
    for name, path in recordings:
        try:
            header = read_header(path)
        except RecordingError as exc:
            raise BatchError(f"{exc}; replay only recordings made by softproxy run --record") from None
        try:
            load_recording(path)  # the body: damage, and what it claims (a replay runs a tick per claimed read)
        except RecordingError as exc:
            raise BatchError(f"{exc}; leave it out of the batch") from None
        scene_name = scene or header.get("scene")
        if not isinstance(scene_name, str) or not scene_name:
            raise BatchError(f"{name}: its header names no scene; give the scene it was recorded on with --scene")
        if scene_name not in scenes:
            try:
                scenes[scene_name] = loaded = load_scene(scene_name)
                loaded.load_model()
            except (SceneError, ValueError) as exc:
                source = "--scene" if scene else f"{name}: recorded on scene {scene_name!r}:"
                raise BatchError(f"{source} {exc}" + ("" if scene else "; give the scene with --scene")) from None
            for v in variations[1:]:
                _varied(loaded, v, f"--vary {v['label']!r} on scene {scene_name!r}")
        loaded = scenes[scene_name]
        needed = loaded.device_fingers
        if header["fingers"] < needed:
            raise BatchError(f"{name}: holds {header['fingers']} finger(s), but scene {scene_name!r} drives "
                             f"{needed}; give the scene it was recorded on with --scene")
        names.append(name)
        for v in variations:
            cells.append({"recording": str(path), "scene": scene_name, "variation": v})
    return cells, names


# ---------------------------------------------------------------------------------------------
# one replay (runs in a worker)

class _Resampled:
    """A device (Device protocol) serving precomputed reads one after the other: what
    `resample` records. A read whose row is a failed read raises DeviceError, as the original did."""

    max_force = max_torque = 1e6

    def __init__(self, values: np.ndarray, valid: np.ndarray, failed: np.ndarray, buttons: np.ndarray) -> None:
        self.values, self.valid, self.failed, self.buttons = values, valid, failed, buttons
        self.fingers = values.shape[1]
        self.reads = 0

    def read(self, t, samples) -> None:
        j = min(self.reads, len(self.values) - 1)
        self.reads += 1
        if self.failed[j]:
            raise DeviceError("the recorded device failed on this read")
        for f, s in enumerate(samples):
            s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist = self.values[j, f].tolist()
            s.buttons, s.valid = int(self.buttons[j, f]), bool(self.valid[j, f])

    def send(self, finger, fx, fy, fz, tx, ty, tz) -> None:
        pass

    def close(self) -> None:
        pass


def resample(recording: Recording, recorded_rate: float, rate_hz: float, ticks: int, path: str | Path,
             scene: str) -> None:
    """Write to `path` the recording as a loop at `rate_hz` running `ticks` ticks reads it: one
    read at t = 0 when the loop starts, then one per tick at t = k / rate_hz. A read takes the
    recorded pose at its time (each record's `t`; read index / rate where those are unusable),
    interpolated linearly between two good records, or the record at or before it as it is
    (so resampling to the recorded rate gives the recording back, bit for bit)."""
    values = recording.values  # (records, fingers, 9): t x y z qw qx qy qz twist
    n = len(values)
    if n == 0:
        raise RecordingError(f"{recording.path}: the recording holds no samples")
    times = values[:, 0, 0].copy()
    if not (np.all(np.isfinite(times)) and np.all(np.diff(times) >= 0.0)):
        times = np.maximum(recording.index - 1, 0) / recorded_rate  # read k > 0 is tick k - 1
    valid = recording.valid != 0
    failed = np.asarray(recording.error, dtype=bool)
    good = ~failed & valid.all(axis=1) & np.isfinite(values[:, :, 1:]).all(axis=(1, 2))
    wanted = np.concatenate([[0.0], np.arange(ticks) / rate_hz])
    # the last record at or before each read's time (within a millionth of a period: the
    # loop's clock and k / rate may differ in the last bits); the start's read is the first
    tolerance = 1e-6 / rate_hz
    k = np.searchsorted(times, wanted + tolerance, side="right") - 1
    k[0] = 0
    k = np.clip(k, 0, n - 1)
    after = np.minimum(k + 1, n - 1)
    span = times[after] - times[k]
    blend = good[k] & good[after] & (after > k) & (span > 0.0) & (wanted - times[k] > tolerance)
    w = np.where(blend, (wanted - times[k]) / np.where(span > 0.0, span, 1.0), 0.0).clip(0.0, 1.0)
    out = values[k].copy()
    mixed = values[k] + w[:, None, None] * (values[after] - values[k])
    out[blend] = mixed[blend]
    quat = out[:, :, 4:8]
    norm = np.linalg.norm(quat, axis=2, keepdims=True)
    out[blend, :, 4:8] = (quat / np.where(norm > 0.0, norm, 1.0))[blend]
    out[blend, :, 0] = wanted[blend, None]  # a record taken as it is keeps its own time
    device = _Resampled(out, valid[k], failed[k], recording.buttons[k])
    recorder = RecordingDevice(device, path, buffer_s=(ticks + 2) / rate_hz + 1.0, scene=scene, rate_hz=rate_hz)
    samples = [DeviceSample() for _ in range(device.fingers)]
    try:
        for j in range(len(wanted)):
            try:
                recorder.read(float(wanted[j]), samples)
            except DeviceError:
                pass  # recorded as a failed read, as the original was
    finally:
        recorder.close()
    if recorder.dropped or recorder.error:
        raise RecordingError(f"{path}: resampling lost {recorder.dropped} reads ({recorder.error or 'writer behind'})")


def _trace_row(loop, body: int, fingers: list, contact: list) -> list[float]:
    """t, the object's position and orientation (NaN without one), and each finger's wrench."""
    data = loop.world.data
    row = [loop.t]
    if body >= 0:
        row += data.xpos[body].tolist() + data.xquat[body].tolist()
        if any(f.body == body for f in fingers):
            contact[0] = True  # touched at some point
            contact[1] = True
        else:
            contact[1] = False
    else:
        row += [math.nan] * 7
    for f in fingers:
        row += [f.fx, f.fy, f.fz, f.tx, f.ty, f.tz]
    return row


def _on_grid(rows: list[list[float]], duration: float, sample_s: float) -> np.ndarray:
    """The trace at t = 0, sample_s, 2 sample_s, ... up to `duration`: each the last row at or
    before that time (rows start at t = 0)."""
    trace = np.array(rows)
    grid = np.arange(int(math.floor(duration / sample_s + 1e-9)) + 1) * sample_s
    k = np.searchsorted(trace[:, 0], grid + 1e-9, side="right") - 1
    return trace[np.clip(k, 0, len(trace) - 1), 1:]


def replay_cell(recording: str, scene: str, variation: dict, sample_s: float = SAMPLE_S) -> dict:
    """Replay one recording under one variation (lockstep); its outcome and its trace on the
    sample grid (object position, orientation, then each finger's force and torque)."""
    header = read_header(recording)
    loaded = _varied(load_scene(scene), variation, f"--vary {variation['label']!r}")
    recorded_rate = _recorded_rate(header, loaded)
    rate = variation["rate"] or recorded_rate
    device = open_device(f"replay:{recording}", loaded)
    try:
        reads = device.recording.reads
        if reads < 2:
            raise RecordingError(f"{recording}: holds {reads} read(s), too few to replay")
        duration = (reads - 1) / recorded_rate  # the start's read, then one per tick
        ticks = int(round(duration * rate))
        with tempfile.TemporaryDirectory(prefix="softproxy-replay-") as scratch:
            if rate != recorded_rate:
                resampled = Path(scratch) / "resampled.rec"
                resample(device.recording, recorded_rate, rate, ticks, resampled, loaded.name)
                device.close()
                device = open_device(f"replay:{resampled}", loaded)
            check_device_fingers(loaded, device, f"recording {recording}")
            measure = loaded.measure
            state: dict = {"rows": [], "contact": [False, False]}

            def on_built(loop) -> None:
                state["loop"] = loop
                state["body"] = loop.world.body_id(measure.object) if measure is not None else -1
                state["rows"].append(_trace_row(loop, state["body"], loop.fingers, state["contact"]))

            def on_tick(loop) -> None:
                state["rows"].append(_trace_row(loop, state["body"], loop.fingers, state["contact"]))

            every = max(1, int(math.floor(sample_s * rate + 1e-9)))
            result = run_scene(loaded, device, duration_s=duration, rate_hz=rate, finger_model=variation["model"],
                               on_built=on_built, on_tick=on_tick, every=every)
    finally:
        device.close()
    loop = state["loop"]
    durations = loop.stats.durations()
    loop.close()
    touched, at_end = state["contact"]
    return {
        "scene": loaded.name, "fingers": len(loop.fingers), "rate_hz": float(rate), "duration_s": duration,
        "ticks": result["ticks"], "object": measure.object if measure is not None else None,
        "outcome": None if measure is None else "held" if at_end else "dropped" if touched else "untouched",
        "turned_deg": result.get("object_rotation_deg"),
        "slip_events": sum(f["slip_events"] for f in result["fingers"]),
        "max_force_N": max((f["max_force_N"] for f in result["fingers"]), default=0.0),
        "faults": sum(result["faults"].values()),
        "tick_us_p50": result["tick_us"]["p50"],
        "tick_us_mean": round(float(durations.mean()) * 1e6, 3) if durations.size else None,
        "trace": _on_grid(state["rows"], duration, sample_s),
    }


# ---------------------------------------------------------------------------------------------
# the table

def compare(reference: np.ndarray, trace: np.ndarray, fingers: int) -> dict:
    """Pose and wrench errors of `trace` against `reference` (both on the sample grid, over the
    samples both have): the object's position (m) and orientation (deg) at the end and at most,
    every finger's force (N) and torque (N·m) error, RMS and largest."""
    n = min(len(reference), len(trace))
    ref, run = reference[:n], trace[:n]
    errors: dict = {}
    if n and np.all(np.isfinite(ref[:, :7])) and np.all(np.isfinite(run[:, :7])):
        position = np.linalg.norm(run[:, :3] - ref[:, :3], axis=1)
        # |q1 - q2| = 2 sin(angle / 4) for unit quaternions (q and -q the same turn): exact 0
        # for equal orientations, where arccos of a dot product rounding to 1 - 1e-16 is not
        chord = np.minimum(np.linalg.norm(run[:, 3:7] - ref[:, 3:7], axis=1),
                           np.linalg.norm(run[:, 3:7] + ref[:, 3:7], axis=1))
        rotation = np.degrees(4.0 * np.arcsin((chord / 2.0).clip(0.0, 1.0)))
        errors.update(position_error_end_m=float(position[-1]), position_error_max_m=float(position.max()),
                      rotation_error_end_deg=float(rotation[-1]), rotation_error_max_deg=float(rotation.max()))
    if n and run.shape[1] == ref.shape[1] == 7 + 6 * fingers:
        wrench = (run[:, 7:] - ref[:, 7:]).reshape(n, fingers, 6)
        force = np.linalg.norm(wrench[:, :, :3], axis=2)
        torque = np.linalg.norm(wrench[:, :, 3:], axis=2)
        errors.update(force_error_rms_N=float(np.sqrt(np.mean(force ** 2))), force_error_max_N=float(force.max()),
                      torque_error_rms_Nm=float(np.sqrt(np.mean(torque ** 2))),
                      torque_error_max_Nm=float(torque.max()))
    return errors


def _rows_of(name: str, outcomes: list[Outcome]) -> list[dict]:
    """The table rows of one recording: its unvaried replay (outcomes[0]) and its variations."""
    reference = outcomes[0].value if outcomes[0].ok else None
    rows = []
    for o in outcomes:
        v = o.value if o.ok else {}
        row = {"recording": name, "variation": o.params["variation"]["label"], "status": "ok" if o.ok else "failed",
               "error": o.error, "scene": o.params["scene"], "cell_s": round(o.seconds, 4)}
        for key in ("fingers", "rate_hz", "duration_s", "ticks", "object", "outcome", "turned_deg", "slip_events",
                    "max_force_N", "faults", "tick_us_p50", "tick_us_mean"):
            row[key] = v.get(key)
        if o.ok and reference is not None:
            row.update(compare(reference["trace"], v["trace"], v["fingers"]))
            if v["outcome"] is not None:
                row["outcome_changed"] = v["outcome"] != reference["outcome"]
        rows.append(row)
    return rows


def _cell(value) -> str:
    """A table cell: floats as repr (shortest round trip, so equal text is equal bits), None empty."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def table_text(rows: list[dict], columns=COLUMNS + TIMING_COLUMNS) -> str:
    """The rows as CSV text with those columns."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])
    return buffer.getvalue()


def _stats(values: list[float]) -> dict:
    values = [v for v in values if v is not None]
    if not values:
        return {"median": None, "max": None}
    return {"median": float(np.median(values)), "max": float(max(values))}


def summarise(rows: list[dict], variations: list[str]) -> dict:
    """Per variation: replays, outcomes, and the spread of the errors, cost and slips over the recordings."""
    summary = {}
    for label in variations:
        mine = [r for r in rows if r["variation"] == label]
        ok = [r for r in mine if r["status"] == "ok"]
        summary[label] = {
            "replays": len(ok), "failed": len(mine) - len(ok),
            **{name: sum(r["outcome"] == name for r in ok) for name in OUTCOMES},
            "outcome_changed": sum(bool(r.get("outcome_changed")) for r in ok),
            "force_error_rms_N": _stats([r.get("force_error_rms_N") for r in ok]),
            "force_error_max_N": _stats([r.get("force_error_max_N") for r in ok]),
            "position_error_max_m": _stats([r.get("position_error_max_m") for r in ok]),
            "rotation_error_max_deg": _stats([r.get("rotation_error_max_deg") for r in ok]),
            "slip_events": sum(r["slip_events"] or 0 for r in ok),
            "tick_us_p50": _stats([r.get("tick_us_p50") for r in ok]),
        }
    return summary


def run_batch(inputs: list[str], specs: list[str], scene: str | None = None, backend: Backend = Backend(),
              progress=None, sample_s: float = SAMPLE_S) -> dict:
    """Plan the batch (BatchError for bad inputs), run every replay on `backend`, and return
    {"rows": [...] in cell order, "summary": {...}}. Each recording's replays are compared as
    soon as they are all in, and their traces let go."""
    cells, names = plan(inputs, specs, scene)
    for c in cells:
        c["sample_s"] = sample_s
    per = len(specs) + 1
    waiting: dict[int, list] = {}
    rows: dict[int, list[dict]] = {}
    start = time.perf_counter()
    for outcome in each_outcome(replay_cell, cells, backend, progress):
        r = outcome.index // per
        group = waiting.setdefault(r, [None] * per)
        group[outcome.index % per] = outcome
        if all(o is not None for o in group):
            rows[r] = _rows_of(names[r], group)
            del waiting[r]
    wall = time.perf_counter() - start
    table = [row for r in sorted(rows) for row in rows[r]]
    labels = [c["variation"]["label"] for c in cells[:per]]
    failed = [{"recording": row["recording"], "variation": row["variation"], "error": row["error"]}
              for row in table if row["status"] != "ok"]
    ok = [row for row in table if row["status"] == "ok"]
    cell_s = sum(row["cell_s"] for row in table)
    replayed = sum(row["duration_s"] for row in ok)
    ticks = sum(row["ticks"] for row in ok)
    summary = {
        "inputs": list(inputs), "scene": scene, "recordings": len(names), "variations": labels,
        "replays": len(cells), "failed": failed, "backend": backend.describe(), "sample_s": sample_s,
        "by_variation": summarise(table, labels),
        "outcomes_sha256": hashlib.sha256(table_text(table, COLUMNS).encode()).hexdigest(),
        "timing": {"wall_s": round(wall, 3), "cells_s": round(cell_s, 3), "replayed_s": round(replayed, 3),
                   "ticks": ticks, "replayed_s_per_wall_s": round(replayed / wall, 2) if wall > 0 else None,
                   "cell_s_mean": round(cell_s / len(table), 4) if table else None},
        "versions": _versions(),
    }
    return {"rows": table, "summary": summary}


def _versions() -> dict:
    """What the outcomes depend on besides the inputs (a batch on another set may differ in the last bits)."""
    from importlib.metadata import PackageNotFoundError, version

    found = {"python": sys.version.split()[0]}
    for name in ("softproxy", "numpy", "mujoco", "numba"):
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = None
    return found


# ---------------------------------------------------------------------------------------------
# output

def chart(result: dict):
    """Per variation: force error and object orientation error over the recordings (one dot
    each), the outcomes, and the cost per tick."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows, labels = result["rows"], result["summary"]["variations"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    x = np.arange(len(labels))
    for ax, key, title in ((axes[0][0], "force_error_rms_N", "rendered force error, RMS (N)"),
                           (axes[0][1], "rotation_error_max_deg", "object orientation error, largest (deg)")):
        for i, label in enumerate(labels):
            values = [r[key] for r in rows if r["variation"] == label and r.get(key) is not None]
            ax.scatter(np.full(len(values), i) + np.linspace(-0.15, 0.15, len(values)),
                       np.maximum(values, 1e-9) if values else [], s=14)
        if any(r.get(key) for r in rows):
            ax.set_yscale("log")
        ax.set_title(f"{title} against the unvaried replay (floor 1e-9)", fontsize=9)
    ax = axes[1][0]
    bottom = np.zeros(len(labels))
    by = result["summary"]["by_variation"]
    for name, colour in zip((*OUTCOMES, "failed"), ("#2ca02c", "#d62728", "#7f7f7f", "#000000")):
        counts = np.array([by[label][name] for label in labels], dtype=float)
        ax.bar(x, counts, bottom=bottom, color=colour, label=name)
        bottom += counts
    ax.set_title("outcome per replay (held: a finger on the object at the end)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[1][1]
    for i, label in enumerate(labels):
        values = [r["tick_us_p50"] for r in rows if r["variation"] == label and r.get("tick_us_p50") is not None]
        ax.scatter(np.full(len(values), i) + np.linspace(-0.15, 0.15, len(values)), values, s=14)
    ax.set_title("cost per tick, p50 (µs)", fontsize=9)
    for ax in axes.flat:
        ax.set_xticks(x, labels, rotation=20, ha="right", fontsize=7)
    fig.suptitle(f"{result['summary']['recordings']} recordings × {len(labels)} replays each", fontsize=10)
    return fig


def write(result: dict, out: str | Path) -> tuple[Path, Path, Path]:
    """replay_batch.csv, .json and .png in `out` (made if missing); their paths."""
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = out / "replay_batch.csv", out / "replay_batch.json", out / "replay_batch.png"
    paths[0].write_text(table_text(result["rows"]))
    paths[1].write_text(json.dumps({**result["summary"], "table": paths[0].name}, indent=1) + "\n")
    fig = chart(result)
    fig.tight_layout()
    fig.savefig(paths[2], dpi=100)
    plt.close(fig)
    return paths


def _g(value, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def report(result: dict, paths) -> None:
    """The summary as text: one line per variation, the failures, where the files went."""
    s = result["summary"]
    t = s["timing"]
    print(f"replay-batch: {s['recordings']} recordings × {len(s['variations'])} replays = {s['replays']} on "
          f"{s['backend']}: {t['wall_s']:.1f} s wall, {t['replayed_s']:.1f} s replayed "
          f"({t['replayed_s_per_wall_s']}× real time)")
    print(f"  {'variation':28s}{'ok':>5s}{'held':>6s}{'dropped':>9s}{'untouched':>11s}{'changed':>9s}"
          f"{'force RMS N (median/max)':>26s}{'pos err m (median/max)':>25s}{'slips':>7s}{'tick p50 µs':>13s}")
    for label, v in s["by_variation"].items():
        f, p = v["force_error_rms_N"], v["position_error_max_m"]
        print(f"  {label:28s}{v['replays']:5d}{v['held']:6d}{v['dropped']:9d}{v['untouched']:11d}"
              f"{v['outcome_changed']:9d}{_g(f['median'], '.3g') + ' / ' + _g(f['max'], '.3g'):>26s}"
              f"{_g(p['median'], '.3g') + ' / ' + _g(p['max'], '.3g'):>25s}{v['slip_events']:7d}"
              f"{_g(v['tick_us_p50']['median'], '.2f'):>13s}")
    for f in s["failed"]:
        print(f"  FAILED {f['recording']} × {f['variation']}: {f['error']}")
    print(f"  outcomes sha256 {s['outcomes_sha256'][:16]}… (every column but the timings; the same on every backend)")
    print(f"  wrote {', '.join(str(p) for p in paths)}")
