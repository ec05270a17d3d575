"""The god-object solver of `softproxy.proxy`, compiled: the same steps on a finger's state row.

A numba twin of `GodObject.update` / `follow` / `reset`. Each function mirrors the Python
method of the same name line by line, in the same order of floating-point operations, so the
two agree to the last bit on primitives (tests/test_compiled.py runs them side by side) and
to rounding on meshes (`softproxy.compiled.mesh`). The Python class stays the reference and
the documentation: read it for the why of every step; comments here only mark where the form
differs.

State: `g` is the finger's row of the state array (columns in `layout`), `near` its row of
the broad phase's shape list; shapes are rows of the table `S` (a mesh's triangles and grid
in the tables `T` and `C`), posed by MuJoCo's `geom_xpos` / `geom_xmat`. A list of
constraint planes is an (n, 5) array of rows (nx, ny, nz, c, shape row) plus a count. Units: m.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softproxy.compiled.layout import PLANE_WIDTH
from softproxy.compiled.shapes import shape_distance, shape_on_face, shape_sweep, shape_to_local, shape_to_world
from softproxy.compiled.tolerances import CONTACT_TOL, GRAZE

MAX_ITERATIONS = 10
"""Sweeps per solve: three for a corner, a few more to follow a curved surface."""
LIFT_TOL = 1e-7
"""After sliding along a constraint plane (a curved shape's or a rounded edge's tangent plane,
a face's plane past the face's edge), re-follow the surface when the proxy has lifted off
the real shape by more than this (m); a proxy this far off a plane no longer rests on it."""
PARALLEL = 1.0 - 1e-9
WORKSPACE_LIMIT = 1e3
"""A device position farther than this from the origin on any axis (m) is garbage, like NaN."""

PLANE_ROOM = 8
"""Rows of a scratch plane list: three planes, plus the ones `_keep_resting` adds before it
keeps the last three."""


@njit(cache=True)
def _load_planes(g, pl):
    """Copy the finger's planes into the scratch list pl; returns their count."""
    n = int(g.nplanes)
    for j in range(n):
        for k in range(PLANE_WIDTH):
            pl[j, k] = g.planes[j, k]
    return n


@njit(cache=True)
def _store_planes(g, pl, n):
    """The finger's planes := the last three of pl[:n] (`resting[-3:]`)."""
    start = n - 3 if n > 3 else 0
    for j in range(start, n):
        for k in range(PLANE_WIDTH):
            g.planes[j - start, k] = pl[j, k]
    g.nplanes = n - start


@njit(cache=True)
def _feasible(pl, n, x, y, z, skip0, skip1):
    for i in range(n):
        if i != skip0 and i != skip1 and pl[i, 0] * x + pl[i, 1] * y + pl[i, 2] * z < pl[i, 3] - CONTACT_TOL:
            return False
    return True


@njit(cache=True)
def _corner(px, py, pz, pl):
    """`proxy._corner`: (found, qx, qy, qz)."""
    ax, ay, az, ca = pl[0, 0], pl[0, 1], pl[0, 2], pl[0, 3]
    bx, by, bz, cb = pl[1, 0], pl[1, 1], pl[1, 2], pl[1, 3]
    cx, cy, cz, cc = pl[2, 0], pl[2, 1], pl[2, 2], pl[2, 3]
    ux, uy, uz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    vx, vy, vz = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
    wx, wy, wz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    det = ax * ux + ay * uy + az * uz
    if abs(det) <= 1e-12:
        return False, 0.0, 0.0, 0.0
    ea = ca - (ax * px + ay * py + az * pz)
    eb = cb - (bx * px + by * py + bz * pz)
    ec = cc - (cx * px + cy * py + cz * pz)
    dx = (ux * ea + vx * eb + wx * ec) / det
    dy = (uy * ea + vy * eb + wy * ec) / det
    dz = (uz * ea + vz * eb + wz * ec) / det
    gab, gac, gbc = ax * bx + ay * by + az * bz, ax * cx + ay * cy + az * cz, bx * cx + by * cy + bz * cz
    c00, c11, c22 = 1.0 - gbc * gbc, 1.0 - gac * gac, 1.0 - gab * gab
    c01, c02, c12 = gac * gbc - gab, gab * gbc - gac, gab * gac - gbc
    gdet = c00 + gab * c01 + gac * c02
    if gdet <= 1e-12:
        return False, 0.0, 0.0, 0.0
    if (c00 * ea + c01 * eb + c02 * ec) / gdet < 0.0 or (c01 * ea + c11 * eb + c12 * ec) / gdet < 0.0 \
            or (c02 * ea + c12 * eb + c22 * ec) / gdet < 0.0:
        return False, 0.0, 0.0, 0.0
    return True, px + dx, py + dy, pz + dz


@njit(cache=True)
def _project_by_enumeration(px, py, pz, pl, n):
    """`proxy._project_by_enumeration`: (found, qx, qy, qz)."""
    if _feasible(pl, n, px, py, pz, -1, -1):
        return True, px, py, pz
    for i in range(n):
        nx, ny, nz, c = pl[i, 0], pl[i, 1], pl[i, 2], pl[i, 3]
        lam = c - (nx * px + ny * py + nz * pz)
        if lam > 0.0:
            qx, qy, qz = px + lam * nx, py + lam * ny, pz + lam * nz
            if _feasible(pl, n, qx, qy, qz, i, -1):
                return True, qx, qy, qz
    for i in range(n):
        for j in range(i + 1, n):
            ax, ay, az, ci = pl[i, 0], pl[i, 1], pl[i, 2], pl[i, 3]
            bx, by, bz, cj = pl[j, 0], pl[j, 1], pl[j, 2], pl[j, 3]
            g = ax * bx + ay * by + az * bz
            det = 1.0 - g * g
            if det < 1e-12:
                continue
            ei = ci - (ax * px + ay * py + az * pz)
            ej = cj - (bx * px + by * py + bz * pz)
            a = (ei - g * ej) / det
            b = (ej - g * ei) / det
            if a < 0.0 or b < 0.0:
                continue
            qx, qy, qz = px + a * ax + b * bx, py + a * ay + b * by, pz + a * az + b * bz
            if _feasible(pl, n, qx, qy, qz, i, j):
                return True, qx, qy, qz
    if n == 3:
        ax, ay, az, ca = pl[0, 0], pl[0, 1], pl[0, 2], pl[0, 3]
        bx, by, bz, cb = pl[1, 0], pl[1, 1], pl[1, 2], pl[1, 3]
        cx, cy, cz, cc = pl[2, 0], pl[2, 1], pl[2, 2], pl[2, 3]
        det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        if abs(det) > 1e-12:
            qx = (ca * (by * cz - bz * cy) - ay * (cb * cz - bz * cc) + az * (cb * cy - by * cc)) / det
            qy = (ax * (cb * cz - bz * cc) - ca * (bx * cz - bz * cx) + az * (bx * cc - cb * cx)) / det
            qz = (ax * (by * cc - cb * cy) - ay * (bx * cc - cb * cx) + ca * (bx * cy - by * cx)) / det
            return True, qx, qy, qz
    return False, 0.0, 0.0, 0.0


@njit(cache=True)
def _project(px, py, pz, pl, n):
    """`proxy._project`: (found, qx, qy, qz)."""
    if n == 1:
        nx, ny, nz, c = pl[0, 0], pl[0, 1], pl[0, 2], pl[0, 3]
        lam = c - (nx * px + ny * py + nz * pz)
        if lam > 0.0:
            return True, px + lam * nx, py + lam * ny, pz + lam * nz
        return True, px, py, pz
    outside = False
    for i in range(n):
        if pl[i, 0] * px + pl[i, 1] * py + pl[i, 2] * pz < pl[i, 3] - CONTACT_TOL:
            outside = True
            break
    if not outside:
        return True, px, py, pz
    if n == 3:
        found, qx, qy, qz = _corner(px, py, pz, pl)
        if found:
            return True, qx, qy, qz
    return _project_by_enumeration(px, py, pz, pl, n)


@njit(cache=True)
def _plane_of(pl, n, s, nx, ny, nz):
    """`proxy._plane_of`: index of shape s's plane of normal n in pl[:n], or -1."""
    for i in range(n):
        if int(pl[i, 4]) == s and pl[i, 0] * nx + pl[i, 1] * ny + pl[i, 2] * nz > PARALLEL:
            return i
    return -1


@njit(cache=True)
def _add_plane(pl, n, nx, ny, nz, c, s):
    """`softproxy.proxy._add_plane` on pl[:n]: the new count."""
    i = _plane_of(pl, n, s, nx, ny, nz)
    if i >= 0:
        for j in range(i, n - 1):
            for k in range(PLANE_WIDTH):
                pl[j, k] = pl[j + 1, k]
        n -= 1
    pl[n, 0], pl[n, 1], pl[n, 2], pl[n, 3], pl[n, 4] = nx, ny, nz, c, s
    n += 1
    if n > 3:
        for j in range(n - 1):
            for k in range(PLANE_WIDTH):
                pl[j, k] = pl[j + 1, k]
        n -= 1
    return n


@njit(cache=True)
def _touched(pl, n, nx, ny, nz):
    """`proxy._touched`: the shape row whose plane is most aligned with n."""
    best, best_dot = int(pl[0, 4]), -2.0
    for i in range(n):
        dot = pl[i, 0] * nx + pl[i, 1] * ny + pl[i, 2] * nz
        if dot > best_dot:
            best, best_dot = int(pl[i, 4]), dot
    return best


@njit(cache=True)
def _on_static_faces(S, xmat, pl, n):
    for i in range(n):
        s = int(pl[i, 4])
        if not (S[s].static and shape_on_face(S, xmat, s, pl[i, 0], pl[i, 1], pl[i, 2])):
            return False
    return True


@njit(cache=True)
def gather_ball(S, T, C, xpos, xmat, g, near, cx, cy, cz, room):
    """`GodObject._gather_ball`."""
    g.bx, g.by, g.bz, g.room = cx, cy, cz, room
    reach = room + g.radius
    count = 0
    for s in range(S.shape[0]):
        k = int(S[s].geom)
        rb = S[s].rbound + reach
        if rb == math.inf:
            if xmat[k, 2] * (cx - xpos[k, 0]) + xmat[k, 5] * (cy - xpos[k, 1]) + xmat[k, 8] * (cz - xpos[k, 2]) <= reach:
                near[count] = s
                count += 1
            continue
        dx, dy, dz = xpos[k, 0] - cx, xpos[k, 1] - cy, xpos[k, 2] - cz
        if dx * dx + dy * dy + dz * dz <= rb * rb:
            near[count] = s
            count += 1
    g.nnear = count


@njit(cache=True)
def push_out(S, T, C, xpos, xmat, g, near):
    """`GodObject._push_out`."""
    r = g.radius
    for _ in range(3):
        moved = False
        for j in range(int(g.nnear)):
            d, nx, ny, nz = shape_distance(S, T, C, xpos, xmat, near[j], g.x, g.y, g.z)
            gap = d - r
            if gap < 0.0:
                push = -gap + CONTACT_TOL
                g.x += push * nx
                g.y += push * ny
                g.z += push * nz
                moved = True
        if not moved:
            return


@njit(cache=True)
def reset(S, T, C, xpos, xmat, g, near, x, y, z):
    """`GodObject.reset`; False (nothing changed) for a position outside the workspace."""
    if not (-WORKSPACE_LIMIT < x < WORKSPACE_LIMIT and -WORKSPACE_LIMIT < y < WORKSPACE_LIMIT
            and -WORKSPACE_LIMIT < z < WORKSPACE_LIMIT):
        return False
    g.x, g.y, g.z = x, y, z
    g.contact = False
    g.nx = g.ny = g.nz = 0.0
    g.touched = -1
    g.depth = 0.0
    g.sticking = False
    g.lx = g.ly = g.lz = 0.0
    for s in range(S.shape[0]):
        near[s] = s
    g.nnear = S.shape[0]
    push_out(S, T, C, xpos, xmat, g, near)
    return True


@njit(cache=True)
def _settle(S, T, C, xpos, xmat, g, near, xd, yd, zd, around_proxy):
    """`GodObject._settle`: returns the proxy position before the push."""
    shape = int(g.touched)
    carrier = -1
    if shape >= 0 and not S[shape].static:
        carrier = shape
        g.x, g.y, g.z = shape_to_world(S, xpos, xmat, shape, g.lx, g.ly, g.lz)
    x, y, z = g.x, g.y, g.z
    if around_proxy:
        gather_ball(S, T, C, xpos, xmat, g, near, x, y, z, g.radius + 1e-3)
    else:
        ex, ey, ez = xd - x, yd - y, zd - z
        gather_ball(S, T, C, xpos, xmat, g, near, 0.5 * (x + xd), 0.5 * (y + yd), 0.5 * (z + zd),
                    0.5 * math.sqrt(ex * ex + ey * ey + ez * ez) + g.radius + 1e-3)
    for j in range(int(g.nnear)):
        s = near[j]
        if s != carrier and (carrier >= 0 or not S[s].static):
            push_out(S, T, C, xpos, xmat, g, near)
            break
    return x, y, z


@njit(cache=True)
def follow(S, T, C, xpos, xmat, g, near):
    """`GodObject.follow`: no device sample; stay on the body, out of what moved in."""
    _settle(S, T, C, xpos, xmat, g, near, g.x, g.y, g.z, True)


@njit(cache=True)
def _sweep(S, T, C, xpos, xmat, g, near, x, y, z, dx, dy, dz, pl, n):
    """`GodObject._sweep`: (found, lam, nx, ny, nz, shape row) of the earliest hit."""
    r = g.radius
    found = False
    best_lam, bnx, bny, bnz, bs = 1.0, 0.0, 0.0, 0.0, -1
    for j in range(int(g.nnear)):
        s = near[j]
        if S[s].convex:
            behind = False
            for i in range(n):
                if int(pl[i, 4]) == s:
                    behind = True
                    break
            if behind:
                continue
        lam, nx, ny, nz = shape_sweep(S, T, C, xpos, xmat, s, x, y, z, dx, dy, dz, r)
        if lam >= 0.0 and lam < best_lam:
            found = True
            best_lam, bnx, bny, bnz, bs = lam, nx, ny, nz, s
    return found, best_lam, bnx, bny, bnz, bs


@njit(cache=True)
def _rests_on(S, T, C, xpos, xmat, g, pl, i, x, y, z, on_surface):
    """`GodObject._rests_on` for plane pl[i]."""
    nx, ny, nz, c = pl[i, 0], pl[i, 1], pl[i, 2], pl[i, 3]
    if not abs(nx * x + ny * y + nz * z - c) <= LIFT_TOL:
        return False
    return on_surface or shape_distance(S, T, C, xpos, xmat, int(pl[i, 4]), x, y, z)[0] - g.radius <= LIFT_TOL


@njit(cache=True)
def _keep_resting(S, T, C, xpos, xmat, g, resting, nr, pl, n, x, y, z):
    """`GodObject._keep_resting`: resting[:nr] (self.planes) plus the planes of pl[:n] the
    proxy at p still rests on; the last three become the finger's planes."""
    for i in range(n):
        if _rests_on(S, T, C, xpos, xmat, g, pl, i, x, y, z, False) and \
                _plane_of(resting, nr, int(pl[i, 4]), pl[i, 0], pl[i, 1], pl[i, 2]) < 0:
            for k in range(PLANE_WIDTH):
                resting[nr, k] = pl[i, k]
            nr += 1
    _store_planes(g, resting, nr)


@njit(cache=True)
def _still_in_corner(S, T, C, xpos, xmat, g, xd, yd, zd, pl, n):
    """`GodObject._still_in_corner`."""
    if not _on_static_faces(S, xmat, pl, n):
        return False
    found, qx, qy, qz = _corner(xd, yd, zd, pl)
    x, y, z = g.x, g.y, g.z
    if not found or abs(qx - x) + abs(qy - y) + abs(qz - z) > 1e-12:
        return False
    ex, ey, ez = x - xd, y - yd, z - zd
    depth = math.sqrt(ex * ex + ey * ey + ez * ez)
    if depth == 0.0:
        return False
    nx, ny, nz = ex / depth, ey / depth, ez / depth
    best = _touched(pl, n, nx, ny, nz)
    g.nx, g.ny, g.nz = nx, ny, nz
    g.depth = depth
    g.touched = best
    return True


@njit(cache=True)
def _still_stuck(S, T, C, xpos, xmat, g, near, xd, yd, zd, pl):
    """`GodObject._still_stuck`."""
    n = _load_planes(g, pl)
    if n == 3:
        return _still_in_corner(S, T, C, xpos, xmat, g, xd, yd, zd, pl, n)
    shape = int(g.touched)
    if n != 1 or not S[shape].planar:
        return False
    x, y, z, r = g.x, g.y, g.z, g.radius
    d, nx, ny, nz = shape_distance(S, T, C, xpos, xmat, shape, x, y, z)
    if abs(d - r) > 1e-7:
        return False
    depth = nx * (x - xd) + ny * (y - yd) + nz * (z - zd)
    if depth <= 0.0:
        return False
    fx, fy, fz = xd + depth * nx, yd + depth * ny, zd + depth * nz
    df, mx, my, mz = shape_distance(S, T, C, xpos, xmat, shape, fx, fy, fz)
    if abs(df - d) > 1e-9 or nx * mx + ny * my + nz * mz < PARALLEL:
        return False
    sx, sy, sz = x - fx, y - fy, z - fz
    if sx * sx + sy * sy + sz * sz > (g.mu_s * depth) ** 2:
        return False
    for j in range(int(g.nnear)):
        s = near[j]
        if s != shape and shape_sweep(S, T, C, xpos, xmat, s, x, y, z, fx - x, fy - y, fz - z, r)[0] >= 0.0:
            return False
    p = g.planes[0]
    p[0], p[1], p[2], p[3], p[4] = nx, ny, nz, nx * x + ny * y + nz * z, shape
    g.nplanes = 1
    g.nx, g.ny, g.nz = nx, ny, nz
    g.depth = depth
    return True


@njit(cache=True)
def _warm_planes(S, T, C, xpos, xmat, g, x, y, z, warm):
    """`GodObject._warm_planes` into warm; returns the count (0: solve cold)."""
    n = int(g.nplanes)
    count = 0
    for j in range(n):
        p = g.planes[j]
        s = int(p[4])
        if not S[s].static:
            return 0
        if shape_on_face(S, xmat, s, p[0], p[1], p[2]):
            for k in range(PLANE_WIDTH):
                warm[count, k] = p[k]
            count += 1
            continue
        if not S[s].convex or g.rounding:
            return 0
        d, nx, ny, nz = shape_distance(S, T, C, xpos, xmat, s, x, y, z)
        if d - g.radius > LIFT_TOL:
            return 0
        if count == 0 or _plane_of(warm, count, s, nx, ny, nz) < 0:
            warm[count, 0], warm[count, 1], warm[count, 2], warm[count, 3], warm[count, 4] = nx, ny, nz, 0.0, s
            count += 1
    return count


@njit(cache=True)
def _move_once(S, T, C, xpos, xmat, g, near, x, y, z, gx, gy, gz, warm, nwarm, pl, kept):
    """One pass of `GodObject._move`. Returns (restart, x, y, z, hx, hy, hz, straight, n):
    restart when a warm start must be solved again cold (the Python method's recursion);
    otherwise the end point, the first surface point, and the resting planes in pl[:n]."""
    n = 0
    has_first = False
    hx = hy = hz = 0.0
    straight = True
    on_surfaces = False
    g.rounding = False
    r = g.radius
    tx, ty, tz = gx, gy, gz
    if nwarm > 0:
        for j in range(nwarm):
            warm[j, 3] = warm[j, 0] * x + warm[j, 1] * y + warm[j, 2] * z
        ex, ey, ez = gx - x, gy - y, gz - z
        graze = GRAZE * math.sqrt(ex * ex + ey * ey + ez * ez)
        found = False
        for j in range(nwarm):
            if warm[j, 3] - (warm[j, 0] * gx + warm[j, 1] * gy + warm[j, 2] * gz) > graze:
                found, qx, qy, qz = _project(gx, gy, gz, warm, nwarm)
                break
        if found:
            for j in range(nwarm):
                for k in range(PLANE_WIDTH):
                    pl[j, k] = warm[j, k]
            n = nwarm
            has_first = True
            hx, hy, hz = x, y, z
            tx, ty, tz = qx, qy, qz
    bx, by, bz, room2 = g.bx, g.by, g.bz, g.room * g.room
    following = False
    for _ in range(MAX_ITERATIONS - n):
        following = False
        dx, dy, dz = tx - x, ty - y, tz - z
        if dx * dx + dy * dy + dz * dz < 1e-24:
            break
        ex, ey, ez = tx - bx, ty - by, tz - bz
        if ex * ex + ey * ey + ez * ez > room2:
            gather_ball(S, T, C, xpos, xmat, g, near, bx, by, bz, math.sqrt(ex * ex + ey * ey + ez * ez) + 1e-3)
            room2 = g.room * g.room
        hit, lam, nx, ny, nz, s = _sweep(S, T, C, xpos, xmat, g, near, x, y, z, dx, dy, dz, pl, n)
        if not hit:
            x, y, z = tx, ty, tz
            if n == 0 or (tx == gx and ty == gy and tz == gz):
                break
            nk = 0
            lifted = False
            for i in range(n):
                si = int(pl[i, 4])
                d, mx, my, mz = shape_distance(S, T, C, xpos, xmat, si, x, y, z)
                if d - r <= LIFT_TOL:
                    for k in range(PLANE_WIDTH):
                        kept[nk, k] = pl[i, k]
                    nk += 1
                    continue
                lifted = True
                dup = False
                for q in range(nk):
                    if int(kept[q, 4]) == si:
                        dup = True
                        break
                if not dup:
                    kept[nk, 0], kept[nk, 1], kept[nk, 2] = mx, my, mz
                    kept[nk, 3] = mx * x + my * y + mz * z - (d - r)
                    kept[nk, 4] = si
                    nk += 1
            if not lifted:
                on_surfaces = True
                break
            g.rounding = True
            if nwarm > 0:
                return True, x, y, z, hx, hy, hz, straight, 0
            straight = False
            for i in range(nk):
                for k in range(PLANE_WIDTH):
                    pl[i, k] = kept[i, k]
            n = nk
            found, qx, qy, qz = _project(gx, gy, gz, pl, n)
            if not found:
                break
            tx, ty, tz = qx, qy, qz
            following = True
            continue
        x, y, z = x + lam * dx, y + lam * dy, z + lam * dz
        if not has_first:
            has_first = True
            hx, hy, hz = x, y, z
        else:
            straight = False
        n = _add_plane(pl, n, nx, ny, nz, nx * x + ny * y + nz * z, s)
        found, qx, qy, qz = _project(gx, gy, gz, pl, n)
        if not found:
            break
        tx, ty, tz = qx, qy, qz
    if following:  # the budget ran out just after a lift: straight toward the goal, as in Python
        dx, dy, dz = gx - x, gy - y, gz - z
        hit, lam, nx, ny, nz, s = _sweep(S, T, C, xpos, xmat, g, near, x, y, z, dx, dy, dz, pl, 0)
        if not hit:
            x, y, z = gx, gy, gz
        else:
            x, y, z = x + lam * dx, y + lam * dy, z + lam * dz
            if not has_first:
                has_first = True
                hx, hy, hz = x, y, z
            n = _add_plane(pl, n, nx, ny, nz, nx * x + ny * y + nz * z, s)
    nr = 0
    for i in range(n):
        if _rests_on(S, T, C, xpos, xmat, g, pl, i, x, y, z, on_surfaces):
            for k in range(PLANE_WIDTH):
                pl[nr, k] = pl[i, k]
            nr += 1
        elif nwarm > 0 and abs(pl[i, 0] * x + pl[i, 1] * y + pl[i, 2] * z - pl[i, 3]) <= LIFT_TOL:
            return True, x, y, z, hx, hy, hz, straight, 0
    if not has_first:
        hx, hy, hz = x, y, z
    return False, x, y, z, hx, hy, hz, straight, nr


@njit(cache=True)
def _move(S, T, C, xpos, xmat, g, near, x, y, z, gx, gy, gz, warm, nwarm, pl, kept):
    """`GodObject._move`: (x, y, z, hx, hy, hz, straight, n), resting planes in pl[:n]."""
    restart, ex, ey, ez, hx, hy, hz, straight, n = _move_once(S, T, C, xpos, xmat, g, near, x, y, z, gx, gy, gz,
                                                              warm, nwarm, pl, kept)
    if restart:  # what the warm start assumed no longer holds: solve again from no planes
        restart, ex, ey, ez, hx, hy, hz, straight, n = _move_once(S, T, C, xpos, xmat, g, near, x, y, z, gx, gy, gz,
                                                                  warm, 0, pl, kept)
    return ex, ey, ez, hx, hy, hz, straight, n


@njit(cache=True)
def update(S, T, C, xpos, xmat, g, near, xd, yd, zd, pl, saved, warm, kept):
    """`GodObject.update`: move the proxy toward the device position (m, world).

    pl, saved, warm, kept: scratch plane lists of PLANE_ROOM rows. False on garbage input
    (the proxy then only follows its body)."""
    if not (-WORKSPACE_LIMIT < xd < WORKSPACE_LIMIT and -WORKSPACE_LIMIT < yd < WORKSPACE_LIMIT
            and -WORKSPACE_LIMIT < zd < WORKSPACE_LIMIT):
        follow(S, T, C, xpos, xmat, g, near)
        return False
    x, y, z = _settle(S, T, C, xpos, xmat, g, near, xd, yd, zd, False)
    if g.sticking and g.x == x and g.y == y and g.z == z \
            and _still_stuck(S, T, C, xpos, xmat, g, near, xd, yd, zd, pl):
        return True
    x, y, z = g.x, g.y, g.z
    nwarm = _warm_planes(S, T, C, xpos, xmat, g, x, y, z, warm)
    fx, fy, fz, hx, hy, hz, straight, n = _move(S, T, C, xpos, xmat, g, near, x, y, z, xd, yd, zd, warm, nwarm, pl, kept)
    if n == 0:
        g.nplanes = 0
        g.x, g.y, g.z = fx, fy, fz
        g.contact = False
        g.touched = -1
        g.depth = 0.0
        g.sticking = False
        return True

    ex, ey, ez = fx - xd, fy - yd, fz - zd
    depth = math.sqrt(ex * ex + ey * ey + ez * ez)
    if depth > 0.0:
        nx, ny, nz = ex / depth, ey / depth, ez / depth
    else:
        nx, ny, nz = pl[n - 1, 0], pl[n - 1, 1], pl[n - 1, 2]
    best = int(pl[0, 4]) if n == 1 else _touched(pl, n, nx, ny, nz)

    sx, sy, sz = hx - fx, hy - fy, hz - fz
    slide = math.sqrt(sx * sx + sy * sy + sz * sz)
    sticking = slide <= g.mu_s * depth
    _store_planes(g, pl, n)
    if sticking:
        fx, fy, fz = hx, hy, hz
        if slide > 0.0:
            _keep_resting(S, T, C, xpos, xmat, g, saved, 0, pl, n, hx, hy, hz)
    elif g.mu_d > 0.0 and slide > 0.0:
        back = g.mu_d * depth / slide
        tx, ty, tz = fx + back * sx, fy + back * sy, fz + back * sz
        if straight:
            fx, fy, fz = tx, ty, tz
        else:
            for j in range(n):  # the frictionless solve's planes, kept aside
                for k in range(PLANE_WIDTH):
                    saved[j, k] = pl[j, k]
            fx, fy, fz, _, _, _, _, m = _move(S, T, C, xpos, xmat, g, near, hx, hy, hz, tx, ty, tz, warm, 0, pl, kept)
            _keep_resting(S, T, C, xpos, xmat, g, pl, m, saved, n, fx, fy, fz)
    g.x, g.y, g.z = fx, fy, fz
    g.contact = True
    g.nx, g.ny, g.nz = nx, ny, nz
    g.depth = depth
    g.sticking = sticking
    g.touched = best
    if not S[best].static:
        g.lx, g.ly, g.lz = shape_to_local(S, xpos, xmat, best, fx, fy, fz)
    return True


def scratch() -> np.ndarray:
    """Four scratch plane lists for `update` (allocated once per engine, not per tick)."""
    return np.zeros((4, PLANE_ROOM, PLANE_WIDTH))


# -- entries for the views (`softproxy.proxy.GodObject`): finger i of a table ------------------
@njit(cache=True)
def reset_row(S, T, C, xpos, xmat, F, near, i, x, y, z):
    return reset(S, T, C, xpos, xmat, F[i], near[i], x, y, z)


@njit(cache=True)
def update_row(S, T, C, xpos, xmat, F, near, i, xd, yd, zd, scratch):
    return update(S, T, C, xpos, xmat, F[i], near[i], xd, yd, zd, scratch[0], scratch[1], scratch[2], scratch[3])


@njit(cache=True)
def follow_row(S, T, C, xpos, xmat, F, near, i):
    follow(S, T, C, xpos, xmat, F[i], near[i])
