"""`CompiledFingers`: every finger of a servo tick in one numba call.

The Python tick spends most of its time in the interpreter (~20 µs of attribute work for
two fingers around a 4 µs `mj_step`); this runs the same fingers — god-object, coupling,
torsion, wrenches, the device clamp — as compiled code on flat arrays, reading poses
straight from MuJoCo. The answers are the Python engine's to the last bit
(tests/test_compiled.py), so the Python classes stay the reference.

The arrays are the state while a loop runs compiled. After every tick the fingers' outputs
(force, torque, contact point, body, P, valid) are written back into their Python objects
(`mirror`); `sync` writes back the rest (proxy, contact, torsion, counters, the solver's
bookkeeping), which the loop does before sensors, `on_tick` callbacks and `stop`. Code
that changes a finger by hand (place it, reset it) calls `pack()` after.
Meshes run compiled too (`softproxy.compiled.mesh`), equal to the Python engine's to rounding
rather than to the bit (where two triangles are equally near, either may answer).
"""

from __future__ import annotations

import math
from numbers import Real

import numpy as np

from softproxy.compiled import finger as kernel
from softproxy.compiled.godobject import pack_god, scratch
from softproxy.compiled.layout import (
    COUNTERS_SEEN, DEVICE_SEEN, F_B, F_BODY, F_B_TAU, F_COLUMNS, F_DT, F_FX, F_FY, F_FZ, F_HAS_TORSION, F_K,
    F_MAX_FORCE, F_MAX_FORCE_SEEN, F_MAX_SPEED, F_MAX_TORQUE, F_NORMAL_FORCE, F_OX, F_OY, F_OZ,
    F_PENETRATION_MAX, F_PLACED, F_PX, F_PY, F_PZ, F_RAMP, F_SCALE, F_SLIDE_EVENTS, F_SOFT_START,
    F_SPIKES_REJECTED, F_SPIKE_RUN, F_STWIST, F_SX, F_SY, F_SZ, F_TORQUE, F_TX, F_TY, F_TZ, F_VALID,
    F_WAS_STICKING, F_XD, F_YD, F_ZD, GOD_SEEN, G_BX, G_BY, G_BZ, G_LX, G_LY, G_LZ, G_NNEAR, G_NPLANES,
    G_PLANES, G_ROOM, G_ROUNDING, IN_X, OUTPUT_AND_SENT, PLANE_WIDTH, SENT_AT, TORSION_SEEN, T_ALPHA_0,
    T_ALPHA_G, T_ALPHA_P, T_GAMMA, T_IN_CONTACT, T_K_TAU, T_LIMIT, T_MU_D, T_MU_PRIME, T_MU_S, T_P_STAR, T_R0,
    T_RATIO, T_SATURATE, T_SLIPPING, T_SLIP_EVENTS, T_TORQUE,
)
from softproxy.compiled.shapes import shape_tables
from softproxy.device import Device
from softproxy.finger import SoftFingerProxy
from softproxy.world import World


class CompiledFingers:
    """The fingers of a `ServoLoop`, run by `run(...)` once per tick (after mj_step1)."""

    def __init__(self, world: World, fingers: list[SoftFingerProxy], device: Device) -> None:
        """ValueError, with the reason, for a world or fingers that cannot run compiled."""
        try:
            self.S, self.T, self.C = shape_tables(world.shapes)
        except ValueError as exc:
            raise ValueError(f"this scene cannot run compiled: {exc}") from None
        for f in fingers:
            if f.god.shapes is not world.shapes:
                raise ValueError(f"this scene cannot run compiled: finger {f.params.name!r} touches "
                                 "shapes of its own, not the world's")
        self.world = world
        self.fingers = fingers
        self.device = device
        self.shapes = world.shapes
        self._index = {id(s): k for k, s in enumerate(self.shapes)}
        d, m = world.data, world.model
        # views into mjData, kept (each attribute access builds a new array object)
        self._xpos, self._xmat, self._cvel = d.geom_xpos, d.geom_xmat, d.cvel
        self._xipos, self._xfrc = d.xipos, d.xfrc_applied
        n = len(fingers)
        self.F = np.zeros((n, F_COLUMNS))
        self.near = np.zeros((n, max(len(self.shapes), 1)), dtype=np.int64)
        self._scratch = scratch()
        self._wrench = np.zeros((m.nbody, 6))
        self._bodies = np.zeros((3, m.nbody), dtype=np.int64)
        self._bodies[kernel.FIXED] = [int(w) == 0 for w in m.body_weldid]  # welded to the world: never pushed
        self._counts = np.zeros(2, dtype=np.int64)
        # the finger rows as one flat buffer of floats: a sample is written in with plain
        # item stores (a numpy row assignment costs more than the stores it saves)
        self._flat = memoryview(self.F).cast("B").cast("d")
        self._inputs = [(i * F_COLUMNS + IN_X, f.params.device_finger) for i, f in enumerate(fingers)]
        self.sent: list[list[float]] = [[0.0] * 6 for _ in fingers]
        """Per finger, what its device finger is sent this tick: force (N) and torque (N·m),
        clamped to the device, zero when unsafe or invalid."""
        self.pack()
        self._compile()

    def _compile(self) -> None:
        """Compile (or load from numba's cache) the tick now, not inside the first tick: one
        call on copies of every array the tick writes."""
        kernel.tick(self.S.copy(), self.T, self.C.copy(), self._xpos, self._xmat, self._cvel, self._xipos,
                    self._xfrc.copy(), self.F.copy(), self.near.copy(), 1e-3, False, False, 1.0, 1.0, scratch(),
                    self._wrench.copy(), self._bodies.copy(), self._counts.copy())

    def pack(self) -> None:
        """Copy every finger's state from its Python objects into the arrays."""
        for i, f in enumerate(self.fingers):
            row = self.F[i]
            tors = f.torsion
            pack_god(f.god, self._index, row, self.near[i])
            row[F_PLACED] = f.placed
            row[F_K], row[F_B], row[F_B_TAU] = f.k, f.b, f.b_tau
            row[F_MAX_FORCE], row[F_MAX_TORQUE] = f.max_force, f.max_torque
            row[F_OX], row[F_OY], row[F_OZ], row[F_SCALE] = f.ox, f.oy, f.oz, f.scale
            row[F_MAX_SPEED], row[F_SOFT_START], row[F_DT], row[F_RAMP] = f.max_speed, f.soft_start, f.dt, f._ramp
            row[F_XD], row[F_YD], row[F_ZD] = f.xd, f.yd, f.zd
            row[F_SX], row[F_SY], row[F_SZ], row[F_STWIST] = f._sx, f._sy, f._sz, f._stwist
            row[F_FX], row[F_FY], row[F_FZ], row[F_TORQUE] = f.fx, f.fy, f.fz, f.torque
            row[F_TX], row[F_TY], row[F_TZ] = f.tx, f.ty, f.tz
            row[F_PX], row[F_PY], row[F_PZ] = f.px, f.py, f.pz
            row[F_BODY], row[F_NORMAL_FORCE], row[F_VALID] = f.body, f.normal_force, f.valid
            row[F_MAX_FORCE_SEEN], row[F_PENETRATION_MAX] = f.max_force_seen, f.penetration_max
            row[F_SLIDE_EVENTS], row[F_SPIKES_REJECTED] = f.slide_events, f.spikes_rejected
            row[F_SPIKE_RUN], row[F_WAS_STICKING] = f._spike_run, f._was_sticking
            row[F_HAS_TORSION] = tors is not None
            if tors is not None:
                row[T_IN_CONTACT] = tors.in_contact
                row[T_ALPHA_0], row[T_ALPHA_P], row[T_ALPHA_G] = tors.alpha_0, tors.alpha_p, tors.alpha_g
                row[T_TORQUE], row[T_LIMIT], row[T_SLIPPING] = tors.torque, tors.limit, tors.slipping
                row[T_SLIP_EVENTS] = tors.slip_events
                row[T_K_TAU], row[T_MU_S], row[T_MU_D], row[T_GAMMA] = tors.k_tau, tors.mu_s, tors.mu_d, tors.gamma
                row[T_SATURATE], row[T_RATIO] = tors.saturate, tors._ratio
                model = tors._model
                row[T_MU_PRIME], row[T_R0], row[T_P_STAR] = model.mu_prime, model.r0, model.p_star

    def mirror(self) -> None:
        """Write this tick's outputs back into the fingers (force and torque, contact point,
        touched body, P, valid): what an application embedding the loop reads after a tick;
        and what each device finger is to be sent into `sent`."""
        sent = self.sent
        for i, (f, r) in enumerate(zip(self.fingers, self.F[:, OUTPUT_AND_SENT].tolist())):
            (f.fx, f.fy, f.fz, f.torque, f.tx, f.ty, f.tz, f.px, f.py, f.pz, body, f.normal_force,
             valid) = r[:SENT_AT]
            f.body = int(body)
            f.valid = valid != 0.0
            sent[i] = r[SENT_AT:]

    def sync(self) -> None:
        """Write the whole state back into the fingers' Python objects (proxy, contact,
        torsion, counters, the solver's bookkeeping) and the shapes' poses: after it every
        attribute reads as after a Python tick, and the Python engine could take over."""
        self.mirror()
        shapes = self.shapes
        for s in self.world.moving:
            s.refresh()
        for i, f in enumerate(self.fingers):
            r = self.F[i].tolist()
            god = f.god
            god.x, god.y, god.z, contact, god.nx, god.ny, god.nz, shape, god.depth, sticking = r[GOD_SEEN]
            god.contact = contact != 0.0
            god.shape = shapes[int(shape)] if shape >= 0.0 else None
            god.sticking = sticking != 0.0
            god.lx, god.ly, god.lz = r[G_LX], r[G_LY], r[G_LZ]
            god._bx, god._by, god._bz, god._room = r[G_BX], r[G_BY], r[G_BZ], r[G_ROOM]
            god._rounding = r[G_ROUNDING] != 0.0
            god.planes = [(*r[p:p + 4], shapes[int(r[p + 4])])
                          for p in range(G_PLANES, G_PLANES + PLANE_WIDTH * int(r[G_NPLANES]), PLANE_WIDTH)]
            god.near = [shapes[k] for k in self.near[i, :int(r[G_NNEAR])].tolist()]
            f.placed = r[F_PLACED] != 0.0
            f.dt, f._ramp = r[F_DT], r[F_RAMP]
            f.xd, f.yd, f.zd = r[DEVICE_SEEN]
            f._sx, f._sy, f._sz, f._stwist = r[F_SX], r[F_SY], r[F_SZ], r[F_STWIST]
            f.max_force_seen, f.penetration_max, slides, spikes = r[COUNTERS_SEEN]
            f.slide_events = int(slides)
            f.spikes_rejected = int(spikes)
            f._spike_run, f._was_sticking = int(r[F_SPIKE_RUN]), r[F_WAS_STICKING] != 0.0
            tors = f.torsion
            if tors is not None:
                in_contact, tors.alpha_0, tors.alpha_p, tors.alpha_g, tors.torque, tors.limit, slipping, slips = \
                    r[TORSION_SEEN]
                tors.in_contact = in_contact != 0.0
                tors.slipping = slipping != 0.0
                tors.slip_events = int(slips)

    def run(self, samples: list, ok: bool, safe: bool, audit: bool, dt: float) -> tuple[int, int]:
        """The fingers' part of one tick from this tick's device samples (after mj_step1).

        `ok`: the device read succeeded. Returns (unusable, unsafe): how many samples were
        unusable (a field not a number, not finite, or refused by their finger) and how many
        wrenches were refused as not finite; the wrenches are in xfrc_applied after, what
        each device finger is to be sent in `sent`."""
        flat = self._flat
        unusable = 0
        for k, j in self._inputs:
            s = samples[j]
            if ok and s.usable():  # every field is now a finite float
                flat[k] = s.x
                flat[k + 1] = s.y
                flat[k + 2] = s.z
                flat[k + 3] = s.twist
                flat[k + 4] = s.qw
                flat[k + 5] = s.qx
                flat[k + 6] = s.qy
                flat[k + 7] = s.qz
                flat[k + 8] = 1.0
            else:
                flat[k + 8] = 0.0
                unusable += ok
        device = self.device
        refused, unsafe = kernel.tick(self.S, self.T, self.C, self._xpos, self._xmat, self._cvel, self._xipos,
                                      self._xfrc, self.F, self.near, dt, safe, audit, _limit(device.max_force),
                                      _limit(device.max_torque), self._scratch, self._wrench, self._bodies,
                                      self._counts)
        self.mirror()
        return unusable + refused, unsafe

    def clear_wrenches(self) -> None:
        """Remove every wrench the fingers put on the bodies (the safe state)."""
        xfrc = self._xfrc
        for j in range(int(self._counts[1])):
            xfrc[self._bodies[kernel.PUSHED, j]] = 0.0
        self._wrench[:] = 0.0
        self._counts[:] = 0


def _limit(value) -> float:
    """A device limit as the float the kernel takes; NaN (which the guard refuses) when it is
    not a number at all."""
    if isinstance(value, float):
        return value
    if isinstance(value, bool) or not isinstance(value, Real):
        return math.nan
    try:
        return float(value)
    except OverflowError:
        return math.nan
