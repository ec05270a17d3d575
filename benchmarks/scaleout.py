"""Scale-out figures (docs/scale-out.md): what `--workers 2` and `--ray` buy over serial.

    python -m softproxy.benchmarks.scaleout [--out DIR] [--recordings 50] [--seconds 5] [--rounds 3]

Measures, on this machine, each backend of `softproxy.cells` (serial, a pool of 2 workers,
Ray started here) on
- the full `bench stability` grid (its cells; the result must equal the serial one exactly);
- a batch replay of `--recordings` example recordings of `--seconds` s each, unvaried and under
  three variations (the table's outcome digest must equal the serial one);
- no-op cells, for the per-cell overhead (s per cell, in the steady state) and the start-up
  of each backend (a pool's workers, `ray.init()`).
Rounds are interleaved (serial, pool, Ray, serial, ...) so a slow spell of a shared machine
lands on every backend; the median and range of the rounds are reported. Ray is shut down
and started again each round, so "Ray" is timed cold (start-up apart) as a command run is.
Writes scaleout.json to --out. Not one of `softproxy bench`: it takes minutes and needs Ray.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

from . import stability
from softproxy.cells import Backend, run_cells, start_ray, stop_ray
from softproxy.example_recordings import generate
from softproxy.replay_batch import run_batch

VARY = ["model=point", "rate=500", "stiffness=4000"]
NOOP_CELLS = (4, 400)  # few and many no-op cells: the difference is the steady per-cell cost


def noop(i: int) -> int:
    """A cell that does nothing: what is left of its time is the backend's."""
    return i


def _backends() -> dict[str, Backend]:
    return {"serial": Backend(), "pool of 2": Backend(workers=2), "ray (local)": Backend(ray="")}


def _ray_start(backend: Backend) -> float:
    """Ray shut down and started again for this round (s it took); 0 for the other backends."""
    if backend.ray is None:
        return 0.0
    stop_ray()
    start = time.perf_counter()
    start_ray(backend.ray)
    # the first task also starts the workers: part of the start-up, not of any sweep
    run_cells(noop, [{"i": i} for i in range(2)], backend)
    return time.perf_counter() - start


def _timed(fn, *args, **kwargs):
    start = time.perf_counter()
    value = fn(*args, **kwargs)
    return time.perf_counter() - start, value


def _spread(values: list[float]) -> dict:
    return {"median": round(statistics.median(values), 3), "min": round(min(values), 3),
            "max": round(max(values), 3), "runs": [round(v, 3) for v in values]}


def measure(folder: Path, recordings: int, seconds: float, rounds: int, log=print) -> dict:
    t, _ = _timed(generate, folder, recordings, seconds, 0)
    log(f"generated {recordings} recordings of {seconds:g} s in {t:.1f} s")
    grid = stability.grid(full=True)
    walls: dict = {name: {"start_s": [], "stability_s": [], "batch_s": [], "noop_few_s": [], "noop_many_s": []}
                   for name in _backends()}
    reference: dict = {}
    equal = {name: {"stability": True, "batch": True} for name in _backends()}
    cell_s = {}
    for r in range(rounds):
        for name, backend in _backends().items():
            w = walls[name]
            w["start_s"].append(_ray_start(backend))
            t, outcomes = _timed(run_cells, stability.cell, grid, backend)
            w["stability_s"].append(t)
            values = [o.value if o.ok else o.error for o in outcomes]
            cell_s.setdefault("stability", sum(o.seconds for o in outcomes))
            if name == "serial" and "stability" not in reference:
                reference["stability"] = values
            equal[name]["stability"] &= values == reference["stability"]
            t, result = _timed(run_batch, [str(folder)], VARY, None, backend)
            w["batch_s"].append(t)
            digest = result["summary"]["outcomes_sha256"]
            cell_s.setdefault("batch", result["summary"]["timing"]["cells_s"])
            reference.setdefault("batch", digest)
            equal[name]["batch"] &= digest == reference["batch"] and not result["summary"]["failed"]
            for key, n in zip(("noop_few_s", "noop_many_s"), NOOP_CELLS):
                t, _ = _timed(run_cells, noop, [{"i": i} for i in range(n)], backend)
                w[key].append(t)
            log(f"round {r + 1}/{rounds} {name:12s} start {w['start_s'][-1]:6.2f} s  stability "
                f"{w['stability_s'][-1]:6.2f} s  batch {w['batch_s'][-1]:6.2f} s  no-op x{NOOP_CELLS[1]} "
                f"{w['noop_many_s'][-1]:6.2f} s  equal {equal[name]}")
    out = {"machine_cpus": _cpus(), "recordings": recordings, "recording_s": seconds, "variations": VARY,
           "stability_cells": len(grid), "batch_cells": recordings * (len(VARY) + 1), "rounds": rounds,
           "serial_cell_s_sum": {k: round(v, 3) for k, v in cell_s.items()}, "backends": {}}
    serial = {k: statistics.median(v) for k, v in walls["serial"].items()}
    for name, w in walls.items():
        med = {k: statistics.median(v) for k, v in w.items()}
        few, many = NOOP_CELLS
        out["backends"][name] = {
            **{k: _spread(v) for k, v in w.items()},
            "speedup_stability": round(serial["stability_s"] / med["stability_s"], 2),
            "speedup_batch": round(serial["batch_s"] / med["batch_s"], 2),
            "speedup_stability_with_start": round(serial["stability_s"] / (med["stability_s"] + med["start_s"]), 2),
            "speedup_batch_with_start": round(serial["batch_s"] / (med["batch_s"] + med["start_s"]), 2),
            "per_cell_overhead_ms": round((med["noop_many_s"] - med["noop_few_s"]) / (many - few) * 1e3, 3),
            "equal_to_serial": equal[name],
        }
    return out


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m softproxy.benchmarks.scaleout", description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="bench-out")
    parser.add_argument("--recordings", type=int, default=50)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="softproxy-scaleout-") as folder:
        result = measure(Path(folder), args.recordings, args.seconds, args.rounds,
                         log=lambda m: print(m, file=sys.stderr, flush=True))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "scaleout.json").write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result, indent=1))
    return 0 if all(all(b["equal_to_serial"].values()) for b in result["backends"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
