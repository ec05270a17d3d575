"""The god-object solver (numba): the engine's 3-DOF proxy, kept outside every shape.

Each tick the proxy moves from where it was toward the device position x_d (Zilles &
Salisbury's god-object, Ruspini's proxy): a sphere of radius r swept against every shape
(`softproxy.compiled.shapes`), stopping at the first surface it moves into, then sliding on
up to three constraint planes — faces, edges, corners and concave creases — all within one
tick. A plane the proxy slides off (a curved shape's tangent plane, a rounded edge's, a
face's past the face's edge) is replaced by the shape's tangent plane under the proxy; when
the tick's MAX_ITERATIONS sweeps run out just after such a lift (a jump of centimetres deep
into a curved surface), one more sweep straight toward the device puts the proxy back on
the surface, in contact, rather than leaving it microns above with no force for a tick.
Every sweep stays inside the ball whose shapes the tick's broad phase gathered. Friction is
the proxy literature's friction cone with a slip state: a stuck proxy stays put while the
device stays inside the static cone (tangential offset <= μ_s × penetration), otherwise it
slips, to the edge of the dynamic cone (μ_d × penetration). A slipping proxy stays in
dynamic friction, trailing the device at the dynamic cone's edge, until the motion stops
(it takes longer than `slide_restick` s to slide a further RESTICK_TRAVEL of its offset) or
reverses (its offset along the way it slid falls below RESTICK_FRACTION × the dynamic
cone), as CHAI3D's finger proxy keeps its slip state and re-sticks below a fraction of the
dynamic cone's angle. Without it (the
literature's per-tick test, `slide_restick` = 0) a steady slide sticks and slips every few
ticks: the lag saw-tooths between the two cones. Details and figures: docs/friction.md.
The touched geom (its body gets the reaction -F and carries the proxy) is chosen where the
proxy ends the tick, among the shapes within TOUCH_TOL of it: the one whose surface normal
there is most aligned with the force, the nearer of two alike (a seam of coplanar faces);
never a neighbour the frictionless solve reached across a seam while friction held the proxy
back. A slipping proxy whose dynamic-cone point lies in free space (the chord across an edge)
is dropped from there toward the device onto the surface below. The proxy is kept in the
frame of the geom it touches, so a moving object carries it; an object that moves into it
pushes it out, never through a static surface: caught in a gap narrower than itself, the
proxy is `squeezed` and rests on the static side (`push_out`).

These kernels are the only god-object: `softproxy.proxy.GodObject` is a view of a finger's
records that calls the `*_row` entries at the end, and `softproxy.compiled.finger` calls
`update` / `follow` / `reset` inside the tick.

State: `fm` and `fd` are the finger's model and data (`layout.FINGER_MODEL`: its radius and
friction; `FINGER_DATA`: the proxy, its planes and contact), `near` its row of the broad phase's
shape list; shapes are rows of the table `S` (a mesh's triangles and grid in the tables `T`
and `C`), posed by MuJoCo's `geom_xpos` / `geom_xmat`. A list of constraint planes is an
(n, 6) array of rows (nx, ny, nz, c, shape row, triangle) plus a count; a plane keeps the
proxy's centre in {y: n·y >= c}, and on a mesh names the triangle it came from, whose
distance tells whether the plane's own feature is still under the proxy. Units: m.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.finite import finite
from softproxy.compiled.kernel import kernel
from softproxy.compiled.material import plane_friction, shape_friction
from softproxy.compiled.layout import GEOM_MESH, PLANE_NORMAL, PLANE_OFFSET, PLANE_ROW, PLANE_SHAPE, PLANE_WIDTH
from softproxy.compiled.shapes import (shape_distance, shape_feature, shape_feature_distance, shape_on_face, shape_sweep,
                                       shape_to_local, shape_to_world, shape_walk_distance)
from softproxy.compiled.tolerances import CONTACT_TOL, GRAZE

MAX_ITERATIONS = 10
"""Sweeps per solve: three for a corner, a few more to follow a curved surface."""
LIFT_TOL = 1e-7
"""After sliding along a constraint plane (a curved shape's or a rounded edge's tangent plane,
a face's plane past the face's edge), re-follow the surface when the proxy has lifted off
the real shape by more than this (m); a proxy this far off a plane no longer rests on it."""
PARALLEL = 1.0 - 1e-9
"""Normals this aligned (cosine) are the same plane's (a plane met again, a face held)."""
WORKSPACE_LIMIT = 1e3
"""A device position farther than this from the origin on any axis (m) is garbage, like NaN."""

RESTICK_FRACTION = 0.6
"""Both friction laws (this cone, and the torsion in `softproxy.compiled.finger`): a slipping
contact re-sticks when its offset (torque), measured along the way it was slipping, falls
below this fraction of the dynamic limit, i.e. the motion reversed by 40 % of the dynamic
offset. CHAI3D's finger proxy ships the same 0.6, on the cone's angle: a band wide enough for
a device's jitter, narrow enough that a real reversal re-sticks within a few ticks."""
RESTICK_TIME = 0.05
"""Default re-stick time of both friction laws (s): a slipping contact that takes longer than
this to slide a further RESTICK_TRAVEL of its dynamic offset has stopped, and sticks again.
Long against a servo period and the gap between encoder counts of a slow slide; short
against a deliberate pause of the hand (~0.1 s and more). 0 re-tests the static limit every
tick (the seed's eq 39, the proxy literature's cone, as printed)."""
RESTICK_TRAVEL = 0.1
"""Both friction laws: the slide (a fraction of the dynamic offset μ_d·depth, or
μ_d|P|^γ/k_τ) a slipping contact must add up within the re-stick time to count as still
moving: Karnopp's zero-velocity band, |v| < 0.1 × offset / restick_time (1.6 mm/s at
μ_d·depth = 0.8 mm; 6.5 mrad/s for a CH torsion at P = 1 N, k_τ = 2), averaged over the
re-stick time so that a device's counts, a force's noise (which moves a slipping proxy a
bounded amount, on new extremes only) and rounding do not keep a stopped contact slipping."""
RESTICK_SPEED, RESTICK_SPIN = 3e-4, 3e-3
"""Slide (m/s) and spin (rad/s): the zero-velocity band's upper bound, whatever the
offset. RESTICK_TRAVEL alone scales the band with the dynamic offset, which grows with the
depth and the grip: at 10 N a CH torsion's band reached 69 mrad/s and a steady twist at
20-50 mrad/s stuck and slipped a dozen times in 5 s with a 40 % torque ripple; a slide 2 mm
deep re-stuck below 2 mm/s. A slipping contact now stays slipping while it slides at least
the smaller of the two: down to 0.3 mm/s and 3 mrad/s at any grip (docs/friction.md)."""


Move = namedtuple("Move", "x y z hx hy hz straight planes")
"""Where a constrained move ended (`_move`): the end point (m), the first surface point it
reached (or the end point), whether the way from that first point to the end was one straight
swept segment (any point on it is reachable), and how many planes it rests on at the end."""

@kernel
def restick_travel(offset_travel, speed, restick_time):
    """The slide a slipping contact must add up within its re-stick time to count as still
    moving: RESTICK_TRAVEL of its dynamic offset (`offset_travel`), or `speed` (RESTICK_SPEED,
    RESTICK_SPIN) for the re-stick time, whichever is smaller (m or rad)."""
    band = speed * restick_time
    return offset_travel if offset_travel < band else band


SQUEEZE_TOL = 1e-6
"""A proxy still this far inside a moving shape once it is out of every static one (m) is
squeezed between them: no position is out of both."""
TOUCH_TOL = 1e-6
"""A proxy sphere within this distance (m) of a shape's surface touches it, for choosing the
touched shape: ten times LIFT_TOL (the farthest a resting proxy sits off what it rests on),
far below the gap to a neighbour across a seam (a tenth of a millimetre and more)."""
SAME_NORMAL = 1e-9
"""Two shapes' normals at the proxy whose cosines with the force's direction differ by no
more than this carry the force alike (coplanar faces at a seam): the nearer shape is touched."""

PLANE_ROOM = 8
"""Rows of a scratch plane list: three planes, plus the ones `_keep_resting` adds before it
keeps the last three."""
SLIDE_HITS = 4
"""Slides in one move after which the proxy is taken to where sliding ends (`_rest_nearest`)
when it can be, once: sweeps that hit a mesh (a mesh finer than the proxy asks one per facet
crossed, and the budget of MAX_ITERATIONS ran out millimetres short), or planes that lifted
off any shape (rolling round an edge with the device D below it and just past it, a tangent
plane at a time, each step is (r + D)/r times the last: ten left the force 3° off on a
scan, the proxy 0.2-7 mm short on a box with the device 0.05-1 mm past its edge). Sooner,
and a proxy held in the dents of a scanned sphere (five sweeps) pays three queries a tick
for none."""


@kernel
def plane(pl, i):
    """Plane i of pl: its unit normal and offset (nx, ny, nz, c; the plane is n·x = c, m)."""
    return pl[i, PLANE_NORMAL], pl[i, PLANE_NORMAL + 1], pl[i, PLANE_NORMAL + 2], pl[i, PLANE_OFFSET]


@kernel
def normal(pl, i):
    """Plane i's unit normal (nx, ny, nz)."""
    return pl[i, PLANE_NORMAL], pl[i, PLANE_NORMAL + 1], pl[i, PLANE_NORMAL + 2]


@kernel
def along(pl, i, x, y, z):
    """Plane i's normal dotted with (x, y, z): a point's n·x (m, compared with the offset) or a
    direction's cosine to it."""
    return pl[i, PLANE_NORMAL] * x + pl[i, PLANE_NORMAL + 1] * y + pl[i, PLANE_NORMAL + 2] * z


@kernel
def set_plane(pl, i, nx, ny, nz, c, shape, row):
    """Row i of pl := the plane n·x = c of shape row `shape`, from row `row` of T (-1: none)."""
    pl[i, PLANE_NORMAL], pl[i, PLANE_NORMAL + 1], pl[i, PLANE_NORMAL + 2], pl[i, PLANE_OFFSET] = nx, ny, nz, c
    pl[i, PLANE_SHAPE], pl[i, PLANE_ROW] = shape, row


@kernel
def _load_planes(fd, pl):
    """Copy the finger's planes into the scratch list pl; returns their count."""
    n = int(fd.nplanes)
    for j in range(n):
        for k in range(PLANE_WIDTH):
            pl[j, k] = fd.planes[j, k]
    return n


@kernel
def _newest_three(dst, pl, n):
    """dst := the newest three of pl[:n] (a proxy rests on three at most); returns how many."""
    start = n - 3 if n > 3 else 0
    for j in range(start, n):
        for k in range(PLANE_WIDTH):
            dst[j - start, k] = pl[j, k]
    return n - start


@kernel
def _store_planes(fd, pl, n):
    """The finger's planes := the newest three of pl[:n]."""
    fd.nplanes = _newest_three(fd.planes, pl, n)


@kernel
def _feasible(pl, n, x, y, z, skip0, skip1):
    """True when (x, y, z) is on or above every plane of pl[:n] (within CONTACT_TOL) but
    pl[skip0] and pl[skip1], the ones it was put on."""
    for i in range(n):
        if i != skip0 and i != skip1 and along(pl, i, x, y, z) < pl[i, PLANE_OFFSET] - CONTACT_TOL:
            return False
    return True


@kernel
def _corner(px, py, pz, pl):
    """The point q on all three planes of pl when it is the projection of p, i.e. q - p =
    Σ λ_i n_i with every λ_i >= 0 (each plane pushes, none pulls): (found, qx, qy, qz)."""
    ax, ay, az, ca = plane(pl, 0)
    bx, by, bz, cb = plane(pl, 1)
    cx, cy, cz, cc = plane(pl, 2)
    # the columns of the inverse of N = [a; b; c] (normals as rows) are b × c, c × a, a × b over det N
    ux, uy, uz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    vx, vy, vz = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
    wx, wy, wz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    det = ax * ux + ay * uy + az * uz
    if abs(det) <= 1e-12:
        return False, 0.0, 0.0, 0.0
    # distances to push p along each plane's normal: e_i = c_i - n_i·p; q = p + N⁻¹ e
    ea = ca - (ax * px + ay * py + az * pz)
    eb = cb - (bx * px + by * py + bz * pz)
    ec = cc - (cx * px + cy * py + cz * pz)
    dx = (ux * ea + vx * eb + wx * ec) / det
    dy = (uy * ea + vy * eb + wy * ec) / det
    dz = (uz * ea + vz * eb + wz * ec) / det
    # q - p = Nᵀλ and N q = c give G λ = e with the Gram matrix G = N Nᵀ (unit normals: ones
    # on its diagonal); λ = G⁻¹ e by cofactors, only its signs matter
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


@kernel
def _project_by_enumeration(px, py, pz, pl, n):
    """`_project` by trying active sets of one, two, then three planes in turn: (found, qx, qy, qz)."""
    if _feasible(pl, n, px, py, pz, -1, -1):
        return True, px, py, pz
    for i in range(n):  # one active plane
        nx, ny, nz, c = plane(pl, i)
        lam = c - (nx * px + ny * py + nz * pz)
        if lam > 0.0:
            qx, qy, qz = px + lam * nx, py + lam * ny, pz + lam * nz
            if _feasible(pl, n, qx, qy, qz, i, -1):
                return True, qx, qy, qz
    for i in range(n):  # two active planes: q = p + a n_i + b n_j on both planes, a, b >= 0
        for j in range(i + 1, n):
            ax, ay, az, ci = plane(pl, i)
            bx, by, bz, cj = plane(pl, j)
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
    if n == 3:  # three active planes: the corner point
        ax, ay, az, ca = plane(pl, 0)
        bx, by, bz, cb = plane(pl, 1)
        cx, cy, cz, cc = plane(pl, 2)
        det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        if abs(det) > 1e-12:  # Cramer's rule for N q = c
            qx = (ca * (by * cz - bz * cy) - ay * (cb * cz - bz * cc) + az * (cb * cy - by * cc)) / det
            qy = (ax * (cb * cz - bz * cc) - ca * (bx * cz - bz * cx) + az * (bx * cc - cb * cx)) / det
            qz = (ax * (by * cc - cb * cy) - ay * (bx * cc - cb * cx) + ca * (bx * cy - by * cx)) / det
            return True, qx, qy, qz
    return False, 0.0, 0.0, 0.0


@kernel
def _project(px, py, pz, pl, n):
    """Closest point to p in the intersection of the n <= 3 half-spaces of pl (KKT, active
    sets): (found, qx, qy, qz); not found when the planes admit no point (a degenerate set,
    e.g. opposite parallel faces closer than the proxy's diameter)."""
    if n == 1:  # the common case, a face: inline
        nx, ny, nz, c = plane(pl, 0)
        lam = c - (nx * px + ny * py + nz * pz)
        if lam > 0.0:
            return True, px + lam * nx, py + lam * ny, pz + lam * nz
        return True, px, py, pz
    outside = False
    for i in range(n):
        if along(pl, i, px, py, pz) < pl[i, PLANE_OFFSET] - CONTACT_TOL:
            outside = True
            break
    if not outside:
        return True, px, py, pz
    if n == 3:  # a proxy held in a corner: try the corner first
        found, qx, qy, qz = _corner(px, py, pz, pl)
        if found:
            return True, qx, qy, qz
    return _project_by_enumeration(px, py, pz, pl, n)


@kernel
def _plane_of(pl, n, s, nx, ny, nz):
    """Index in pl[:n] of shape s's plane of normal n (parallel within PARALLEL), or -1."""
    for i in range(n):
        if int(pl[i, PLANE_SHAPE]) == s and along(pl, i, nx, ny, nz) > PARALLEL:
            return i
    return -1


@kernel
def _add_plane(pl, n, nx, ny, nz, c, s, f):
    """Add a constraint plane just hit (shape row s, feature f) to pl[:n]; returns the new
    count. The same plane met again is replaced, not doubled, and the oldest goes when there
    would be four."""
    i = _plane_of(pl, n, s, nx, ny, nz)
    if i >= 0:
        for j in range(i, n - 1):
            for k in range(PLANE_WIDTH):
                pl[j, k] = pl[j + 1, k]
        n -= 1
    set_plane(pl, n, nx, ny, nz, c, s, f)
    n += 1
    if n > 3:
        for j in range(n - 1):
            for k in range(PLANE_WIDTH):
                pl[j, k] = pl[j + 1, k]
        n -= 1
    return n


@kernel
def _touched(pl, n, nx, ny, nz):
    """The touched shape of a proxy resting on all the planes pl[:n] (a corner): the row whose
    plane is most aligned with the force's n, `_touched_at`'s rule."""
    best, best_dot = int(pl[0, PLANE_SHAPE]), -2.0
    for i in range(n):
        dot = along(pl, i, nx, ny, nz)
        if dot > best_dot:
            best, best_dot = int(pl[i, PLANE_SHAPE]), dot
    return best


@kernel
def _touched_at(sh, fm, fd, near, x, y, z, nx, ny, nz, rested):
    """The shape the proxy at (x, y, z) touches, where it ends the tick (the pushed body is
    its body, the proxy is carried in its frame): among the near shapes whose surface is
    within TOUCH_TOL of the sphere, the one whose outward normal there is most aligned with
    the force's direction n, i.e. the constraint that carries the force; on a tie within
    SAME_NORMAL (two flat faces side by side at a seam) the nearer, then the lower row; -1
    when none is within TOUCH_TOL (the proxy floats: `_land`).

    The planes of the frictionless solve do not tell: friction may hold the proxy back on
    one geom while the frictionless proxy went on across a seam onto its neighbour. The
    finger's first `rested` planes are known to rest on their shapes' surfaces at the proxy
    (checked by the solve): their shapes are in touch, their normals the planes', no query."""
    S, xpos = sh.S, sh.xpos
    r = fm.radius
    best, best_dot, best_gap = -1, -2.0, math.inf
    for j in range(int(fd.nnear)):
        s = near[j]
        dot = -2.0
        for i in range(rested):
            if int(fd.planes[i, PLANE_SHAPE]) == s:
                c = along(fd.planes, i, nx, ny, nz)
                if c > dot:
                    dot = c
        if dot > -2.0:  # resting on it (within LIFT_TOL): gap 0
            if dot > best_dot + SAME_NORMAL or (dot >= best_dot - SAME_NORMAL and 0.0 < best_gap):
                best, best_dot, best_gap = s, dot, 0.0
            continue
        k = int(S[s].geom)
        reach = S[s].rbound + r + TOUCH_TOL
        ex, ey, ez = x - xpos[k, 0], y - xpos[k, 1], z - xpos[k, 2]
        if ex * ex + ey * ey + ez * ez > reach * reach:
            continue  # its bounding sphere is out of touch (a plane's never is): no query
        d, mx, my, mz = shape_distance(sh, s, x, y, z)
        gap = d - r
        if gap > TOUCH_TOL:
            continue
        dot = mx * nx + my * ny + mz * nz
        if dot > best_dot + SAME_NORMAL or (dot >= best_dot - SAME_NORMAL and gap < best_gap):
            best, best_dot, best_gap = s, dot, gap
    return best


@kernel
def _nearest(sh, fd, near, x, y, z):
    """The near shape nearest the point (x, y, z) and its answer there: (row, signed distance
    (m), outward normal); row -1 when no shape is near."""
    best, best_d, bx, by, bz = -1, math.inf, 0.0, 0.0, 0.0
    for j in range(int(fd.nnear)):
        s = near[j]
        d, nx, ny, nz = shape_distance(sh, s, x, y, z)
        if d < best_d:
            best, best_d, bx, by, bz = s, d, nx, ny, nz
    return best, best_d, bx, by, bz


@kernel
def _land(sh, fm, fd, near, x, y, z, xd, yd, zd, pl):
    """A proxy in contact that touches no shape at (x, y, z), brought onto a surface: a
    slipping proxy's point on the dynamic cone's edge lies on the chord from where it was
    held to the frictionless proxy, and across a convex edge or a step down that chord runs
    in free space (up to the step's height off every surface). The proxy is swept from there
    toward the device, which lies inside the constraint, onto the first surface it meets, so
    it ends touching the shape it pushes. pl: a scratch plane list. Returns the position."""
    dx, dy, dz = xd - x, yd - y, zd - z
    hit, lam, _, _, _, _ = _sweep(sh, fm, fd, near, x, y, z, dx, dy, dz, pl, 0)
    if hit:
        return x + lam * dx, y + lam * dy, z + lam * dz
    return x, y, z


@kernel
def _on_static_faces(S, xmat, pl, n):
    """True when every plane is a planar face of a shape that never moves: such a plane holds
    from tick to tick for as long as the proxy touches the face."""
    for i in range(n):
        s = int(pl[i, PLANE_SHAPE])
        if not (S[s].static and shape_on_face(S, xmat, s, *normal(pl, i))):
            return False
    return True


@kernel
def gather_ball(sh, fm, fd, near, cx, cy, cz, room):
    """near: every shape the proxy can touch while its centre stays within `room` (m) of c,
    the shapes whose bounding sphere meets the ball of radius room + r (a plane: when the
    ball reaches its surface). The ball is kept (bx, by, bz, room): a sub-move that would
    leave it widens it first."""
    S, xpos, xmat = sh.S, sh.xpos, sh.xmat
    fd.ball[0], fd.ball[1], fd.ball[2], fd.ball_room = cx, cy, cz, room
    reach = room + fm.radius
    count = 0
    popped = fd.popped  # a shape the finger popped through is not there for it until it is out
    for s in range(S.shape[0]):
        if s == popped:
            continue
        k = int(S[s].geom)
        rb = S[s].rbound + reach
        if rb == math.inf:  # a plane: near when the ball reaches its surface
            if xmat[k, 2] * (cx - xpos[k, 0]) + xmat[k, 5] * (cy - xpos[k, 1]) + xmat[k, 8] * (cz - xpos[k, 2]) <= reach:
                near[count] = s
                count += 1
            continue
        dx, dy, dz = xpos[k, 0] - cx, xpos[k, 1] - cy, xpos[k, 2] - cz
        if dx * dx + dy * dy + dz * dz <= rb * rb:
            near[count] = s
            count += 1
    fd.nnear = count


@kernel
def _push_out_of(sh, fm, fd, near, static):
    """One pass: the proxy out of every shape of `near` that is static (or moving) it overlaps,
    to CONTACT_TOL outside. True when it moved."""
    S = sh.S
    r = fm.radius
    moved = False
    for j in range(int(fd.nnear)):
        s = near[j]
        if S[s].static != static:
            continue
        d, nx, ny, nz = shape_distance(sh, s, fd.pos[0], fd.pos[1], fd.pos[2])
        gap = d - r
        if gap < 0.0:
            push = -gap + CONTACT_TOL
            fd.pos[0] += push * nx
            fd.pos[1] += push * ny
            fd.pos[2] += push * nz
            moved = True
    return moved


@kernel
def push_out(sh, fm, fd, near):
    """Move the proxy out of any shape of `near` it overlaps (an object moved into it), to
    CONTACT_TOL outside: out of the moving shapes, then out of the static ones, a few rounds
    (a push out of one shape can push into another). The static shapes have the last word: a
    moving object never pushes the proxy through a static surface. Where no position is out
    of both (a gap narrower than the proxy) the proxy stays on the static side and the finger
    is `squeezed`; while it is, the moving shape does not push it at all (out through its far
    side would be a jump of its whole thickness), until it has moved off the proxy."""
    S = sh.S
    was = fd.squeezed
    for _ in range(4):
        moved = False if was else _push_out_of(sh, fm, fd, near, False)
        moved = _push_out_of(sh, fm, fd, near, True) or moved
        if not moved:
            break
    fd.squeezed = False
    for j in range(int(fd.nnear)):
        s = near[j]
        if not S[s].static and shape_distance(sh, s, fd.pos[0], fd.pos[1], fd.pos[2])[0] - fm.radius < -SQUEEZE_TOL:
            fd.squeezed = True
            fd.squeeze_ticks += 1
            return


@kernel(inline="always")
def let_go(fd):
    """The proxy touches nothing: no contact, no touched shape, no planes, no depth, no stick
    (where it is stays: `pos` is the caller's)."""
    fd.contact = False
    fd.touched = -1
    fd.nplanes = 0
    fd.nfree = 0
    fd.depth = 0.0
    fd.sticking = False


@kernel
def _rest_squeezed(sh, fd, near, xd, yd, zd):
    """A squeezed proxy (`push_out`) rests where the static surfaces put it, in contact with
    the nearest static shape: the finger renders that surface's spring force (never into it),
    held, no sweep through the moving object that overlaps it."""
    S = sh.S
    best, bd, bnx, bny, bnz = -1, math.inf, 0.0, 0.0, 0.0
    for j in range(int(fd.nnear)):
        s = near[j]
        if S[s].static:
            d, nx, ny, nz = shape_distance(sh, s, fd.pos[0], fd.pos[1], fd.pos[2])
            if d < bd:
                best, bd, bnx, bny, bnz = s, d, nx, ny, nz
    fd.free_pos[:] = fd.pos
    fd.nfree = 0
    if best < 0:  # squeezed against no static shape: not expected (only a static one pushes last)
        let_go(fd)
        return
    fd.contact = True
    fd.touched = best
    fd.normal[:] = bnx, bny, bnz
    depth = (fd.pos[0] - xd) * bnx + (fd.pos[1] - yd) * bny + (fd.pos[2] - zd) * bnz
    fd.depth = depth if depth > 0.0 else 0.0
    fd.sticking = True
    fd.nplanes = 1
    set_plane(fd.planes, 0, bnx, bny, bnz, bnx * fd.pos[0] + bny * fd.pos[1] + bnz * fd.pos[2], best, -1.0)


@kernel
def reset(sh, fm, fd, near, x, y, z):
    """Put the proxy at (x, y, z) with no contact, every shape near (none popped through),
    pushed out of any it overlaps; False (nothing changed) for a position outside the workspace."""
    S = sh.S
    if not (-WORKSPACE_LIMIT < x < WORKSPACE_LIMIT and -WORKSPACE_LIMIT < y < WORKSPACE_LIMIT
            and -WORKSPACE_LIMIT < z < WORKSPACE_LIMIT):
        return False
    fd.pos[:] = x, y, z
    fd.contact = False
    fd.normal[:] = 0.0
    fd.touched = -1
    fd.depth = 0.0
    fd.sticking = False
    fd.slide_idle = 0.0
    fd.local[:] = 0.0
    fd.squeezed = False  # a new place has no past: pushed out of a moving shape as any proxy is
    fd.popped = -1
    for s in range(S.shape[0]):
        near[s] = s
    fd.nnear = S.shape[0]
    push_out(sh, fm, fd, near)
    return True


@kernel
def _settle(sh, fm, fd, near, xd, yd, zd, around_proxy):
    """Carry the proxy with the touched body, gather the shapes near it and the device, push
    it out of any that moved into it. Returns the proxy position before the push."""
    S, xpos, xmat = sh.S, sh.xpos, sh.xmat
    shape = int(fd.touched)
    carrier = -1
    if shape >= 0 and not S[shape].static:
        # carried by the touched object (stored in its frame at the end of last tick)
        carrier = shape
        fd.pos[:] = shape_to_world(S, xpos, xmat, shape, fd.local[0], fd.local[1], fd.local[2])
    x, y, z = fd.pos
    # broad phase: the shapes near the ball that holds both the proxy and the device, with a
    # margin of 1 mm (`_move_once` widens it if a sub-move would leave it)
    if around_proxy:
        gather_ball(sh, fm, fd, near, x, y, z, fm.radius + 1e-3)
    else:
        ex, ey, ez = xd - x, yd - y, zd - z
        gather_ball(sh, fm, fd, near, 0.5 * (x + xd), 0.5 * (y + yd), 0.5 * (z + zd),
                    0.5 * math.sqrt(ex * ex + ey * ey + ez * ez) + fm.radius + 1e-3)
    # Only a moving shape can have come into the proxy, or a static one if the proxy itself
    # was carried; the carrier holds the proxy where it was, outside.
    for j in range(int(fd.nnear)):
        s = near[j]
        if s != carrier and (carrier >= 0 or not S[s].static):
            push_out(sh, fm, fd, near)
            break
    else:
        fd.squeezed = False
    return x, y, z


@kernel
def follow(sh, fm, fd, near):
    """Without a device sample: the proxy stays on the body it touches and out of anything
    that moved into it, so a skipped tick never leaves it inside a moving object."""
    _settle(sh, fm, fd, near, fd.pos[0], fd.pos[1], fd.pos[2], True)


@kernel
def _sweep(sh, fm, fd, near, x, y, z, dx, dy, dz, pl, n):
    """Earliest hit over the near shapes of the sphere moving by (dx, dy, dz): (found, lam,
    nx, ny, nz, shape row).

    pl[:n]: constraint planes that the start and the end of the move both satisfy. A convex
    shape owning one of them lies behind it, so a move on or above it cannot enter the shape:
    it is not swept (a slide along a face or a tangent plane sweeps only the other shapes)."""
    S = sh.S
    r = fm.radius
    found = False
    best_lam, bnx, bny, bnz, bs = 1.0, 0.0, 0.0, 0.0, -1
    for j in range(int(fd.nnear)):
        s = near[j]
        if S[s].convex:
            behind = False
            for i in range(n):
                if int(pl[i, PLANE_SHAPE]) == s:
                    behind = True
                    break
            if behind:
                continue
        lam, nx, ny, nz = shape_sweep(sh, s, x, y, z, dx, dy, dz, r)
        if lam >= 0.0 and lam < best_lam:
            found = True
            best_lam, bnx, bny, bnz, bs = lam, nx, ny, nz, s
    return found, best_lam, bnx, bny, bnz, bs


@kernel
def _rests_on(sh, fm, fd, pl, i, x, y, z, on_surface):
    """True when the proxy at (x, y, z) still rests on plane pl[i] and on its shape's real
    surface, both within LIFT_TOL (m): a plane runs on past a face's edge, a curved shape
    falls away from its tangent plane, and a point friction held back short of the plane (on
    a rounded edge below a face's plane) does not rest on it. `on_surface`: the shape's
    surface is known to be under the proxy already, or its own triangle is (a mesh's)."""
    S, T, xpos, xmat = sh.S, sh.T, sh.xpos, sh.xmat
    nx, ny, nz, c = plane(pl, i)
    if not abs(nx * x + ny * y + nz * z - c) <= LIFT_TOL:
        return False
    if on_surface:
        return True
    s, f = int(pl[i, PLANE_SHAPE]), int(pl[i, PLANE_ROW])
    if f >= 0 and shape_feature_distance(S, T, xpos, xmat, s, f, x, y, z)[0] - fm.radius <= LIFT_TOL:
        return True
    return shape_distance(sh, s, x, y, z)[0] - fm.radius <= LIFT_TOL


@kernel
def _keep_resting(sh, fm, fd, resting, nr, pl, n, x, y, z):
    """After friction held the proxy back from the frictionless end: the planes it rests on
    at (x, y, z), resting[:nr] (those a slide itself ran into) plus those of pl[:n] (the
    frictionless solve's) it still touches, on their real surfaces, not past an edge. The
    newest three become the finger's planes: what the next tick's warm start builds on."""
    for i in range(n):
        if _rests_on(sh, fm, fd, pl, i, x, y, z, False) and \
                _plane_of(resting, nr, int(pl[i, PLANE_SHAPE]), *normal(pl, i)) < 0:
            for k in range(PLANE_WIDTH):
                resting[nr, k] = pl[i, k]
            nr += 1
    _store_planes(fd, resting, nr)


@kernel
def _still_in_corner(sh, fd, xd, yd, zd, pl, n):
    """`_still_stuck` in a corner of three static faces: holds while projecting the device
    onto the three planes gives the corner point, where the proxy is (every plane pushes)."""
    S, xmat = sh.S, sh.xmat
    if not _on_static_faces(S, xmat, pl, n):
        return False
    found, qx, qy, qz = _corner(xd, yd, zd, pl)
    x, y, z = fd.pos
    if not found or abs(qx - x) + abs(qy - y) + abs(qz - z) > 1e-12:
        return False
    ex, ey, ez = x - xd, y - yd, z - zd
    depth = math.sqrt(ex * ex + ey * ey + ez * ez)
    if depth == 0.0:
        return False
    nx, ny, nz = ex / depth, ey / depth, ez / depth
    best = _touched(pl, n, nx, ny, nz)
    fd.normal[:] = nx, ny, nz
    fd.depth = depth
    fd.touched = best  # a static face: nothing carries the proxy
    return True


@kernel
def _still_stuck(sh, fm, fd, near, xd, yd, zd, pl):
    """Fast path of the hold: a stuck proxy that stays stuck, on one flat face or pinned in a
    corner of three static faces; True when it does (n, depth and planes updated).

    What the full solve would find, for a fraction of its cost. On a face: the proxy does not
    move, the frictionless proxy f is the device projected onto the face (checked to lie on
    the same face, the way there clear of every other shape), and the cone test passes. In a
    corner: the device pushes into all three faces, so f is the corner, where the proxy
    already is."""
    S = sh.S
    n = _load_planes(fd, pl)
    if n == 3:
        return _still_in_corner(sh, fd, xd, yd, zd, pl, n)
    shape = int(fd.touched)
    if n != 1 or not S[shape].planar:
        return False
    x, y, z, r = fd.pos[0], fd.pos[1], fd.pos[2], fm.radius
    d, nx, ny, nz = shape_distance(sh, shape, x, y, z)
    if abs(d - r) > 1e-7:
        return False
    depth = nx * (x - xd) + ny * (y - yd) + nz * (z - zd)
    if depth <= 0.0:
        return False
    fx, fy, fz = xd + depth * nx, yd + depth * ny, zd + depth * nz
    df, mx, my, mz = shape_distance(sh, shape, fx, fy, fz)
    if abs(df - d) > 1e-9 or nx * mx + ny * my + nz * mz < PARALLEL:
        return False
    sx, sy, sz = x - fx, y - fy, z - fz
    if sx * sx + sy * sy + sz * sz > (shape_friction(sh, fm, shape, x, y, z)[0] * depth) ** 2:
        return False
    for j in range(int(fd.nnear)):  # an obstacle on the face between the proxy and f changes f
        s = near[j]
        if s != shape and shape_sweep(sh, s, x, y, z, fx - x, fy - y, fz - z, r)[0] >= 0.0:
            return False
    set_plane(fd.planes, 0, nx, ny, nz, nx * x + ny * y + nz * z, shape, -1.0)
    fd.nplanes = 1
    fd.normal[:] = nx, ny, nz
    fd.depth = depth
    return True


@kernel
def _warm_planes(sh, fm, fd, x, y, z, warm):
    """Last tick's planes to start the solve from, into warm; returns their count (0: solve
    cold), when every one belongs to a static shape.

    A proxy resting on a face, an edge or a corner keeps resting on the same shapes from tick
    to tick: starting from their planes saves a sweep per plane. A planar face's plane is kept
    as it was; a convex shape's plane elsewhere (a rounded edge or corner, a curved surface)
    is its tangent plane under the proxy now, one distance query, unless the last solve slid
    round a curve (it would lift off again). A static mesh's plane (a triangle's, or the
    tangent plane at its edge or vertex) is kept as it was while the proxy is stuck and on it
    (a proxy in a pocket of a scanned surface rests on three, a sweep each to find again);
    a sliding proxy crosses facets and would lift off them. A plane may run on past the
    shape's surface: a proxy that lifts off one (past a face's edge, round a curve) is solved
    again from no planes (`_move`), so a warm start ends where the cold solve ends. Never
    unsafe either way: every motion is still swept."""
    S, xmat = sh.S, sh.xmat
    n = int(fd.nplanes)
    count = 0
    for j in range(n):
        p = fd.planes[j]
        s = int(p[PLANE_SHAPE])
        if not S[s].static:
            return 0
        if shape_on_face(S, xmat, s, *normal(fd.planes, j)):
            for k in range(PLANE_WIDTH):
                warm[count, k] = p[k]
            count += 1
            continue
        if fd.rounding:  # sliding round a curve: a warm start would lift
            return 0
        if not S[s].convex:
            # a static mesh's plane, while the proxy is stuck and still on it
            if not fd.sticking or abs(along(fd.planes, j, x, y, z) - fd.planes[j, PLANE_OFFSET]) > LIFT_TOL:
                return 0
            for k in range(PLANE_WIDTH):
                warm[count, k] = p[k]
            count += 1
            continue
        d, nx, ny, nz = shape_distance(sh, s, x, y, z)
        if d - fm.radius > LIFT_TOL:
            return 0
        # (a box's face and its rounded edge at their seam give one plane; its offset is taken
        # through the proxy in _move_once)
        if count == 0 or _plane_of(warm, count, s, nx, ny, nz) < 0:
            warm[count, 0], warm[count, 1], warm[count, 2], warm[count, 3], warm[count, 4] = nx, ny, nz, 0.0, s
            warm[count, 5] = shape_feature(S, s)
            count += 1
    return count


@kernel
def _free_from_last(sh, fm, fd, near, xd, yd, zd, warm):
    """Last tick's frictionless proxy's planes, to solve this tick's frictionless proxy from
    there, into warm; returns their count (0: solve from the proxy) and the proxy's gap (m)
    to the surface it touches, within TOUCH_TOL (the chord of a slide back to the dynamic
    cone floats up to that over a concave patch: `update` then sweeps it down first).

    A proxy on a static mesh is tested against the frictionless proxy, where sliding from it
    ends: over a scanned surface a few facets away, one sweep per facet (five a tick at a
    million triangles). The proxy and last tick's frictionless proxy were both reached from
    last tick's proxy through free space, and nothing near has moved since, so sliding on
    from there is a way the proxy could slide too: the solve starts there, on the planes
    the device presses into (a plane it pulls away from is left behind: the sweeps meet its
    surface again if it is in the way), while the device presses into one at least and into
    the surface at the proxy (which is then where the proxy touches first, as a sweep from
    it would find)."""
    S, T, xpos, xmat = sh.S, sh.T, sh.xpos, sh.xmat
    n = int(fd.nfree)
    if n == 0 or not fd.contact or fd.touched < 0:
        return 0, 0.0
    # its own planes first: on a primitive (convex) the first one says no
    fx, fy, fz, r = fd.free_pos[0], fd.free_pos[1], fd.free_pos[2], fm.radius
    m = 0
    for j in range(n):
        p = fd.free_planes[j]
        s, f = int(p[PLANE_SHAPE]), int(p[PLANE_ROW])
        if S[s].convex:
            return 0, 0.0
        for k in range(PLANE_WIDTH):
            warm[m, k] = p[k]
        if f >= 0:
            # its triangle's tangent plane where the frictionless proxy is now: a plane found
            # at an edge or a vertex lifts off it within ~30 µm of sliding round it (r = 5 mm),
            # a fresh mesh query each time
            d, mx, my, mz = shape_feature_distance(S, T, xpos, xmat, s, f, fx, fy, fz)
            if d - r <= LIFT_TOL:
                warm[m, 0], warm[m, 1], warm[m, 2] = mx, my, mz
                warm[m, 3] = mx * fx + my * fy + mz * fz - (d - r)
        # a plane the device no longer presses into is left behind (a crease along a curved
        # wall the device pulls away from): the sweeps from there meet it if it is in the way
        if warm[m, 0] * xd + warm[m, 1] * yd + warm[m, 2] * zd < warm[m, 3]:
            m += 1
    if m == 0:
        return 0, 0.0
    for j in range(int(fd.nnear)):
        if not S[near[j]].static:
            return 0, 0.0
    x, y, z = fd.pos
    d, nx, ny, nz = shape_distance(sh, int(fd.touched), x, y, z)
    if d - fm.radius > TOUCH_TOL or nx * (xd - x) + ny * (yd - y) + nz * (zd - z) >= 0.0:
        return 0, 0.0
    return m, d - fm.radius


@kernel
def _arrives(sh, fm, fd, near, x, y, z, dx, dy, dz, pl):
    """True when a sweep by (dx, dy, dz) (m) from (x, y, z) meets nothing before its end,
    where it may arrive touching (within LIFT_TOL); never for a way with NaN or inf in it."""
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not finite(abs(x) + abs(y) + abs(z) + length):
        return False
    hit, lam, _, _, _, _ = _sweep(sh, fm, fd, near, x, y, z, dx, dy, dz, pl, 0)
    return not hit or (1.0 - lam) * length <= LIFT_TOL


@kernel
def _clear_way(sh, fm, fd, near, x, y, z, px, py, pz, nx, ny, nz, pl):
    """True when the proxy can move from (x, y, z), on the surface, to (px, py, pz), resting
    on it with outward normal n there, through free space: straight, or over the arc.

    Over a convex patch the straight way dips under the surface: by (L/2)·tan(θ/4) on the
    circle through both ends with their normals θ apart (L the chord), by microns where the
    proxy rolls round an edge toward the facet beyond. The way over lifts each end by
    twice that along its normal first, three sweeps: it crosses no rise higher than the
    arc's own, and no surface (every leg is swept)."""
    dx, dy, dz = px - x, py - y, pz - z
    if _arrives(sh, fm, fd, near, x, y, z, dx, dy, dz, pl):
        return True
    s, _, mx, my, mz = _nearest(sh, fd, near, x, y, z)
    c = min(mx * nx + my * ny + mz * nz, 1.0)  # (unit normals: a hair over 1 by rounding)
    if s < 0 or c <= 0.0:
        return False
    # twice (L/2)·tan(θ/4), from c = cos θ: tan(θ/4) = t / (1 + √(1 + t²)), t = tan(θ/2) = √((1 - c)/(1 + c))
    t2 = math.sqrt((1.0 - c) / (1.0 + c))
    lift = math.sqrt(dx * dx + dy * dy + dz * dz) * t2 / (1.0 + math.sqrt(1.0 + t2 * t2)) + LIFT_TOL
    ux, uy, uz = x + lift * mx, y + lift * my, z + lift * mz
    vx, vy, vz = px + lift * nx, py + lift * ny, pz + lift * nz
    return _arrives(sh, fm, fd, near, x, y, z, ux - x, uy - y, uz - z, pl) \
        and _arrives(sh, fm, fd, near, ux, uy, uz, vx - ux, vy - uy, vz - uz, pl) \
        and _arrives(sh, fm, fd, near, vx, vy, vz, px - vx, py - vy, pz - vz, pl)


@kernel
def _rest_nearest(sh, fm, fd, near, x, y, z, gx, gy, gz, pl):
    """The end of a move toward the goal g (m, world) from (x, y, z), when it is the position
    r off the surface point q nearest the goal, along the normal there: (found, the
    position), and the plane it rests on (q's tangent plane) in pl[0] when found.

    No free position lies nearer the goal than r - d(goal) (r + |d| inside a solid), and this
    one does when the sphere there overlaps nothing, so it is where sliding ends; taken when,
    besides, the way to it is clear (`_clear_way`: no pop-through). On a mesh finer than the
    proxy the sliding solve asks a sweep per facet crossed (ten a millimetre on a concave
    patch of 0.14 mm triangles), and rolling round an edge it creeps (SLIDE_HITS): this asks
    a distance at the goal, one to four sweeps and a distance at the end. A corner (the end
    overlaps another shape) is left to sliding."""
    S = sh.S
    r = fm.radius
    s, d, nx, ny, nz = _nearest(sh, fd, near, gx, gy, gz)
    if s < 0 or d >= r:
        return False, x, y, z
    f = shape_feature(S, s)  # before the sweep below queries s again
    px, py, pz = gx + (r - d) * nx, gy + (r - d) * ny, gz + (r - d) * nz
    ex, ey, ez = px - fd.ball[0], py - fd.ball[1], pz - fd.ball[2]
    if ex * ex + ey * ey + ez * ez > fd.ball_room * fd.ball_room:  # past the shapes gathered
        return False, x, y, z
    if not _clear_way(sh, fm, fd, near, x, y, z, px, py, pz, nx, ny, nz, pl):
        return False, x, y, z
    for j in range(int(fd.nnear)):
        if shape_distance(sh, near[j], px, py, pz)[0] - r < -LIFT_TOL:
            return False, x, y, z
    set_plane(pl, 0, nx, ny, nz, nx * px + ny * py + nz * pz, s, f)
    return True, px, py, pz


@kernel
def _move_once(sh, fm, fd, near, x, y, z, gx, gy, gz, warm, nwarm, pl, kept, follow_lifts):
    """Constrained motion from (x, y, z) toward (gx, gy, gz), starting from the planes
    warm[:nwarm] the proxy rests on (none: cold). Returns (restart, Move): restart when what
    a warm start assumed no longer holds (`_move` solves again cold); otherwise where the
    move ended (a `Move`), the planes the proxy rests on at the end in pl[:Move.planes].
    `follow_lifts`: a warm start's plane that lifts is followed on as a cold solve follows
    it, not solved again (the frictionless proxy's solve, which wants only where sliding
    ends, not the first surface point)."""
    S, T, xpos, xmat = sh.S, sh.T, sh.xpos, sh.xmat
    n = 0
    has_first = False
    hx = hy = hz = 0.0
    straight = True
    on_surfaces = False
    fd.rounding = False
    r = fm.radius
    tx, ty, tz = gx, gy, gz
    if nwarm > 0:
        # through the proxy as it is now: it may sit up to LIFT_TOL off a plane's old offset,
        # and a target on the old offset would then lie a hair inside the face
        for j in range(nwarm):
            warm[j, 3] = warm[j, 0] * x + warm[j, 1] * y + warm[j, 2] * z
        # only a device pressing into a plane keeps the proxy on it from the start, by more
        # than a graze of the motion, as a sweep would count it
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
    # a warm start saves the sweeps that would have found its planes, one each, not the budget
    # of those that follow: it ends where a cold solve ends, for less
    bx, by, bz, room2 = fd.ball[0], fd.ball[1], fd.ball[2], fd.ball_room * fd.ball_room
    following = False  # the last sweep slid along a tangent plane that then lifted off
    hits = 0
    for _ in range(MAX_ITERATIONS - n):
        following = False
        dx, dy, dz = tx - x, ty - y, tz - z
        if dx * dx + dy * dy + dz * dz < 1e-24:
            break
        # every sweep stays in the ball whose shapes were gathered: a target that slides out of
        # it (round a curved surface, along a plane's projection) widens it first
        ex, ey, ez = tx - bx, ty - by, tz - bz
        if ex * ex + ey * ey + ez * ez > room2:
            gather_ball(sh, fm, fd, near, bx, by, bz, math.sqrt(ex * ex + ey * ey + ez * ez) + 1e-3)
            room2 = fd.ball_room * fd.ball_room
        # the proxy and the target are on or above every plane (the target is projected onto
        # them; a hit, a lifted plane's replacement lie below the proxy)
        hit, lam, nx, ny, nz, s = _sweep(sh, fm, fd, near, x, y, z, dx, dy, dz, pl, n)
        if not hit:
            x, y, z = tx, ty, tz
            if n == 0 or (tx == gx and ty == gy and tz == gz):
                break
            # a plane whose shape fell away under the proxy (a curved shape's tangent plane, a
            # rounded edge's, a face's plane past the face's edge) is replaced by the shape's
            # tangent plane below the proxy now (its linearisation where the proxy is) and the
            # others kept: a crease of a face and a curved shape is followed along both at once.
            # On a mesh, one shape of many features, a plane holds while its own triangle is
            # under the proxy, or the next facet in its plane is (the nearest a walk from its
            # triangle reaches: a facet elsewhere on the mesh is not this plane's surface, and
            # the sweep that follows meets any in the way)
            nk = 0
            lifted = False
            fdist = fnx = fny = fnz = 0.0
            for i in range(n):
                si, fi = int(pl[i, PLANE_SHAPE]), int(pl[i, PLANE_ROW])
                if fi >= 0:
                    d, mx, my, mz = shape_feature_distance(S, T, xpos, xmat, si, fi, x, y, z)
                    if d - r <= LIFT_TOL:
                        for k in range(PLANE_WIDTH):  # its own triangle is under the proxy
                            kept[nk, k] = pl[i, k]
                        nk += 1
                        continue
                    fdist, fnx, fny, fnz = d, mx, my, mz  # its triangle's distance and normal
                    d, mx, my, mz, walked = shape_walk_distance(sh, si, fi, x, y, z)
                    f = float(walked)
                else:
                    d, mx, my, mz = shape_distance(sh, si, x, y, z)
                    f = shape_feature(S, si)
                if d - r <= LIFT_TOL:
                    if S[si].convex or 1.0 - along(pl, i, mx, my, mz) <= LIFT_TOL / r:
                        # on its shape's surface; on a mesh, on the next facet in its plane
                        for k in range(PLANE_WIDTH):
                            kept[nk, k] = pl[i, k]
                        kept[nk, 5] = f
                        nk += 1
                        continue
                    if fi >= 0:
                        # the facet under the proxy is another than the plane's triangle, and
                        # not in its plane: an edge hit and slid past, beside a facet still
                        # touched. Its triangle's tangent plane replaces it below
                        d, mx, my, mz, f = fdist, fnx, fny, fnz, float(fi)
                lifted = True
                dup = False
                for q in range(nk):
                    if int(kept[q, 4]) == si and kept[q, 5] == f:
                        dup = True
                        break
                if not dup:
                    kept[nk, 0], kept[nk, 1], kept[nk, 2] = mx, my, mz
                    kept[nk, 3] = mx * x + my * y + mz * z - (d - r)
                    kept[nk, 4], kept[nk, 5] = si, f
                    nk += 1
            if not lifted:
                on_surfaces = True  # every plane's real surface is under the proxy
                break
            fd.rounding = True
            if nwarm > 0 and not follow_lifts:  # what the warm start assumed no longer holds: solve cold
                return True, Move(x, y, z, hx, hy, hz, straight, 0)
            straight = False
            for i in range(nk):
                for k in range(PLANE_WIDTH):
                    pl[i, k] = kept[i, k]
            n = nk
            hits += 1  # rolling round an edge creeps: SLIDE_HITS
            if hits == SLIDE_HITS:
                done, x, y, z = _rest_nearest(sh, fm, fd, near, x, y, z, gx, gy, gz, pl)
                if done:
                    n = 1
                    break
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
        hits += 1
        if hits == SLIDE_HITS and S[s].type == GEOM_MESH:
            # sliding across a mesh's facets, one sweep each: to where sliding ends, if that
            # is one clear move away
            done, x, y, z = _rest_nearest(sh, fm, fd, near, x, y, z, gx, gy, gz, pl)
            if done:
                n = 1
                break
        n = _add_plane(pl, n, nx, ny, nz, nx * x + ny * y + nz * z, s, shape_feature(S, s))
        found, qx, qy, qz = _project(gx, gy, gz, pl, n)
        if not found:
            break
        tx, ty, tz = qx, qy, qz
    if following:
        # the budget ran out just after the proxy lifted off a curved surface it was following
        # (a jump of centimetres a tick deep into it): one sweep straight toward the goal puts
        # it back on the surface, in contact, instead of microns above it with no force for a tick
        dx, dy, dz = gx - x, gy - y, gz - z
        hit, lam, nx, ny, nz, s = _sweep(sh, fm, fd, near, x, y, z, dx, dy, dz, pl, 0)
        if not hit:
            x, y, z = gx, gy, gz
        else:
            x, y, z = x + lam * dx, y + lam * dy, z + lam * dz
            if not has_first:
                has_first = True
                hx, hy, hz = x, y, z
            n = _add_plane(pl, n, nx, ny, nz, nx * x + ny * y + nz * z, s, shape_feature(S, s))
    nr = 0  # keep only the planes the proxy still rests on (the loop may end before it checked)
    for i in range(n):
        if _rests_on(sh, fm, fd, pl, i, x, y, z, on_surfaces):
            for k in range(PLANE_WIDTH):
                pl[nr, k] = pl[i, k]
            nr += 1
        elif nwarm > 0 and abs(along(pl, i, x, y, z) - pl[i, PLANE_OFFSET]) <= LIFT_TOL:
            # on a plane, off its shape: solve again from no planes, as above
            return True, Move(x, y, z, hx, hy, hz, straight, 0)
    if not has_first:
        hx, hy, hz = x, y, z
    return False, Move(x, y, z, hx, hy, hz, straight, nr)


@kernel
def _move(sh, fm, fd, near, x, y, z, gx, gy, gz, warm, nwarm, pl, kept, follow_lifts):
    """`_move_once`, warm-started, and solved again cold when the warm start's planes did not
    hold: a `Move`, the resting planes in pl[:Move.planes]."""
    restart, move = _move_once(sh, fm, fd, near, x, y, z, gx, gy, gz, warm, nwarm, pl, kept, follow_lifts)
    if restart:  # what the warm start assumed no longer holds: solve again from no planes
        restart, move = _move_once(sh, fm, fd, near, x, y, z, gx, gy, gz, warm, 0, pl, kept, False)
    return move


@kernel
def _slips(fm, fd, sx, sy, sz, slide, depth, mu_s, mu_d):
    """The friction cone's state this tick, from the offset s = h - f (m) of the proxy's first
    surface point h from the frictionless proxy f, |s| = slide, and the depth (m): True for
    slipping (dynamic cone), False for stuck (static cone); mu_s, mu_d: the cone's coefficients.

    A proxy that slipped last tick keeps slipping while it has slid RESTICK_TRAVEL of its
    offset within `slide_restick` s (the motion has not stopped) and s along the way it last
    slid (slide_u) is at least
    RESTICK_FRACTION × μ_d·depth (the motion has not reversed). Otherwise, stuck or
    re-stuck, it slips when s leaves the static cone, |s| > μ_s·depth: with `slide_restick`
    0 that is the only test, every tick."""
    if fd.contact and not fd.sticking and fd.slide_idle < fm.slide_restick:
        along = sx * fd.slide_dir[0] + sy * fd.slide_dir[1] + sz * fd.slide_dir[2]
        if along >= RESTICK_FRACTION * mu_d * depth:
            return True
    return slide > mu_s * depth


@kernel
def update(sh, fm, fd, near, xd, yd, zd, dt, pl, saved, warm, kept):
    """Move the proxy toward the device position (m, world) over a tick of dt s (the friction
    cone's re-stick time counts in it): the tick's god-object.

    pl, saved, warm, kept: scratch plane lists of PLANE_ROOM rows. False on NaN, Inf or a
    position outside the workspace: the proxy then only follows its body (`follow`)."""
    S, xpos, xmat = sh.S, sh.xpos, sh.xmat
    if not (-WORKSPACE_LIMIT < xd < WORKSPACE_LIMIT and -WORKSPACE_LIMIT < yd < WORKSPACE_LIMIT
            and -WORKSPACE_LIMIT < zd < WORKSPACE_LIMIT):
        follow(sh, fm, fd, near)
        return False
    x, y, z = _settle(sh, fm, fd, near, xd, yd, zd, False)
    if fd.squeezed:
        _rest_squeezed(sh, fd, near, xd, yd, zd)
        return True
    if fd.sticking and fd.pos[0] == x and fd.pos[1] == y and fd.pos[2] == z \
            and _still_stuck(sh, fm, fd, near, xd, yd, zd, pl):
        return True
    x, y, z = fd.pos
    n = 0
    nfree, gap = _free_from_last(sh, fm, fd, near, xd, yd, zd, warm)
    hx, hy, hz = x, y, z
    if nfree > 0 and gap > LIFT_TOL:
        # the proxy ended last tick on the chord of its slide back to the dynamic cone, which
        # floats up to TOUCH_TOL over a concave patch: where it touches first is where a
        # sweep from it toward the device touches, as the solve from it would find
        hit, lam, _, _, _, _ = _sweep(sh, fm, fd, near, x, y, z, xd - x, yd - y, zd - z, pl, 0)
        if hit:
            hx, hy, hz = x + lam * (xd - x), y + lam * (yd - y), z + lam * (zd - z)
        else:
            nfree = 0
    if nfree > 0:
        # a plane lifting on the way is followed on: both ends are reached through free space
        move = _move(sh, fm, fd, near, fd.free_pos[0], fd.free_pos[1], fd.free_pos[2], xd, yd, zd,
                     warm, nfree, pl, kept, True)
        fx, fy, fz, n = move.x, move.y, move.z, move.planes
        straight = False  # the proxy is where it touches first (h)
    if n == 0:
        nwarm = _warm_planes(sh, fm, fd, x, y, z, warm)
        move = _move(sh, fm, fd, near, x, y, z, xd, yd, zd, warm, nwarm, pl, kept, False)
        fx, fy, fz, hx, hy, hz, straight, n = move
    # the frictionless proxy and its planes, for the next tick
    fd.free_pos[:] = fx, fy, fz
    fd.nfree = _newest_three(fd.free_planes, pl, n)
    if n == 0:
        fd.pos[:] = fx, fy, fz
        let_go(fd)
        return True

    # constraint direction: from the device to the frictionless proxy
    ex, ey, ez = fx - xd, fy - yd, fz - zd
    depth = math.sqrt(ex * ex + ey * ey + ez * ez)
    if depth > 0.0:
        nx, ny, nz = ex / depth, ey / depth, ez / depth
    else:
        nx, ny, nz = normal(pl, n - 1)

    # friction cone, tested from the first surface point the proxy reached this tick
    sx, sy, sz = hx - fx, hy - fy, hz - fz
    slide = math.sqrt(sx * sx + sy * sy + sz * sz)
    mu_s, mu_d = plane_friction(sh, fm, pl, n, hx, hy, hz)  # the touched shapes' materials, where it touched
    slipping = _slips(fm, fd, sx, sy, sz, slide, depth, mu_s, mu_d)
    # held at h: stuck, or slipping with the device inside the dynamic cone (not pulling on)
    held = not slipping or slide <= mu_d * depth
    _store_planes(fd, pl, n)
    if held:
        fx, fy, fz = hx, hy, hz
        if slide > 0.0:  # held back: keep the planes that reach back to h
            _keep_resting(sh, fm, fd, saved, 0, pl, n, hx, hy, hz)
    else:
        # slides: remember which way, for the reversal test of the next ticks
        fd.slide_dir[:] = sx / slide, sy / slide, sz / slide
        if fd.sticking or not fd.contact:  # a new slip
            fd.slide_idle = fd.slide_travel = 0.0
        fd.slide_travel += slide - mu_d * depth
    if slipping:  # the stop watch: time since the proxy last slid RESTICK_TRAVEL of its offset
        if fd.slide_travel >= restick_travel(RESTICK_TRAVEL * mu_d * depth, RESTICK_SPEED, fm.slide_restick):
            fd.slide_idle = fd.slide_travel = 0.0
        else:
            fd.slide_idle += dt
    if not held and mu_d > 0.0:
        # back to the dynamic cone's edge: a point on the way from h to the frictionless proxy
        # (back < 1 since slide > μ_d·depth)
        back = mu_d * depth / slide
        tx, ty, tz = fx + back * sx, fy + back * sy, fz + back * sz
        if straight:  # h to f was one swept, clear segment: t lies on it, nothing to sweep
            fx, fy, fz = tx, ty, tz
        else:
            for j in range(n):  # the frictionless solve's planes, kept aside
                for k in range(PLANE_WIDTH):
                    saved[j, k] = pl[j, k]
            move = _move(sh, fm, fd, near, hx, hy, hz, tx, ty, tz, warm, 0, pl, kept, False)
            fx, fy, fz = move.x, move.y, move.z
            _keep_resting(sh, fm, fd, pl, move.planes, saved, n, fx, fy, fz)
    fd.contact = True
    fd.normal[:] = nx, ny, nz
    fd.depth = depth
    fd.sticking = not slipping
    # the finger's planes rest on their shapes at the proxy (checked by the solve or by
    # _keep_resting), except those of the frictionless proxy kept for a point on the chord
    rested = 0 if (not held and mu_d > 0.0 and straight) else int(fd.nplanes)
    best = _touched_at(sh, fm, fd, near, fx, fy, fz, nx, ny, nz, rested)
    if best < 0:  # floating on the chord across an edge: down onto the surface it pushes
        fx, fy, fz = _land(sh, fm, fd, near, fx, fy, fz, xd, yd, zd, saved)
        best = _touched_at(sh, fm, fd, near, fx, fy, fz, nx, ny, nz, 0)
        if best < 0:  # not expected: a proxy in contact ends on a surface
            best = _nearest(sh, fd, near, fx, fy, fz)[0]
    fd.pos[:] = fx, fy, fz
    fd.touched = best
    if not S[best].static:  # remember the proxy in the touched geom's frame: it carries it
        fd.local[:] = shape_to_local(S, xpos, xmat, best, fx, fy, fz)
    return True


def scratch() -> np.ndarray:
    """Four scratch plane lists for `update` (allocated once per engine, not per tick)."""
    return np.zeros((4, PLANE_ROOM, PLANE_WIDTH))


# -- entries for the views (`softproxy.proxy.GodObject`): finger i of a table ------------------
@kernel(entry=True)
def reset_row(sh, fg, i, x, y, z):
    return reset(sh, fg.model[i], fg.data[i], fg.near[i], x, y, z)


@kernel(entry=True)
def update_row(sh, fg, i, xd, yd, zd, dt):
    sc = fg.scratch
    return update(sh, fg.model[i], fg.data[i], fg.near[i], xd, yd, zd, dt, sc[0], sc[1], sc[2], sc[3])


@kernel(entry=True)
def follow_row(sh, fg, i):
    follow(sh, fg.model[i], fg.data[i], fg.near[i])
