"""The 3-DOF god-object: the point a finger of radius r would touch, kept outside every shape.

Each tick the proxy moves from where it was toward the device position x_d (Zilles &
Salisbury's god-object, Ruspini's proxy): a sphere of radius r swept against every shape
(`softproxy.geometry`), stopping at the first surface it moves into, then sliding on up to
three constraint planes — faces, edges, corners and concave creases — all within one
tick; a plane the proxy slides off (a curved shape's tangent plane, a rounded edge's, a
face's past the face's edge) is replaced by the shape's tangent plane under the proxy;
when the tick's MAX_ITERATIONS sweeps run out just after such a lift (a jump of
centimetres deep into a curved surface), one more sweep straight toward the device puts
the proxy back on the surface, in contact, rather than leaving it microns above with no
force for a tick. Every sweep stays inside the ball whose shapes the tick's broad phase
gathered. Friction follows the proxy literature's friction cone: the proxy sticks while
the device stays inside the static cone (tangential offset ≤ μ_s × penetration) and
otherwise slides to the edge of the dynamic cone.

The proxy is stored in the frame of the geom it touches, so a moving object carries it;
an object that moves into it pushes it out. Units: m, N, N/m, N·s/m.
"""

from __future__ import annotations

import math

from softproxy.geometry import CONTACT_TOL, GRAZE, Shape

MAX_ITERATIONS = 10
"""Sweeps per solve: three for a corner, a few more to follow a curved surface."""
LIFT_TOL = 1e-7
"""After sliding along a constraint plane (a curved shape's or a rounded edge's tangent plane,
a face's plane past the face's edge), re-follow the surface when the proxy has lifted off
the real shape by more than this (m); a proxy this far off a plane no longer rests on it."""
PARALLEL = 1.0 - 1e-9
WORKSPACE_LIMIT = 1e3
"""A device position farther than this from the origin on any axis (m) is garbage, like NaN."""


def _project(px: float, py: float, pz: float, planes: list) -> tuple[float, float, float] | None:
    """Closest point to p in the intersection of ≤ 3 half-spaces n·y ≥ c (KKT, active sets).

    `planes` holds (nx, ny, nz, c, shape). Returns None when the planes admit no point (a
    degenerate set, e.g. opposite parallel faces closer than the proxy's diameter).
    """
    if len(planes) == 1:  # the common case, a face: inline
        nx, ny, nz, c, _ = planes[0]
        lam = c - (nx * px + ny * py + nz * pz)
        return (px + lam * nx, py + lam * ny, pz + lam * nz) if lam > 0.0 else (px, py, pz)

    for nx, ny, nz, c, _ in planes:
        if nx * px + ny * py + nz * pz < c - CONTACT_TOL:
            break
    else:
        return (px, py, pz)
    if len(planes) == 3:  # a proxy held in a corner: try the corner first
        corner = _corner(px, py, pz, planes)
        if corner is not None:
            return corner
    return _project_by_enumeration(px, py, pz, planes)


def _project_by_enumeration(px: float, py: float, pz: float, planes: list) -> tuple[float, float, float] | None:
    """`_project` by trying active sets of one, two, then three planes in turn."""
    def feasible(x, y, z, skip=()):
        for i, (nx, ny, nz, c, _) in enumerate(planes):
            if i not in skip and nx * x + ny * y + nz * z < c - CONTACT_TOL:
                return False
        return True

    if feasible(px, py, pz):
        return (px, py, pz)
    n = len(planes)
    # one active plane
    for i in range(n):
        nx, ny, nz, c, _ = planes[i]
        lam = c - (nx * px + ny * py + nz * pz)
        if lam > 0.0:
            qx, qy, qz = px + lam * nx, py + lam * ny, pz + lam * nz
            if feasible(qx, qy, qz, (i,)):
                return (qx, qy, qz)
    # two active planes: q = p + a n_i + b n_j on both planes, a, b ≥ 0
    for i in range(n):
        for j in range(i + 1, n):
            ax, ay, az, ci, _ = planes[i]
            bx, by, bz, cj, _ = planes[j]
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
            if feasible(qx, qy, qz, (i, j)):
                return (qx, qy, qz)
    # three active planes: the corner point
    if n == 3:
        (ax, ay, az, ca, _), (bx, by, bz, cb, _), (cx, cy, cz, cc, _) = planes
        det = ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)
        if abs(det) > 1e-12:
            # Cramer's rule for N q = c
            qx = (ca * (by * cz - bz * cy) - ay * (cb * cz - bz * cc) + az * (cb * cy - by * cc)) / det
            qy = (ax * (cb * cz - bz * cc) - ca * (bx * cz - bz * cx) + az * (bx * cc - cb * cx)) / det
            qz = (ax * (by * cc - cb * cy) - ay * (bx * cc - cb * cx) + ca * (bx * cy - by * cx)) / det
            return (qx, qy, qz)
    return None


def _on_static_faces(planes: list) -> bool:
    """True when every plane is a planar face of a shape that never moves: such a plane
    holds from tick to tick for as long as the proxy touches the face."""
    for p in planes:
        s = p[4]
        if not (s.static and s.on_face(p[0], p[1], p[2])):
            return False
    return True


def _plane_of(planes: list, s: Shape, nx: float, ny: float, nz: float) -> int:
    """Index in `planes` of shape s's plane of normal n (parallel within PARALLEL), or -1."""
    for i, p in enumerate(planes):
        if p[4] is s and p[0] * nx + p[1] * ny + p[2] * nz > PARALLEL:
            return i
    return -1


def _add_plane(planes: list, plane: tuple) -> None:
    """Add a constraint plane (nx, ny, nz, c, shape) just hit: the same plane met again is
    replaced, not doubled, and the oldest goes when there would be four."""
    i = _plane_of(planes, plane[4], plane[0], plane[1], plane[2])
    if i >= 0:
        del planes[i]
    planes.append(plane)
    if len(planes) > 3:
        del planes[0]


def _touched(planes: list, nx: float, ny: float, nz: float) -> Shape:
    """The touched shape: the one whose active plane is most aligned with the force's n."""
    best, best_dot = planes[0][4], -2.0
    for px, py, pz, _, s in planes:
        dot = px * nx + py * ny + pz * nz
        if dot > best_dot:
            best, best_dot = s, dot
    return best


def _corner(px: float, py: float, pz: float, planes: list) -> tuple[float, float, float] | None:
    """The point q on all three planes when it is the projection of p, i.e. q - p = Σ λ_i n_i
    with every λ_i ≥ 0 (each plane pushes, none pulls); otherwise None."""
    (ax, ay, az, ca, _), (bx, by, bz, cb, _), (cx, cy, cz, cc, _) = planes
    # the columns of the inverse of N = [a; b; c] (normals as rows) are b × c, c × a, a × b over det N
    ux, uy, uz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx   # b × c
    vx, vy, vz = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax   # c × a
    wx, wy, wz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx   # a × b
    det = ax * ux + ay * uy + az * uz
    if abs(det) <= 1e-12:
        return None
    # distances to push p along each plane's normal: e_i = c_i - n_i·p; q = p + N⁻¹ e
    ea = ca - (ax * px + ay * py + az * pz)
    eb = cb - (bx * px + by * py + bz * pz)
    ec = cc - (cx * px + cy * py + cz * pz)
    dx = (ux * ea + vx * eb + wx * ec) / det
    dy = (uy * ea + vy * eb + wy * ec) / det
    dz = (uz * ea + vz * eb + wz * ec) / det
    # q - p = Nᵀλ and N q = c give G λ = e with the Gram matrix G = N Nᵀ (unit normals:
    # ones on its diagonal); λ = G⁻¹ e by cofactors, only its signs matter
    gab, gac, gbc = ax * bx + ay * by + az * bz, ax * cx + ay * cy + az * cz, bx * cx + by * cy + bz * cz
    c00, c11, c22 = 1.0 - gbc * gbc, 1.0 - gac * gac, 1.0 - gab * gab
    c01, c02, c12 = gac * gbc - gab, gab * gbc - gac, gab * gac - gbc
    gdet = c00 + gab * c01 + gac * c02
    if gdet <= 1e-12:
        return None
    if (c00 * ea + c01 * eb + c02 * ec) / gdet < 0.0 or (c01 * ea + c11 * eb + c12 * ec) / gdet < 0.0 \
            or (c02 * ea + c12 * eb + c22 * ec) / gdet < 0.0:
        return None
    return (px + dx, py + dy, pz + dz)


class GodObject:
    """Translational proxy of one finger. `update(x_d)` moves it; read the contact fields after.

    Fields after `update`: x, y, z (proxy centre, m); contact (bool); nx, ny, nz (unit
    contact normal, out of the object); shape (the touched Shape or None); depth (how far
    the device is inside the constraint, m); sticking (bool).
    """

    __slots__ = (
        "shapes", "radius", "mu_s", "mu_d", "x", "y", "z", "contact", "nx", "ny", "nz", "shape",
        "depth", "sticking", "lx", "ly", "lz", "planes", "near", "_bx", "_by", "_bz", "_room", "_rounding",
    )

    def __init__(self, shapes: list[Shape], radius: float, mu_s: float = 0.0, mu_d: float = 0.0,
                 position: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        if not (math.isfinite(radius) and radius >= 0.0):
            raise ValueError(f"radius must be a finite number >= 0 (m), got {radius!r}")
        for name, mu in (("mu_s", mu_s), ("mu_d", mu_d)):
            if not (math.isfinite(mu) and mu >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {mu!r}")
        if mu_d > mu_s:
            raise ValueError(f"mu_d ({mu_d}) must be <= mu_s ({mu_s})")
        self.shapes = shapes
        self.radius = float(radius)
        for s in shapes:  # nothing the queries need is built in the tick
            s.prepare(self.radius)
        self.mu_s = float(mu_s)
        self.mu_d = float(mu_d)
        self.planes: list = []
        self.near: list[Shape] = shapes
        self._bx = self._by = self._bz = 0.0
        self._room = math.inf
        self._rounding = False  # the last solve followed a surface round (a plane lifted off)
        self.reset(*position)

    def reset(self, x: float, y: float, z: float) -> None:
        """Put the proxy at (x, y, z) with no contact (pushed out of any shape it overlaps)."""
        if not all(-WORKSPACE_LIMIT < v < WORKSPACE_LIMIT for v in (x, y, z)):
            raise ValueError(f"proxy position must lie within ±{WORKSPACE_LIMIT} m, got {(x, y, z)!r}")
        self.x, self.y, self.z = float(x), float(y), float(z)
        self.contact = False
        self.nx, self.ny, self.nz = 0.0, 0.0, 0.0
        self.shape = None
        self.depth = 0.0
        self.sticking = False
        self.lx = self.ly = self.lz = 0.0
        self.near = self.shapes
        self._push_out()

    # -- the tick -------------------------------------------------------------------
    def update(self, xd: float, yd: float, zd: float) -> bool:
        """Move the proxy toward the device position (m, world).

        Returns False on NaN/Inf/garbage: the proxy then only follows its body (`follow`).
        """
        if not (-WORKSPACE_LIMIT < xd < WORKSPACE_LIMIT and -WORKSPACE_LIMIT < yd < WORKSPACE_LIMIT
                and -WORKSPACE_LIMIT < zd < WORKSPACE_LIMIT):
            self.follow()
            return False
        x, y, z = self._settle(xd, yd, zd)
        if self.sticking and self.x == x and self.y == y and self.z == z and self._still_stuck(xd, yd, zd):
            return True
        x, y, z = self.x, self.y, self.z
        fx, fy, fz, first, straight = self._solve(x, y, z, xd, yd, zd)
        planes = self.planes
        if not planes:
            self.x, self.y, self.z = fx, fy, fz
            self.contact = False
            self.shape = None
            self.depth = 0.0
            self.sticking = False
            return True

        # constraint direction: from the device to the frictionless proxy
        ex, ey, ez = fx - xd, fy - yd, fz - zd
        depth = math.sqrt(ex * ex + ey * ey + ez * ez)
        if depth > 0.0:
            nx, ny, nz = ex / depth, ey / depth, ez / depth
        else:
            nx, ny, nz = planes[-1][0], planes[-1][1], planes[-1][2]
        best = planes[0][4] if len(planes) == 1 else _touched(planes, nx, ny, nz)

        # friction cone, tested from the first surface point the proxy reached this tick
        hx, hy, hz = first
        sx, sy, sz = hx - fx, hy - fy, hz - fz
        slide = math.sqrt(sx * sx + sy * sy + sz * sz)
        sticking = slide <= self.mu_s * depth
        if sticking:
            fx, fy, fz = hx, hy, hz
            if slide > 0.0:  # held back: keep the planes that reach back to h
                self.planes = []
                self._keep_resting(planes, hx, hy, hz)
        elif self.mu_d > 0.0 and slide > 0.0:
            # back to the dynamic cone's edge: a point on the way from h to the frictionless
            # proxy (back < 1 since slide > μ_s·depth ≥ μ_d·depth)
            back = self.mu_d * depth / slide
            tx, ty, tz = fx + back * sx, fy + back * sy, fz + back * sz
            if straight:  # h to f was one swept, clear segment: t lies on it, nothing to sweep
                fx, fy, fz = tx, ty, tz
            else:
                saved = self.planes
                fx, fy, fz, _, _ = self._move(hx, hy, hz, tx, ty, tz)
                self._keep_resting(saved, fx, fy, fz)
        self.x, self.y, self.z = fx, fy, fz
        self.contact = True
        self.nx, self.ny, self.nz = nx, ny, nz
        self.depth = depth
        self.sticking = sticking
        self.shape = best
        if not best.static:  # remember the proxy in the touched geom's frame: it carries it
            self.lx, self.ly, self.lz = best.to_local(fx, fy, fz)
        return True

    def _keep_resting(self, planes: list, x: float, y: float, z: float) -> None:
        """After friction held the proxy back from the frictionless end: the planes it rests on
        at (x, y, z), those of the frictionless solve it still touches (on their real
        surfaces, not past an edge) added to `self.planes` (those a slide itself ran into).
        What the next tick's warm start builds on."""
        resting = self.planes
        for p in planes:
            if self._rests_on(p, x, y, z) and _plane_of(resting, p[4], p[0], p[1], p[2]) < 0:
                resting.append(p)
        self.planes = resting[-3:]

    def _rests_on(self, plane: tuple, x: float, y: float, z: float, on_surface: bool = False) -> bool:
        """True when the proxy at (x, y, z) still rests on this constraint plane and on its
        shape's real surface, both within LIFT_TOL (m): a plane runs on past a face's edge, a
        curved shape falls away from its tangent plane, and a point friction held back short
        of the plane (on a rounded edge below a face's plane) does not rest on it.
        `on_surface`: the shape's surface is known to be under the proxy already."""
        nx, ny, nz, c, s = plane
        return abs(nx * x + ny * y + nz * z - c) <= LIFT_TOL and (
            on_surface or s.distance(x, y, z)[0] - self.radius <= LIFT_TOL)

    def follow(self) -> None:
        """Without a device sample: the proxy stays on the body it touches and out of anything
        that moved into it, so a skipped tick never leaves it inside a moving object."""
        self._settle(self.x, self.y, self.z, around_proxy=True)

    # -- pieces -----------------------------------------------------------------------
    def _settle(self, xd: float, yd: float, zd: float, around_proxy: bool = False) -> tuple[float, float, float]:
        """Carry the proxy with the touched body, gather the shapes near it and the device,
        push it out of any that moved into it. Returns the proxy position before the push."""
        shape = self.shape
        carrier = None
        if shape is not None and not shape.static:
            # carried by the touched object (stored in its frame at the end of last tick)
            carrier = shape
            lx, ly, lz = self.lx, self.ly, self.lz
            self.x = shape.r00 * lx + shape.r01 * ly + shape.r02 * lz + shape.px
            self.y = shape.r10 * lx + shape.r11 * ly + shape.r12 * lz + shape.py
            self.z = shape.r20 * lx + shape.r21 * ly + shape.r22 * lz + shape.pz
        x, y, z = self.x, self.y, self.z
        # broad phase: the shapes near the ball that holds both the proxy and the device, with
        # a margin of 1 mm (`_move` widens it if a sub-move would leave it)
        if around_proxy:
            self._gather_ball(x, y, z, self.radius + 1e-3)
        else:
            ex, ey, ez = xd - x, yd - y, zd - z
            self._gather_ball(0.5 * (x + xd), 0.5 * (y + yd), 0.5 * (z + zd),
                              0.5 * math.sqrt(ex * ex + ey * ey + ez * ez) + self.radius + 1e-3)
        # Only a moving shape can have come into the proxy, or a static one if the
        # proxy itself was carried; the carrier holds the proxy where it was, outside.
        for s in self.near:
            if s is not carrier and (carrier is not None or not s.static):
                self._push_out()
                break
        return x, y, z

    def _still_stuck(self, xd: float, yd: float, zd: float) -> bool:
        """Fast path of the hold: a stuck proxy that stays stuck, on one flat face or pinned in
        a corner of three static faces.

        What the full solve would find, for a fraction of its cost. On a face: the proxy does
        not move, the frictionless proxy f is the device projected onto the face (checked to
        lie on the same face, the way there clear of every other shape), and the cone test
        passes. In a corner: the device pushes into all three faces, so f is the corner,
        where the proxy already is.
        """
        planes = self.planes
        if len(planes) == 3:
            return self._still_in_corner(xd, yd, zd)
        shape = self.shape
        if len(planes) != 1 or not shape.flat:
            return False
        x, y, z, r = self.x, self.y, self.z, self.radius
        d, nx, ny, nz = shape.distance(x, y, z)
        if abs(d - r) > 1e-7:
            return False
        depth = nx * (x - xd) + ny * (y - yd) + nz * (z - zd)
        if depth <= 0.0:
            return False
        fx, fy, fz = xd + depth * nx, yd + depth * ny, zd + depth * nz
        df, mx, my, mz = shape.distance(fx, fy, fz)
        if abs(df - d) > 1e-9 or nx * mx + ny * my + nz * mz < PARALLEL:
            return False
        sx, sy, sz = x - fx, y - fy, z - fz
        if sx * sx + sy * sy + sz * sz > (self.mu_s * depth) ** 2:
            return False
        for s in self.near:  # an obstacle on the face between the proxy and f changes f
            if s is not shape and s.sweep(x, y, z, fx - x, fy - y, fz - z, r) is not None:
                return False
        self.planes = [(nx, ny, nz, nx * x + ny * y + nz * z, shape)]
        self.nx, self.ny, self.nz = nx, ny, nz
        self.depth = depth
        return True

    def _still_in_corner(self, xd: float, yd: float, zd: float) -> bool:
        """`_still_stuck` in a corner of three static faces: holds while projecting the device
        onto the three planes gives the corner point, where the proxy is (every plane pushes)."""
        planes = self.planes
        if not _on_static_faces(planes):
            return False
        q = _corner(xd, yd, zd, planes)
        x, y, z = self.x, self.y, self.z
        if q is None or abs(q[0] - x) + abs(q[1] - y) + abs(q[2] - z) > 1e-12:
            return False
        ex, ey, ez = x - xd, y - yd, z - zd
        depth = math.sqrt(ex * ex + ey * ey + ez * ez)
        if depth == 0.0:
            return False
        nx, ny, nz = ex / depth, ey / depth, ez / depth
        best = _touched(planes, nx, ny, nz)
        self.nx, self.ny, self.nz = nx, ny, nz
        self.depth = depth
        self.shape = best  # a static face: nothing carries the proxy
        return True

    def _gather_ball(self, cx: float, cy: float, cz: float, room: float) -> None:
        """`near`: every shape the proxy can touch while its centre stays within `room` (m) of c,
        the shapes whose bounding sphere meets the ball of radius room + r."""
        self._bx, self._by, self._bz, self._room = cx, cy, cz, room
        reach = room + self.radius
        near = []
        for s in self.shapes:
            rb = s.rbound + reach
            if rb == math.inf:  # a plane: near when the ball reaches its surface
                if s.r02 * (cx - s.px) + s.r12 * (cy - s.py) + s.r22 * (cz - s.pz) <= reach:
                    near.append(s)
                continue
            dx, dy, dz = s.px - cx, s.py - cy, s.pz - cz
            if dx * dx + dy * dy + dz * dz <= rb * rb:
                near.append(s)
        self.near = near

    def _push_out(self) -> None:
        """Move the proxy out of any shape it overlaps (an object moved into it)."""
        r = self.radius
        for _ in range(3):
            moved = False
            for s in self.near:
                d, nx, ny, nz = s.distance(self.x, self.y, self.z)
                gap = d - r
                if gap < 0.0:
                    push = -gap + CONTACT_TOL
                    self.x += push * nx
                    self.y += push * ny
                    self.z += push * nz
                    moved = True
            if not moved:
                return

    def _sweep(self, x, y, z, dx, dy, dz, planes=()):
        """Earliest hit over all shapes of the sphere moving by (dx, dy, dz): (lam, nx, ny, nz, shape).

        `planes`: constraint planes that the start and the end of the move both satisfy. A
        convex shape owning one of them lies behind it, so a move on or above it cannot enter
        the shape: it is not swept (a slide along a face or a tangent plane sweeps only the
        other shapes)."""
        r = self.radius
        best = None
        best_lam = 1.0
        behind = [p[4] for p in planes if p[4].convex] if planes else ()
        for s in self.near:
            if s in behind:
                continue
            hit = s.sweep(x, y, z, dx, dy, dz, r)
            if hit is not None and hit[0] < best_lam:
                best_lam = hit[0]
                best = (hit[0], hit[1], hit[2], hit[3], s)
        return best

    def _solve(self, x, y, z, gx, gy, gz):
        """`_move` warm-started with last tick's planes when every one belongs to a static shape.

        A proxy resting on a face, an edge or a corner keeps resting on the same shapes from
        tick to tick: starting from their planes saves a sweep per plane. A planar face's plane
        is kept as it was; a convex shape's plane elsewhere (a rounded edge or corner, a curved
        surface) is its tangent plane under the proxy now, one distance query, unless the last
        solve slid round a curve (it would lift off again). A plane may run on past the shape's
        surface: a proxy that lifts off one (past a face's edge, round a curve) is solved again
        from no planes, so a warm start ends where the cold solve ends. Never unsafe either
        way: every motion is still swept.
        """
        return self._move(x, y, z, gx, gy, gz, self._warm_planes(x, y, z))

    def _warm_planes(self, x: float, y: float, z: float) -> list | None:
        """Last tick's planes to start `_solve` from, as `_solve` says, or None: solve cold."""
        warm = []
        for p in self.planes:
            s = p[4]
            if not s.static:
                return None
            if s.on_face(p[0], p[1], p[2]):
                warm.append(p)
                continue
            if not s.convex or self._rounding:  # sliding round a curve: a warm start would lift
                return None
            d, nx, ny, nz = s.distance(x, y, z)
            if d - self.radius > LIFT_TOL:
                return None
            # (a box's face and its rounded edge at their seam give one plane; its offset is
            # taken through the proxy in _move)
            if not warm or _plane_of(warm, s, nx, ny, nz) < 0:
                warm.append((nx, ny, nz, 0.0, s))
        return warm or None

    def _move(self, x, y, z, gx, gy, gz, warm=None):
        """Constrained motion toward (gx, gy, gz). Leaves the tight planes in self.planes.

        `warm`: planes the proxy rests on at (x, y, z) to start from. Returns the end point,
        the first surface point reached (or the end point), and whether the way from that
        first point to the end was one straight swept segment (any point on it is reachable).
        """
        planes: list = []
        first = None
        straight = True
        on_surfaces = False
        self._rounding = False
        r = self.radius
        x0, y0, z0 = x, y, z
        tx, ty, tz = gx, gy, gz
        if warm:
            # through the proxy as it is now: it may sit up to 1e-7 m off a plane's old offset,
            # and a target on the old offset would then lie a hair inside the face
            warm = [(nx, ny, nz, nx * x + ny * y + nz * z, s) for nx, ny, nz, _, s in warm]
            # only a device pressing into a plane keeps the proxy on it from the start, by
            # more than a graze of the motion, as a sweep would count it
            ex, ey, ez = gx - x, gy - y, gz - z
            graze = GRAZE * math.sqrt(ex * ex + ey * ey + ez * ez)
            for nx, ny, nz, c, _ in warm:
                if c - (nx * gx + ny * gy + nz * gz) > graze:
                    target = _project(gx, gy, gz, warm)
                    break
            else:
                target = None
            if target is not None:
                planes = warm
                first = (x, y, z)
                tx, ty, tz = target
        # a warm start saves the sweeps that would have found its planes, one each, not the
        # budget of those that follow: it ends where a cold solve ends, for less
        bx, by, bz, room2 = self._bx, self._by, self._bz, self._room * self._room
        following = False  # the last sweep slid along a tangent plane that then lifted off
        for _ in range(MAX_ITERATIONS - len(planes)):
            following = False
            dx, dy, dz = tx - x, ty - y, tz - z
            if dx * dx + dy * dy + dz * dz < 1e-24:
                break
            # every sweep stays in the ball whose shapes were gathered: a target that slides out
            # of it (round a curved surface, along a plane's projection) widens it first
            ex, ey, ez = tx - bx, ty - by, tz - bz
            if ex * ex + ey * ey + ez * ez > room2:
                self._gather_ball(bx, by, bz, math.sqrt(ex * ex + ey * ey + ez * ez) + 1e-3)
                room2 = self._room * self._room
            # the proxy and the target are on or above every plane (the target is projected
            # onto them; a hit, a lifted plane's replacement lie below the proxy)
            hit = self._sweep(x, y, z, dx, dy, dz, planes)
            if hit is None:
                x, y, z = tx, ty, tz
                if not planes or (tx == gx and ty == gy and tz == gz):
                    break
                # a plane whose shape fell away under the proxy (a curved shape's tangent
                # plane, a rounded edge's, a face's plane past the face's edge) is replaced by
                # the shape's tangent plane below the proxy now (its linearisation where the
                # proxy is) and the others kept: a crease of a face and a curved shape is
                # followed along both at once
                kept = []
                lifted = False
                for p in planes:
                    s = p[4]
                    d, nx, ny, nz = s.distance(x, y, z)
                    if d - r <= LIFT_TOL:
                        kept.append(p)
                        continue
                    lifted = True
                    for q in kept:
                        if q[4] is s:
                            break
                    else:
                        kept.append((nx, ny, nz, nx * x + ny * y + nz * z - (d - r), s))
                if not lifted:
                    on_surfaces = True  # every plane's real surface is under the proxy
                    break
                self._rounding = True
                if warm:  # what the warm start assumed no longer holds: solve cold
                    return self._move(x0, y0, z0, gx, gy, gz)
                straight = False
                planes = kept
                target = _project(gx, gy, gz, planes)
                if target is None:
                    break
                tx, ty, tz = target
                following = True
                continue
            lam, nx, ny, nz, s = hit
            x, y, z = x + lam * dx, y + lam * dy, z + lam * dz
            if first is None:
                first = (x, y, z)
            else:
                straight = False
            _add_plane(planes, (nx, ny, nz, nx * x + ny * y + nz * z, s))
            target = _project(gx, gy, gz, planes)
            if target is None:
                break
            tx, ty, tz = target
        if following:
            # the budget ran out just after the proxy lifted off a curved surface it was
            # following (a jump of centimetres a tick deep into it): one sweep straight toward
            # the goal puts it back on the surface, in contact, instead of microns above it
            # with no force for a tick
            dx, dy, dz = gx - x, gy - y, gz - z
            hit = self._sweep(x, y, z, dx, dy, dz)
            if hit is None:
                x, y, z = gx, gy, gz
            else:
                lam, nx, ny, nz, s = hit
                x, y, z = x + lam * dx, y + lam * dy, z + lam * dz
                if first is None:
                    first = (x, y, z)
                _add_plane(planes, (nx, ny, nz, nx * x + ny * y + nz * z, s))
        # keep only the planes the proxy still rests on (the loop may end before it checked)
        resting = []
        for p in planes:
            if self._rests_on(p, x, y, z, on_surfaces):
                resting.append(p)
            elif warm and abs(p[0] * x + p[1] * y + p[2] * z - p[3]) <= LIFT_TOL:
                # on a plane, off its shape: solve again from no planes, as above
                return self._move(x0, y0, z0, gx, gy, gz)
        self.planes = resting
        return x, y, z, (first if first is not None else (x, y, z)), straight
