"""The fingers of one servo tick, compiled: coupling, torsion, wrench and device clamp.

numba twins of `SoftFingerProxy.update` / `hold` / `place`, `TorsionalFriction`,
`World.push` / the wrench half of `World.end_step` and `ServoLoop._send`'s clamp (the same
`softproxy.device_guard.guard_wrench`, compiled), on the
finger rows of the state array (columns in `layout`). Like `softproxy.compiled.godobject`
they follow the Python methods step by step, in the same order of floating-point
operations; the Python classes are the reference and say why. Units: m, N, N·m, rad, s.
"""

from __future__ import annotations

import math

from numba import njit

from softproxy import device_guard
from softproxy.compiled import godobject
from softproxy.compiled.layout import (
    IN_QW, IN_QX, IN_QY, IN_QZ, IN_TWIST, IN_VALID, IN_X, IN_Y, IN_Z, D_FX, D_FY, D_FZ, D_TX, D_TY, D_TZ, F_B, F_B_TAU, F_BODY, F_DT, F_FX, F_FY, F_FZ, F_HAS_TORSION, F_K,
    F_MAX_FORCE, F_MAX_FORCE_SEEN, F_MAX_SPEED, F_MAX_TORQUE, F_NORMAL_FORCE, F_OX, F_OY, F_OZ,
    F_PENETRATION_MAX, F_PLACED, F_PX, F_PY, F_PZ, F_RAMP, F_SCALE, F_SLIDE_EVENTS, F_SOFT_START,
    F_SPIKE_RUN, F_SPIKES_REJECTED, F_STWIST, F_SX, F_SY, F_SZ, F_TORQUE, F_TX, F_TY, F_TZ, F_VALID,
    F_WAS_STICKING, F_XD, F_YD, F_ZD, G_CONTACT, G_NX, G_NY, G_NZ, G_RADIUS, G_SHAPE, G_STICKING, G_X, G_Y,
    G_Z, S_BODY, T_ALPHA_0, T_ALPHA_G, T_ALPHA_P, T_GAMMA, T_IN_CONTACT, T_K_TAU, T_LIMIT, T_MU_PRIME,
    T_MU_S, T_P_STAR, T_R0, T_RATIO, T_SATURATE, T_SLIP_EVENTS, T_SLIPPING, T_TORQUE,
)
from softproxy.compiled.shapes import shape_distance
from softproxy.finger import SPIKE_PATIENCE
from softproxy.fingertip import P_MAX


@njit(cache=True)
def _finite(v):
    return v == v and v != math.inf and v != -math.inf


# -- torsion (softproxy.torsion.TorsionalFriction) ---------------------------------------------
@njit(cache=True)
def torsion_touch(f, alpha_s):
    if not _finite(alpha_s):
        alpha_s = 0.0
    f[T_IN_CONTACT] = 1.0
    f[T_ALPHA_0] = f[T_ALPHA_P] = f[T_ALPHA_G] = alpha_s
    f[T_TORQUE] = f[T_LIMIT] = 0.0
    f[T_SLIPPING] = 0.0


@njit(cache=True)
def torsion_release(f):
    f[T_IN_CONTACT] = 0.0
    f[T_ALPHA_0] = f[T_ALPHA_P] = f[T_ALPHA_G] = 0.0
    f[T_TORQUE] = f[T_LIMIT] = 0.0
    f[T_SLIPPING] = 0.0


@njit(cache=True)
def torsion_step(f, alpha_s, P):
    """`TorsionalFriction.step`: M on the finger about n (N·m)."""
    if f[T_IN_CONTACT] == 0.0:
        return 0.0
    if not _finite(alpha_s):
        f[T_TORQUE] = 0.0
        return 0.0
    P = abs(P)
    if not P <= P_MAX:
        P = P_MAX if P == P else 0.0
    if f[T_SATURATE] != 0.0:
        mu_prime = f[T_MU_PRIME]
        if mu_prime > 0.0:
            p_star = f[T_P_STAR]  # FingertipModel.piecewise_torque, inlined (P is already clamped)
            if P <= p_star:
                law = mu_prime * P ** f[T_GAMMA]
            else:
                law = f[T_R0] * (P - p_star) + mu_prime * p_star ** f[T_GAMMA]
            limit = f[T_MU_S] / mu_prime * law
        else:
            limit = 0.0
    else:
        limit = f[T_MU_S] * P ** f[T_GAMMA]
    f[T_ALPHA_G] = alpha_s
    k_tau = f[T_K_TAU]
    stretch = f[T_ALPHA_P] - alpha_s
    if limit > abs(k_tau * stretch):
        f[T_SLIPPING] = 0.0
    else:
        slack = limit * f[T_RATIO] / k_tau
        if stretch > 0.0:
            f[T_ALPHA_P] = alpha_s + slack
        elif stretch < 0.0:
            f[T_ALPHA_P] = alpha_s - slack
        else:
            f[T_ALPHA_P] = alpha_s
        if f[T_SLIPPING] == 0.0 and stretch != 0.0:
            f[T_SLIP_EVENTS] += 1.0
        f[T_SLIPPING] = 1.0 if stretch != 0.0 else 0.0
    f[T_LIMIT] = limit
    f[T_TORQUE] = k_tau * (f[T_ALPHA_P] - alpha_s)
    return f[T_TORQUE]


# -- the finger (softproxy.finger.SoftFingerProxy) -------------------------------------------
@njit(cache=True)
def clear_output(f):
    f[F_FX] = f[F_FY] = f[F_FZ] = 0.0
    f[F_TORQUE] = f[F_TX] = f[F_TY] = f[F_TZ] = 0.0
    f[F_PX] = f[F_PY] = f[F_PZ] = 0.0
    f[F_BODY] = -1.0
    f[F_NORMAL_FORCE] = 0.0
    f[F_VALID] = 0.0


@njit(cache=True)
def _follow_body(S, cvel, f):
    """Eqs 41–42: the touched body's spin about n drags α_p (`SoftFingerProxy._follow_body`)."""
    if f[F_HAS_TORSION] != 0.0 and f[T_IN_CONTACT] != 0.0:
        b = int(S[int(f[G_SHAPE]), S_BODY])
        omega_n = cvel[b, 0] * f[G_NX] + cvel[b, 1] * f[G_NY] + cvel[b, 2] * f[G_NZ]
        alpha_p = f[T_ALPHA_P] + omega_n * f[F_DT]
        if _finite(alpha_p):
            f[T_ALPHA_P] = alpha_p


@njit(cache=True)
def place(S, T, C, xpos, xmat, f, near, x, y, z):
    """`SoftFingerProxy.place`: False (finger left unplaced) outside the workspace."""
    xd, yd, zd = f[F_OX] + f[F_SCALE] * x, f[F_OY] + f[F_SCALE] * y, f[F_OZ] + f[F_SCALE] * z
    if not godobject.reset(S, T, C, xpos, xmat, f, near, xd, yd, zd):
        f[F_PLACED] = 0.0
        return False
    f[F_PLACED] = 1.0
    f[F_RAMP] = 0.0 if f[F_SOFT_START] > 0.0 else 1.0
    f[F_XD], f[F_YD], f[F_ZD] = xd, yd, zd
    if f[F_HAS_TORSION] != 0.0:
        torsion_release(f)
    return True


@njit(cache=True)
def hold(S, T, C, xpos, xmat, cvel, f, near):
    """`SoftFingerProxy.hold`: no usable sample; zero force, the proxy follows its body, the
    soft start's ramp winds down."""
    if f[F_BODY] >= 0.0:
        _follow_body(S, cvel, f)
    if f[F_SOFT_START] > 0.0:
        ramp = f[F_RAMP] - f[F_DT] / f[F_SOFT_START]
        f[F_RAMP] = ramp if ramp > 0.0 else 0.0
    if f[F_PLACED] != 0.0:
        godobject.follow(S, T, C, xpos, xmat, f, near)
    clear_output(f)


@njit(cache=True)
def update(S, T, C, xpos, xmat, cvel, f, near, x, y, z, twist, dt, scratch):
    """`SoftFingerProxy.update` from a device sample (device frame, m, rad) over dt (s)."""
    f[F_DT] = dt
    if f[F_BODY] >= 0.0:
        _follow_body(S, cvel, f)
    if f[F_PLACED] == 0.0:
        ok = place(S, T, C, xpos, xmat, f, near, x, y, z) and _finite(twist)
        clear_output(f)
        return ok
    xd = f[F_OX] + f[F_SCALE] * x
    yd = f[F_OY] + f[F_SCALE] * y
    zd = f[F_OZ] + f[F_SCALE] * z
    ex, ey, ez = xd - f[F_XD], yd - f[F_YD], zd - f[F_ZD]
    reach = f[F_MAX_SPEED] * dt
    if ex * ex + ey * ey + ez * ez > reach * reach and f[F_SPIKE_RUN] < SPIKE_PATIENCE:
        f[F_SPIKE_RUN] += 1.0
        f[F_SPIKES_REJECTED] += 1.0
        godobject.follow(S, T, C, xpos, xmat, f, near)  # _rest: the finger is placed here
        clear_output(f)
        return False
    f[F_SPIKE_RUN] = 0.0
    if not godobject.update(S, T, C, xpos, xmat, f, near, xd, yd, zd, scratch[0], scratch[1], scratch[2], scratch[3]) \
            or not _finite(twist):
        clear_output(f)
        return False
    f[F_XD], f[F_YD], f[F_ZD] = xd, yd, zd
    f[F_VALID] = 1.0
    if f[G_CONTACT] == 0.0:
        f[F_WAS_STICKING] = 0.0
        f[F_SX] = f[F_SY] = f[F_SZ] = 0.0
        f[F_STWIST] = 0.0
        if f[F_HAS_TORSION] != 0.0 and f[T_IN_CONTACT] != 0.0:
            torsion_release(f)
        f[F_FX] = f[F_FY] = f[F_FZ] = 0.0
        f[F_TORQUE] = f[F_TX] = f[F_TY] = f[F_TZ] = 0.0
        f[F_BODY] = -1.0
        f[F_NORMAL_FORCE] = 0.0
        return True

    if f[F_WAS_STICKING] != 0.0 and f[G_STICKING] == 0.0:
        f[F_SLIDE_EVENTS] += 1.0
    f[F_WAS_STICKING] = f[G_STICKING]
    # translational virtual coupling
    sx, sy, sz = f[G_X] - xd, f[G_Y] - yd, f[G_Z] - zd
    k = f[F_K]
    c = f[F_B] / dt
    fx = k * sx + c * (sx - f[F_SX])
    fy = k * sy + c * (sy - f[F_SY])
    fz = k * sz + c * (sz - f[F_SZ])
    f[F_SX], f[F_SY], f[F_SZ] = sx, sy, sz
    ramp = f[F_RAMP]
    if ramp < 1.0:
        v = ramp + dt / f[F_SOFT_START]
        ramp = v if v < 1.0 else 1.0
        f[F_RAMP] = ramp
    fmax = f[F_MAX_FORCE] * ramp
    f2 = fx * fx + fy * fy + fz * fz
    if f2 > fmax * fmax:
        s = fmax / math.sqrt(f2) if f2 > 0.0 else 0.0
        fx, fy, fz = fx * s, fy * s, fz * s
    nx, ny, nz = f[G_NX], f[G_NY], f[G_NZ]
    P = fx * nx + fy * ny + fz * nz
    if P < 0.0:
        fx, fy, fz = fx - P * nx, fy - P * ny, fz - P * nz
        P = 0.0
    f[F_FX], f[F_FY], f[F_FZ] = fx, fy, fz
    f[F_NORMAL_FORCE] = P
    r = f[G_RADIUS]
    f[F_PX], f[F_PY], f[F_PZ] = f[G_X] - r * nx, f[G_Y] - r * ny, f[G_Z] - r * nz
    f[F_BODY] = S[int(f[G_SHAPE]), S_BODY]
    fmag = math.sqrt(fx * fx + fy * fy + fz * fz)
    if fmag > f[F_MAX_FORCE_SEEN]:
        f[F_MAX_FORCE_SEEN] = fmag

    # torsional DOF (eqs 38–40)
    if f[F_HAS_TORSION] == 0.0:
        return True
    if f[T_IN_CONTACT] == 0.0:
        torsion_touch(f, twist)
        f[F_STWIST] = 0.0
    M = torsion_step(f, twist, P)
    stretch = f[T_ALPHA_P] - twist
    M += f[F_B_TAU] / dt * (stretch - f[F_STWIST])
    f[F_STWIST] = stretch
    limit, torque = f[T_LIMIT], abs(f[T_TORQUE])
    bound = limit if limit > torque else torque
    if bound > f[F_MAX_TORQUE] * ramp:
        bound = f[F_MAX_TORQUE] * ramp
    M = bound if M > bound else -bound if M < -bound else M
    f[F_TORQUE] = M
    f[F_TX], f[F_TY], f[F_TZ] = M * nx, M * ny, M * nz
    return True


@njit(cache=True)
def audit(S, T, C, xpos, xmat, f):
    """`SoftFingerProxy.audit`: deepest the proxy sits inside any shape now (m)."""
    if f[F_PLACED] == 0.0:
        return 0.0
    worst = 0.0
    for s in range(S.shape[0]):
        inside = f[G_RADIUS] - shape_distance(S, T, C, xpos, xmat, s, f[G_X], f[G_Y], f[G_Z])[0]
        if inside > worst:
            worst = inside
    if worst > f[F_PENETRATION_MAX]:
        f[F_PENETRATION_MAX] = worst
    return worst


# -- the world's wrenches (softproxy.world.World) ---------------------------------------------
FIXED, TOUCHED, PUSHED = 0, 1, 2
"""Rows of the `bodies` array: welded to the world (1/0), touched this tick, pushed last tick."""


@njit(cache=True)
def _listed(bodies, n, body):
    """True when body is among bodies[:n] (`body in list`)."""
    for j in range(n):
        if bodies[j] == body:
            return True
    return False


@njit(cache=True)
def _push(wrench, bodies, counts, body, fx, fy, fz, px, py, pz, tx, ty, tz):
    """`World.push`: force at p plus a pure torque, as a wrench about the world origin."""
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


@njit(cache=True)
def _write_wrenches(xfrc, xipos, wrench, bodies, counts):
    """The wrench half of `World.end_step`: this tick's wrenches into xfrc_applied, last
    tick's cleared. counts = (touched this tick, pushed last tick)."""
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


guard_wrench = njit(cache=True)(device_guard.guard_wrench)


@njit(cache=True)
def _clamp_for_device(f, safe, fmax, tmax):
    """`ServoLoop._send`: what the device is sent, zero when unsafe or invalid; False when
    the guard refused the wrench (not finite, or limits that are not numbers)."""
    good = True
    if safe or f[F_VALID] == 0.0:
        fx = fy = fz = tx = ty = tz = 0.0
    else:
        good, fx, fy, fz, tx, ty, tz = guard_wrench(f[F_FX], f[F_FY], f[F_FZ], f[F_TX], f[F_TY], f[F_TZ],
                                                    f[F_MAX_FORCE], f[F_MAX_TORQUE], fmax, tmax)
    f[D_FX], f[D_FY], f[D_FZ], f[D_TX], f[D_TY], f[D_TZ] = fx, fy, fz, tx, ty, tz
    return good


@njit(cache=True)
def tick(S, T, C, xpos, xmat, cvel, xipos, xfrc, F, near, dt, safe, check, fmax, tmax, scratch, wrench, bodies,
         counts):
    """Every finger's part of `ServoLoop.tick`, after mj_step1 and before mj_step2.

    Each finger row holds this tick's device sample in its IN_ columns; a sample not valid
    (or from a failed read) or not finite holds the finger. Writes the fingers' wrenches into
    xfrc_applied and what each device finger is sent into its D_ columns. `bodies`: rows
    FIXED (welded to the world), TOUCHED and PUSHED (body lists, lengths in `counts`).
    Returns (refused, unsafe): how many valid samples were refused (not finite, or refused by
    their finger: spikes, garbage positions, a non-finite twist), and how many wrenches were
    not finite (zeroed before they reached a body or the device)."""
    refused = 0
    unsafe = 0
    for i in range(F.shape[0]):
        f = F[i]
        row = near[i]
        if f[IN_VALID] == 0.0:
            hold(S, T, C, xpos, xmat, cvel, f, row)
        elif not _finite(f[IN_X] + f[IN_Y] + f[IN_Z] + f[IN_QW] + f[IN_QX] + f[IN_QY] + f[IN_QZ] + f[IN_TWIST]):
            refused += 1
            hold(S, T, C, xpos, xmat, cvel, f, row)
        else:
            if not update(S, T, C, xpos, xmat, cvel, f, row, f[IN_X], f[IN_Y], f[IN_Z], f[IN_TWIST], dt, scratch):
                refused += 1
            if safe:
                clear_output(f)
            elif not _finite(f[F_FX] + f[F_FY] + f[F_FZ] + f[F_TX] + f[F_TY] + f[F_TZ]):
                unsafe += 1
                clear_output(f)
            if f[F_BODY] >= 0.0:
                _push(wrench, bodies, counts, int(f[F_BODY]), -f[F_FX], -f[F_FY], -f[F_FZ],
                      f[F_PX], f[F_PY], f[F_PZ], -f[F_TX], -f[F_TY], -f[F_TZ])
        if check:
            audit(S, T, C, xpos, xmat, f)
        if not _clamp_for_device(f, safe, fmax, tmax):
            unsafe += 1
    _write_wrenches(xfrc, xipos, wrench, bodies, counts)
    return refused, unsafe
