"""Two rates: the shapes the haptic ticks touch, carried forward between MuJoCo's steps.

With `ServoLoop(physics_rate_hz=...)` MuJoCo steps once every `every` haptic ticks (its step
H = every × the servo period) and the haptic ticks in between render against a local model
of the world (Adachi's "intermediate representation"): every moving shape near a finger at
the pose MuJoCo's last state gives, carried forward with its body's velocity, and with its
body's response to the fingers' own wrenches since that state (one generalised-velocity
change per tick, through the operational-space response the implicit coupling computes:
`softproxy.compiled.coupling`). MuJoCo then integrates each finger's wrench averaged over
the haptic ticks of its step (`finger.write_wrenches`' scale).

At each MuJoCo step the carried pose and the new state differ by what the local model left
out (the other contacts, the change of the mass matrix, and MuJoCo's own integration: its
Euler step moves a body by H times its velocity at the end of the step, half a step's
velocity change ahead of the local model). That difference is not a jump: it is kept as an
offset that fades out linearly over FADE_STEPS steps (`body_err`; what is left of the last
offset at an update is carried into the next), so a shape's carried pose is continuous
across updates and converges on MuJoCo's trajectory. A body's pose is carried about its
centre of mass (xipos) by a rotation vector θ and a displacement p:

    θ(τ) = ω τ + Θ(τ) + f(τ) e_θ,   p(τ) = v τ + P(τ) + f(τ) e_p,   f(τ) = 1 - τ / (FADE_STEPS H),

ω, v the body's velocity at MuJoCo's last state (v at its centre of mass), Θ, P the integral
of the fingers' response since then, e the offset kept at the update; a geom at x₀, R₀ then is
at c + p + R(θ)(x₀ - c), R(θ) R₀. The carried angular velocity (cvel's first three, which
drags the fingers' torsion, eqs 41-42) is ω + Θ' - e_θ / (FADE_STEPS H). Units: m, s, rad.

Measured on the shipped grasp (a 100 g box, k = 2000 N/m, a 1 kHz loop; docs/engine-log.md):
without the fingers' response in the local model the force rang at the physics rate (steps
of 0.5 N p99 at 250 Hz); with it, the force's largest step at 100 to 250 Hz is the one-rate
run's own (0.25 N, at first touch). An offset faded over one step fed MuJoCo's integration
error back through the fingers' damper each step: at 100 Hz (kH²/m = 2) the box's velocity
rang and the grasp was lost, and at 50 Hz too; faded over 2, 4 or 8 steps it holds at both
(largest step 0.25 N at 100 Hz, 0.38 N at 50 Hz with 4). Starting each step half a velocity
change ahead, to meet MuJoCo's Euler step, was tried and made it worse.
"""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel


# a body's rows in body_vel, body_err, body_off and body_spin: angular (3), then linear (3)
FADE_STEPS = 4.0
"""MuJoCo steps over which the offset between a carried pose and MuJoCo's new one fades out
(the module docstring: over one step the grasp rang at 100 Hz)."""
NEAR_MARGIN = 2e-3
"""m beyond a finger's broad-phase ball (and the shape's own motion over a step) within
which a moving shape is carried every tick."""


@kernel(inline="always")
def _rotate(tx, ty, tz, x, y, z):
    """R(θ) applied to (x, y, z): the rotation by the rotation vector θ (rad), Rodrigues."""
    a2 = tx * tx + ty * ty + tz * tz
    if a2 < 1e-16:  # second order: sin a / a → 1, (1 - cos a) / a² → 1/2
        s, c = 1.0, 0.5
    else:
        a = math.sqrt(a2)
        s, c = math.sin(a) / a, (1.0 - math.cos(a)) / a2
    # θ × v and θ × (θ × v)
    cx, cy, cz = ty * z - tz * y, tz * x - tx * z, tx * y - ty * x
    dx, dy, dz = ty * cz - tz * cy, tz * cx - tx * cz, tx * cy - ty * cx
    return x + s * cx + c * dx, y + s * cy + c * dy, z + s * cz + c * dz


@kernel
def _log(R):
    """The rotation vector (rad) of the 3×3 rotation R (row-major 9): axis × angle."""
    tr = R[0] + R[4] + R[8]
    c = 0.5 * (tr - 1.0)
    c = 1.0 if c > 1.0 else (-1.0 if c < -1.0 else c)
    a = math.acos(c)
    wx, wy, wz = R[7] - R[5], R[2] - R[6], R[3] - R[1]
    if a < 1e-6:
        return 0.5 * wx, 0.5 * wy, 0.5 * wz
    s = math.sin(a)
    if s < 1e-6:  # a half turn: the axis from the symmetric part
        x = math.sqrt(max(0.0, 0.5 * (R[0] + 1.0)))
        y = math.sqrt(max(0.0, 0.5 * (R[4] + 1.0)))
        z = math.sqrt(max(0.0, 0.5 * (R[8] + 1.0)))
        y = y if R[1] >= 0.0 else -y
        z = z if R[2] >= 0.0 else -z
        return a * x, a * y, a * z
    k = 0.5 * a / s
    return k * wx, k * wy, k * wz


@kernel
def snapshot(cr, dt, H, fresh):
    """At a MuJoCo step (after mj_step1): its state becomes the local model's. The offset each
    moving body's carried pose had from the new state is kept to fade (none when `fresh`:
    the loop's first step). Every shape's carried pose restarts from MuJoCo's (those near a
    finger are carried again by `carry` this tick). dt: the time since the last state (s; a
    step, H, in lockstep; what MuJoCo's thread took in a threaded run).

    The local model's generalised acceleration without the fingers (`qacc_free`: gravity,
    the other contacts, all held over the step) is MuJoCo's last one less the fingers' part
    of it, which the local model itself integrated over the last step (`dqvel`)."""
    for b in cr.moving:
        c = cr.body_com[b]
        v = cr.body_vel[b]
        e = cr.body_err[b]
        o = cr.body_off[b]
        # the new state: centre of mass, orientation (ximat), ω and v at the centre of mass
        # (MuJoCo's cvel: ω, and the velocity of the point at the subtree's centre of mass)
        nc = cr.xipos[b]
        sc = cr.subtree_com[cr.body_rootid[b]]
        w = cr.d_cvel[b]
        rx, ry, rz = nc[0] - sc[0], nc[1] - sc[1], nc[2] - sc[2]
        vx = w[3] + w[1] * rz - w[2] * ry
        vy = w[4] + w[2] * rx - w[0] * rz
        vz = w[5] + w[0] * ry - w[1] * rx
        if fresh or not cr.body_near[b]:  # no finger near it: nothing carried to keep continuous
            for j in range(6):
                e[j] = 0.0
        else:
            # where the local model carried the body to by the end of the step just taken
            left = max(0.0, 1.0 - dt / (FADE_STEPS * H))
            tx, ty, tz = v[0] * dt + o[0] + left * e[0], v[1] * dt + o[1] + left * e[1], v[2] * dt + o[2] + left * e[2]
            px = c[0] + v[3] * dt + o[3] + left * e[3]
            py = c[1] + v[4] * dt + o[4] + left * e[4]
            pz = c[2] + v[5] * dt + o[5] + left * e[5]
            # its orientation R(θ) X_old against the new X: the offset E = R(θ) X_old X_newᵀ
            X0, X1, E = cr.body_xmat[b], cr.ximat[b], cr.scratch
            for i in range(3):
                for j in range(3):
                    E[3 * i + j] = X0[3 * i] * X1[3 * j] + X0[3 * i + 1] * X1[3 * j + 1] + X0[3 * i + 2] * X1[3 * j + 2]
            for j in range(3):
                E[j], E[3 + j], E[6 + j] = _rotate(tx, ty, tz, E[j], E[3 + j], E[6 + j])
            e[0], e[1], e[2] = _log(E)
            e[3], e[4], e[5] = px - nc[0], py - nc[1], pz - nc[2]
        c[0], c[1], c[2] = nc[0], nc[1], nc[2]
        X, Xn = cr.body_xmat[b], cr.ximat[b]
        for j in range(9):
            X[j] = Xn[j]
        v[0], v[1], v[2], v[3], v[4], v[5] = w[0], w[1], w[2], vx, vy, vz
        spin = cr.body_spin[b]
        for j in range(6):
            o[j] = 0.0
            spin[j] = 0.0
        cr.touched[b] = False
        cr.body_near[b] = False
        _bound(cr, b, H)
    for k in range(cr.qvel.shape[0]):
        cr.qacc_free[k] = cr.d_qacc[k] - (0.0 if fresh else cr.dqvel[k] / dt)
    cr.qvel0[:] = cr.d_qvel
    cr.qvel[:] = cr.d_qvel
    cr.dqvel[:] = 0.0
    cr.snap_xpos[:] = cr.d_xpos
    cr.snap_xmat[:] = cr.d_xmat
    cr.geom_xpos[:] = cr.d_xpos
    cr.geom_xmat[:] = cr.d_xmat
    cr.cvel[:] = cr.d_cvel


@kernel(inline="always")
def _bound(cr, b, H):
    """How far body b's carried pose may get from where the step began, within the fade:
    body_bound[b] = (displacement (m), turn (rad)), from its velocity, the fingers' change of
    it and its offset (`carry`'s broad test)."""
    v, e, spin = cr.body_vel[b], cr.body_err[b], cr.body_spin[b]
    span = FADE_STEPS * H
    speed = math.sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5]) + math.sqrt(spin[3] * spin[3] + spin[4] * spin[4] + spin[5] * spin[5])
    turn = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + math.sqrt(spin[0] * spin[0] + spin[1] * spin[1] + spin[2] * spin[2])
    cr.body_bound[b, 0] = speed * span + math.sqrt(e[3] * e[3] + e[4] * e[4] + e[5] * e[5]) + math.sqrt(
        cr.body_off[b, 3] ** 2 + cr.body_off[b, 4] ** 2 + cr.body_off[b, 5] ** 2)
    cr.body_bound[b, 1] = turn * span + math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) + math.sqrt(
        cr.body_off[b, 0] ** 2 + cr.body_off[b, 1] ** 2 + cr.body_off[b, 2] ** 2)


@kernel(inline="always")
def _carry_shape(cr, k, b, tau, fade, H):
    """Geom k at its body b's carried pose, τ s into the step (fade: what is left of the offset)."""
    v, e, o, c = cr.body_vel[b], cr.body_err[b], cr.body_off[b], cr.body_com[b]
    tx = v[0] * tau + o[0] + fade * e[0]
    ty = v[1] * tau + o[1] + fade * e[1]
    tz = v[2] * tau + o[2] + fade * e[2]
    x0 = cr.snap_xpos[k]
    rx, ry, rz = _rotate(tx, ty, tz, x0[0] - c[0], x0[1] - c[1], x0[2] - c[2])
    x = cr.geom_xpos[k]
    x[0] = c[0] + v[3] * tau + o[3] + fade * e[3] + rx
    x[1] = c[1] + v[4] * tau + o[4] + fade * e[4] + ry
    x[2] = c[2] + v[5] * tau + o[5] + fade * e[5] + rz
    R0, R = cr.snap_xmat[k], cr.geom_xmat[k]
    for j in range(3):  # each column of R₀ rotated
        R[j], R[3 + j], R[6 + j] = _rotate(tx, ty, tz, R0[j], R0[3 + j], R0[6 + j])
    w, spin = cr.cvel[b], cr.body_spin[b]
    w[0] = v[0] + spin[0] - e[0] / (H * FADE_STEPS)
    w[1] = v[1] + spin[1] - e[1] / (H * FADE_STEPS)
    w[2] = v[2] + spin[2] - e[2] / (H * FADE_STEPS)


@kernel
def carry(cr, fingers, tau, H):
    """Every moving shape near a placed finger at its carried pose τ s into the step of H s
    (into the local geom_xpos, geom_xmat and cvel the haptic side's `Shapes` read). Near: its
    bounding sphere where the step began, widened by as far as its body may get within the
    fade (`body_bound`), within NEAR_MARGIN of the ball the finger's broad phase last gathered."""
    FM, FD = fingers.rows.model, fingers.rows.data
    fade = 1.0 - tau / (H * FADE_STEPS)
    for j in range(cr.mover_geom.shape[0]):
        k, b, rb = cr.mover_geom[j], cr.mover_body[j], cr.mover_rbound[j]
        near = rb == math.inf
        if not near:
            x0 = cr.snap_xpos[k]
            grown = rb + cr.body_bound[b, 0] + rb * cr.body_bound[b, 1] + NEAR_MARGIN
            for i in range(FD.shape[0]):
                fd = FD[i]
                if not fd.placed:
                    continue
                reach = grown + FM[i].radius + fd.ball_room
                dx, dy, dz = x0[0] - fd.ball[0], x0[1] - fd.ball[1], x0[2] - fd.ball[2]
                if dx * dx + dy * dy + dz * dz <= reach * reach:
                    near = True
                    break
        if near:
            cr.body_near[b] = True
            _carry_shape(cr, k, b, tau, fade, H)


@kernel
def respond(cr, FD, ws, n, h, H):
    """The local model over one haptic tick of h s: its generalised velocity under the held
    acceleration (`qacc_free`) and this tick's sent wrenches (on the fingers; the bodies get
    minus them), -h Σ M⁻¹Gᵀ W over the coupled fingers (`ws`, `n`: the implicit coupling's
    workspace and how many it coupled); each touched body's twist change from that, at its
    centre of mass (`body_spin`), and its integral over the tick into `body_off` (and its
    `body_bound` widened). A body keeps its change once touched, until the next MuJoCo step
    (of H s)."""
    jacs, _, _, Q, _, _, rows, body_dofs = ws
    nv = cr.qvel.shape[0]
    dq, q, a = cr.dqvel, cr.qvel, cr.qacc_free
    for k in range(nv):
        q[k] += h * a[k]
    for f in range(n):
        fd = FD[rows[f]]
        if fd.push_body != fd.body:  # no wrench reached the body this tick
            continue
        W0, W1, W2 = fd.sent_force
        W3 = fd.sent_torque[0] * fd.normal[0] + fd.sent_torque[1] * fd.normal[1] + fd.sent_torque[2] * fd.normal[2]
        M = Q[f]
        body = int(fd.body)
        lo, hi = body_dofs[body, 0], body_dofs[body, 1]
        for k in range(lo, hi):  # (Q is filled over the finger's tree only)
            step = h * (M[0, k] * W0 + M[1, k] * W1 + M[2, k] * W2 + M[3, k] * W3)
            dq[k] -= step
            q[k] -= step
    for f in range(n):
        fd = FD[rows[f]]
        b = int(fd.body)
        J = jacs[f]
        lx = ly = lz = wx = wy = wz = 0.0
        lo, hi = body_dofs[b, 0], body_dofs[b, 1]
        for k in range(lo, hi):
            d = q[k] - cr.qvel0[k]
            if d != 0.0:
                lx += J[0, k] * d
                ly += J[1, k] * d
                lz += J[2, k] * d
                wx += J[3, k] * d
                wy += J[4, k] * d
                wz += J[5, k] * d
        c, p = cr.body_com[b], fd.contact_pos  # at the centre of mass: v_c = v_p + ω × (c - p)
        rx, ry, rz = c[0] - p[0], c[1] - p[1], c[2] - p[2]
        spin = cr.body_spin[b]
        spin[0], spin[1], spin[2] = wx, wy, wz
        spin[3], spin[4], spin[5] = lx + wy * rz - wz * ry, ly + wz * rx - wx * rz, lz + wx * ry - wy * rx
        cr.touched[b] = True
    for b in cr.moving:
        if cr.touched[b]:
            o, spin = cr.body_off[b], cr.body_spin[b]
            for j in range(6):
                o[j] += h * spin[j]
            _bound(cr, b, H)
