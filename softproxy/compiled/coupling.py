"""The fingers' wrenches on the touched bodies, integrated implicitly: stable for any inertia.

Each finger couples its device to the body it touches through a spring-damper (translation
k, b; torsion about the contact normal k_τ, b_τ). Written explicitly, from the body's velocity
at the start of a tick, that spring is unstable on a light body: a 5 g knob under a default
finger (k_τ h²/I ≈ 2.5 at 1 kHz) spun up from a nudge to 28 rad/s. Here the wrench a tick
applies is solved together with the body's answer to it over the tick (backward Euler), as
MuJoCo integrates its own contacts (docs/coupling.md, "Coupling to a body"):

    (I + H A) W = W_exp + h K u + H a_free,    H = h²K + hB,

for the 4 channels of every finger in contact with a body that moves (the force at its
contact point, world x y z, and the torque about its normal n): W the fingers' wrenches (on
the fingers; the bodies get -W), W_exp what each finger's spring-damper gives from the state
now (`finger.update`), u the contact's velocity now, A = G M⁻¹ Gᵀ the mobility of the
channels (`body_response`: one Jacobian and one solve per finger, cross terms between
fingers on one tree included), and a_free the contact's acceleration without the fingers,
taken from the last step's total (qacc) plus what the fingers' last wrenches contributed to
it (+A·W_prev). In equilibrium
the solve gives W = W_exp exactly; on a body that is heavy against the coupling (A → 0) it
is W_exp plus the spring's stretch over the tick's motion; on a light one it is what the
coupled pair does in one implicit step, which dissipates rather than injects energy.

Where the contact does not act as a spring the channel is left as the finger computed it
(H = 0): along the surface while the proxy slides (friction, not the spring, sets it),
about n while the torsion slips. The solved wrench is put back within the finger's laws:
no pull (P = F·n ≥ 0), the tangential force within the static cone, the torque within what
friction holds, both within the finger's clamps. The device and the body then get this same
wrench after the device's clamp (`finger.tick`).
"""

from __future__ import annotations

import math

import numpy as np

from softproxy.compiled.body_response import point_jacobian, response, response_in_tree
from softproxy.compiled.kernel import kernel
from softproxy.compiled.vector import dot3

CHANNELS = 4
"""Per finger: force x, y, z at the contact point (N, world) and torque about its normal (N·m)."""


def workspace(model, fingers: int) -> tuple:
    """The scratch `implicit` needs for an mjModel and a loop of `fingers` fingers:
    (J per finger, M⁻¹Jᵀ per finger, G and Q per finger (channels × nv),
    the system (4n × 4n+1), the channels' table (4n × 5: H, hK, W_prev, u, a_free), the
    coupled fingers' rows (n), and per body the dofs of its tree (nbody × 2: first, end; 0, 0
    for a body welded to the world); G, Q and M⁻¹Jᵀ are filled over a coupled finger's body's
    tree only. Eight arrays: each array a kernel takes costs a reference count in and out of
    every call it goes through, the tick's three deep."""
    n = max(1, int(fingers))
    nv = int(model.nv)
    body_dofs = np.zeros((model.nbody, 2), dtype=np.int64)
    for b, tree in enumerate(model.body_treeid):
        if tree >= 0:
            first = int(model.tree_dofadr[tree])
            body_dofs[b] = first, first + int(model.tree_dofnum[tree])
    return (np.zeros((n, 6, nv)), np.zeros((n, 6, nv)),
            np.zeros((n, CHANNELS, nv)), np.zeros((n, CHANNELS, nv)),
            np.zeros((CHANNELS * n, CHANNELS * n + 1)), np.zeros((CHANNELS * n, 5)), np.zeros(n, dtype=np.int64),
            body_dofs)


@kernel
def _solve(system, n):
    """Solve the n × n system in system[:, :n] against system[:, n] in place (Gaussian
    elimination, partial pivoting); the solution in system[:, n]. False when singular."""
    for col in range(n):
        pivot = col
        best = abs(system[col, col])
        for r in range(col + 1, n):
            if abs(system[r, col]) > best:
                best, pivot = abs(system[r, col]), r
        if not best > 0.0:
            return False
        if pivot != col:
            for c in range(col, n + 1):
                system[col, c], system[pivot, c] = system[pivot, c], system[col, c]
        for r in range(col + 1, n):
            factor = system[r, col] / system[col, col]
            if factor != 0.0:
                for c in range(col, n + 1):
                    system[r, c] -= factor * system[col, c]
    for r in range(n - 1, -1, -1):
        acc = system[r, n]
        for c in range(r + 1, n):
            acc -= system[r, c] * system[c, n]
        system[r, n] = acc / system[r, r]
    return True


@kernel(inline="always")
def _dot_columns(a, b, lo, hi):
    """Σ_k a[k] b[k] over the dofs lo..hi of a's tree (a: a channel's Jacobian row, zero
    outside them and mostly zeros within). Inlined by numba: `implicit` calls it (4n)² times a
    tick, and LLVM left it a call of its own, two reference counts in and out each time."""
    acc = 0.0
    for k in range(lo, hi):
        if a[k] != 0.0:
            acc += a[k] * b[k]
    return acc


@kernel
def implicit(m, d, mass, qvel, qacc, FM, FD, bodies_fixed, h, ws, prev):
    """Every finger in contact with a body that moves: its wrench (fd.force, fd.torque,
    fd.torque_n, fd.normal_force) solved implicitly with the bodies' answer over this tick of h s (the module
    docstring). Between mj_step1 and mj_step2, after every finger's update; `m`, `d`: the
    mjModel's and mjData's addresses, `mass` that mjData's `layout.MassMatrix`. Each finger's
    Jacobian and solve cost its body's kinematic tree only (M is block diagonal by tree: two
    fingers on different trees do not answer each other). `bodies_fixed`: 1 for a body welded
    to the world. `qacc`: with `prev`, MuJoCo's last, which holds the
    fingers' last wrenches (added back to get a_free); without, already without them (two
    rates: `softproxy.compiled.carry`'s held acceleration). Returns how many fingers were
    coupled (their rows of ws filled, in `rows`)."""
    jacs, mijs, G, Q, system, chan, rows, body_dofs = ws
    nv = qvel.shape[0]
    n = 0
    point = chan[0, :3]  # (scratch: the table is filled after the last Jacobian)
    for i in range(FD.shape[0]):
        fd = FD[i]
        body = int(fd.body)
        if not fd.valid or body <= 0 or bodies_fixed[body] or n >= rows.shape[0]:
            continue
        point[0], point[1], point[2] = fd.contact_pos
        lo, hi = body_dofs[body, 0], body_dofs[body, 1]
        point_jacobian(m, d, body, np.uintp(point.ctypes.data), jacs[n])
        if hi - lo == nv:  # one tree: one solve of the six rows
            response(m, d, jacs[n], mijs[n])
        else:
            response_in_tree(mass, jacs[n], mijs[n], lo, hi)
        # the 4 channels' rows: the point's linear rows, and n·(angular rows)
        J, MJ, g, q = jacs[n], mijs[n], G[n], Q[n]
        nx, ny, nz = fd.normal
        for k in range(lo, hi):
            for c in range(3):
                g[c, k] = J[c, k]
                q[c, k] = MJ[c, k]
            g[3, k] = nx * J[3, k] + ny * J[4, k] + nz * J[5, k]
            q[3, k] = nx * MJ[3, k] + ny * MJ[4, k] + nz * MJ[5, k]
        rows[n] = i
        n += 1
    if n == 0:
        return 0
    size = CHANNELS * n
    # per channel r: H (h²K + h(B + η), η a viscous surface's; 0 where the channel is not a
    # spring this tick), h K, the
    # finger's wrench last tick on this body (its share of last step's qacc), u, a_free
    for a in range(n):
        fm, fd = FM[rows[a]], FD[rows[a]]
        spring_tau = fm.has_torsion and fd.in_contact and not fd.slipping
        same = prev and fd.push_body == fd.body
        r0 = CHANNELS * a
        for c in range(3):
            chan[r0 + c, 0] = h * h * fd.contact_stiffness + h * (fd.contact_damping + fd.contact_viscosity)
            chan[r0 + c, 1] = h * fd.contact_stiffness
        chan[r0 + 3, 0] = h * h * fm.torsion_stiffness + h * fm.torsion_damping if spring_tau else 0.0
        chan[r0 + 3, 1] = h * fm.torsion_stiffness if spring_tau else 0.0
        # (sent_ still holds last tick's wrench here: this tick's clamp comes after)
        chan[r0, 2] = fd.sent_force[0] - fd.texture_sent[0] if same else 0.0  # (what the body got)
        chan[r0 + 1, 2] = fd.sent_force[1] - fd.texture_sent[1] if same else 0.0
        chan[r0 + 2, 2] = fd.sent_force[2] - fd.texture_sent[2] if same else 0.0
        chan[r0 + 3, 2] = dot3(fd.sent_torque, fd.normal) if same else 0.0
    # A = G M⁻¹ Gᵀ into the system (zero between fingers on different trees), u = G qvel,
    # a_free = G qacc + A W_prev
    for r in range(size):
        a, c = r // CHANNELS, r % CHANNELS
        body = int(FD[rows[a]].body)
        lo, hi = body_dofs[body, 0], body_dofs[body, 1]
        acc = _dot_columns(G[a, c], qacc, lo, hi)
        for e in range(size):
            other = int(FD[rows[e // CHANNELS]].body)  # (fingers on another tree: zero)
            A = _dot_columns(G[a, c], Q[e // CHANNELS, e % CHANNELS], lo, hi) if body_dofs[other, 0] == lo else 0.0
            system[r, e] = A
            acc += A * chan[e, 2]
        chan[r, 3] = _dot_columns(G[a, c], qvel, lo, hi)
        chan[r, 4] = acc
    # each finger's rows times its H, and the right-hand side W_exp + h K u + H a_free; the
    # force block's H and K are k·I while the proxy sticks, k·n nᵀ while it slides (H plus
    # hη across n on a viscous surface, whose damper acts along the slide too)
    for a in range(n):
        fd = FD[rows[a]]
        r0 = CHANNELS * a
        nx, ny, nz = fd.normal
        hb, hk = chan[r0, 0], chan[r0, 1]
        if fd.sticking:
            for c in range(3):
                for e in range(size):
                    system[r0 + c, e] *= hb
                system[r0 + c, size] = hk * chan[r0 + c, 3] + hb * chan[r0 + c, 4]
        else:
            un = nx * chan[r0, 3] + ny * chan[r0 + 1, 3] + nz * chan[r0 + 2, 3]
            an = nx * chan[r0, 4] + ny * chan[r0 + 1, 4] + nz * chan[r0 + 2, 4]
            hv = h * fd.contact_viscosity  # a viscous surface damps the slide too: hη across n
            for e in range(size):
                along = nx * system[r0, e] + ny * system[r0 + 1, e] + nz * system[r0 + 2, e]
                system[r0, e] = hb * nx * along + hv * (system[r0, e] - nx * along)
                system[r0 + 1, e] = hb * ny * along + hv * (system[r0 + 1, e] - ny * along)
                system[r0 + 2, e] = hb * nz * along + hv * (system[r0 + 2, e] - nz * along)
            rhs = hk * un + hb * an
            system[r0, size] = rhs * nx + hv * (chan[r0, 4] - an * nx)
            system[r0 + 1, size] = rhs * ny + hv * (chan[r0 + 1, 4] - an * ny)
            system[r0 + 2, size] = rhs * nz + hv * (chan[r0 + 2, 4] - an * nz)
        hb_tau = chan[r0 + 3, 0]
        for e in range(size):
            system[r0 + 3, e] *= hb_tau
        system[r0 + 3, size] = chan[r0 + 3, 1] * chan[r0 + 3, 3] + hb_tau * chan[r0 + 3, 4]
        # (a texture's relief is the hand's alone: not in the wrench the body answers)
        system[r0, size] += fd.force[0] - fd.texture_force[0]
        system[r0 + 1, size] += fd.force[1] - fd.texture_force[1]
        system[r0 + 2, size] += fd.force[2] - fd.texture_force[2]
        system[r0 + 3, size] += fd.torque_n
    for r in range(size):
        system[r, r] += 1.0
    if not _solve(system, size):  # (not expected: I + H A is positive definite) the wrenches as computed
        return n
    for a in range(n):
        r0 = CHANNELS * a
        fd = FD[rows[a]]
        within_laws(FM[rows[a]], fd, system[r0, size], system[r0 + 1, size], system[r0 + 2, size], system[r0 + 3, size])
        fd.force[0] += fd.texture_force[0]
        fd.force[1] += fd.texture_force[1]
        fd.force[2] += fd.texture_force[2]
    return n


@kernel
def within_laws(fm, fd, fx, fy, fz, M):
    """The solved wrench into the finger's data, within its laws: no pull through the surface,
    the tangential force within the static cone μ_s·P, the torque within what friction holds
    (the static limit, or the spring where larger), both within the finger's clamps (the soft
    start's ramp included). A wrench that is not finite leaves the finger's own."""
    if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz) and math.isfinite(M)):
        return
    nx, ny, nz = fd.normal
    normal = fx * nx + fy * ny + fz * nz
    P = normal if normal > 0.0 else 0.0
    tx, ty, tz = fx - normal * nx, fy - normal * ny, fz - normal * nz
    t = math.sqrt(tx * tx + ty * ty + tz * tz)
    cone = fd.contact_friction[0] * P
    if t > cone:
        s = cone / t
        tx, ty, tz = tx * s, ty * s, tz * s
    fx, fy, fz = P * nx + tx, P * ny + ty, P * nz + tz
    fmax = fm.max_force * fd.ramp
    f2 = fx * fx + fy * fy + fz * fz
    if f2 > fmax * fmax:
        s = fmax / math.sqrt(f2)
        fx, fy, fz, P = fx * s, fy * s, fz * s, P * s
    fd.force[:] = fx, fy, fz
    fd.normal_force = P
    if fm.has_torsion and fd.in_contact:
        torque_within_laws(fm, fd, M)


@kernel
def torque_within_laws(fm, fd, M):
    """A torque M about n (N·m) into the finger's data (torque_n, and M·n in torque): never past what
    friction holds (the static limit, or the spring torque where that is larger), nor past
    the clamp (the soft start's ramp included)."""
    limit, spring = fd.limit, abs(fd.spring_torque)
    bound = limit if limit > spring else spring
    if bound > fm.max_torque * fd.ramp:
        bound = fm.max_torque * fd.ramp
    M = bound if M > bound else -bound if M < -bound else M
    fd.torque_n = M
    nx, ny, nz = fd.normal  # (M * fd.normal would allocate an array every tick)
    fd.torque[:] = M * nx, M * ny, M * nz
