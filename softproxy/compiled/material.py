"""What a finger feels of the shape it touches (numba): the shape's material and its effects.

A shape's material (fields of its SHAPE record, `softproxy.material` fills them) changes the
contact a finger renders on it; a shape without one (`material` False) renders the finger's
own coupling and friction, read as before. Rules (docs/materials.md):

- the spring and damper are the finger's, or the surface's where that is softer (lesser):
  a device renders at most what its finger was tuned to render stably, as CHAI3D clips a
  material's stiffness at the device's;
- the friction cone is the pair's static and dynamic coefficients where the material gives
  them, otherwise the finger's times the geom's MJCF friction (1 for MuJoCo's default geom);
- the torsional limit is the finger's law scaled as the sliding coefficient was (torsional
  friction is that same coefficient integrated over the contact patch), times `torsion`;
- effects (CHAI3D's `cMaterial`): viscosity, a damper on the finger's motion relative to the
  surface; vibration along the normal; a height grating (texture) rendered as the lateral
  force P·∇h of the slope under the finger (Minsky's lateral-force gradient); stick-slip,
  a tangential spring to an anchor that jumps to the finger when the spring passes its break
  force; and a magnet that pulls the finger toward the surface within its reach (out of
  contact: touching, the surface bears the pull); popthrough, a surface the finger passes
  through when it presses harder than a force.
Units: m, N, N·m, s, rad.
"""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import PLANE_SHAPE
from softproxy.compiled.shapes import shape_distance, shape_to_local, shape_to_world
from softproxy.compiled.vector import to_world_frame


@kernel(inline="always")
def shape_friction(sh, fm, shape, x, y, z):
    """The static and dynamic coefficients of a finger's cone on `shape` (a row of S) at the
    world point (x, y, z) (m): a textured shape's modulated along its grating."""
    r = sh.S[shape]
    if not r.material:
        return fm.mu_s, fm.mu_d
    mu_s, mu_d = r.friction[0], r.friction[1]
    if mu_s == mu_s:  # the pair's, as the material gives them (or a geom of higher priority)
        if mu_d != mu_d:  # a geom's own: dynamic at the finger's ratio of it
            mu_d = mu_s * (fm.mu_d / fm.mu_s) if fm.mu_s > 0.0 else mu_s
    else:
        g = r.friction_scale
        mu_s, mu_d = fm.mu_s * g, fm.mu_d * g
    period, modulation = r.texture[3], r.texture[5]
    if modulation != 0.0 and period > 0.0:
        f = 1.0 + modulation * math.sin(2.0 * math.pi * _along_texture(sh, shape, x, y, z) / period)
        mu_s, mu_d = mu_s * f, mu_d * f
    return mu_s, mu_d


@kernel(inline="always")
def _along_texture(sh, shape, x, y, z):
    """The world point (m) along the shape's grating axis, in its geom frame (m)."""
    t = sh.S[shape].texture
    lx, ly, lz = shape_to_local(sh.S, sh.xpos, sh.xmat, shape, x, y, z)
    return t[0] * lx + t[1] * ly + t[2] * lz


@kernel
def plane_friction(sh, fm, pl, n, x, y, z):
    """The cone of a proxy at (x, y, z) (m) resting on planes pl[:n] (their shapes'
    coefficients): the least static one and its dynamic one, so a corner of glass and rubber
    slides along the glass; the finger's own with no plane."""
    mu_s, mu_d = fm.mu_s, fm.mu_d
    first = True
    for i in range(n):
        ms, md = shape_friction(sh, fm, int(pl[i, PLANE_SHAPE]), x, y, z)
        if first or ms < mu_s:
            mu_s, mu_d, first = ms, md, False
    return mu_s, mu_d


@kernel
def touch(sh, fm, fd, shape):
    """The contact's spring, damper, cone and torsion factor from the touched shape's material
    into the finger's contact_ fields (the finger's own where it has none)."""
    r = sh.S[shape]
    fd.texture_force[:] = 0.0
    if not r.material:
        fd.contact_stiffness = fm.stiffness
        fd.contact_damping = fm.damping
        fd.contact_friction[0] = fm.mu_s
        fd.contact_friction[1] = fm.mu_d
        fd.contact_torsion = 1.0
        fd.contact_viscosity = 0.0
        return
    k, b = r.stiffness, r.damping
    fd.contact_stiffness = k if k < fm.stiffness else fm.stiffness
    fd.contact_damping = b if b < fm.damping else fm.damping
    mu_s, mu_d = shape_friction(sh, fm, shape, fd.pos[0], fd.pos[1], fd.pos[2])
    fd.contact_friction[0] = mu_s
    fd.contact_friction[1] = mu_d
    fd.contact_torsion = r.torsion * (mu_s / fm.mu_s if fm.mu_s > 0.0 else 1.0)
    fd.contact_viscosity = r.viscosity


@kernel
def surface_force(sh, fm, fd, shape, P, dt):
    """What the touched shape's effects add to the finger's force this tick (N, world), in
    contact: viscosity on the motion relative to the surface (`rel_move` over dt), the
    vibration along n, the texture's lateral force and the stick-slip spring. P, the normal
    force (N) the slope scales with, is the coupling's."""
    S = sh.S
    r = S[shape]
    fx = fy = fz = 0.0
    nx, ny, nz = fd.normal
    eta = r.viscosity
    if eta > 0.0:  # η(v_surface - v_device): rel_move is the surface's move less the device's
        c = eta / dt
        fx, fy, fz = c * fd.rel_move[0], c * fd.rel_move[1], c * fd.rel_move[2]
    freq, amp = r.vibration[0], r.vibration[1]
    if amp > 0.0:
        v = amp * math.sin(fd.vibration_phase)
        fx, fy, fz = fx + v * nx, fy + v * ny, fz + v * nz
        phase = fd.vibration_phase + 2.0 * math.pi * freq * dt
        fd.vibration_phase = phase - 2.0 * math.pi * math.floor(phase / (2.0 * math.pi))
    period, height = r.texture[3], r.texture[4]
    if height > 0.0 and period > 0.0:
        # the slope of h(u) = height sin(2π u / period) under the device, u along the axis
        # (geom frame); the lateral force -P dh/du along the axis's tangential part pushes
        # back up every rise and forward down every fall. It is the hand's alone: the body,
        # flat in MuJoCo, gets no push from relief it does not have (`texture_force` is left
        # out of its wrench); pushed, a light body pinched on a 0.1 mm grating shook itself
        # out of the grip
        ax, ay, az = r.texture[0], r.texture[1], r.texture[2]
        w = 2.0 * math.pi / period
        dx, dy, dz = fd.device_pos
        slope = height * w * math.cos(w * _along_texture(sh, shape, dx, dy, dz))
        wx, wy, wz = to_world_frame(sh.xmat, int(r.geom), ax, ay, az)
        along = wx * nx + wy * ny + wz * nz
        tx, ty, tz = wx - along * nx, wy - along * ny, wz - along * nz
        q = -P * slope
        fx, fy, fz = fx + q * tx, fy + q * ty, fz + q * tz
        fd.texture_force[:] = q * tx, q * ty, q * tz
    brk, k_ss = r.stick_slip[0], r.stick_slip[1]
    if brk > 0.0 and k_ss > 0.0:
        px, py, pz = fd.pos
        if not fd.anchored:
            fd.anchor[:] = shape_to_local(S, sh.xpos, sh.xmat, shape, px, py, pz)
            fd.anchored = True
        (ax, ay, az) = fd.anchor
        ox, oy, oz = shape_to_world(S, sh.xpos, sh.xmat, shape, ax, ay, az)
        ex, ey, ez = ox - px, oy - py, oz - pz
        en = ex * nx + ey * ny + ez * nz  # along the surface only
        ex, ey, ez = ex - en * nx, ey - en * ny, ez - en * nz
        sx, sy, sz = k_ss * ex, k_ss * ey, k_ss * ez
        if sx * sx + sy * sy + sz * sz > brk * brk:  # slips: the anchor jumps to the finger
            fd.anchor[:] = shape_to_local(S, sh.xpos, sh.xmat, shape, px, py, pz)
        else:
            fx, fy, fz = fx + sx, fy + sy, fz + sz
    return fx, fy, fz


@kernel
def pops(S, fd, shape, P):
    """True when the finger presses `shape` harder than its popthrough force (P, the
    coupling's normal force, N): the finger passes through it, and the broad phase leaves the
    shape out (`popped`) until the proxy is out of it again. The caller lets the god-object go
    of the contact where it is (its stretch, stored in the spring, is dropped: energy lost,
    never made)."""
    limit = S[shape].popthrough
    if not (limit > 0.0 and P > limit):
        return False
    fd.popped = shape
    return True


@kernel
def pop_done(sh, fm, fd):
    """The shape the finger popped through is felt again once the proxy is clear of it."""
    if fd.popped >= 0 and shape_distance(sh, fd.popped, fd.pos[0], fd.pos[1], fd.pos[2])[0] > fm.radius:
        fd.popped = -1


@kernel
def leave(fd):
    """Contact broken: the effects' state cleared."""
    fd.texture_force[:] = 0.0
    fd.vibration_phase = 0.0
    fd.anchored = False


@kernel
def magnet(sh, fm, fd):
    """The magnets' pull on the finger this tick into effect_force (N, world), added to its
    force out of contact: each magnetic shape within reach of the proxy pulls it toward its
    nearest point with F (1 - gap / reach), F at the surface (gap, the proxy's distance from
    the surface). In contact the pull holds the proxy on the surface, which bears it, and the
    hand feels the coupling alone (the field's store stays full until the finger leaves). The pull grows toward the surface, so a hand moved in and out under the
    zero-order hold takes in more than it gets: the field is passive as sampled; what it has
    given the hand on the way to here goes to `field_energy` (J), the passivity observer's
    account of the field. The touched (or nearest pulling) body gets the reaction. False when
    nothing pulls."""
    S = sh.S
    fx = fy = fz = 0.0
    given = 0.0
    pulled = False
    x, y, z = fd.pos
    best = math.inf
    for s in range(S.shape[0]):
        pull, reach = S[s].magnet[0], S[s].magnet[1]
        if not (pull > 0.0 and reach > 0.0):
            continue
        d, nx, ny, nz = shape_distance(sh, s, x, y, z)
        gap = d - fm.radius
        if gap < 0.0:
            gap = 0.0
        if gap >= reach:
            continue
        f = pull * (1.0 - gap / reach)
        given += 0.5 * f * (reach - gap)  # the work of the pull from its reach down to here
        fx, fy, fz = fx - f * nx, fy - f * ny, fz - f * nz
        pulled = True
        if fd.body < 0 and gap < best:  # the nearest pulling body takes the reaction
            best = gap
            fd.body = S[s].body
            r = d if d > 0.0 else 0.0
            fd.contact_pos[:] = x - r * nx, y - r * ny, z - r * nz
    fd.field_energy = given
    owed = fd.energy + given  # the observer's E over this tick's motion, against the store now
    if owed < fd.energy_min:
        fd.energy_min = owed
    if fd.contact:  # the pull holds the proxy on the surface, which bears it: the hand feels the coupling
        fx = fy = fz = 0.0
        pulled = False
    fd.effect_force[:] = fx, fy, fz
    if pulled:
        fd.force[0] += fx
        fd.force[1] += fy
        fd.force[2] += fz
    return pulled
