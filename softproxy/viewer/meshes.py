"""Triangle meshes for the MuJoCo geom types and the viewer's own glyphs (numpy, no GL).

Every builder returns a float32 array of shape (n, 8): one row per triangle corner,
position (3), normal (3), texture coordinate (2), in the geom's own frame (the frame
MuJoCo poses with `geom_xpos` / `geom_xmat`), already scaled by the geom's size.
"""

from __future__ import annotations

import numpy as np

PLANE, HFIELD, SPHERE, CAPSULE, ELLIPSOID, CYLINDER, BOX, MESH = range(8)
DEFAULT_RGBA = (0.5, 0.5, 0.5, 1.0)  # MuJoCo's geom default: a material's colour wins over it


def _grid(pos: np.ndarray, nrm: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Triangles of a (rows, cols) parametric grid of positions, normals and uvs."""
    r, c = pos.shape[:2]
    i, j = np.meshgrid(np.arange(r - 1), np.arange(c - 1), indexing="ij")
    a = (i * c + j).ravel()
    b = a + 1
    d = a + c
    e = d + 1
    idx = np.stack([a, d, e, a, e, b], axis=1).ravel()
    v = np.concatenate([pos.reshape(-1, 3), nrm.reshape(-1, 3), uv.reshape(-1, 2)], axis=1)
    return v[idx].astype(np.float32)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0)


def ellipsoid(a: float, b: float, c: float, slices: int = 32, stacks: int = 16) -> np.ndarray:
    """Ellipsoid with semi-axes a, b, c (a sphere when equal)."""
    u = np.linspace(0.0, 2.0 * np.pi, slices + 1)
    v = np.linspace(0.0, np.pi, stacks + 1)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    unit = np.stack([np.sin(vv) * np.cos(uu), np.sin(vv) * np.sin(uu), np.cos(vv)], axis=-1)
    axes = np.array([a, b, c])
    pos = unit * axes
    nrm = _unit(unit / axes)
    uv = np.stack([uu / (2 * np.pi), vv / np.pi], axis=-1)
    return _grid(pos, nrm, uv)


def sphere(r: float, slices: int = 32, stacks: int = 16) -> np.ndarray:
    return ellipsoid(r, r, r, slices, stacks)


def capsule(r: float, half: float, slices: int = 32, stacks: int = 16) -> np.ndarray:
    """Capsule along z: a cylinder of radius r and half-length `half` with hemispherical caps."""
    u = np.linspace(0.0, 2.0 * np.pi, slices + 1)
    h = stacks // 2
    v = np.concatenate([np.linspace(0.0, np.pi / 2, h + 1), np.linspace(np.pi / 2, np.pi, h + 1)])
    shift = np.concatenate([np.full(h + 1, half), np.full(h + 1, -half)])
    vv, uu = np.meshgrid(v, u, indexing="ij")
    unit = np.stack([np.sin(vv) * np.cos(uu), np.sin(vv) * np.sin(uu), np.cos(vv)], axis=-1)
    pos = unit * r
    pos[..., 2] += shift[:, None]
    uv = np.stack([uu / (2 * np.pi), np.broadcast_to(np.linspace(0, 1, v.size)[:, None], uu.shape)], axis=-1)
    return _grid(pos, unit, uv)


def _disk(r: float, z: float, up: bool, slices: int) -> np.ndarray:
    u = np.linspace(0.0, 2.0 * np.pi, slices + 1)
    rim = np.stack([r * np.cos(u), r * np.sin(u), np.full_like(u, z)], axis=-1)
    centre = np.array([0.0, 0.0, z])
    tris = []
    for k in range(slices):
        p, q = (rim[k], rim[k + 1]) if up else (rim[k + 1], rim[k])
        tris.extend([centre, p, q])
    pos = np.array(tris)
    nrm = np.tile([0.0, 0.0, 1.0 if up else -1.0], (len(pos), 1))
    uv = pos[:, :2] / (2 * r) + 0.5 if r > 0 else np.zeros((len(pos), 2))
    return np.concatenate([pos, nrm, uv], axis=1).astype(np.float32)


def cylinder(r: float, half: float, slices: int = 32, z0: float | None = None) -> np.ndarray:
    """Closed cylinder along z from -half to +half (or from z0 to z0 + 2 half)."""
    lo = -half if z0 is None else z0
    hi = lo + 2.0 * half
    u = np.linspace(0.0, 2.0 * np.pi, slices + 1)
    zz, uu = np.meshgrid(np.array([hi, lo]), u, indexing="ij")
    nrm = np.stack([np.cos(uu), np.sin(uu), np.zeros_like(uu)], axis=-1)
    pos = np.stack([r * np.cos(uu), r * np.sin(uu), zz], axis=-1)
    uv = np.stack([uu / (2 * np.pi), (zz - lo) / max(hi - lo, 1e-12)], axis=-1)
    return np.concatenate([_grid(pos, nrm, uv), _disk(r, hi, True, slices), _disk(r, lo, False, slices)])


def cone(r: float, length: float, slices: int = 32) -> np.ndarray:
    """Cone along +z: base of radius r at z = 0, tip at z = length."""
    u = np.linspace(0.0, 2.0 * np.pi, slices + 1)
    zz, uu = np.meshgrid(np.array([length, 0.0]), u, indexing="ij")
    rr = np.where(zz > 0.0, 0.0, r)
    slope = r / length
    nrm = _unit(np.stack([np.cos(uu), np.sin(uu), np.full_like(uu, slope)], axis=-1))
    pos = np.stack([rr * np.cos(uu), rr * np.sin(uu), zz], axis=-1)
    uv = np.stack([uu / (2 * np.pi), zz / length], axis=-1)
    return np.concatenate([_grid(pos, nrm, uv), _disk(r, 0.0, False, slices)])


def box(sx: float, sy: float, sz: float) -> np.ndarray:
    """Box with half-sizes sx, sy, sz."""
    out = []
    half = np.array([sx, sy, sz])
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            a, b = [k for k in range(3) if k != axis]
            corners = []
            for ca, cb in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = np.zeros(3)
                p[axis] = sign * half[axis]
                p[a] = ca * half[a]
                p[b] = cb * half[b]
                corners.append((p, ((ca + 1) / 2, (cb + 1) / 2)))
            for k in (0, 1, 2, 0, 2, 3):
                p, uv = corners[k]
                out.append([*p, *n, *uv])
    return np.array(out, dtype=np.float32)


def plane(sx: float, sy: float) -> np.ndarray:
    """Plane z = 0 in the geom frame, half-extents sx, sy, normal +z; uv spans 0..1."""
    c = [(-sx, -sy, 0.0, 0.0), (sx, -sy, 1.0, 0.0), (sx, sy, 1.0, 1.0), (-sx, sy, 0.0, 1.0)]
    return np.array([[x, y, 0.0, 0.0, 0.0, 1.0, u, v] for k in (0, 1, 2, 0, 2, 3) for x, y, u, v in [c[k]]],
                    dtype=np.float32)


def triangles(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None = None,
              face_normals: np.ndarray | None = None) -> np.ndarray:
    """A triangle mesh: per-corner normals `normals[face_normals]` (MuJoCo's, smooth where the
    surface is, split at creases) if given, else flat per-face normals."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]  # (f, 3, 3)
    pos = tri.reshape(-1, 3)
    if normals is not None and face_normals is not None and len(normals):
        nrm = _unit(np.asarray(normals, dtype=np.float64)[np.asarray(face_normals, dtype=np.int64)].reshape(-1, 3))
    else:
        n = _unit(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))
        nrm = np.repeat(n, 3, axis=0)
    return np.concatenate([pos, nrm, np.zeros((len(pos), 2))], axis=1).astype(np.float32)


def geom_mesh(model, g: int, plane_extent: float = 1.0) -> np.ndarray | None:
    """Mesh of geom `g` of a compiled MuJoCo model, in its frame; None for types not drawn
    (height fields, SDFs). A plane of size 0 (infinite) is drawn `plane_extent` wide."""
    t = int(model.geom_type[g])
    s = model.geom_size[g]
    if t == PLANE:
        sx = s[0] if s[0] > 0 else plane_extent
        sy = s[1] if s[1] > 0 else plane_extent
        return plane(sx, sy)
    if t == SPHERE:
        return sphere(s[0])
    if t == CAPSULE:
        return capsule(s[0], s[1])
    if t == ELLIPSOID:
        return ellipsoid(s[0], s[1], s[2])
    if t == CYLINDER:
        return cylinder(s[0], s[1])
    if t == BOX:
        return box(s[0], s[1], s[2])
    if t == MESH:
        m = int(model.geom_dataid[g])
        if m < 0:
            return None
        va, vn = int(model.mesh_vertadr[m]), int(model.mesh_vertnum[m])
        fa, fn = int(model.mesh_faceadr[m]), int(model.mesh_facenum[m])
        if vn == 0 or fn == 0:
            return None
        normals = face_normals = None
        try:
            na, nn = int(model.mesh_normaladr[m]), int(model.mesh_normalnum[m])
            if nn > 0:
                normals = model.mesh_normal[na:na + nn]
                face_normals = model.mesh_facenormal[fa:fa + fn]
        except AttributeError:  # a MuJoCo without per-corner normals: flat shading
            pass
        return triangles(model.mesh_vert[va:va + vn], model.mesh_face[fa:fa + fn], normals, face_normals)
    return None


def geom_rgba(model, g: int) -> tuple[float, float, float, float]:
    """The colour MuJoCo shows: the geom's rgba, or its material's if the geom kept the default."""
    rgba = tuple(float(v) for v in model.geom_rgba[g])
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, DEFAULT_RGBA):
        rgba = tuple(float(v) for v in model.mat_rgba[mat])
    return rgba


def geom_visible(model, g: int) -> bool:
    """MuJoCo's default visibility: groups 0-2, not fully transparent."""
    return int(model.geom_group[g]) <= 2 and geom_rgba(model, g)[3] > 0.0
