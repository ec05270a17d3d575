"""`softproxy bench godobject`: cost of one god-object update, per finger per tick.

The situations CHAI3D's finger proxy is measured in (its figures in the README): free space, held
on a box face, on an edge, on a corner, sliding on a face, and a 10k-triangle sphere mesh
pressed and sliding; plus ours: a concave three-plane corner and the inside of the
non-convex bowl of the `mesh_object` scene, pressed and sliding. A 5 mm proxy, the device
scripted per situation. Each update is timed alone; the table gives p50 / p99 in µs next to
the targets (≤ 10 µs on primitives, ≤ 30 µs on a 10k-triangle mesh) and CHAI3D's figures.
A Python function call is timed in the same run, so the figures can be read in calls.

Each update is timed from Python through `GodObject.update`, the view a library user calls
(its Python and the call of the kernel's entry point, ~1 µs of each figure: the free-space
row, where the kernel does almost nothing, shows it). In the servo tick one compiled call
serves every finger, so the tick pays the kernel alone.
"""

from __future__ import annotations

import math
import time

import mujoco
import numpy as np

from .report import Progress, figure, publish
from softproxy.proxy import GodObject
from softproxy.scene import load_scene
from softproxy.world import World

RADIUS = 0.005
"""Proxy radius (m), CHAI3D's setting in TARGETS.md."""
DEPTH = 0.002
"""How far the device is held under the surface (m)."""

_BOX = """<mujoco><worldbody>
  <geom name="box" type="box" size="0.05 0.05 0.05"/>
</worldbody></mujoco>"""

_CONCAVE = """<mujoco><worldbody>
  <geom name="floor" type="plane" size="1 1 0.01"/>
  <geom name="wall_x" type="box" size="0.05 0.2 0.1" pos="-0.05 0 0.1"/>
  <geom name="wall_y" type="box" size="0.2 0.05 0.1" pos="0 -0.05 0.1"/>
</worldbody></mujoco>"""


def _sphere_mesh_xml(radius: float = 0.05, count: int = 51) -> tuple[str, int]:
    """MJCF of a uv-sphere mesh (trimesh) of about 10k triangles, inline vertices and faces."""
    import trimesh

    mesh = trimesh.creation.uv_sphere(radius=radius, count=[count, count])
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    verts = " ".join(f"{v:.9g}" for v in mesh.vertices.ravel())
    faces = " ".join(str(i) for i in mesh.faces.ravel())
    xml = (f'<mujoco><asset><mesh name="ball" vertex="{verts}" face="{faces}"/></asset>'
           f'<worldbody><geom name="ball" type="mesh" mesh="ball"/></worldbody></mujoco>')
    return xml, len(mesh.faces)


def _orbit(cx, cy, cz, rho, speed_rad, plane="xz"):
    """Device path on a circle of radius rho about c (m), speed_rad rad per tick."""
    def at(i):
        a = 0.3 + 0.5 * math.sin(i * speed_rad)  # sweeps back and forth over an arc
        if plane == "xz":
            return cx + rho * math.sin(a), cy, cz + rho * math.cos(a)
        return cx + rho * math.sin(a), cy, cz - rho * math.cos(a)
    return at


def situations() -> list[dict]:
    """Each: name, MJCF (or scene name), mu, proxy start, device path (tick -> x_d), CHAI3D µs."""
    s = RADIUS - DEPTH  # device height over a face
    top = 0.05
    ball_xml, ball_tris = _sphere_mesh_xml()
    ball_r = 0.05 + RADIUS - DEPTH
    bowl_r = 0.035 - RADIUS + DEPTH  # the bowl's inner sphere, about (0, 0, 0.04)
    return [
        {"name": "free space", "xml": _BOX, "mu": 0.5, "start": (0.0, 0.0, 0.2),
         "path": lambda i: (0.05 * math.sin(i * 0.01), 0.0, 0.2), "chai3d": 0.03, "target": 10.0},
        {"name": "box face, held", "xml": _BOX, "mu": 0.5, "start": (0.01, 0.005, 0.07),
         "path": lambda i: (0.01 + 1e-5 * math.sin(i * 0.1), 0.005, top + s), "chai3d": 1.2, "target": 10.0},
        {"name": "box edge", "xml": _BOX, "mu": 0.0, "start": (0.07, 0.0, 0.07),
         "path": lambda i: (top + s * 0.7, 0.002 * math.sin(i * 0.01), top + s * 0.7), "chai3d": 1.2, "target": 10.0},
        {"name": "box corner", "xml": _BOX, "mu": 0.0, "start": (0.07, 0.07, 0.07),
         "path": lambda i: (top + s * 0.5, top + s * 0.5, top + s * 0.5 + 1e-5 * math.sin(i * 0.1)),
         "chai3d": 2.8, "target": 10.0},
        {"name": "box face, sliding", "xml": _BOX, "mu": 0.3, "start": (0.0, 0.0, 0.07),
         "path": lambda i: (0.03 * math.sin(i * 0.005), 0.01 * math.cos(i * 0.003), top + s),
         "chai3d": 1.5, "target": 10.0},
        {"name": "concave corner (3 planes)", "xml": _CONCAVE, "mu": 0.0, "start": (0.03, 0.03, 0.03),
         "path": lambda i: (0.002 * math.sin(i * 0.01), 0.002 * math.cos(i * 0.01), 0.003), "chai3d": None,
         "target": 10.0},
        {"name": f"sphere mesh {ball_tris} tri, pressed", "xml": ball_xml, "mu": 0.5, "start": (0.0, 0.0, 0.08),
         "path": lambda i: (1e-5 * math.sin(i * 0.1), 0.0, ball_r), "chai3d": 122.0, "target": 30.0},
        {"name": f"sphere mesh {ball_tris} tri, sliding", "xml": ball_xml, "mu": 0.3, "start": (0.0, 0.0, 0.08),
         "path": _orbit(0.0, 0.0, 0.0, ball_r, 0.004), "chai3d": 47.0, "target": 30.0},
        {"name": "bowl 7200 tri (non-convex), pressed", "scene": "mesh_object", "mu": 0.5, "start": (0.0, 0.0, 0.03),
         "path": lambda i: (1e-5 * math.sin(i * 0.1), 0.0, 0.04 - bowl_r), "chai3d": None, "target": 30.0},
        {"name": "bowl 7200 tri (non-convex), sliding", "scene": "mesh_object", "mu": 0.3, "start": (0.0, 0.0, 0.03),
         "path": _orbit(0.0, 0.0, 0.04, bowl_r, 0.004, plane="bowl"), "chai3d": None, "target": 30.0},
    ]


def _world(case: dict) -> World:
    if "scene" in case:
        return World(load_scene(case["scene"]).load_model())
    return World(mujoco.MjModel.from_xml_string(case["xml"]))


def _python_call_us(n: int = 200_000) -> float:
    """Median cost of calling an empty Python method (µs): the unit of scalar Python."""
    class _Null:
        def f(self, a, b, c):
            return None
    obj = _Null()
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            obj.f(1.0, 2.0, 3.0)
        best = min(best, (time.perf_counter() - t0) / n * 1e6)
    return best


def _pass(case: dict, updates: int, warm: int):
    """The god-object on the case's path: (µs per update, contacts, deepest inside (m))."""
    world = _world(case)
    god = GodObject(world.shapes, RADIUS, case["mu"], 0.8 * case["mu"], case["start"])
    path = case["path"]
    clock = time.perf_counter
    for i in range(warm):
        god.update(*path(i))
    times = np.empty(updates)
    worst = 0.0
    contacts = 0
    for i in range(updates):
        xd, yd, zd = path(warm + i)
        t0 = clock()
        god.update(xd, yd, zd)
        times[i] = clock() - t0
        contacts += god.contact
        worst = max(worst, _inside(world, god.x, god.y, god.z))
    return times * 1e6, contacts, worst


def _inside(world: World, x: float, y: float, z: float) -> float:
    """How deep a RADIUS proxy at p sits inside the world's deepest shape (m, 0 when outside)."""
    return max(0.0, max(RADIUS - shape.distance(x, y, z)[0] for shape in world.shapes))


def measure(updates: int = 3000, warm: int = 500, progress=None) -> dict:
    """Time every situation; returns the result dict (µs)."""
    rows = []
    cases = situations()
    for k, case in enumerate(cases):
        if progress is not None:
            progress(f"{case['name']} ({k + 1}/{len(cases)})")
        us, contacts, worst = _pass(case, updates, warm)
        row = {
            "situation": case["name"],
            "p50_us": round(float(np.percentile(us, 50)), 2),
            "p99_us": round(float(np.percentile(us, 99)), 2),
            "target_us": case["target"],
            "chai3d_us": case["chai3d"],
            "contact_fraction": round(contacts / updates, 3),
            "penetration_max_m": float(worst),
            "_us": us,
        }
        rows.append(row)
    return {"radius_m": RADIUS, "updates": updates, "python_call_us": round(_python_call_us(), 4), "rows": rows}


def chart(result: dict):
    fig, ax = figure(1, 1, (9, 4.5))
    rows = result["rows"]
    names = [r["situation"] for r in rows]
    y = np.arange(len(rows))
    ax.barh(y, [r["p50_us"] for r in rows], color="#4a7ab8", label="softproxy p50")
    ax.scatter([r["p99_us"] for r in rows], y, color="#1f3d66", marker="|", s=200, label="softproxy p99")
    ax.scatter([r["target_us"] for r in rows], y, color="#c03030", marker="x", label="target")
    chai = [(r["chai3d_us"], i) for i, r in enumerate(rows) if r["chai3d_us"]]
    ax.scatter([c for c, _ in chai], [i for _, i in chai], color="#30a030", marker="o", label="CHAI3D (C++)")
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xscale("log")
    ax.set_xlabel("µs per update")
    ax.set_title(f"god-object update, {result['radius_m'] * 1e3:g} mm proxy")
    ax.legend(loc="lower right", fontsize=8)
    return fig


def main(args) -> int:
    progress = Progress("godobject")
    updates = 10_000 if getattr(args, "full", False) else 3000
    result = measure(updates, progress=progress)
    progress.done()
    fig = chart(result)
    for r in result["rows"]:
        del r["_us"]
    publish(args, "godobject", result, fig, print_report)
    return 0


def print_report(result: dict) -> None:
    """What `softproxy bench godobject` prints: the result as a table."""
    print(f"god-object update, {result['radius_m'] * 1e3:g} mm proxy, {result['updates']} updates each "
          f"(a Python call costs {result['python_call_us']} µs here); µs")
    print(f"  {'situation':40s}{'p50':>8s}{'p99':>8s}{'target':>8s}{'CHAI3D':>8s}  inside max (m)")
    for r in result["rows"]:
        chai = f"{r['chai3d_us']:8.2f}" if r["chai3d_us"] else f"{'-':>8s}"
        flag = "  (over target)" if r["p50_us"] > r["target_us"] else ""
        print(f"  {r['situation']:40s}{r['p50_us']:8.2f}{r['p99_us']:8.2f}{r['target_us']:8.1f}{chai}  "
              f"{r['penetration_max_m']:.1e}{flag}")
