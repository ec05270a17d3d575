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
views of a finger record (`layout.FINGER`, `f` here) that call the `*_row` entries, `World`
calls `push` and `write_wrenches`, `ServoLoop` calls `tick`. Units: m, N, N·m, rad, s.
"""

from __future__ import annotations

import math

from numba import njit

from softproxy.compiled import coupling, godobject, passivity
from softproxy.compiled.finite import finite
from softproxy.compiled.guard import P_MAX, guard_wrench
from softproxy.compiled.godobject import RESTICK_FRACTION, RESTICK_SPIN, RESTICK_TRAVEL, restick_travel
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
@njit(cache=True, error_model="numpy")
def torsion_touch(f, alpha_s):
    """Contact made: the proxy twist starts at the finger's current twist α_s (rad), so the
    torque starts at zero (a non-finite twist counts as 0); stuck."""
    if not finite(alpha_s):
        alpha_s = 0.0
    f.in_contact = True
    f.alpha_0 = f.alpha_p = f.alpha_g = alpha_s
    f.spring_torque = f.limit = 0.0
    f.slipping = False
    f.slip_dir = f.slip_idle = f.slip_travel = 0.0


@njit(cache=True, error_model="numpy")
def torsion_release(f):
    """Contact broken: torsion state cleared, no torque."""
    f.in_contact = False
    f.alpha_0 = f.alpha_p = f.alpha_g = 0.0
    f.spring_torque = f.limit = 0.0
    f.slipping = False
    f.slip_dir = f.slip_idle = f.slip_travel = 0.0


@njit(cache=True, error_model="numpy")
def torsion_step(f, alpha_s, P, dt):
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
    if not f.in_contact:
        return 0.0
    if not finite(alpha_s):
        f.spring_torque = 0.0
        return 0.0
    P = abs(P)
    if not P <= P_MAX:
        P = P_MAX if P == P else 0.0
    if f.saturate:
        # the static limit follows the piecewise law of eq 26 (linear above P*, eq 27),
        # scaled from the model's μ'_m to this finger's μ_s
        mu_prime = f.mu_prime
        if mu_prime > 0.0:
            p_star = f.p_star
            if P <= p_star:
                law = mu_prime * P ** f.gamma
            else:
                law = f.r0 * (P - p_star) + mu_prime * p_star ** f.gamma
            limit = f.torsion_mu_s / mu_prime * law
        else:
            limit = 0.0
    else:
        limit = f.torsion_mu_s * P ** f.gamma
    f.alpha_g = alpha_s
    k_tau = f.k_tau
    stretch = f.alpha_p - alpha_s
    slack = limit * f.ratio / k_tau  # the dynamic offset μ_d|P|^γ/k_τ (rad)
    was = f.slipping
    # the slip state: still moving (slid RESTICK_TRAVEL of the offset within torsion_restick s)
    # the same way (the spring along the slip at least RESTICK_FRACTION of the dynamic
    # torque): dynamic friction
    if was and f.slip_idle < f.torsion_restick and stretch * f.slip_dir >= RESTICK_FRACTION * slack:
        if stretch * f.slip_dir > slack:  # the goal pulls on: trail it at the dynamic offset
            f.slip_travel += stretch * f.slip_dir - slack
            f.alpha_p = alpha_s + f.slip_dir * slack
        # the stop watch: time since α_p last slid RESTICK_TRAVEL of the offset
        if f.slip_travel >= restick_travel(RESTICK_TRAVEL * slack, RESTICK_SPIN, f.torsion_restick):
            f.slip_idle = f.slip_travel = 0.0
        else:
            f.slip_idle += dt
    # eq 39: the proxy sticks while the static limit exceeds the spring torque.
    elif limit > abs(k_tau * stretch):
        f.slipping = False
    else:
        # eq 40 with its missing sign: stay μ_d|P|^γ/k_τ behind the goal, on the side the
        # proxy was on, so the slipping torque keeps the twist's direction.
        if stretch > 0.0:
            f.alpha_p = alpha_s + slack
            f.slip_dir = 1.0
        elif stretch < 0.0:
            f.alpha_p = alpha_s - slack
            f.slip_dir = -1.0
        else:
            f.alpha_p = alpha_s
        if not was and stretch != 0.0:
            f.slip_events += 1
        f.slipping = stretch != 0.0
        f.slip_idle = f.slip_travel = 0.0
    f.limit = limit
    f.spring_torque = k_tau * (f.alpha_p - alpha_s)
    return f.spring_torque


@njit(cache=True, error_model="numpy")
def torsion_follow(f, omega_n, dt):
    """Eqs 41-42: α_p += (ω·n)Δt, the touched object's signed spin about n (rad/s) over Δt (s).
    The seed's |ω·n| would drag the proxy forwards whichever way the object turned; the signed
    value makes a stuck proxy turn with the object, in either direction."""
    if not f.in_contact:
        return
    alpha_p = f.alpha_p + omega_n * dt
    if finite(alpha_p):
        f.alpha_p = alpha_p


# -- the finger (softproxy.finger.SoftFingerProxy) -------------------------------------------
@njit(cache=True, error_model="numpy")
def clear_output(f):
    """Zero force and torque, no contact reported, the sample not used: the safe state."""
    f.fx = f.fy = f.fz = 0.0
    f.torque = f.tx = f.ty = f.tz = 0.0
    f.px = f.py = f.pz = 0.0
    f.body = -1
    f.normal_force = 0.0
    f.valid = False
    f.twist_prev = math.nan  # the torsional damper starts afresh at the next rendered tick


@njit(cache=True, error_model="numpy")
def _follow_body(S, cvel, f):
    """Eqs 41-42: the touched body's spin about n (rad/s, world; MuJoCo's cvel after mj_step1)
    drags α_p, signed."""
    if f.has_torsion and f.in_contact:
        b = int(S[int(f.touched)].body)
        omega_n = cvel[b, 0] * f.nx + cvel[b, 1] * f.ny + cvel[b, 2] * f.nz
        torsion_follow(f, omega_n, f.dt)
        f.body_turn = omega_n * f.dt


@njit(cache=True, error_model="numpy")
def place(sh, f, near, x, y, z):
    """Put the proxy at a device position (device frame, m), out of contact and torsion, the
    soft start's ramp back at zero. False, and the finger left unplaced, for a position
    outside the workspace: an unplaced finger places itself at its first good sample and
    renders nothing then."""
    xd, yd, zd = f.ox + f.scale * x, f.oy + f.scale * y, f.oz + f.scale * z
    if not godobject.reset(sh, f, near, xd, yd, zd):
        f.placed = False
        return False
    f.placed = True
    f.ramp = 0.0 if f.soft_start > 0.0 else 1.0
    f.energy = 0.0  # the passivity observer starts afresh: nothing stored, nothing owed
    f.xd, f.yd, f.zd = xd, yd, zd
    if f.has_torsion:
        torsion_release(f)
    return True


@njit(cache=True, error_model="numpy")
def hold(sh, f, near):
    """No usable device sample this tick: zero force, the proxy only follows its body. The
    soft start's ramp winds down as fast as it winds up, so after an outage of T s (a device
    error, invalid samples) the clamps come back from max·(1 - T/soft_start): a finger that
    moved into an object meanwhile gets no kick; one lost sample costs a hundredth of the
    clamp at 1 kHz (0.1 s soft start), not the grip. α_p turns with the touched body on every
    held tick, as the proxy follows it (keyed on the contact, not on `body`: clear_output
    empties that)."""
    S, cvel = sh.S, sh.cvel
    f.rel_dx = f.rel_dy = f.rel_dz = f.rel_turn = 0.0  # (nothing was sent over a held tick to count)
    if f.touched >= 0:
        _follow_body(S, cvel, f)
    if f.soft_start > 0.0:
        ramp = f.ramp - f.dt / f.soft_start
        f.ramp = ramp if ramp > 0.0 else 0.0
    if f.placed:
        godobject.follow(sh, f, near)
    clear_output(f)


@njit(cache=True, error_model="numpy")
def update(sh, f, near, x, y, z, twist, dt, scratch):
    """One tick from a device sample (device frame, m and rad) over period dt (s): god-object,
    virtual coupling, torsion. False when the sample was not used (a spike held back, a
    position outside the workspace, a non-finite twist): the finger then renders zero force."""
    S, xpos, xmat, cvel = sh.S, sh.xpos, sh.xmat, sh.cvel
    f.dt = dt
    f.body_turn = 0.0
    f.rel_dx = f.rel_dy = f.rel_dz = f.rel_turn = 0.0
    if f.touched >= 0:  # in contact last tick (or held since): the body it touches turns α_p with it
        _follow_body(S, cvel, f)
    if not f.placed:
        ok = place(sh, f, near, x, y, z) and finite(twist)
        clear_output(f)
        return ok
    xd = f.ox + f.scale * x
    yd = f.oy + f.scale * y
    zd = f.oz + f.scale * z
    # velocity-spike filter: a jump no hand makes in one period is held back for up to
    # SPIKE_PATIENCE ticks; a device that really moved that far is followed after that
    ex, ey, ez = xd - f.xd, yd - f.yd, zd - f.zd
    reach = f.max_speed * dt
    if ex * ex + ey * ey + ez * ez > reach * reach and f.spike_run < SPIKE_PATIENCE:
        f.spike_run += 1
        f.spikes_rejected += 1
        godobject.follow(sh, f, near)  # zero force; the proxy stays on its body
        clear_output(f)
        return False
    f.spike_run = 0
    if not finite(twist):  # an unusable sample: the proxy stays where it was, on its body
        godobject.follow(sh, f, near)
        clear_output(f)
        return False
    # for the damper, before the god-object moves the proxy: how far the touched surface
    # under the proxy moved relative to the device over the tick (the proxy is kept in the
    # touched geom's frame: the way that frame carried it; a shape that never moves, none)
    was_contact = f.contact
    wx, wy, wz = f.xd - xd, f.yd - yd, f.zd - zd
    shape = int(f.touched)
    if was_contact and shape >= 0 and not S[shape].static:
        cx, cy, cz = shape_to_world(S, xpos, xmat, shape, f.lx, f.ly, f.lz)
        wx, wy, wz = wx + cx - f.x, wy + cy - f.y, wz + cz - f.z
    f.rel_dx, f.rel_dy, f.rel_dz = wx, wy, wz  # (the passivity observer's port motion)
    if not godobject.update(sh, f, near, xd, yd, zd, dt, scratch[0], scratch[1], scratch[2], scratch[3]):
        clear_output(f)
        return False
    f.xd, f.yd, f.zd = xd, yd, zd
    f.valid = True
    if not f.contact:
        f.was_sticking = False
        if f.has_torsion and f.in_contact:
            torsion_release(f)
        f.fx = f.fy = f.fz = 0.0
        f.torque = f.tx = f.ty = f.tz = 0.0
        f.body = -1
        f.normal_force = 0.0
        return True

    if f.was_sticking and not f.sticking:
        f.slide_events += 1
    f.was_sticking = f.sticking
    # translational virtual coupling: the spring to the proxy, the damper on the device's
    # velocity relative to the touched surface (docs/coupling.md: never on the proxy's own
    # motion, which jumps when it breaks free or drops off an edge)
    sx, sy, sz = f.x - xd, f.y - yd, f.z - zd
    nx, ny, nz = f.nx, f.ny, f.nz
    if not was_contact:
        # contact made this tick: the proxy stopped on the surface part-way along the device's
        # move, so |s| is at most the device's move, counted from the touch on; and a device
        # that moved less than |s| (a finger placed inside an object: not at all) only that
        w2 = wx * wx + wy * wy + wz * wz
        s2 = sx * sx + sy * sy + sz * sz
        q = math.sqrt(w2 / s2) if w2 < s2 else 1.0
        wx, wy, wz = sx * q, sy * q, sz * q
    elif not f.sticking:  # slipping: along the surface friction acts, not the damper
        wn = wx * nx + wy * ny + wz * nz
        wx, wy, wz = wn * nx, wn * ny, wn * nz
    k = f.k
    c = f.b / dt  # (an unvalidated b of 1e308 makes c Inf and the force NaN: a counted fault)
    fx = k * sx + c * wx
    fy = k * sy + c * wy
    fz = k * sz + c * wz
    ramp = f.ramp
    if ramp < 1.0:  # soft start: no kick when a finger starts inside an object
        v = ramp + dt / f.soft_start
        ramp = v if v < 1.0 else 1.0
        f.ramp = ramp
    fmax = f.max_force * ramp
    f2 = fx * fx + fy * fy + fz * fz
    if f2 > fmax * fmax:
        s = fmax / math.sqrt(f2) if f2 > 0.0 else 0.0
        fx, fy, fz = fx * s, fy * s, fz * s
    P = fx * nx + fy * ny + fz * nz
    if P < 0.0:  # damping pulling the finger into the surface: contact carries no pull
        fx, fy, fz = fx - P * nx, fy - P * ny, fz - P * nz
        P = 0.0
    f.fx, f.fy, f.fz = fx, fy, fz
    f.normal_force = P
    r = f.radius
    f.px, f.py, f.pz = f.x - r * nx, f.y - r * ny, f.z - r * nz
    f.body = S[int(f.touched)].body
    fmag = math.sqrt(fx * fx + fy * fy + fz * fz)
    if fmag > f.max_force_seen:
        f.max_force_seen = fmag

    # torsional DOF (eqs 38–40)
    if not f.has_torsion:
        return True
    if not f.in_contact:
        torsion_touch(f, twist)
        f.twist_prev = twist
    M = torsion_step(f, twist, P, dt)
    if not finite(f.twist_prev):  # the first rendered tick after one that rendered nothing
        f.twist_prev = twist
    f.rel_turn = f.body_turn - (twist - f.twist_prev)
    # the torsional damper acts on the finger's twist rate relative to the touched body's spin
    # about n, b_τ(ω_body - α̇_s), as the translational one on the device's velocity relative
    # to the surface: never on the proxy's own jump when it slips (which flipped the torque's
    # sign for a tick at every slip). Slipping, dynamic friction acts, not the damper.
    if not f.slipping:
        M += f.b_tau / dt * f.rel_turn
    f.twist_prev = twist
    # the damping never takes |M| past what friction holds, nor past the clamp
    coupling.torque_within_laws(f, M)
    return True


@njit(cache=True, error_model="numpy")
def audit(sh, f):
    """Deepest the proxy sits inside any shape now (m, >= 0), kept in penetration_max: the
    check that no finger was let in. An unplaced finger has no proxy in the world yet: 0."""
    S = sh.S
    if not f.placed:
        return 0.0
    worst = 0.0
    for s in range(S.shape[0]):
        inside = f.radius - shape_distance(sh, s, f.x, f.y, f.z)[0]
        if inside > worst:
            worst = inside
    if worst > f.penetration_max:
        f.penetration_max = worst
    return worst


# -- the world's wrenches (softproxy.world.World) ---------------------------------------------
FIXED, TOUCHED, PUSHED = 0, 1, 2
"""Rows of the `bodies` array: welded to the world (1/0), touched this tick, pushed last tick."""


@njit(cache=True, error_model="numpy")
def _listed(bodies, n, body):
    """True when body is among bodies[:n]."""
    for j in range(n):
        if bodies[j] == body:
            return True
    return False


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def write_wrenches(xfrc, xipos, wrench, bodies, counts):
    """This tick's wrenches into xfrc_applied, each moved to its body's centre of mass
    (M_com = M_origin - c × F); last tick's cleared. counts = (touched this tick, pushed last tick)."""
    touched, pushed = bodies[TOUCHED], bodies[PUSHED]
    for j in range(counts[1]):
        body = pushed[j]
        if not _listed(touched, counts[0], body):
            for k in range(6):
                xfrc[body, k] = 0.0
    for j in range(counts[0]):
        body = touched[j]
        w = wrench[body]
        fx, fy, fz, mx, my, mz = w[0], w[1], w[2], w[3], w[4], w[5]
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


@njit(cache=True, error_model="numpy")
def _clamp_for_device(f, safe, fmax, tmax):
    """What the device is sent for this finger, into its sent_ fields: zero on the watchdog's
    zero-force tick (`safe`) or when the sample was not used, otherwise the wrench through
    `guard.guard_wrench` (finite, within the finger's and the device's clamps). False
    when the guard refused the wrench (not finite, or limits that are not numbers)."""
    good = True
    if safe or not f.valid:
        fx = fy = fz = tx = ty = tz = 0.0
    else:
        good, fx, fy, fz, tx, ty, tz = guard_wrench(f.fx, f.fy, f.fz, f.tx, f.ty, f.tz,
                                                    f.max_force, f.max_torque, fmax, tmax)
    f.sent_fx, f.sent_fy, f.sent_fz, f.sent_tx, f.sent_ty, f.sent_tz = fx, fy, fz, tx, ty, tz
    return good


@njit(cache=True, error_model="numpy")
def tick(mj, sh, fingers, dt, safe, check, fmax, tmax, control):
    """Every finger's part of `ServoLoop.tick`, after mj_step1 and before mj_step2 (`mj`,
    `sh`, `fingers`: MjViews, Shapes, FingerTables of `softproxy.compiled.layout`).

    Each finger record holds this tick's device sample in its in_ fields; a sample not valid
    (or from a failed read) or not finite holds the finger. The fingers' wrenches on moving
    bodies are then solved implicitly with the bodies' answer (`coupling.implicit`, over the
    mjModel/mjData, their qvel and qacc; `fingers.ws` its workspace), and each finger's
    energy observed, and with `control` the excess dissipated (`passivity`). Adds the fingers'
    wrenches to `wrench` (`write_wrenches` puts them in xfrc_applied) and writes what each
    device finger is sent into its sent_ fields. `bodies`: rows FIXED (welded to the world),
    TOUCHED and PUSHED (body lists, lengths in `counts`).
    Returns (refused, unsafe): how many valid samples were refused (not finite, or refused by
    their finger: spikes, garbage positions, a non-finite twist), and how many wrenches were
    not finite (zeroed before they reached a body or the device). The touched body gets the
    reaction of exactly the wrench the device is sent, after every clamp (the finger's, the
    device's, the soft start's), so both sides of the coupling exchange the same energy."""
    F, near, scratch, wrench, bodies, counts = (fingers.F, fingers.near, fingers.scratch, fingers.wrench,
                                                fingers.bodies, fingers.counts)
    refused = 0
    unsafe = 0
    for i in range(F.shape[0]):
        f = F[i]
        row = near[i]
        if not f.in_valid:
            hold(sh, f, row)
        elif not finite(f.in_x + f.in_y + f.in_z + f.in_qw + f.in_qx + f.in_qy + f.in_qz + f.in_twist):
            refused += 1
            hold(sh, f, row)
        else:
            if not update(sh, f, row, f.in_x, f.in_y, f.in_z, f.in_twist, dt, scratch):
                refused += 1
            if safe:
                clear_output(f)
            elif not finite(f.fx + f.fy + f.fz + f.tx + f.ty + f.tz):
                unsafe += 1
                clear_output(f)
        if check:
            audit(sh, f)
        passivity.observe(f)  # last tick's sends times this tick's motion
    if not safe:
        coupling.implicit(mj.m, mj.d, mj.qvel, mj.qacc, F, bodies[FIXED], dt, fingers.ws)
    for i in range(F.shape[0]):
        f = F[i]
        if control and not safe:
            passivity.control(f, dt)
        if not _clamp_for_device(f, safe, fmax, tmax):
            unsafe += 1
            clear_output(f)
        f.push_body = -1
        if f.body >= 0.0:  # one wrench for both sides: the body gets the reaction of what the device is sent
            push(wrench, bodies, counts, int(f.body), -f.sent_fx, -f.sent_fy, -f.sent_fz,
                 f.px, f.py, f.pz, -f.sent_tx, -f.sent_ty, -f.sent_tz)
            f.push_body = f.body
    return refused, unsafe


# -- entries for the views: record i of a table ----------------------------------------------
@njit(cache=True, error_model="numpy")
def torsion_touch_row(F, i, alpha_s):
    torsion_touch(F[i], alpha_s)


@njit(cache=True, error_model="numpy")
def torsion_release_row(F, i):
    torsion_release(F[i])


@njit(cache=True, error_model="numpy")
def torsion_step_row(F, i, alpha_s, P, dt):
    return torsion_step(F[i], alpha_s, P, dt)


@njit(cache=True, error_model="numpy")
def torsion_follow_row(F, i, omega_n, dt):
    torsion_follow(F[i], omega_n, dt)


@njit(cache=True, error_model="numpy")
def place_row(sh, F, near, i, x, y, z):
    return place(sh, F[i], near[i], x, y, z)


@njit(cache=True, error_model="numpy")
def hold_row(sh, F, near, i):
    hold(sh, F[i], near[i])


@njit(cache=True, error_model="numpy")
def update_row(sh, F, near, i, x, y, z, twist, dt, scratch):
    return update(sh, F[i], near[i], x, y, z, twist, dt, scratch)


@njit(cache=True, error_model="numpy")
def clear_output_row(F, i):
    clear_output(F[i])


@njit(cache=True, error_model="numpy")
def audit_row(sh, F, i):
    return audit(sh, F[i])
