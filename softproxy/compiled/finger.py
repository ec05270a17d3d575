"""The fingers of one servo tick (numba): coupling, torsion, wrenches on the bodies, device clamp.

Each finger is a 4-DOF soft-finger proxy (seed 002 §7): the god-object position
(`softproxy.compiled.godobject`) plus the twist α_p about the contact normal n, coupled to
the device by a virtual spring-damper, F = k(x_p - x_d) + b(v_s - v_d) and
M = k_τ(α_p - α_g) + b_τ(ω_b - α̇_s), the torsional damper on the device's twist rate
relative to the touched body's spin ω_b about n while stuck (none while slipping: dynamic
friction acts). The damper acts on the device's velocity v_d relative to the touched
surface's v_s under the proxy, never on the proxy's own motion, which jumps (breaking free
of friction, dropping off an edge): |b(v_s - v_d)| is bounded by
b times the device's speed relative to the surface, a proxy jump renders only its spring
force, and the damper dissipates (docs/coupling.md). F and M are what the finger feels; the
touched body gets -F at the contact point and -M·n. The device's twist α_s is taken about the
finger's own axis, from the fingertip back toward the hand: +n when it presses straight on.
`tick` runs every finger of a servo tick in one call: each finger's update (or hold, without
a usable sample), its wrench on the touched body (`push`; `write_wrenches` puts them in
MuJoCo), and what each device finger is sent, through `softproxy.compiled.guard.guard_wrench`.

These kernels are the only implementation: `SoftFingerProxy` and `TorsionalFriction` are
views of a finger's records (`layout.FINGER_MODEL` and `FINGER_DATA`, `fm` and `fd` here) that
call the `*_row` entries, `World`
calls `push` and `write_wrenches`, `ServoLoop` calls `tick`. Units: m, N, N·m, rad, s.
"""

from __future__ import annotations

import math


from softproxy.compiled import coupling, godobject, material, passivity
from softproxy.compiled.finite import finite
from softproxy.compiled.guard import P_MAX, guard_wrench
from softproxy.compiled.godobject import RESTICK_FRACTION, RESTICK_SPIN, RESTICK_TRAVEL, restick_travel
from softproxy.compiled.kernel import kernel
from softproxy.compiled.shapes import shape_distance, shape_to_world

SPIKE_PATIENCE = 3
"""Consecutive ticks a position jump is held back as a spike before it is believed."""


# -- torsion (eqs 38-42; `softproxy.torsion.TorsionalFriction` is the view) ---------------------
# Seed 002 §7 with DESIGN's errata: eq 40 lacks sign(α_g - α_p), without which a slip in the
# negative direction overshoots the goal and flips the torque; eq 41's |ω·n| loses the way the
# object turned. The goal α_g is the device twist measured from where contact began: α_p
# starts at the device twist, so M starts at zero. Angles are right-handed about n (out of
# the object, toward the finger); M is the torque on the finger, the object gets -M about n.
#
# The slip state (a choice; docs/friction.md): eq 39 read literally re-tests the static limit
# every tick, so under a steady twist the proxy slips to μ_d|P|^γ, sticks until the spring
# climbs back to μ_s|P|^γ, slips again: a saw-tooth of ~110 Hz at 0.1 rad/s (P = 1 N,
# k_τ = 2). Here, as in Karnopp's model, a slipping contact stays in dynamic friction
# (|M| = μ_d|P|^γ, α_p trailing the goal) until the relative motion stops (it takes longer
# than `torsion_restick` s to slide a further RESTICK_TRAVEL of its offset) or reverses (k_τ(α_p - α_g) along the slip below RESTICK_FRACTION of
# μ_d|P|^γ); only then is eq 39's static limit needed to slip again. `torsion_restick` = 0
# is eq 39 as printed, every tick.
@kernel
def torsion_touch(fd, alpha_s):
    """Contact made: the proxy twist starts at the finger's current twist α_s (rad), so the
    torque starts at zero (a non-finite twist counts as 0); stuck."""
    if not finite(alpha_s):
        alpha_s = 0.0
    fd.in_contact = True
    fd.alpha_0 = fd.alpha_p = fd.alpha_g = alpha_s
    fd.spring_torque = fd.limit = 0.0
    fd.slipping = False
    fd.slip_dir = fd.slip_idle = fd.slip_travel = 0.0


@kernel
def torsion_release(fd):
    """Contact broken: torsion state cleared, no torque."""
    fd.in_contact = False
    fd.alpha_0 = fd.alpha_p = fd.alpha_g = 0.0
    fd.spring_torque = fd.limit = 0.0
    fd.slipping = False
    fd.slip_dir = fd.slip_idle = fd.slip_travel = 0.0


@kernel
def torsion_step(fm, fd, alpha_s, P, dt):
    """One servo tick of dt s (eqs 38-40, with the slip state): new α_p from device twist α_s
    (rad) and normal force P (N).

    Returns M = k_τ(α_p - α_g), the torque on the finger about n (N·m). A non-finite α_s
    holds the state and returns 0; a non-finite P counts as no normal force, one above P_MAX
    as P_MAX (so |P|^γ cannot overflow). The static limit is torsion_mu_s·|P|^γ, or eq 26's
    saturating law; the dynamic torque is the static limit times μ_d/μ_s (`ratio`).

    Stuck, α_p stays while the static limit exceeds |M| (eq 39); past it the contact slips
    (one slip event) and α_p goes to μ_d|P|^γ/k_τ short of the goal (eq 40, signed).
    Slipping, it keeps slipping while it has slid RESTICK_TRAVEL of its dynamic offset within
    `torsion_restick` s and the spring torque along the slip is at least RESTICK_FRACTION of
    μ_d|P|^γ: α_p trails the goal by μ_d|P|^γ/k_τ when the goal pulls on, and holds when it
    does not."""
    if not fd.in_contact:
        return 0.0
    if not finite(alpha_s):
        fd.spring_torque = 0.0
        return 0.0
    P = abs(P)
    if not P <= P_MAX:
        P = P_MAX if P == P else 0.0
    if fm.saturate:
        # the static limit follows the piecewise law of eq 26 (linear above P*, eq 27),
        # scaled from the model's μ'_m to this finger's μ_s
        mu_prime = fm.mu_prime
        if mu_prime > 0.0:
            p_star = fm.p_star
            if P <= p_star:
                law = mu_prime * P ** fm.gamma
            else:
                law = fm.r0 * (P - p_star) + mu_prime * p_star ** fm.gamma
            limit = fm.torsion_mu_s / mu_prime * law
        else:
            limit = 0.0
    else:
        limit = fm.torsion_mu_s * P ** fm.gamma
    limit *= fd.contact_torsion  # the touched material's share (1: none)
    fd.alpha_g = alpha_s
    k_tau = fm.torsion_stiffness
    stretch = fd.alpha_p - alpha_s
    slack = limit * fm.ratio / k_tau  # the dynamic offset μ_d|P|^γ/k_τ (rad)
    was = fd.slipping
    # the slip state: still moving (slid RESTICK_TRAVEL of the offset within torsion_restick s)
    # the same way (the spring along the slip at least RESTICK_FRACTION of the dynamic
    # torque): dynamic friction
    if was and fd.slip_idle < fm.torsion_restick and stretch * fd.slip_dir >= RESTICK_FRACTION * slack:
        if stretch * fd.slip_dir > slack:  # the goal pulls on: trail it at the dynamic offset
            fd.slip_travel += stretch * fd.slip_dir - slack
            fd.alpha_p = alpha_s + fd.slip_dir * slack
        # the stop watch: time since α_p last slid RESTICK_TRAVEL of the offset
        if fd.slip_travel >= restick_travel(RESTICK_TRAVEL * slack, RESTICK_SPIN, fm.torsion_restick):
            fd.slip_idle = fd.slip_travel = 0.0
        else:
            fd.slip_idle += dt
    # eq 39: the proxy sticks while the static limit exceeds the spring torque.
    elif limit > abs(k_tau * stretch):
        fd.slipping = False
    else:
        # eq 40 with its missing sign: stay μ_d|P|^γ/k_τ behind the goal, on the side the
        # proxy was on, so the slipping torque keeps the twist's direction.
        if stretch > 0.0:
            fd.alpha_p = alpha_s + slack
            fd.slip_dir = 1.0
        elif stretch < 0.0:
            fd.alpha_p = alpha_s - slack
            fd.slip_dir = -1.0
        else:
            fd.alpha_p = alpha_s
        if not was and stretch != 0.0:
            fd.slip_events += 1
        fd.slipping = stretch != 0.0
        fd.slip_idle = fd.slip_travel = 0.0
    fd.limit = limit
    fd.spring_torque = k_tau * (fd.alpha_p - alpha_s)
    return fd.spring_torque


@kernel
def torsion_follow(fd, omega_n, dt):
    """Eqs 41-42: α_p += (ω·n)Δt, the touched object's signed spin about n (rad/s) over Δt (s).
    The seed's |ω·n| would drag the proxy forwards whichever way the object turned; the signed
    value makes a stuck proxy turn with the object, in either direction."""
    if not fd.in_contact:
        return
    alpha_p = fd.alpha_p + omega_n * dt
    if finite(alpha_p):
        fd.alpha_p = alpha_p


# -- the finger (softproxy.finger.SoftFingerProxy) -------------------------------------------
@kernel
def clear_output(fd):
    """Zero force and torque, no contact reported, the sample not used: the safe state."""
    fd.force[:] = 0.0
    fd.torque_n = fd.torque[:] = 0.0
    fd.contact_pos[:] = 0.0
    fd.body = -1
    fd.normal_force = 0.0
    fd.valid = False
    fd.twist_prev = math.nan  # the torsional damper starts afresh at the next rendered tick


@kernel
def _follow_body(S, cvel, fm, fd):
    """Eqs 41-42: the touched body's spin about n (rad/s, world; MuJoCo's cvel after mj_step1)
    drags α_p, signed."""
    if fm.has_torsion and fd.in_contact:
        b = int(S[int(fd.touched)].body)
        omega_n = cvel[b, 0] * fd.normal[0] + cvel[b, 1] * fd.normal[1] + cvel[b, 2] * fd.normal[2]
        torsion_follow(fd, omega_n, fd.dt)
        fd.body_turn = omega_n * fd.dt


@kernel(inline="always")
def to_world(fm, x, y, z):
    """A device position (device frame, m) in the world (m): origin + scale × device."""
    ox, oy, oz = fm.origin
    s = fm.scale
    return ox + s * x, oy + s * y, oz + s * z


@kernel
def place(sh, fm, fd, near, x, y, z):
    """Put the proxy at a device position (device frame, m), out of contact and torsion, the
    soft start's ramp back at zero. False, and the finger left unplaced, for a position
    outside the workspace: an unplaced finger places itself at its first good sample and
    renders nothing then."""
    xd, yd, zd = to_world(fm, x, y, z)
    if not godobject.reset(sh, fm, fd, near, xd, yd, zd):
        fd.placed = False
        return False
    fd.placed = True
    fd.ramp = 0.0 if fm.soft_start > 0.0 else 1.0
    fd.energy = 0.0  # the passivity observer starts afresh: nothing stored, nothing owed
    fd.device_pos[:] = xd, yd, zd
    if fm.has_torsion:
        torsion_release(fd)
    return True


@kernel
def hold(sh, fm, fd, near):
    """No usable device sample this tick: zero force, the proxy only follows its body. The
    soft start's ramp winds down as fast as it winds up, so after an outage of T s (a device
    error, invalid samples) the clamps come back from max·(1 - T/soft_start): a finger that
    moved into an object meanwhile gets no kick; one lost sample costs a hundredth of the
    clamp at 1 kHz (0.1 s soft start), not the grip. α_p turns with the touched body on every
    held tick, as the proxy follows it (keyed on the contact, not on `body`: clear_output
    empties that)."""
    S, cvel = sh.S, sh.cvel
    fd.rel_move[:] = fd.rel_turn = 0.0  # (nothing was sent over a held tick to count)
    fd.surface_move[:] = 0.0
    if fd.touched >= 0:
        _follow_body(S, cvel, fm, fd)
    if fm.soft_start > 0.0:
        ramp = fd.ramp - fd.dt / fm.soft_start
        fd.ramp = ramp if ramp > 0.0 else 0.0
    if fd.placed:
        godobject.follow(sh, fm, fd, near)
    clear_output(fd)


@kernel
def _free(fm, fd):
    """A tick out of contact: torsion and the surface's effects let go, nothing rendered."""
    fd.was_sticking = False
    if fm.has_torsion and fd.in_contact:
        torsion_release(fd)
    material.leave(fd)
    fd.force[:] = 0.0
    fd.torque_n = fd.torque[:] = 0.0
    fd.body = -1
    fd.normal_force = 0.0


@kernel
def update(sh, fm, fd, near, x, y, z, twist, dt, scratch):
    """One tick from a device sample (device frame, m and rad) over period dt (s): god-object,
    virtual coupling, torsion. False when the sample was not used (a spike held back, a
    position outside the workspace, a non-finite twist): the finger then renders zero force."""
    S, xpos, xmat, cvel = sh.S, sh.xpos, sh.xmat, sh.cvel
    fd.dt = dt
    fd.body_turn = 0.0
    fd.rel_move[:] = fd.rel_turn = 0.0
    fd.surface_move[:] = 0.0
    if fd.touched >= 0:  # in contact last tick (or held since): the body it touches turns α_p with it
        _follow_body(S, cvel, fm, fd)
    if not fd.placed:
        ok = place(sh, fm, fd, near, x, y, z) and finite(twist)
        clear_output(fd)
        return ok
    xd, yd, zd = to_world(fm, x, y, z)
    # velocity-spike filter: a jump no hand makes in one period is held back for up to
    # SPIKE_PATIENCE ticks; a device that really moved that far is followed after that
    ex, ey, ez = xd - fd.device_pos[0], yd - fd.device_pos[1], zd - fd.device_pos[2]
    reach = fm.max_speed * dt
    if ex * ex + ey * ey + ez * ez > reach * reach and fd.spike_run < SPIKE_PATIENCE:
        fd.spike_run += 1
        fd.spikes_rejected += 1
        godobject.follow(sh, fm, fd, near)  # zero force; the proxy stays on its body
        clear_output(fd)
        return False
    fd.spike_run = 0
    if not finite(twist):  # an unusable sample: the proxy stays where it was, on its body
        godobject.follow(sh, fm, fd, near)
        clear_output(fd)
        return False
    # for the damper, before the god-object moves the proxy: how far the touched surface
    # under the proxy moved relative to the device over the tick (the proxy is kept in the
    # touched geom's frame: the way that frame carried it; a shape that never moves, none)
    was_contact = fd.contact
    wx, wy, wz = fd.device_pos[0] - xd, fd.device_pos[1] - yd, fd.device_pos[2] - zd
    shape = int(fd.touched)
    bx = by = bz = 0.0
    if was_contact and shape >= 0 and not S[shape].static:
        cx, cy, cz = shape_to_world(S, xpos, xmat, shape, fd.local[0], fd.local[1], fd.local[2])
        bx, by, bz = cx - fd.pos[0], cy - fd.pos[1], cz - fd.pos[2]
        wx, wy, wz = wx + bx, wy + by, wz + bz
    fd.rel_move[:] = wx, wy, wz  # (the passivity observer's port motion)
    fd.surface_move[:] = bx, by, bz
    material.pop_done(sh, fm, fd)
    if not godobject.update(sh, fm, fd, near, xd, yd, zd, dt, scratch[0], scratch[1], scratch[2], scratch[3]):
        clear_output(fd)
        return False
    fd.device_pos[:] = xd, yd, zd
    fd.valid = True
    if not fd.contact:
        _free(fm, fd)
        return True

    touched = int(fd.touched)
    material.touch(sh, fm, fd, touched)
    if fd.was_sticking and not fd.sticking:
        fd.slide_events += 1
    fd.was_sticking = fd.sticking
    # translational virtual coupling: the spring to the proxy, the damper on the device's
    # velocity relative to the touched surface (docs/coupling.md: never on the proxy's own
    # motion, which jumps when it breaks free or drops off an edge)
    sx, sy, sz = fd.pos[0] - xd, fd.pos[1] - yd, fd.pos[2] - zd
    nx, ny, nz = fd.normal
    if not was_contact:
        # contact made this tick: the proxy stopped on the surface part-way along the device's
        # move, so |s| is at most the device's move, counted from the touch on; and a device
        # that moved less than |s| (a finger placed inside an object: not at all) only that
        w2 = wx * wx + wy * wy + wz * wz
        s2 = sx * sx + sy * sy + sz * sz
        q = math.sqrt(w2 / s2) if w2 < s2 else 1.0
        wx, wy, wz = sx * q, sy * q, sz * q
    elif not fd.sticking:  # slipping: along the surface friction acts, not the damper
        wn = wx * nx + wy * ny + wz * nz
        wx, wy, wz = wn * nx, wn * ny, wn * nz
    k = fd.contact_stiffness
    c = fd.contact_damping / dt  # (an unvalidated b of 1e308 makes c Inf and the force NaN: a counted fault)
    fx = k * sx + c * wx
    fy = k * sy + c * wy
    fz = k * sz + c * wz
    if S[touched].material:  # the surface's effects, scaled by the coupling's normal force
        P = fx * nx + fy * ny + fz * nz
        if material.pops(S, fd, touched, P):  # through it: nothing to render this tick
            godobject.let_go(fd)
            _free(fm, fd)
            return True
        ex, ey, ez = material.surface_force(sh, fm, fd, touched, P if P > 0.0 else 0.0, dt)
        fx, fy, fz = fx + ex, fy + ey, fz + ez
    ramp = fd.ramp
    if ramp < 1.0:  # soft start: no kick when a finger starts inside an object
        v = ramp + dt / fm.soft_start
        ramp = v if v < 1.0 else 1.0
        fd.ramp = ramp
    fmax = fm.max_force * ramp
    f2 = fx * fx + fy * fy + fz * fz
    if f2 > fmax * fmax:
        s = fmax / math.sqrt(f2) if f2 > 0.0 else 0.0
        fx, fy, fz = fx * s, fy * s, fz * s
    P = fx * nx + fy * ny + fz * nz
    if P < 0.0:  # damping pulling the finger into the surface: contact carries no pull
        fx, fy, fz = fx - P * nx, fy - P * ny, fz - P * nz
        P = 0.0
    fd.force[:] = fx, fy, fz
    fd.normal_force = P
    r = fm.radius
    fd.contact_pos[:] = fd.pos[0] - r * nx, fd.pos[1] - r * ny, fd.pos[2] - r * nz
    fd.body = S[touched].body
    fmag = math.sqrt(fx * fx + fy * fy + fz * fz)
    if fmag > fd.max_force_seen:
        fd.max_force_seen = fmag

    # torsional DOF (eqs 38–40)
    if not fm.has_torsion:
        return True
    if not fd.in_contact:
        torsion_touch(fd, twist)
        fd.twist_prev = twist
    M = torsion_step(fm, fd, twist, P, dt)
    if not finite(fd.twist_prev):  # the first rendered tick after one that rendered nothing
        fd.twist_prev = twist
    fd.rel_turn = fd.body_turn - (twist - fd.twist_prev)
    # the torsional damper acts on the finger's twist rate relative to the touched body's spin
    # about n, b_τ(ω_body - α̇_s), as the translational one on the device's velocity relative
    # to the surface: never on the proxy's own jump when it slips (which flipped the torque's
    # sign for a tick at every slip). Slipping, dynamic friction acts, not the damper.
    if not fd.slipping:
        M += fm.torsion_damping / dt * fd.rel_turn
    fd.twist_prev = twist
    # the damping never takes |M| past what friction holds, nor past the clamp
    coupling.torque_within_laws(fm, fd, M)
    return True


@kernel
def audit(sh, fm, fd):
    """Deepest the proxy sits inside any shape now (m, >= 0), kept in penetration_max: the
    check that no finger was let in. An unplaced finger has no proxy in the world yet: 0."""
    S = sh.S
    if not fd.placed:
        return 0.0
    worst = 0.0
    for s in range(S.shape[0]):
        if s == fd.popped:  # passed through on purpose
            continue
        inside = fm.radius - shape_distance(sh, s, fd.pos[0], fd.pos[1], fd.pos[2])[0]
        if inside > worst:
            worst = inside
    if worst > fd.penetration_max:
        fd.penetration_max = worst
    return worst


# -- the world's wrenches (softproxy.world.World) ---------------------------------------------
FIXED, TOUCHED, PUSHED = 0, 1, 2
"""Rows of the `bodies` array: welded to the world (1/0), touched this tick, pushed last tick."""


@kernel
def _listed(bodies, n, body):
    """True when body is among bodies[:n]."""
    for j in range(n):
        if bodies[j] == body:
            return True
    return False


@kernel
def push(wrench, bodies, counts, body, fx, fy, fz, px, py, pz, tx, ty, tz):
    """Force (N) at world point p (m) plus a pure torque (N·m) on `body`, added to this tick's
    wrench about the world origin (so no body position is read per push); nothing on a body
    welded to the world."""
    if bodies[FIXED, body]:
        return
    touched = bodies[TOUCHED]
    if not _listed(touched, counts[0], body):
        touched[counts[0]] = body
        counts[0] += 1
    w = wrench[body]
    w[0] += fx
    w[1] += fy
    w[2] += fz
    w[3] += py * fz - pz * fy + tx
    w[4] += pz * fx - px * fz + ty
    w[5] += px * fy - py * fx + tz


@kernel(entry=True)
def write_wrenches(xfrc, xipos, wrench, bodies, counts, scale):
    """The wrenches summed since the last write into xfrc_applied, times `scale` (1 / the
    haptic ticks summed: their average), each moved to its body's centre of mass
    (M_com = M_origin - c × F); the last write's cleared. counts = (touched since, pushed last write)."""
    touched, pushed = bodies[TOUCHED], bodies[PUSHED]
    for j in range(counts[1]):
        body = pushed[j]
        if not _listed(touched, counts[0], body):
            for k in range(6):
                xfrc[body, k] = 0.0
    for j in range(counts[0]):
        body = touched[j]
        w = wrench[body]
        fx, fy, fz, mx, my, mz = w[0] * scale, w[1] * scale, w[2] * scale, w[3] * scale, w[4] * scale, w[5] * scale
        cx, cy, cz = xipos[body, 0], xipos[body, 1], xipos[body, 2]
        xfrc[body, 0], xfrc[body, 1], xfrc[body, 2] = fx, fy, fz
        xfrc[body, 3] = mx - (cy * fz - cz * fy)
        xfrc[body, 4] = my - (cz * fx - cx * fz)
        xfrc[body, 5] = mz - (cx * fy - cy * fx)
        for k in range(6):
            w[k] = 0.0
        pushed[j] = body
    counts[1] = counts[0]
    counts[0] = 0


@kernel
def _clamp_for_device(fm, fd, safe, fmax, tmax):
    """What the device is sent for this finger, into its sent_ fields: zero on the watchdog's
    zero-force tick (`safe`) or when the sample was not used, otherwise the wrench through
    `guard.guard_wrench` (finite, within the finger's and the device's clamps). False
    when the guard refused the wrench (not finite, or limits that are not numbers)."""
    good = True
    if safe or not fd.valid:
        fx = fy = fz = tx = ty = tz = 0.0
    else:
        (fx, fy, fz), (tx, ty, tz) = fd.force, fd.torque
        good, fx, fy, fz, tx, ty, tz = guard_wrench(fx, fy, fz, tx, ty, tz, fm.max_force, fm.max_torque, fmax, tmax)
    fd.sent_force[:] = fx, fy, fz
    fd.sent_torque[:] = tx, ty, tz
    return good


@kernel
def tick(mj, sh, fingers, dt, safe, check, fmax, tmax, control, cr):
    """Every finger's part of `ServoLoop.tick`, after mj_step1 and before mj_step2 (`mj`,
    `sh`, `fingers`: MjViews, Shapes, FingerTables of `softproxy.compiled.layout`).

    Each finger's data holds this tick's device sample in its in_ fields; a sample not valid
    (or from a failed read) or not finite holds the finger. The fingers' wrenches on moving
    bodies are then solved implicitly with the bodies' answer (`coupling.implicit`, over the
    mjModel/mjData, their qvel and qacc; `fingers.ws` its workspace), and each finger's
    energy observed, and with `control` the excess dissipated (`passivity`). Adds the fingers'
    wrenches to `wrench` (`write_wrenches` puts them in xfrc_applied) and writes what each
    device finger is sent into its sent_ fields (the body gets the reaction less a texture's
    relief, `material.surface_force`). With two rates (`cr`, the local model; None
    with one rate) the coupling solves against the local model's velocity and held
    acceleration (and the caller lets the sent wrenches move it: `carry.respond`). `bodies`:
    rows FIXED (welded to the world), TOUCHED and PUSHED (body lists, lengths in `counts`).
    Returns (refused, unsafe, coupled): how many valid samples were refused (not finite, or refused by
    their finger: spikes, garbage positions, a non-finite twist), and how many wrenches were
    not finite (zeroed before they reached a body or the device), and how many fingers the
    implicit coupling coupled (their rows of `fingers.ws`). The touched body gets the
    reaction of exactly the wrench the device is sent (less a texture's relief, the hand's
    alone), after every clamp (the finger's, the
    device's, the soft start's), so both sides of the coupling exchange the same energy."""
    FM, FD, near, scratch = fingers.rows
    wrench, bodies, counts = fingers.wrench, fingers.bodies, fingers.counts
    refused = 0
    unsafe = 0
    for i in range(FD.shape[0]):
        fm, fd = FM[i], FD[i]
        row = near[i]
        if not fd.in_valid:
            hold(sh, fm, fd, row)
        elif not finite(fd.in_pos.sum() + fd.in_quat.sum() + fd.in_twist):
            refused += 1
            hold(sh, fm, fd, row)
        else:
            if not update(sh, fm, fd, row, fd.in_pos[0], fd.in_pos[1], fd.in_pos[2], fd.in_twist, dt, scratch):
                refused += 1
            if safe:
                clear_output(fd)
            elif not finite(fd.force.sum() + fd.torque.sum()):
                unsafe += 1
                clear_output(fd)
        if check:
            audit(sh, fm, fd)
        passivity.observe(fm, fd)  # last tick's sends times this tick's motion
    coupled = 0
    if not safe:
        if cr is not None:
            coupled = coupling.implicit(mj.m, mj.d, mj.mass, cr.qvel, cr.qacc_free, FM, FD, bodies[FIXED], dt,
                                        fingers.ws, False)
        else:
            coupled = coupling.implicit(mj.m, mj.d, mj.mass, mj.qvel, mj.qacc, FM, FD, bodies[FIXED], dt, fingers.ws,
                                        True)
    for i in range(FD.shape[0]):
        fm, fd = FM[i], FD[i]
        if control and not safe:
            passivity.control(fm, fd, dt)
        if fm.magnets and fd.valid and not safe:
            material.magnet(sh, fm, fd)
        if not _clamp_for_device(fm, fd, safe, fmax, tmax):
            unsafe += 1
            clear_output(fd)
        fd.push_body = -1
        fd.texture_sent[:] = 0.0
        if fd.body >= 0.0:  # one wrench for both sides: the body gets the reaction of what the device is sent
            (fx, fy, fz), (tx, ty, tz), (px, py, pz) = fd.sent_force, fd.sent_torque, fd.contact_pos
            if fd.valid and not safe:  # less a texture's relief, the hand's alone
                (ex, ey, ez) = fd.texture_force
                fx, fy, fz = fx - ex, fy - ey, fz - ez
                fd.texture_sent[:] = ex, ey, ez
            push(wrench, bodies, counts, int(fd.body), -fx, -fy, -fz, px, py, pz, -tx, -ty, -tz)
            fd.push_body = fd.body
    return refused, unsafe, coupled


# -- entries for the views: finger i of a table (`fg`: a `layout.Fingers`) ----------------------
@kernel(entry=True)
def torsion_touch_row(fg, i, alpha_s):
    torsion_touch(fg.data[i], alpha_s)


@kernel(entry=True)
def torsion_release_row(fg, i):
    torsion_release(fg.data[i])


@kernel(entry=True)
def torsion_step_row(fg, i, alpha_s, P, dt):
    return torsion_step(fg.model[i], fg.data[i], alpha_s, P, dt)


@kernel(entry=True)
def torsion_follow_row(fg, i, omega_n, dt):
    torsion_follow(fg.data[i], omega_n, dt)


@kernel(entry=True)
def place_row(sh, fg, i, x, y, z):
    return place(sh, fg.model[i], fg.data[i], fg.near[i], x, y, z)


@kernel(entry=True)
def hold_row(sh, fg, i):
    hold(sh, fg.model[i], fg.data[i], fg.near[i])


@kernel(entry=True)
def update_row(sh, fg, i, x, y, z, twist, dt):
    return update(sh, fg.model[i], fg.data[i], fg.near[i], x, y, z, twist, dt, fg.scratch)


@kernel(entry=True)
def clear_output_row(fg, i):
    clear_output(fg.data[i])


@kernel(entry=True)
def audit_row(sh, fg, i):
    return audit(sh, fg.model[i], fg.data[i])
