"""The `softproxy` command line: one subcommand per job, each with a `--json` form.

A mistake on the command line or in a file it names ends the command with exit status 2
and one line on stderr naming the flag, file or field and what was expected; it is found
before any servo loop runs. Tracebacks are left for bugs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import sys
import warnings
from pathlib import Path

from softproxy.fingertip import MODELS

OUTPUT_SUFFIXES = {"--snapshot": (".png", "a PNG image"), "--video": (".mp4", "an MP4 video (H.264)")}
"""The file name ending each output flag of `softproxy run` takes (checked before the run)."""
MAX_BENCH_S = 3600.0
"""Longest benchmark duration (--duration, --paced), s: benchmarks keep per-tick arrays."""
_NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE)
"""An argument that is a negative number, not an option (argparse's own pattern misses -1.5e-05)."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors, that takes "-1.5e-05" as a number, not as an option."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER  # the pattern argparse tells numbers from options by

    def error(self, message: str):
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _print_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> None:
    """Print `rows` as an aligned text table; `columns` are (key, header, format)."""
    cells = [[header for _, header, _ in columns]]
    for row in rows:
        cells.append(["-" if row.get(key) is None else format(row[key], fmt) for key, _, fmt in columns])
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns))]
    for i, r in enumerate(cells):
        print("  ".join(c.rjust(w) if i and j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))))


def cmd_models(args: argparse.Namespace) -> int:
    """List the fingertip models: constants, the saturating law the engine uses beside the
    power law (N·mm at 1 and 3 N), and how closely each follows the measured fingertip."""
    from softproxy import fingertip
    from softproxy.schema import FingerParams

    saturate = FingerParams().saturate
    rows = []
    for m in MODELS.values():
        row = m.as_dict()
        fit = fingertip.fit_to_measured(m, saturate)
        if fit:
            fit.pop("refitted_model")
            row["measured_fingertip"] = fit
        rows.append(row)
    law_name = "saturating" if saturate else "power"
    measured = {f"at_{P:g}N_Nmm": 1e3 * fingertip.e3_torque(P) for P in (1.0, 3.0)}
    grips = fingertip.MEASURED_GRIPS
    if args.json:
        print(json.dumps({"models": rows, "engine_law": law_name, "measured_fingertip": measured,
                          "measured_grips_N": list(grips)}, indent=2))
        return 0
    flat = [{**r, "rms": r.get("measured_fingertip", {}).get("rms"),
             "max": r.get("measured_fingertip", {}).get("max"),
             "refit_mu": r.get("measured_fingertip", {}).get("refitted_mu_prime_Nmm"),
             "refit_rms": r.get("measured_fingertip", {}).get("refitted", {}).get("rms")} for r in rows]
    flat.append({"name": "measured fingertip", "saturating_limit_at_1N_Nmm": measured["at_1N_Nmm"],
                 "saturating_limit_at_3N_Nmm": measured["at_3N_Nmm"]})
    print("Fingertip models (Simulating human fingers: a Soft Finger Proxy Model and Algorithm, Table 1)")
    print(f"The engine's torsional limit is the {law_name} law"
          + (" (the default): M = mu' |P|^gamma up to P*, then linear with slope "
             f"r0 = {1e3 * fingertip.R0:.2f} mm; with saturate = false, the power law M = mu' |P|^gamma."
             if saturate else ": M = mu' |P|^gamma at every grip."))
    print(f"Torques in N·mm. vs measured: relative error of the engine's law against the measured "
          f"fingertip at {grips[0]:g}-{grips[-1]:g} N (RMS, largest); refit: mu' fitted to it (P* follows).")
    _print_table(
        flat,
        [
            ("name", "model", "s"),
            ("gamma", "gamma", ".4f"),
            ("mu_prime_Nmm", "mu' (N·mm/N^g)", ".4f"),
            ("p_star_N", "P* (N)", ".4f"),
            ("saturating_limit_at_1N_Nmm", "saturating M@1N", ".3f"),
            ("saturating_limit_at_3N_Nmm", "M@3N", ".3f"),
            ("torque_limit_at_1N_Nmm", "power law M@1N", ".3f"),
            ("torque_limit_at_3N_Nmm", "M@3N", ".3f"),
            ("rms", "vs measured RMS", ".2f"),
            ("max", "largest", ".2f"),
            ("refit_mu", "refit mu'", ".3f"),
            ("refit_rms", "refit RMS", ".2f"),
        ],
    )
    for line in models_verdict(rows):
        print(line)
    return 0


def models_verdict(rows: list[dict]) -> list[str]:
    """Which fingertip model follows the measured fingertip, and by how much, in plain words
    (from the `softproxy models` rows, each with its `measured_fingertip` fit)."""
    fits = {r["name"]: r["measured_fingertip"] for r in rows if "measured_fingertip" in r}
    best = min(fits, key=lambda n: fits[n]["rms"])
    others = [n for n in fits if n != best]
    ratio = [fits[n]["rms"] / fits[best]["rms"] for n in others]
    refit = [fits[n]["refitted"]["rms"] for n in others]
    lines = [f"Closest to the measured fingertip: {best} (RMS {fits[best]['rms']:.2f}). "
             f"{', '.join(others)} are {min(ratio):.1f}-{max(ratio):.1f}x further from it "
             f"(RMS {', '.join(format(fits[n]['rms'], '.2f') for n in others)}; "
             f"largest error {', '.join(format(fits[n]['max'], '.1f') + ' at ' + format(fits[n]['max_at_N'], 'g') + ' N' for n in others)})."]
    if all(r > fits[best]["rms"] for r in refit):
        lines.append(f"Refitting mu' (the one constant the paper leaves free) brings them to RMS "
                     f"{', '.join(f'{r:.2f}' for r in refit)}: still short of {best}, their exponents being too "
                     "low for the fingertip's steep rise at light touch. The engine keeps the paper's constants; "
                     "softproxy.fingertip.refitted(name) gives a refitted law.")
    else:
        lines.append(f"Refitting mu' (the one constant the paper leaves free) brings them to RMS "
                     f"{', '.join(f'{r:.2f}' for r in refit)}; softproxy.fingertip.refitted(name) gives that law.")
    return lines


def _physics_rate(text: str) -> float | str:
    """--physics-rate: a rate in Hz, or "auto" (`softproxy.local_model.AUTO`; not imported here,
    which would load the compiled engine for `--help`)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a rate in Hz or 'auto', got {text!r}") from None


def _parse_faults(text: str) -> dict:
    """`nan=0.01,drop=0.001` -> {"nan": 0.01, "drop": 0.001}; ValueError naming --faults and
    the bad item. The fault names are the device's to check (see `_open_run_device`)."""
    faults = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        try:
            p = float(value)
        except ValueError:
            p = math.nan
        if not sep or not name.strip() or not 0.0 <= p <= 1.0:
            raise ValueError(f"--faults: {item!r} is not NAME=PROBABILITY with a probability per read in [0, 1] "
                             f"(e.g. nan=0.01,drop=0.001)")
        faults[name.strip()] = p
    return faults


def _check_output(flag: str, path: str) -> None:
    """ValueError naming `flag` unless `path` can be written (tried now, so a run is not lost
    to a typo in a folder name found only when the run is over); a new file is removed again."""
    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{flag} {path}: is a folder; give a file name")
    existed = p.exists()
    try:  # append: an existing file is not truncated; non-blocking: a FIFO with no reader fails, not hangs
        os.close(os.open(p, os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NONBLOCK", 0), 0o666))
    except OSError as exc:
        raise ValueError(f"{flag} {path}: cannot write there ({exc.strerror}); give a path in a writable folder") from None
    if not existed:
        p.unlink(missing_ok=True)


def _check_out_folder(command: str, folder: str) -> bool:
    """True if --out `folder` exists or can be made, and a file can be written in it; else one
    line on stderr naming the flag and False (checked before the work, not after it)."""
    import tempfile

    try:
        Path(folder).mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        print(f"softproxy {command}: --out {folder}: cannot write files there ({exc.strerror or exc}); "
              f"give a writable folder", file=sys.stderr)
        return False
    return True


def _check_run_flags(args: argparse.Namespace) -> dict | None:
    """Check `softproxy run`'s flags before anything is loaded; the --faults table (or None).
    ValueError naming the flag and what it takes."""
    from softproxy.schema import MAX_DURATION_S
    from softproxy.servo import MAX_RATE_HZ, MIN_RATE_HZ

    if args.duration is not None and not (math.isfinite(args.duration) and 0.0 < args.duration <= MAX_DURATION_S):
        raise ValueError(f"--duration must be a number of seconds > 0 and at most {MAX_DURATION_S:g} (24 h), "
                         f"got {args.duration!r}")
    if args.rate is not None and not (math.isfinite(args.rate) and MIN_RATE_HZ <= args.rate <= MAX_RATE_HZ):
        raise ValueError(f"--rate must be a servo rate between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g} Hz, got {args.rate!r}")
    if args.rt_priority is not None:
        from softproxy.scheduling import check_priority

        try:
            check_priority(args.rt_priority)
        except ValueError as exc:
            raise ValueError(f"--rt-priority: {exc}") from None
        if args.headless and not args.realtime:
            raise ValueError("--rt-priority schedules a real-time run: add --realtime (a lockstep run is not paced)")
    for kind in args.device or ["sim"]:
        name, colon, argument = kind.partition(":")
        if colon and not argument:
            raise ValueError(f"--device {kind!r}: give the argument after ':' (e.g. replay:run.rec)")
    faults = _parse_faults(args.faults) if args.faults else None
    other = [kind for kind in args.device or ["sim"] if kind != "sim"]
    if faults and other:
        raise ValueError(f"--faults: only the simulated device injects faults; use it with --device sim "
                         f"(got --device {other[0]})")
    if args.record and args.device and len(args.device) > 1:
        raise ValueError("--record records one device: give --device once to record a run")
    outputs = [(flag, path) for flag, path in (("--snapshot", args.snapshot), ("--video", args.video),
                                               ("--record", args.record)) if path]
    for flag, path in outputs:
        _check_output(flag, path)
        suffix = OUTPUT_SUFFIXES.get(flag)
        if suffix and Path(path).suffix.lower() != suffix[0]:
            raise ValueError(f"{flag} {path}: writes {suffix[1]}; give a file name ending in {suffix[0]} "
                             f"(e.g. {flag} {Path(path).with_suffix(suffix[0]).name})")
    for i, (flag, path) in enumerate(outputs):
        for other, later in outputs[i + 1:]:
            if os.path.realpath(path) == os.path.realpath(later):
                raise ValueError(f"{flag} and {other} both name {path}; give each its own file")
    return faults


def _open_run_device(args: argparse.Namespace, scene, faults: dict | None):
    """The run's device (several: a DeviceGroup of them, in order), each checked to drive its
    fingers of the scene. Each error names what is to blame: --device (a type or an argument
    such as a recording), --faults, or the scene's [device] table. The devices opened are
    closed again if a later one fails."""
    from softproxy.device_group import DeviceGroup
    from softproxy.scene import SceneError

    kinds = args.device or ["sim"] * len(scene.devices or [scene.device])
    tables = len(scene.devices or [scene.device])
    if len(kinds) != tables:
        said = "[[device]] tables" if tables > 1 else "device"
        raise SceneError(f"--device given {len(kinds)} time(s), but scene {scene.name!r} ({scene.path}) has {tables} "
                         f"{said}: give --device once per device, in the order of the scene's tables")
    devices = []
    try:
        for k, kind in enumerate(kinds):
            devices.append(_open_one_device(kind, k, len(kinds), scene, faults))
        return devices[0] if len(devices) == 1 else DeviceGroup(devices)
    except BaseException:
        for d in devices:
            d.close()
        raise


def _open_one_device(kind: str, index: int, count: int, scene, faults: dict | None):
    """Device `index` of the run (`_open_run_device`), checked to drive its fingers."""
    from softproxy.run import check_device_fingers, device_table, device_types, open_device
    from softproxy.scene import SceneError

    name, _, argument = kind.partition(":")
    if name not in device_types():
        raise SceneError(f"--device {kind}: no device type {name!r}; installed: {', '.join(device_types())}")
    table = device_table(scene, index)
    where = "[device]" if count == 1 else f"device[{index}]"
    configured = table.get("type")
    if not argument and configured not in (None, name):
        other = "" if name == "sim" else f", or give {name} its own argument (--device {name}:ARGUMENT)"
        which = "a" if count == 1 else f"device {index} as a"
        raise SceneError(f"--device {name}{' (the default)' if name == 'sim' else ''}: scene {scene.name!r} "
                         f"({scene.path}) configures {which} {configured!r} device: run it with --device "
                         f"{configured}{other}")
    try:
        # errors from the scene's [device] name the scene (device 0: the call of one device)
        device = open_device(kind, scene) if index == 0 else open_device(kind, scene, index=index)
    except (ValueError, RuntimeError) as exc:
        if argument:
            said = str(exc)  # a device's own message may already name the flag
            raise SceneError(said if said.startswith(f"--device {kind}") else f"--device {kind}: {said}") from None
        raise
    if faults:
        # the scene's own [device] opened above; the faults merged in can only fail on
        # themselves, so the second opening's errors name the flag
        device.close()
        more = {"index": index} if index else {}
        device = open_device(kind, scene, {**table, "faults": faults}, source="--faults", **more)
    label = f"{scene.path}: {where}" if name == "sim" and not argument else f"--device {kind}"
    try:
        check_device_fingers(scene, device, label, index)
    except SceneError:
        device.close()
        raise
    return device


def _print_fingertip_sensors(f: dict) -> None:
    """One line per fingertip sensor channel a finger ran (softproxy.fingertip_sensors)."""
    t = f.get("tactile")
    if t is not None:
        c = t["last_pressure_centre_m"]
        where = f"centre ({c[0] * 1e3:+.2f}, {c[1] * 1e3:+.2f}) mm" if c else "no contact"
        print(f"  {f['name']} tactile: {t['frames']} frames at {t['rate_hz']:g} Hz ({t['contact_frames']} in contact), "
              f"last total force {t['last_total_force_N']:.3f} N, {where}; errors {t['errors']}")
    s = f.get("sensing")
    if s is not None:
        e = s["error"]
        errs = (f"location error max {e['location_max_m'] * 1e3:.4f} mm, RMS {e['location_rms_m'] * 1e3:.4f} mm; "
                f"normal force error max {e['normal_force_max_N']:.4f} N" if s["sensed"] else "nothing sensed")
        print(f"  {f['name']} sensing ({s['noise']} noise): {s['sensed']} contacts sensed at {s['rate_hz']:g} Hz, "
              f"{s['refused']} refused; {errs}; errors {s['errors']}")


def _print_stiffness_notes(scene, device, allow_stiffer: bool) -> None:
    """One line on stderr per finger stiffer than its device renders stably (`softproxy.stiffness_cap`);
    SceneError when a cap cannot be met."""
    from softproxy.device_group import DeviceGroup
    from softproxy.scene import SceneError
    from softproxy.stiffness_cap import cap_fingers

    members = device.devices if isinstance(device, DeviceGroup) else [device]
    try:
        notes = cap_fingers(scene.fingers, members, allow_stiffer)[1]
    except ValueError as exc:
        raise SceneError(f"{scene.path}: {exc}") from None
    for note in notes:
        print(f"softproxy run: note: {note}", file=sys.stderr)


def cmd_run(args: argparse.Namespace) -> int:
    """Run a scene on a device and print the result; a window shows it unless --headless.

    The window is its own process reading shared memory (softproxy.viewer): the run is paced
    in real time while it is open, and no frame of drawing ever delays a tick. --snapshot and
    --video render offscreen (EGL) after the run, from state copied during it.
    """
    from softproxy.run import replay_notes, run_scene
    from softproxy.scene import SceneError, load_scene

    try:
        faults = _check_run_flags(args)
    except ValueError as exc:
        print(f"softproxy run: {exc}", file=sys.stderr)
        return 2
    window = not args.headless
    if window:
        from softproxy.viewer.launch import display_problem

        problem = display_problem()
        if problem:
            print(f"softproxy run: cannot open the viewer window: {problem}.\n"
                  f"  Run it without a window: softproxy run {args.scene} --headless "
                  f"(add --snapshot FILE.png for a picture of the end of the run)", file=sys.stderr)
            return 3
    views = None
    try:
        scene = load_scene(args.scene)
        scene.load_model()  # the MJCF's own mistakes (RK4, an SDF geom, a missing body) before a device opens
        if window or args.snapshot or args.video:
            from softproxy.viewer.attach import RunViews, parse_size

            views = RunViews(scene, window=window, snapshot=args.snapshot, video=args.video,
                             size=parse_size(args.size), duration_s=args.duration)
        device = _open_run_device(args, scene, faults)
    except (SceneError, ValueError, RuntimeError) as exc:
        if views is not None:
            views.close()
        print(f"softproxy run: {exc}", file=sys.stderr)
        return 2
    for note in replay_notes(scene, device, args.rate or scene.rate_hz):
        print(f"softproxy run: note: {note}", file=sys.stderr)
    realtime = args.realtime or window  # a window shows the run as it happens
    if views is not None and window and not args.realtime:
        views.note = "softproxy run: the viewer window is open; the run is paced in real time"
    duration = args.duration if args.duration is not None else scene.duration_s
    bar = _run_progress(duration, realtime)
    on_tick = views.on_tick if views else None
    if bar is not None:
        on_tick = bar.chain(on_tick)
    try:
        try:
            _print_stiffness_notes(scene, device, args.allow_stiffer)  # before the run; the run caps them too
            result = run_scene(scene, device, duration_s=args.duration, rate_hz=args.rate,
                               finger_model=args.finger_model, realtime=realtime, record=args.record,
                               on_built=views.on_built if views else None, on_tick=on_tick,
                               every=1 if views is not None and views.video is not None else 10,  # video frames on time
                               priority=args.rt_priority, passivity=not args.no_passivity,
                               allow_stiffer=args.allow_stiffer, physics_rate_hz=args.physics_rate)
        finally:
            device.close()
            if bar is not None:
                bar.close()
        if views is not None:
            try:
                views.save()
            except (OSError, ValueError) as exc:  # a disk that filled up during the run, say
                print(f"softproxy run: writing {args.snapshot or args.video} failed after the run: "
                      f"{' '.join(str(getattr(exc, 'strerror', None) or exc).split())}", file=sys.stderr)
                return 1
        if args.json:
            print(json.dumps(result, indent=2))
        else:
            two = (f", MuJoCo at {result['physics_rate_hz']:g} Hz" if result['physics_rate_hz'] != result['rate_hz']
                   else "")
            print(f"scene {result['scene']}: {result['ticks']} ticks at {result['rate_hz']:g} Hz{two} "
                  f"({'real time' if result['realtime'] else 'lockstep'})")
            if "object_rotation_deg" in result:
                print(f"  {result['object']} turned {result['object_rotation_deg']:+.3f} deg about the measured "
                      f"axis since start_s (max {result['object_rotation_max_deg']:.3f} deg), "
                      f"height {result['object_height_m'] * 1000:.1f} mm")
            _print_table(result["fingers"], [
                ("name", "finger", "s"), ("model", "model", "s"), ("max_force_N", "max F (N)", ".3f"),
                ("proxy_penetration_max_m", "max penetration (m)", ".2e"), ("slip_events", "slips", "d"),
            ])
            for f in result["fingers"]:
                _print_fingertip_sensors(f)
            owed = max(f["energy_owed_max_J"] for f in result["fingers"]) if result["fingers"] else 0.0
            acted = sum(f["passivity_ticks"] for f in result["fingers"])
            print(f"  passivity: controller {'on' if result['passivity_controller'] else 'OFF'}, acted on {acted} "
                  f"finger-ticks; the most any coupling owed {owed:.3g} J")
            t = result["tick_us"]
            print(f"  tick p50 {t['p50']} us, p99 {t['p99']} us, max {t['max']} us; faults {result['faults']}")
            for line in result["warnings"]:
                print(f"  warning: {line}")
            for k, d in enumerate(result.get("devices", [])):
                if d["read_failures"]:
                    print(f"  device {k} ({d['device']}) failed {d['read_failures']} reads (its fingers rendered "
                          f"zero force then): {d['last_error']}")
            if result.get("device_error"):
                print(f"  the device failed ({result['faults']['device_error']} ticks, zero force each): "
                      f"{result['device_error']}")
            if result.get("deadline_misses") is not None:
                print(f"  deadline misses {result['deadline_misses']} ({result['scheduling']})")
            if result.get("physics_thread"):
                p = result["physics_thread"]
                print(f"  MuJoCo's thread: {p['steps']} steps, {p['late_steps']} fell behind real time, "
                      f"the costliest {p['max_step_ms']:.2f} ms")
            if "device" in result:
                d = result["device"]
                print(f"  device: injected {d['faults_injected']}; largest force sent {d['max_force_sent_N']} N "
                      f"(clamp {d['force_clamp_N']} N), NaN sends {d['nan_sends']}")
        sys.stdout.flush()
        if views is not None:
            views.wait_window()
    except SceneError as exc:  # found while building the loop
        print(f"softproxy run: {exc}", file=sys.stderr)
        return 2
    except Exception as exc:
        from softproxy.viewer.launch import ViewerUnavailable

        if not isinstance(exc, ViewerUnavailable):
            raise
        print(f"softproxy run: {exc}.\n  Run it without a window: softproxy run {args.scene} --headless "
              f"(add --snapshot FILE.png for a picture of the end of the run)", file=sys.stderr)
        return 3
    finally:
        if views is not None:
            views.close()
    return 0


def cmd_sense(args: argparse.Namespace) -> int:
    """Contact sensing (Liu et al., Finger contact sensing): where and how a wrench on the fingertip was applied."""
    from softproxy.sensing import sense_main

    try:
        result = sense_main(args.wrench, args.sensor_frame)
    except ValueError as exc:
        print(f"softproxy sense: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        for key, value in result.items():
            print(f"  {key:18s} {value}")
    return 0 if result.get("explained", True) else 1


def cmd_tactile(args: argparse.Namespace) -> int:
    """The Inoue-Hirai tactile simulation (seeds 000/001)."""
    from softproxy.tactile import tactile_main

    if not _check_out_folder("tactile", args.out):
        return 2
    return tactile_main(args.json, args.out)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit the fingertip laws to the measured fingertip's force and contact area, or to a table of your own."""
    from softproxy.calibration import calibrate_main

    if not _check_out_folder("calibrate", args.out):
        return 2
    return calibrate_main(args.data, args.json, args.out)


def cmd_devices(args: argparse.Namespace) -> int:
    """Connected HID devices and the profile that matches each, and whether each vendor-SDK
    backend (a device plugin whose module has `availability()`) can run here (adapters are plugins)."""
    import importlib
    from importlib.metadata import entry_points

    backends, hid = [], None
    for ep in sorted(entry_points(group="softproxy.devices"), key=lambda e: e.name):
        if ep.name == "hid":
            hid = ep
            continue
        if ep.name in ("sim", "replay"):  # built in, no SDK to look for (and no numba import for a listing)
            continue
        try:
            availability = getattr(importlib.import_module(ep.module), "availability", None)
            if availability is not None:
                backends.append(availability())
        except Exception as exc:  # a broken plugin is reported, not fatal to the listing
            backends.append({"backend": ep.name, "binding": False, "sdk": False, "devices": None,
                             "message": f"cannot load {ep.module}: {type(exc).__name__}: {exc}"})
    if hid is not None:
        module = __import__(hid.module, fromlist=["devices_main"])
        return module.devices_main(args.json, backends=backends)
    print("softproxy devices: no HID device support installed", file=sys.stderr)
    if args.json:
        print(json.dumps({"backends": backends}, indent=2))
    else:
        for b in backends:
            print(f"{b['backend']}: {b['message']}")
    return 1


def _benchmarks() -> dict:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group="softproxy.benchmarks")}


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark (or all of them) by name."""
    for flag, value in (("--duration", args.duration), ("--paced", args.paced)):
        if value is not None and not (math.isfinite(value) and 0.0 < value <= MAX_BENCH_S):
            print(f"softproxy bench: {flag} must be a number of seconds > 0 and at most {MAX_BENCH_S:g}, got {value!r}",
                  file=sys.stderr)
            return 2
    benches = _benchmarks()
    names = sorted(benches) if args.name == "all" else [args.name]
    for name in names:
        if name not in benches:
            print(f"softproxy bench: no benchmark {name!r}; have: {', '.join(sorted(benches))}, all", file=sys.stderr)
            return 2
    from softproxy.cells import Backend, BackendError, SweepStopped

    try:  # the grids of stability and tradeoff run their cells on this (softproxy.cells)
        args.backend = Backend.from_flags(args.workers, args.ray, "softproxy bench", args.oversubscribe)
    except BackendError as exc:
        print(exc, file=sys.stderr)
        return 2
    if args.backend.note:
        print(f"softproxy bench: note: {args.backend.note}", file=sys.stderr)
    if not _check_out_folder("bench", args.out):
        return 2
    for name in names:
        try:
            code = benches[name].load()(args)
        except BackendError as exc:  # Ray that cannot start or be reached
            print(f"softproxy bench: {exc}", file=sys.stderr)
            return 2
        except SweepStopped as exc:
            print(f"softproxy bench: {name}: {exc}", file=sys.stderr)
            return exc.status
        if code:
            return code
    return 0


def cmd_replay_batch(args: argparse.Namespace) -> int:
    """Replay recordings under variations of the engine; one table, a summary and a chart."""
    from softproxy.cells import Backend, BackendError, SweepStopped
    from softproxy.replay_batch import BatchError, report, run_batch, write

    try:
        backend = Backend.from_flags(args.workers, args.ray, "softproxy replay-batch", args.oversubscribe)
    except BackendError as exc:
        print(exc, file=sys.stderr)
        return 2
    if backend.note:
        print(f"softproxy replay-batch: note: {backend.note}", file=sys.stderr)
    if not _check_out_folder("replay-batch", args.out):
        return 2
    try:
        result = run_batch(args.recordings, args.vary, args.scene, backend, _progress_bar("replay-batch"))
    except (BatchError, BackendError) as exc:
        print(f"softproxy replay-batch: {exc}", file=sys.stderr)
        return 2
    except SweepStopped as exc:  # a signal: the batch stops as a whole, nothing written
        print(f"softproxy replay-batch: {exc}", file=sys.stderr)
        return exc.status
    paths = write(result, args.out)
    if args.json:
        print(json.dumps(result["summary"], indent=2))
    else:
        report(result, paths)
    return 1 if result["summary"]["failed"] else 0


class _RunProgress:
    """A tqdm bar of servo seconds on stderr for a run that takes a while (on_tick feeds it)."""

    def __init__(self, duration_s: float) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(duration_s, 3), desc="  run", unit="s", file=sys.stderr, leave=False,
                        bar_format="{desc} {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s servo time [{elapsed}<{remaining}]")

    def chain(self, on_tick):
        """on_tick(loop) that moves the bar to the loop's time, then calls `on_tick` if given."""
        def tick(loop) -> None:
            self.bar.update(round(loop.t - self.bar.n, 3))  # tqdm redraws at most 10 times a second
            if on_tick is not None:
                on_tick(loop)
        return tick

    def close(self) -> None:
        self.bar.close()


def _run_progress(duration_s: float, realtime: bool) -> _RunProgress | None:
    """A progress bar for a real-time run longer than 2 s on a terminal (a lockstep run of a
    day's servo time takes minutes, so it gets one past a minute of servo time); else None."""
    if not sys.stderr.isatty() or duration_s <= (2.0 if realtime else 60.0):
        return None
    return _RunProgress(duration_s)


def _progress_bar(command: str):
    """progress(done, total, outcome) for softproxy.cells: a tqdm bar on stderr, silent when
    stderr is not a terminal, gone when the last cell is in."""
    from tqdm import tqdm

    bar = tqdm(desc=f"  {command}", unit="cell", file=sys.stderr, leave=False, disable=not sys.stderr.isatty())

    def progress(done: int, total: int, outcome) -> None:
        bar.total = total
        bar.update(1)
        if done == total:
            bar.close()

    return progress


def _scenes_epilog() -> str:
    """The shipped and registered scenes, one line each with its description, for `run --help`."""
    import tomllib

    from softproxy.scene import list_scenes

    lines = ["scenes:"]
    for path in list_scenes():
        try:
            description = tomllib.loads(path.read_text()).get("scene", {}).get("description", "")
        except (OSError, tomllib.TOMLDecodeError):
            description = "(cannot be read)"
        lines.append(f"  {path.stem:<18} {description}")
    return "\n".join(lines)


def _device_types() -> list[str]:
    from softproxy.run import device_types

    return device_types()


def cmd_compile(args: argparse.Namespace) -> int:
    """Build each scene's servo loop once, so that its kernels are compiled now and a first
    run loads them from numba's cache. Each scene is driven by a still simulated device of as
    many fingers as it needs, whatever device it names (the tick's kernels are the same)."""
    import time

    from softproxy.run import build, open_device
    from softproxy.scene import SceneError, list_scenes, load_scene

    names = args.scenes or [str(p) for p in list_scenes()]
    try:
        scenes = [load_scene(name) for name in names]  # every name checked before any compiles
    except SceneError as exc:
        print(f"softproxy compile: {exc}", file=sys.stderr)
        return 2
    for scene in scenes:
        wall, cpu = time.monotonic(), time.process_time()
        devices = [open_device("sim", scene, {"type": "sim", "finger": [{"keyframes": [[0.0, 0.0, 0.0, 0.0, 0.0]]}]
                                              * max(1, scene.fingers_of(k))}, source="softproxy compile")
                   for k in range(len(scene.devices or [scene.device]))]
        loop = build(scene, devices, realtime=False)
        loop.close()
        print(f"{scene.name}: ready in {time.monotonic() - wall:.1f} s ({time.process_time() - cpu:.1f} s of CPU)",
              flush=True)
    return 0


def cmd_schema(args: argparse.Namespace) -> int:
    """Write the JSON Schema of a scene TOML, a HID profile and a [device] table for editors."""
    from softproxy.schema import write_json_schemas

    if not _check_out_folder("schema", args.out):
        return 2
    for path in write_json_schemas(args.out):
        print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="softproxy", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("models", help="list the fingertip models and their constants")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_models)

    p = sub.add_parser("run", help="run a scene (e.g. two_finger_grasp) on a device",
                       epilog=_scenes_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene name (listed below) or path to its .toml")
    p.add_argument("--device", action="append", default=None,
                   help="device: sim (the scene's scripted device, default), replay:FILE (a recording), "
                        "hid or hid:PROFILE (a HID device; `softproxy devices` lists them and the profiles), "
                        "or another installed type (installed: " + ", ".join(_device_types()) + "); once per "
                        "device, in the order of a scene's [[device]] tables (two hands: give it twice)")
    p.add_argument("--allow-stiffer", action="store_true",
                   help="keep a finger's stiffness and damping above what its device renders stably (research; "
                        "by default they are capped to the device's figures, one line saying so)")
    p.add_argument("--record", metavar="FILE", default=None, help="stream every device sample to FILE as the run goes (replay it with --device replay:FILE)")
    p.add_argument("--faults", metavar="SPEC", default=None,
                   help="inject device faults (sim): e.g. nan=0.01,drop=0.001,spike=0.001,stall=0.0005 (per read)")
    p.add_argument("--headless", action="store_true",
                   help="no window (without it a window shows the run, paced in real time)")
    p.add_argument("--snapshot", metavar="FILE.png", default=None,
                   help="write a picture of the last tick (offscreen, EGL) to FILE.png")
    p.add_argument("--video", metavar="FILE.mp4", default=None,
                   help="write an MP4 of the run at 30 fps (offscreen; needs the imageio-ffmpeg wheel)")
    p.add_argument("--size", metavar="WxH", default="1024x768",
                   help="window, snapshot and video size in pixels (default 1024x768, at least 640x480)")
    p.add_argument("--duration", type=float, default=None, help="seconds to run (default: the scene's)")
    p.add_argument("--rate", type=float, default=None, help="servo rate in Hz (default: the scene's)")
    p.add_argument("--physics-rate", type=_physics_rate, default=None, metavar="HZ",
                   help="two rates: MuJoCo steps at HZ, a whole fraction of the servo rate, and the ticks between "
                        "render against the shapes carried forward; 'auto': as fast as the world's step cost lets "
                        "it (default: the scene's; else a step every tick)")
    p.add_argument("--finger-model", choices=list(MODELS), default=None, help="override every finger's model")
    p.add_argument("--realtime", action="store_true", help="pace ticks in real time (default: lockstep)")
    p.add_argument("--rt-priority", type=int, default=None, metavar="N",
                   help="run a real-time run's servo thread under SCHED_FIFO at priority N (1-99; needs root, "
                        "CAP_SYS_NICE or an rtprio limit; the result says what was granted)")
    p.add_argument("--no-passivity", action="store_true",
                   help="switch the passivity controller off (for experiments: the coupling may then give the "
                        "hand energy it never put in)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("sense", help="contact sensing: recover the contact from a fingertip wrench (Liu et al.)")
    p.add_argument("--wrench", nargs=6, type=float, required=True, metavar=("FX", "FY", "FZ", "MX", "MY", "MZ"),
                   help="wrench the contact exerts on the fingertip, N and N·m, ellipsoid frame")
    p.add_argument("--sensor-frame", action="store_true", help="the wrench (and the answer) in the paper's sensor frame")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_sense)

    p = sub.add_parser("tactile", help="tactile pressure image simulations")
    p.add_argument("simulation", choices=["inoue-hirai"], help="inoue-hirai: seeds 000/001's rotating finger")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--out", default="bench-out", help="folder for the PNG (default bench-out)")
    p.set_defaults(func=cmd_tactile)

    p = sub.add_parser("calibrate", help="fit the fingertip laws to measured force and contact area")
    p.add_argument("--data", default=None, help="CSV with depth_mm, force_N, contact_area_mm2 (default: the measured fingertip's)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--out", default="bench-out", help="folder for the PNG (default bench-out)")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("schema", help="write the JSON Schema of scene files, HID profiles and [device] tables "
                                      "(for editors) into a folder")
    p.add_argument("--out", default="schema", help="folder for the .schema.json files (default schema)")
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser("compile", help="compile the servo tick of every shipped scene (or those named) now, so "
                                       "their first runs load it from the cache")
    p.add_argument("scenes", nargs="*", help="scene names or TOML paths (default: every shipped scene)")
    p.set_defaults(func=cmd_compile)

    p = sub.add_parser("devices", help="list connected HID devices and their profiles, and the vendor SDK backends")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_devices)

    names = ", ".join(sorted(_benchmarks()))
    p = sub.add_parser("bench", help=f"run a benchmark: {names}, or all")
    p.add_argument("name", help=f"benchmark name ({names}), or all")
    p.add_argument("--duration", type=float, default=5.0, help="seconds of servo time to time (default 5)")
    p.add_argument("--paced", type=float, default=None, help="seconds of the paced (real-time) run (default: --duration)")
    p.add_argument("--out", default="bench-out", help="folder for JSON and charts (default bench-out)")
    p.add_argument("--full", action="store_true", help="the long versions (e.g. a 20 s grasp hold)")
    p.add_argument("--quick", action="store_true", help="multirate: 1 s runs instead of --duration's")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.add_argument("--realtime", action="store_true",
                   help="latency: also pace under SCHED_FIFO (priority 80) on a CPU of its own, where the OS "
                        "grants it: a busy loop that can starve the machine's other work while it runs")
    _add_backend_flags(p, "the grids of stability and tradeoff")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("replay-batch", help="replay recordings under variations (model, rate, stiffness, friction): "
                                            "one table, summary and chart")
    p.add_argument("recordings", nargs="+", metavar="RECORDING", help="recording files, or folders of them (*.rec)")
    p.add_argument("--vary", action="append", default=[], metavar="KEY=VALUE[,KEY=VALUE]",
                   help="one variation per flag, e.g. model=point, rate=500, stiffness=4000,damping=2, "
                        "mu_s=0.5,mu_d=0.4 (each recording is also replayed unvaried, the reference)")
    p.add_argument("--scene", default=None, help="the scene to replay on (default: the one each recording names)")
    p.add_argument("--out", default="batch-out", help="folder for the CSV table, JSON summary and chart "
                                                      "(default batch-out)")
    p.add_argument("--json", action="store_true", help="print the JSON summary")
    _add_backend_flags(p, "the replays")
    p.set_defaults(func=cmd_replay_batch)
    return parser


def _add_backend_flags(p: argparse.ArgumentParser, what: str) -> None:
    """--workers N and --ray [ADDRESS]: where `what` run (softproxy.cells; serial without either)."""
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"run {what} in N worker processes (default: serially, in this process); at most "
                        f"one per CPU unless --oversubscribe")
    p.add_argument("--oversubscribe", action="store_true",
                   help="let --workers N start more worker processes than there are CPUs")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help=f"run {what} as Ray tasks: on a Ray started here, or on the cluster at ADDRESS "
                        f"(auto, HOST:6379, ray://HOST:10001); needs pip install 'softproxy[cluster]'")


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("softproxy")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "(not installed)"


def _standard_streams_open() -> None:
    """Put /dev/null where stdin, stdout or stderr is closed (`softproxy run ... >&-`): no file
    opened later (a recording, a device) can take their numbers, and Python has a stream to
    write to; what would have been printed there goes nowhere, and the command runs as asked."""
    for fd, mode in ((0, os.O_RDONLY), (1, os.O_WRONLY), (2, os.O_WRONLY)):
        try:
            os.fstat(fd)
        except OSError:
            try:
                devnull = os.open(os.devnull, mode)
            except OSError:
                continue
            if devnull != fd:
                os.dup2(devnull, fd)
                os.close(devnull)
    for name, fd, mode in (("stdout", 1, "w"), ("stderr", 2, "w")):
        if getattr(sys, name) is None:
            try:
                setattr(sys, name, open(fd, mode, closefd=False))
            except OSError:
                pass


def main(argv: list[str] | None = None) -> int:
    """The command line; its status. Every Python it starts (the viewer, a pool's or Ray's
    workers, and what those start) runs with PYTHONSAFEPATH=1: nothing from the working folder
    (softproxy.working_folder)."""
    from softproxy.working_folder import safe_path_for_children

    with safe_path_for_children():
        return _main(argv)


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    """How the command line shows a warning: `softproxy: warning: MESSAGE` (the message names
    the file and field; where in softproxy it was raised is no help to a user)."""
    return f"softproxy: warning: {message}\n"


def _main(argv: list[str] | None) -> int:
    shown = warnings.formatwarning
    warnings.formatwarning = _one_line_warning
    try:
        return _command(argv)
    finally:
        warnings.formatwarning = shown  # (a caller of main() in the same process keeps its own)


def _command(argv: list[str] | None) -> int:
    _standard_streams_open()
    args = build_parser().parse_args(argv)
    try:
        code = args.func(args)
        sys.stdout.flush()  # a reader that went away shows here, not in the interpreter's last flush
        return code
    except BrokenPipeError:
        # whoever read our output went away (`softproxy calibrate | head`): stop quietly, as a
        # pipe's writer does, with 128 + SIGPIPE; the subcommand's own cleanup (a device's
        # zero force) has run on the way out. Later writes to stdout go nowhere, so the
        # interpreter's last flush cannot fail again.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):  # stdout is no file (captured, closed)
            pass
        return 128 + getattr(signal, "SIGPIPE", 13)
    except KeyboardInterrupt:
        print(f"softproxy {args.command}: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT


if __name__ == "__main__":
    sys.exit(main())
