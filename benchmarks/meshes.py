"""`softproxy bench meshes`: loading meshes at CAD scale, and a tick's cost on them.

Three kinds of mesh, each at about 10k, 100k and 1M triangles, all about 10 cm across and
generated here (numpy): CAD-like parts of long slivers (cylinders tessellated as a CAD export
does: one sliver per section down the side, a fan on each cap, tilted), a near-flat gently
curved open grid, and a scanned-like sphere with radial noise. Then three shapes at one size
each whose load once grew with a vertex's valence or a triangle's length (`HUBS`): a
cylinder whose caps are fans of 25,000 slivers about one vertex, a UV sphere whose poles
hold 50,000 of its 100,000 triangles, a 256 × 256 height field (as MuJoCo collides with it,
`softproxy.geometry.hfield_triangles`: its walls and bottom fan are slivers metres long).
Per mesh: the time and the peak memory to load it (`MeshShape` on explicit triangles, then
the engine's tables; tracemalloc's peak, and the process's resident set's peak over what it
was before), and the god-object update's cost per finger (p50 / p99, µs) with a 5 mm proxy
pressed into it and sliding on it; on the 100k meshes with 1, 2 and 5 fingers on the one
mesh.
"""

from __future__ import annotations

import gc
import math
import sys
import time
import tracemalloc
import warnings

import mujoco
import numpy as np
import trimesh

from .report import Progress, figure, publish

RADIUS = 0.005
"""Proxy radius (m)."""
DEPTH = 0.002
"""How far the device is held under the surface (m)."""
SIZES = (10_000, 100_000, 1_000_000)
"""Triangles per mesh (about)."""
FINGERS = (1, 2, 5)
"""Fingers on one mesh, on the 100k-triangle meshes."""
_GEOM = '<mujoco><worldbody><body name="b"><geom name="g" type="box" size=".01 .01 .01"/></body></worldbody></mujoco>'


# ---------------------------------------------------------------------------------------
# Meshes (geom frame, m)
# ---------------------------------------------------------------------------------------

def cylinder(sections: int, r: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed cylinder (radius r, height h, m; axis z, base at z = 0) as a CAD export
    tessellates it: two slivers per section down the side, each cap a fan of slivers about
    its centre."""
    a = np.linspace(0.0, 2.0 * math.pi, sections, endpoint=False)
    ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
    v = np.vstack([np.column_stack([ring, np.zeros(sections)]), np.column_stack([ring, np.full(sections, h)]),
                   [[0.0, 0.0, 0.0], [0.0, 0.0, h]]])
    j = np.arange(sections)
    k = (j + 1) % sections
    lo, hi, c0, c1 = j, j + sections, 2 * sections, 2 * sections + 1
    f = np.vstack([np.column_stack([lo, k, hi]), np.column_stack([k, k + sections, hi]),
                   np.column_stack([np.full(sections, c0), k, lo]),
                   np.column_stack([np.full(sections, c1), hi, k + sections])])
    return v, f


def slivers(triangles: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """25 closed cylinders (radius 6-8 mm, height 1-3 cm, tilted up to 15°) on a 2.5 cm grid,
    each of `sections` sides as a CAD export tessellates it: two slivers per section running
    the cylinder's height (aspect up to ~10⁴ at 1M), a fan of slivers on each cap."""
    rng = np.random.default_rng(seed)
    sections = max(8, triangles // (4 * 25))
    verts, faces = [], []
    base = 0
    for i in range(25):
        v, f = cylinder(sections, rng.uniform(0.006, 0.008), rng.uniform(0.01, 0.03))
        tilt = rng.uniform(-0.26, 0.26, 2)
        cx, sx, cy, sy = math.cos(tilt[0]), math.sin(tilt[0]), math.cos(tilt[1]), math.sin(tilt[1])
        turn = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]) @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        v = v @ turn.T + [0.025 * (i % 5) - 0.05, 0.025 * (i // 5) - 0.05, rng.uniform(-0.005, 0.005)]
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    return np.vstack(verts), np.vstack(faces)


def grid(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """An open sheet 10 cm square, gently curved (3 mm waves 8-10 cm long), of n × n vertices."""
    n = max(3, int(math.sqrt(triangles / 2.0)) + 1)
    x, y = np.meshgrid(np.linspace(-0.05, 0.05, n), np.linspace(-0.05, 0.05, n), indexing="ij")
    z = 0.003 * np.sin(2.0 * math.pi * x / 0.08) * np.cos(2.0 * math.pi * y / 0.1)
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    f = np.vstack([np.column_stack([a, a + n, a + 1]), np.column_stack([a + 1, a + n, a + n + 1])])
    return v, f


def noisy_sphere(triangles: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A geodesic sphere (radius 5 cm, 20 k² triangles) with radial noise of a tenth of an edge,
    as a scan: isotropic triangles, locally dented everywhere."""
    k = max(1, int(round(math.sqrt(triangles / 20.0))))
    t = (1.0 + math.sqrt(5.0)) / 2.0
    ico = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                    [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    tri = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                    [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                    [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    # points of each face by integer barycentrics (i, j, k - i - j): a point on a shared edge is
    # the same sum of the same two terms from either face, so equal bit for bit and welded
    ii, jj = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    keep = ii + jj <= k
    ii, jj = ii[keep], jj[keep]
    index = -np.ones((k + 1, k + 1), dtype=np.int64)
    index[ii, jj] = np.arange(len(ii))
    a, b = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    up = (a + b < k).ravel()
    down = (a + b < k - 1).ravel()
    a, b = a.ravel(), b.ravel()
    local = np.vstack([np.column_stack([index[a, b], index[a + 1, b], index[a, b + 1]])[up],
                       np.column_stack([index[a + 1, b], index[a + 1, b + 1], index[a, b + 1]])[down]])
    points = (ii[None, :, None] * ico[tri[:, 0]][:, None, :] + jj[None, :, None] * ico[tri[:, 1]][:, None, :]
              + (k - ii - jj)[None, :, None] * ico[tri[:, 2]][:, None, :]) / k
    v, inverse = np.unique(points.reshape(-1, 3), axis=0, return_inverse=True)
    f = inverse.reshape(-1)[(local[None, :, :] + len(ii) * np.arange(20)[:, None, None]).reshape(-1, 3)]
    v /= np.linalg.norm(v, axis=1)[:, None]
    edge = 1.1 / k  # about, on the unit sphere
    v *= 0.05 * (1.0 + 0.1 * edge * np.random.default_rng(seed).standard_normal(len(v)))[:, None]
    return v, f


KINDS = {"slivers (CAD-like)": slivers, "near-flat grid": grid, "noisy sphere": noisy_sphere}


def fan_cylinder(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder (radius 1 cm, 3 cm tall, axis z, base at z = 0) as a CAD export tessellates
    it: triangles / 4 sections, two slivers per section down the side, each cap a fan of
    slivers about its centre (a vertex of triangles / 4 triangles)."""
    return cylinder(max(8, triangles // 4), 0.01, 0.03)


def uv_sphere(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A UV sphere (radius 5 cm, poles on z) of triangles / 4 segments and three rings: each
    pole a fan of triangles / 4 slivers about one vertex (half the triangles in the two),
    and one band of slivers between them."""
    segments = max(8, triangles // 4)
    r = 0.05
    theta = np.array([math.pi / 3.0, 2.0 * math.pi / 3.0])
    phi = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    v = np.column_stack([r * np.sin(t).ravel() * np.cos(p).ravel(), r * np.sin(t).ravel() * np.sin(p).ravel(),
                         r * np.cos(t).ravel()])
    v = np.vstack([v, [[0.0, 0.0, r], [0.0, 0.0, -r]]])
    north, south = len(v) - 2, len(v) - 1
    j = np.arange(segments)
    k = (j + 1) % segments
    f = np.vstack([np.column_stack([np.full(segments, north), j, k]),
                   np.column_stack([j, segments + j, k]), np.column_stack([k, segments + j, segments + k]),
                   np.column_stack([np.full(segments, south), segments + k, segments + j])])
    return v, f


def height_field(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """A rows × rows height field 20 m square (cells ~8 cm), rolling hills up to 5 cm over a
    10 cm base, as MuJoCo collides with it: `softproxy.geometry.hfield_triangles` of a model
    holding it (the surface, four walls of slivers 10-15 cm tall and 8 cm wide, and a bottom
    fan of slivers 10-14 m long about its centre)."""
    from softproxy.geometry import hfield_triangles

    x, y = np.meshgrid(np.linspace(0.0, 1.0, rows), np.linspace(0.0, 1.0, rows))
    z = 0.5 + 0.25 * np.sin(23.0 * x + 3.0 * np.cos(17.0 * y)) * np.cos(19.0 * y) + 0.1 * np.sin(61.0 * x * y)
    z = (z - z.min()) / (z.max() - z.min())
    model = mujoco.MjModel.from_xml_string(
        f'<mujoco><asset><hfield name="h" nrow="{rows}" ncol="{rows}" size="10 10 0.05 0.1"/></asset>'
        '<worldbody><geom type="hfield" hfield="h"/></worldbody></mujoco>')
    model.hfield_data[:] = z.ravel()
    return hfield_triangles(model, 0)


HUBS = {"fan-capped cylinder": (fan_cylinder, 100_000, (0.0, 0.0, 0.03)),
        "UV sphere, fan poles": (uv_sphere, 100_000, (0.0, 0.0, 0.05)),
        "height field": (height_field, 256, None)}
"""Shapes timed at one size (their generator, its argument, where the finger is held: the hub
of the top cap's fan, the north pole; None: `spots`), where a vertex of high valence or a
sliver metres long once made the load grow faster than the triangles."""


# ---------------------------------------------------------------------------------------
# Measurements
# ---------------------------------------------------------------------------------------

def _model():
    model = mujoco.MjModel.from_xml_string(_GEOM)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def load(vertices, faces):
    """(ShapeSet, seconds, peak bytes traced, peak bytes of the resident set over what it was
    before) of a mesh shape on the triangles, built from scratch."""
    from softproxy.geometry import ShapeSet
    from softproxy.mesh import MeshShape, MeshWarning

    model, data = _model()
    gc.collect()
    before = resident_peak(reset=True)
    tracemalloc.start()
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MeshWarning)  # the near-flat grid is an open sheet on purpose
        shape = MeshShape(model, data, 0, True, triangles=(vertices, faces))
    shapes = ShapeSet([shape], data)
    seconds = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return shapes, seconds, peak, max(0, resident_peak() - before)


def resident_peak(reset: bool = False) -> int:
    """The process's peak resident set (bytes): on Linux, since the last reset (`reset` sets
    it to the resident set now, and returns that); elsewhere the peak since it started."""
    try:
        if reset:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
        with open("/proc/self/status") as f:
            fields = dict(line.split(":", 1) for line in f)
        return int(fields["VmHWM"].split()[0]) * 1024
    except (OSError, KeyError, ValueError):
        import resource

        scale = 1 if sys.platform == "darwin" else 1024  # bytes on macOS, kB elsewhere
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * scale


def spots(vertices, faces, count: int, seed: int = 1):
    """`count` places on the mesh at least 1.5 cm apart, on its upper side: (point, outward normal)."""
    rng = np.random.default_rng(seed)
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    centre = (a + b + c) / 3.0
    upward = n[:, 2] > 0.9
    up = np.flatnonzero(upward & (np.abs(centre[:, :2]) < 0.04).all(axis=1))
    if len(up) == 0:  # a coarse mesh (a height field's cells): the upward triangle nearest the middle
        up = np.flatnonzero(upward)[np.argsort(np.abs(centre[upward, :2]).max(axis=1))[:1]]
    chosen = []
    for i in rng.permutation(up):
        if all(np.linalg.norm(centre[i] - centre[j]) > 0.015 for j in chosen):
            chosen.append(i)
            if len(chosen) == count:
                break
    return [(centre[i], n[i]) for i in chosen]


def ticks(shapes, places, sliding: bool, updates: int, warm: int, path: list | None = None) -> np.ndarray:
    """µs per god-object update, every finger's each tick, for fingers held at `places`
    (pressed DEPTH in, still but for a 10 µm tremor, or sliding on 3 mm circles); the first
    finger's proxy centre after each timed update is appended to `path` (m) when given."""
    from softproxy.proxy import GodObject

    gods = [GodObject(shapes, RADIUS, 0.5, 0.4, tuple(p + 3 * RADIUS * n)) for p, n in places]
    frames = []
    for p, n in places:
        t = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        t /= np.linalg.norm(t)
        frames.append((p + (RADIUS - DEPTH) * n, t, np.cross(n, t)))
    clock = time.perf_counter
    out = np.empty((updates, len(gods)))
    for i in range(-warm, updates):
        for f, (god, (at, u, w)) in enumerate(zip(gods, frames)):
            if sliding:
                a = 0.004 * i
                x = at + 0.003 * (math.cos(a) * u + math.sin(a) * w)
            else:
                x = at + 1e-5 * math.sin(0.1 * i) * u
            t0 = clock()
            god.update(*x)
            if i >= 0:
                out[i, f] = clock() - t0
                if path is not None and f == 0:
                    path.append((god.x, god.y, god.z))
    return out.ravel() * 1e6


def within_reach(vertices, faces, path, every: int = 20) -> np.ndarray:
    """Per `every`-th tick of a proxy's path (m), how many triangles lie within its radius
    plus that tick's move of its centre: those the tick's sweeps must rule out or touch
    (the work an exact proxy cannot skip without a certificate). Brute force: the boxes of
    all triangles, then trimesh's closest points on those within reach."""
    tri = vertices[faces]
    lo, hi = tri.min(axis=1), tri.max(axis=1)
    path = np.asarray(path)
    counts = []
    for i in range(1, len(path), every):
        c = path[i]
        reach = RADIUS + float(np.linalg.norm(c - path[i - 1])) + 1e-6
        near = tri[((np.clip(c, lo, hi) - c) ** 2).sum(axis=1) <= reach * reach]
        # each triangle moved to its first vertex and scaled to unit size: trimesh's closest
        # point compares with absolute tolerances, and on a facet 0.45 mm across it answered
        # 0.1 mm off the point over its middle (1 µm too far at r = 5 mm)
        a = near[:, 0]
        size = np.maximum(np.linalg.norm(near - a[:, None], axis=2).max(axis=1), np.finfo(float).tiny)[:, None]
        q = trimesh.triangles.closest_point((near - a[:, None]) / size[:, :, None], (c - a) / size)
        counts.append(int((np.linalg.norm(a + size * q - c, axis=1) <= reach).sum()))
    return np.array(counts)


def measure(sizes=SIZES, updates: int = 2000, warm: int = 300, progress=None, hubs=None) -> dict:
    """Load and tick every kind at every size, then the BESIDE kinds' smallest mesh beside a
    copy of their largest, then the HUBS shapes (at the sizes `hubs` gives, by name, if it
    does); returns the result dict."""
    load(*grid(200))  # the compiled kernels loaded (compiled on a first run), not timed
    rows = []
    for kind, make in KINDS.items():
        for size in sizes:
            if progress is not None:
                progress(f"{kind}, {size} triangles")
            v, f = make(size)
            fingers = FINGERS if size == sizes[len(sizes) // 2] else (1,)
            rows.append(_row(kind, v, f, spots(v, f, max(fingers)), fingers, updates, warm))
    for kind in BESIDE:
        if progress is not None:
            progress(f"{kind}, {sizes[0]} triangles beside {sizes[-1]}")
        v, f = KINDS[kind](sizes[0])
        far_v, far_f = KINDS[kind](sizes[-1])
        row = _row(kind, np.vstack([v, far_v + BESIDE_OFFSET]), np.vstack([f, far_f + len(v)]), spots(v, f, 1), (1,),
                   updates, warm)
        row["beside"] = len(far_f)
        rows.append(row)
    for kind, (make, size, at) in HUBS.items():
        if progress is not None:
            progress(kind)
        v, f = make(size if hubs is None else hubs[kind])
        where = spots(v, f, 1) if at is None else [(np.array(at), np.array([0.0, 0.0, 1.0]))]
        row = _row(kind, v, f, where, (1,), updates, warm)
        row["hub"] = int(np.bincount(np.asarray(f).ravel()).max())  # the highest valence
        rows.append(row)
    return {"radius_m": RADIUS, "updates": updates, "rows": rows}


BESIDE = ("slivers (CAD-like)", "noisy sphere")
"""Kinds timed again at their smallest size beside a copy of their largest, BESIDE_OFFSET away:
the same spot and triangles within reach in a mesh 100 times the size."""
BESIDE_OFFSET = (0.2, 0.0, 0.0)
"""Where the larger copy lies from the smaller (m): clear of the smaller and of its spots."""


def _row(kind: str, v, f, where, fingers, updates: int, warm: int) -> dict:
    """One row: the mesh loaded, then `fingers` fingers at `where` ticked pressed and sliding."""
    shapes, seconds, peak, resident = load(v, f)
    row = {"kind": kind, "triangles": int(shapes[0].triangles), "load_s": round(seconds, 3),
           "peak_mb": round(peak / 1e6, 1), "rss_mb": round(resident / 1e6, 1)}
    for mode in ("pressed", "sliding"):
        # each spot alone, then the fingers together: a finger's cost in company is
        # compared with the same spots' cost alone (spots differ: a concave one costs more)
        path = []
        alone = [ticks(shapes, [spot], mode == "sliding", updates, warm, path if i == 0 else None)
                 for i, spot in enumerate(where[:max(fingers)])]
        row[f"{mode}_in_reach_p50"] = float(np.percentile(within_reach(v, f, path), 50))
        for count in fingers:
            us = alone[0] if count == 1 else ticks(shapes, where[:count], mode == "sliding", updates, warm)
            row[f"{mode}_{count}f_p50_us"] = round(float(np.percentile(us, 50)), 2)
            row[f"{mode}_{count}f_p99_us"] = round(float(np.percentile(us, 99)), 2)
            if count > 1:
                base = np.concatenate(alone[:count])
                row[f"{mode}_{count}f_alone_p99_us"] = round(float(np.percentile(base, 99)), 2)
    return row


def chart(result: dict):
    rows = result["rows"]
    fig, axes = figure(1, 3, (14, 4.5))
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    colours = ["#4a7ab8", "#c07030", "#30a050"]
    for kind, colour in zip(kinds, colours):
        mine = [r for r in rows if r["kind"] == kind and "beside" not in r and "hub" not in r]
        n = [r["triangles"] for r in mine]
        axes[0].plot(n, [r["load_s"] for r in mine], "o-", color=colour, label=kind)
        axes[1].plot(n, [r["peak_mb"] for r in mine], "o-", color=colour, label=kind)
        axes[2].plot(n, [r["pressed_1f_p99_us"] for r in mine], "o-", color=colour, label=f"{kind}, pressed")
        axes[2].plot(n, [r["sliding_1f_p99_us"] for r in mine], "s--", color=colour, label=f"{kind}, sliding")
        for r in rows:
            if r["kind"] == kind and "beside" in r:
                axes[2].plot([r["triangles"]], [r["sliding_1f_p99_us"]], "*", ms=11, color=colour,
                             label=f"{kind}, sliding: smallest beside largest")
    for r, marker in zip([r for r in rows if "hub" in r], "^vD"):
        axes[0].plot([r["triangles"]], [r["load_s"]], marker, color="#7050a0", label=r["kind"])
        axes[1].plot([r["triangles"]], [r["peak_mb"]], marker, color="#7050a0", label=r["kind"])
    axes[0].axhline(5.0, color="#c03030", lw=0.8, ls=":", label="target at 100k (5 s)")
    axes[1].axhline(500.0, color="#c03030", lw=0.8, ls=":", label="target at 100k (500 MB)")
    axes[2].axhline(1000.0, color="#c03030", lw=0.8, ls=":", label="a 1 kHz tick (1000 µs)")
    for ax, label in zip(axes, ("load (s)", "peak memory at load (MB)", "update p99, one finger (µs)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("triangles")
        ax.set_ylabel(label)
        ax.legend(fontsize=7)
    axes[0].set_title("load time")
    axes[1].set_title("load memory (tracemalloc peak)")
    axes[2].set_title(f"god-object update, {result['radius_m'] * 1e3:g} mm proxy")
    return fig


def main(args) -> int:
    progress = Progress("meshes")
    result = measure(SIZES, updates=5000 if getattr(args, "full", False) else 2000, progress=progress)
    progress.done()
    fig = chart(result)
    publish(args, "meshes", result, fig, print_report)
    return 0


def print_report(result: dict) -> None:
    """What `softproxy bench meshes` prints: the result as a table."""
    print(f"meshes: load and god-object update ({result['radius_m'] * 1e3:g} mm proxy, {result['updates']} updates "
          "per finger); µs per finger update, p50/p99")
    print("  (with several fingers: p99 in company / p99 of the same spots each alone; in reach: the")
    print("  median tick's triangles within the proxy's radius plus its move, an exact sweep's work, pressed/sliding)")
    print("  (peak MB: tracemalloc's peak; RSS MB: the resident set's peak over what it was before the load)")
    print(f"  {'mesh':20s}{'triangles':>10s}{'load s':>8s}{'peak MB':>9s}{'RSS MB':>8s}  {'fingers':>7s}"
          f"{'pressed':>16s}{'sliding':>16s}{'in reach':>10s}{'p99 ratio':>14s}")
    previous = {}
    for r in result["rows"]:
        if "beside" in r and "beside" not in previous:
            print(f"  the smallest again, {BESIDE_OFFSET[0] * 100:g} cm from a copy of the largest "
                  "(the same spot and triangles within reach):")
        if "hub" in r and "hub" not in previous:
            print("  high valence and long slivers (the finger on the cap's hub, on the pole, on the field):")
        previous = r
        for count in FINGERS:
            if f"pressed_{count}f_p50_us" not in r:
                continue
            head = (f"  {r['kind']:20s}{r['triangles']:10d}{r['load_s']:8.2f}{r['peak_mb']:9.1f}{r['rss_mb']:8.1f}"
                    if count == 1 else " " * 57)
            ratio = "" if count == 1 else (
                f"{r[f'pressed_{count}f_p99_us'] / r[f'pressed_{count}f_alone_p99_us']:6.2f}/"
                f"{r[f'sliding_{count}f_p99_us'] / r[f'sliding_{count}f_alone_p99_us']:<6.2f}")
            reach = f"{r['pressed_in_reach_p50']:5.0f}/{r['sliding_in_reach_p50']:<4.0f}" if count == 1 else " " * 10
            print(f"{head}  {count:7d}{r[f'pressed_{count}f_p50_us']:8.1f}/{r[f'pressed_{count}f_p99_us']:<7.1f}"
                  f"{r[f'sliding_{count}f_p50_us']:8.1f}/{r[f'sliding_{count}f_p99_us']:<7.1f}{reach}{ratio:>14s}")
