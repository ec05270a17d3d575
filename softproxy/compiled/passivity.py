"""Time-domain passivity of each finger's coupling: an observer of the energy it exchanges, and
a controller that dissipates what it would otherwise create (Hannaford & Ryu 2002).

The coupling (spring-damper, proxy, friction) sits between two ports: the hand, which the
device moves by Δx_d while it renders F (held over the tick), and the touched body, whose
contact point moves by Δx_b while it gets -F. The energy flowing into the coupling over a tick
is F·(Δx_b - Δx_d) + M·(Δθ_b - Δα_s) (the torque about n, the body's turn and the device's
twist), exact for the force the device held over that tick. The observer E is its running
sum: a passive coupling never gives back more than it took, E >= 0. A magnet's pull
(`softproxy.compiled.material.magnet`) is a conservative field, a store of its own: what it
gave the hand on the way in (`field_energy`) it takes back on the way out, so the debt is
E + field_energy. Credit is kept only up
to what the springs could give back now (E is capped at ½k|x_p - x_d|² + ½k_τ(α_p - α_s)²):
what the damper and friction dissipated cannot excuse energy created later. Under a
zero-order hold a sampled spring gives back ½k·Δs² more than a continuous one each tick it
moves by Δs (Colgate's "negative damping" kh/2); where that drives E below zero the
controller adds, for the next tick, a damper on the relative motion (the same wrench on the
device and the body), sized to dissipate the deficit at the last tick's relative speed.
Raising the wrench (a press) it is capped at k·h + b N·s/m (k_τ·h + b_τ for the torsion),
about twice the damping a sampled spring lacks; lowering it (a release) at CUT times that,
never past zero. During a finger's soft start neither counts a debt nor acts: the ramp is
what bounds a finger placed inside an object. Units: J, N, m, rad, s.
"""

from __future__ import annotations

import math


from softproxy.compiled.coupling import within_laws
from softproxy.compiled.kernel import kernel
from softproxy.compiled.vector import dist2, dot3

TOLERANCE_J = 1e-9
"""A deficit the controller leaves alone (J): rounding in the energy sums of a held grasp is
~1e-19 J, a real one on a stiff wall ~1e-5 J a tick; a nanojoule is what 1 mN does over 1 µm."""
CUT = 20.0
"""How much faster than it may raise the wrench the controller may lower it (× the raise cap
k·h + b): enough to take a wall's force to zero in the tick after a bounce at 250 Hz, where the
deficit is paid at a relative speed a tenth of the bounce's; bounded so a small deficit on a
near-still contact (a held grasp's lift: ~10 µJ at µm per tick) is paid over tens of ticks,
a fraction of a newton at a time, not by dropping the grip."""


@kernel
def observe(fm, fd):
    """After the finger's update: the energy the coupling took in over the last tick (what
    the device was sent then, `sent_`, times this tick's relative motion, `rel_`) into the
    observer E; E capped at what the springs could give back now, ½k|x_p - x_d|² +
    ½k_τ(α_p - α_s)² (an upper bound: clamps, the controller and friction only lower what a
    spring returns); the lowest E kept."""
    dE = dot3(fd.sent_force, fd.rel_move) + dot3(fd.sent_torque, fd.normal) * fd.rel_turn
    # a texture's relief is the hand's alone: the body did not get it over its own move
    dE -= dot3(fd.texture_sent, fd.surface_move)
    if not math.isfinite(dE):
        return
    fd.energy_in += dE
    stored = 0.0
    if fd.contact and fd.valid:
        stored = 0.5 * fd.contact_stiffness * dist2(fd.pos, fd.device_pos)
        if fm.has_torsion and fd.in_contact and fm.torsion_stiffness > 0.0:
            stored += 0.5 * fd.spring_torque * fd.spring_torque / fm.torsion_stiffness
    E = fd.energy + dE
    if not math.isfinite(E):
        return
    if E > stored:
        E = stored
    if fd.ramp < 1.0 and E < 0.0:
        # during the soft start the ramp bounds what a finger placed inside an object releases
        # (its stretch was never put in by the hand): no debt is counted until it is done
        E = 0.0
    fd.energy = E
    if not fm.magnets and E < fd.energy_min:  # (with magnets, `material.magnet` keeps it: E + their store)
        fd.energy_min = E


@kernel
def _gain_cap(along, square, cap):
    """The largest damper gain the controller may use on one channel (N/m or N·m/rad over a
    tick), `along` the wrench times the relative motion, `square` the wrench squared: raising
    the wrench (along >= 0) `cap`; lowering it, down to zero along the wrench and no further,
    at most CUT × `cap`."""
    if along < 0.0:
        most = square / -along
        return most if most < CUT * cap else CUT * cap
    return cap


@kernel
def control(fm, fd, dt):
    """While E < 0: a damper on the relative motion for the next tick of dt s, the wrench the
    same on the device and the body, sized to dissipate the deficit at the last tick's relative
    speed, once the deficit is past TOLERANCE_J. Where it raises the wrench (the motion takes
    energy in: a press) it is capped at k·h + b (N·s/m; k_τ·h + b_τ for the torsion); where it
    lowers it (the motion gives energy back: a release) at CUT times that, and never past zero;
    the rest is left for the ticks after.
    The wrench is kept within the finger's laws. Returns the energy it plans to dissipate (J)."""
    owed = fd.energy + fd.field_energy
    if owed >= -TOLERANCE_J or not fd.valid or not fd.contact or fd.ramp < 1.0:
        return 0.0
    (wx, wy, wz), turn = fd.rel_move, fd.rel_turn
    cap = fd.contact_stiffness * dt + fd.contact_damping  # N·s/m
    cap_tau = fm.torsion_stiffness * dt + fm.torsion_damping if fm.has_torsion and fd.in_contact else 0.0
    ratio = cap_tau / cap if cap > 0.0 else 0.0  # the torsion's share, as the two caps stand
    w2 = wx * wx + wy * wy + wz * wz
    room = w2 + ratio * turn * turn
    if not room > 0.0:
        return 0.0
    c = -owed / room  # N/m of relative motion: dissipates the deficit in one tick at this speed
    c_tau = ratio * c
    # (the wrench times the motion < 0: it gives energy back over this motion)
    fx, fy, fz = fd.force
    most = _gain_cap(fx * wx + fy * wy + fz * wz, fx * fx + fy * fy + fz * fz, cap / dt)
    c = c if c < most else most
    most = _gain_cap(fd.torque_n * turn, fd.torque_n * fd.torque_n, cap_tau / dt)
    c_tau = c_tau if c_tau < most else most
    planned = c * w2 + c_tau * turn * turn
    if not planned > 0.0:
        return 0.0
    within_laws(fm, fd, fx + c * wx, fy + c * wy, fz + c * wz, fd.torque_n + c_tau * turn)
    fd.pc_ticks += 1
    fd.pc_energy += planned
    return planned
