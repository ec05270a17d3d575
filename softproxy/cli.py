"""The `softproxy` command line: one subcommand per job, each with a `--json` form."""

from __future__ import annotations

import argparse
import json
import sys

from softproxy.fingertip import MODELS


def _print_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> None:
    """Print `rows` as an aligned text table; `columns` are (key, header, format)."""
    cells = [[header for _, header, _ in columns]]
    for row in rows:
        cells.append(["-" if row.get(key) is None else format(row[key], fmt) for key, _, fmt in columns])
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns))]
    for i, r in enumerate(cells):
        print("  ".join(c.rjust(w) if i and j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))))


def cmd_models(args: argparse.Namespace) -> int:
    """List the fingertip models with their exponents and derived constants."""
    rows = [m.as_dict() for m in MODELS.values()]
    if args.json:
        print(json.dumps({"models": rows}, indent=2))
        return 0
    print("Fingertip models (seed 002, Table 1; torque limit M = mu' |P|^gamma)")
    _print_table(
        rows,
        [
            ("name", "model", "s"),
            ("gamma", "gamma", ".4f"),
            ("mu_prime_Nmm", "mu' (N·mm/N^g)", ".4f"),
            ("p_star_N", "P* (N)", ".4f"),
            ("torque_limit_at_1N_Nmm", "M@1N (N·mm)", ".3f"),
            ("torque_limit_at_3N_Nmm", "M@3N (N·mm)", ".3f"),
        ],
    )
    return 0


def _parse_faults(text: str) -> dict:
    """`nan=0.01,drop=0.001` -> {"nan": 0.01, "drop": 0.001}; ValueError naming the bad item."""
    faults = {}
    for item in text.split(","):
        name, sep, value = item.partition("=")
        try:
            faults[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--faults: {item!r} is not NAME=PROBABILITY") from None
        if not sep:
            raise ValueError(f"--faults: {item!r} is not NAME=PROBABILITY")
    return faults


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


def cmd_run(args: argparse.Namespace) -> int:
    """Run a scene on a device and print the result; a window shows it unless --headless.

    The window is its own process reading shared memory (softproxy.viewer): the run is paced
    in real time while it is open, and no frame of drawing ever delays a tick. --snapshot and
    --video render offscreen (EGL) after the run, from state copied during it.
    """
    from softproxy.run import open_device, run_scene
    from softproxy.scene import SceneError, load_scene

    window = not args.headless
    if window:
        from softproxy.viewer.launch import display_problem

        problem = display_problem()
        if problem:
            print(f"softproxy run: cannot open the viewer window: {problem}.\n"
                  f"  Run it without a window: softproxy run {args.scene} --headless "
                  f"(add --snapshot FILE.png for a picture of the end of the run)", file=sys.stderr)
            return 3
    try:
        scene = load_scene(args.scene)
        if args.faults:
            scene.device["faults"] = _parse_faults(args.faults)
        views = None
        if window or args.snapshot or args.video:
            from softproxy.viewer.attach import RunViews, parse_size

            views = RunViews(scene, window=window, snapshot=args.snapshot, video=args.video,
                             size=parse_size(args.size), duration_s=args.duration)
        device = open_device(args.device, scene)
    except (SceneError, ValueError, RuntimeError) as exc:
        print(f"softproxy run: {exc}", file=sys.stderr)
        return 2
    realtime = args.realtime or window  # a window shows the run as it happens
    if views is not None and window and not args.realtime:
        views.note = "softproxy run: the viewer window is open; the run is paced in real time"
    try:
        try:
            result = run_scene(scene, device, duration_s=args.duration, rate_hz=args.rate,
                               finger_model=args.finger_model, realtime=realtime, record=args.record,
                               compiled=args.compiled,
                               on_built=views.on_built if views else None, on_tick=views.on_tick if views else None)
        finally:
            device.close()
        if views is not None:
            views.save()
        if args.json:
            print(json.dumps(result, indent=2))
        else:
            print(f"scene {result['scene']}: {result['ticks']} ticks at {result['rate_hz']:g} Hz "
                  f"({'real time' if result['realtime'] else 'lockstep'}, {result['engine']} fingers)")
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
            t = result["tick_us"]
            print(f"  tick p50 {t['p50']} us, p99 {t['p99']} us, max {t['max']} us; faults {result['faults']}")
            if result.get("device_error"):
                print(f"  the device failed ({result['faults']['device_error']} ticks, zero force each): "
                      f"{result['device_error']}")
            if result.get("deadline_misses") is not None:
                print(f"  deadline misses {result['deadline_misses']}")
            if "device" in result:
                d = result["device"]
                print(f"  device: injected {d['faults_injected']}; largest force sent {d['max_force_sent_N']} N "
                      f"(clamp {d['force_clamp_N']} N), NaN sends {d['nan_sends']}")
        sys.stdout.flush()
        if views is not None:
            views.wait_window()
    except SceneError as exc:  # found while building the loop (e.g. --compiled on a mesh scene)
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
    """Contact sensing (seed 003): where and how a wrench on the fingertip was applied."""
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

    return tactile_main(args.json, args.out)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit the fingertip laws to seed 004's measurements or to a table of your own."""
    from softproxy.calibration import calibrate_main

    return calibrate_main(args.data, args.json, args.out)


def cmd_devices(args: argparse.Namespace) -> int:
    """Connected HID devices and the profile that matches each (the HID adapter is a plugin)."""
    from importlib.metadata import entry_points

    for ep in entry_points(group="softproxy.devices"):
        if ep.name == "hid":
            module = __import__(ep.module, fromlist=["devices_main"])
            return module.devices_main(args.json)
    print("softproxy devices: no HID device support installed", file=sys.stderr)
    return 1


def _benchmarks() -> dict:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group="softproxy.benchmarks")}


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark (or all of them) by name."""
    benches = _benchmarks()
    names = sorted(benches) if args.name == "all" else [args.name]
    for name in names:
        if name not in benches:
            print(f"softproxy bench: no benchmark {name!r}; have: {', '.join(sorted(benches))}, all", file=sys.stderr)
            return 2
    for name in names:
        code = benches[name].load()(args)
        if code:
            return code
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="softproxy", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("models", help="list the fingertip models and their constants")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_models)

    p = sub.add_parser("run", help="run a scene (e.g. two_finger_grasp) on a device")
    p.add_argument("scene", help="scene name or path to its .toml")
    p.add_argument("--device", default="sim",
                   help="device: sim (the scene's scripted device, default) or replay:FILE (a recording)")
    p.add_argument("--record", metavar="FILE", default=None, help="save every device sample to FILE")
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
    p.add_argument("--finger-model", choices=list(MODELS), default=None, help="override every finger's model")
    p.add_argument("--realtime", action="store_true", help="pace ticks in real time (default: lockstep)")
    p.add_argument("--compiled", action="store_true",
                   help="run the fingers as compiled code (numba; primitive shapes only; the same answers, "
                        "a tick ~2x faster; the first run compiles for ~30 s, later runs load the cache)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("sense", help="contact sensing: recover the contact from a fingertip wrench (seed 003)")
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
    p.add_argument("--data", default=None, help="CSV with depth_mm, force_N, contact_area_mm2 (default: seed 004's)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.add_argument("--out", default="bench-out", help="folder for the PNG (default bench-out)")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("devices", help="list connected HID devices and their matching profiles")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_devices)

    p = sub.add_parser("bench", help="run a benchmark: latency, godobject, peer, stability, tradeoff, sensing, or all")
    p.add_argument("name", help="benchmark name, or all")
    p.add_argument("--duration", type=float, default=5.0, help="seconds of servo time to time (default 5)")
    p.add_argument("--paced", type=float, default=None, help="seconds of the paced (real-time) run (default: --duration)")
    p.add_argument("--out", default="bench-out", help="folder for JSON and charts (default bench-out)")
    p.add_argument("--full", action="store_true", help="the long versions (e.g. a 20 s grasp hold)")
    p.add_argument("--json", action="store_true", help="print the JSON result")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
