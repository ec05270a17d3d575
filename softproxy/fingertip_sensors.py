"""Fingertip sensors inside the servo tick: a tactile image and intrinsic contact sensing per finger.

A scene switches them on per finger (`tactile = true` / `sensing = true`, or a table; see
`softproxy.scene`). `softproxy.run.build` then appends one channel per finger and option to
`ServoLoop.sensors`; the loop calls `channel.tick(loop)` once per tick, after every finger's
force has been sent to the device and before MuJoCo's second half-step. A scene that asks
for neither leaves the list empty: the tick then pays one loop over an empty list and no
tactile or sensing code runs. A channel only *reads* its finger's contact output, works on
every `every`-th tick only (its `rate_hz`, e.g. 100 Hz at a 1 kHz servo), and catches every
exception it raises (counted in `errors`, message in `last_error`): it can never change the
force rendered. It is not free in real time, though: a working tick is longer by the
channel's cost (`softproxy bench tradeoff` reports it).

Pad frame (both channels; **Choice**: the proxy is a sphere with no orientation of its own)
    Each finger has a pad direction p̂ (world unit vector the pad faces, i.e. toward what it
    touches) and a distal direction d̂ (toward the fingertip's end, made ⟂ p̂). Scene keys
    `pad` and `distal`; with no `pad` the pad is latched at every new contact as -n (the
    contact normal n points out of the object, toward the finger), so the first frame of a
    contact is pressed straight on and later frames see how the normal turned since. With
    no `distal`, d̂ is world +z made ⟂ p̂ (world +x when the pad faces within 25° of
    vertical). The device twist α_s (right-handed about the finger axis -p̂, as in
    `softproxy.finger`) turns d̂ about -p̂: by α_s for a scene-given pad, by α_s - α_s(touch)
    for a latched one. Lateral axis l̂ = d̂ × p̂.

Tactile (seeds 000/001 through `softproxy.tactile.TactileSensor`) — how a contact maps to the
Inoue–Hirai inputs (**Choice**)
    - sensing-plane frame: +z = p̂, +x = d̂ (the model's "distal"), +y = p̂ × d̂;
    - no finger joint: the proxy has none, so the finger angle θ of 000 eq 1 stays 0 and
      `joint_distance` = 0. (Mapping the pad-to-normal angle onto θ with the joint under the
      tip was tried and rejected: a rotation about the sphere's own centre adds no compression
      to springs already in contact, eqs 7–9, so the image barely moved under a 10° tilt.)
    - the angle between the pad and the contact is the object's roll β about the fingertip
      (eqs 20–30: the object turns while the finger holds still, at the same distance p from
      the tip's centre): β = atan2(u·d̂, u·p̂) with u = -n, so β > 0 tilts the object's normal
      toward +x and moves the centre of pressure distally; the component of u along +y has
      no place in the planar model and is dropped (reported as `lateral_roll_rad`);
    - indentation d (000 eq 1) from the proxy's normal force P through the virtual-spring
      fingertip's own law pressed straight: the springs at h > r - d compress by h - r + d,
      dP = E (h - r + d)/h, whose integral over the contact disc is F = π E d², so
      d = √(P / (π E)) and the image carries P while the pad faces the contact
      (`indentation = "force"`, default; rolled by β it carries less, e.g. 6 % less at 10°);
      `indentation = "depth"` uses the device penetration |x_p - x_d| (m) instead, which
      ties the image to the coupling stiffness. The history of eqs 10–16 integrates d;
    - the fingertip radius r defaults to the finger's proxy radius, the sensor side to 2r
      (the whole base: the paper's 12 mm sensor on a 10 mm tip misses the rim of a 3 N
      contact), E to the paper's 0.3636 MPa, 10 × 10 cells, 2 × 2 samples per cell (the
      standalone default is 4 × 4: ~0.36 ms a frame instead of ~0.22 ms), at most
      `max_substeps` = 10 history sub-steps per frame (bounds a frame's cost);
    - a roll under `ROLL_DEADBAND` (1 mrad) is imaged as none: the straight image costs
      ~60 µs, the rolled one ~200 µs (two more spring fields), and the centre of pressure
      moves by under 2 µm per mrad;
    - contact lost, or a normal at 60° or more from the pad, clears the history and the
      image reads zero.

Sensing (seed 003 through `softproxy.sensing.ContactSensor`) — the fingertip's pose (**Choice**)
    The ellipsoid frame (semi-axes a = 9.5, b = 17, c = 10.5 mm along x, y, z; the skin
    covers z ≥ 0) is x = l̂, y = d̂ (the finger's long axis, b), z = p̂ (the pad, c). Its
    centre is placed so that the skin, shrunk by Δd = P/E1 (eqs 1–2), touches the proxy's
    contact point x_c with outward normal -n: p_c = point_with_normal(Rᵀ(-n), Δd) in the
    ellipsoid frame and centre = x_c - R p_c. The wrench on the fingertip about that centre
    is F_e = Rᵀ F, M_e = p_c × F_e + Rᵀ(M n) (eq 6: the proxy's force F on the finger through
    the contact point plus its torque M about n). It is moved into the Nano17 frame (eqs
    3–4), optionally given the seed's sensor noise there (`noise = "gauss"`: σ = 1/160 N and
    1/32 N·mm per channel from a `random.Random(seed)`; `"quantise"`: rounded to those
    steps), and solved. Ground truth is what the proxy knows: the point p_c, normal force
    P, friction F - (F·n)n, local torque -M (about the outward normal -n). Errors per
    frame: location ‖p̂ - p‖ (m), |f̂_n - P| (N), ‖f̂_t - f_t‖ (N), |τ̂ - τ| (N·m); a refused
    wrench (no pushing contact explains it, or outside the skin envelope) counts in `refused`.
"""

from __future__ import annotations

import math
import random
from collections import deque

from softproxy.schema import SensingSpec, TactileSpec  # noqa: F401 (the options, declared in softproxy.schema)
from softproxy.sensing import FORCE_LSB, TORQUE_LSB, ContactSensor, Fingertip
from softproxy.tactile import TactileSensor

_VERTICAL = math.cos(math.radians(25.0))
ROLL_DEADBAND = 1e-3
"""A roll (rad) below which the tactile image is computed unrolled (cost: see the module docstring)."""
MAX_TILT = math.radians(60.0)
"""Largest pad-to-normal angle (roll) the tactile channel images (TactileSensor's clamp), rad."""


def _r(v: float, digits: int = 7) -> float:
    """Rounded for the JSON result, with -0.0 written as 0.0."""
    return round(v, digits) + 0.0


def default_distal(pad: tuple) -> tuple[float, float, float]:
    """World +z made ⟂ `pad` (world +x if the pad faces within 25° of vertical), unit."""
    ref = (1.0, 0.0, 0.0) if abs(pad[2]) > _VERTICAL else (0.0, 0.0, 1.0)
    return _perpendicular(ref, pad)


def _perpendicular(v, p) -> tuple[float, float, float]:
    """The unit part of `v` ⟂ unit `p`."""
    k = v[0] * p[0] + v[1] * p[1] + v[2] * p[2]
    x, y, z = v[0] - k * p[0], v[1] - k * p[1], v[2] - k * p[2]
    n = math.sqrt(x * x + y * y + z * z)
    return (x / n, y / n, z / n)


class PadFrame:
    """A finger's pad frame in the world: pad p̂, distal d̂ (turned by the device twist), lateral l̂."""

    def __init__(self, pad: tuple | None, distal: tuple | None) -> None:
        self.fixed = pad is not None
        self.pad = pad
        self.distal0 = None if pad is None else (distal if distal is not None else default_distal(pad))
        if pad is not None:
            self.distal0 = _perpendicular(self.distal0, pad)
        self.twist0 = 0.0
        self.distal = self.distal0
        self.lateral = None

    def touch(self, nx: float, ny: float, nz: float, twist: float) -> None:
        """A new contact: latch the pad to -n (unless the scene fixed it) and the twist reference."""
        if not self.fixed:
            self.pad = (-nx, -ny, -nz)
            self.distal0 = default_distal(self.pad)
            self.twist0 = twist

    def orient(self, twist: float) -> None:
        """d̂ = d̂0 turned about -p̂ by the twist since the reference (rad); l̂ = d̂ × p̂."""
        p, d = self.pad, self.distal0
        a = twist - self.twist0
        if a != 0.0:
            c, s = math.cos(a), -math.sin(a)  # about -p̂: (−p̂) × d = −(p̂ × d)
            kx, ky, kz = p[1] * d[2] - p[2] * d[1], p[2] * d[0] - p[0] * d[2], p[0] * d[1] - p[1] * d[0]
            d = (c * d[0] + s * kx, c * d[1] + s * ky, c * d[2] + s * kz)
        self.distal = d
        self.lateral = (d[1] * p[2] - d[2] * p[1], d[2] * p[0] - d[0] * p[2], d[0] * p[1] - d[1] * p[0])


class _Channel:
    """Decimation, exception fence and counters shared by both channels."""

    kind = "channel"

    def __init__(self, finger, rate_hz: float, servo_rate_hz: float, pad, distal, history: int) -> None:
        self.finger = finger
        self.device_finger = finger.params.device_finger  # the row of loop.samples it reads (`attach` sets the loop's)
        self.every = max(1, int(round(servo_rate_hz / rate_hz)))
        self.rate_hz = servo_rate_hz / self.every  # the rate actually run, Hz
        self._countdown = self.every
        self.frame = PadFrame(pad, distal)
        self.in_contact = False
        self.frames = 0          # working ticks
        self.contact_frames = 0  # working ticks with a contact to process
        self.errors = 0          # exceptions caught (never propagated)
        self.last_error = ""
        self.history: deque = deque(maxlen=history)

    def tick(self, loop) -> None:
        """Called by the servo loop every tick; works on every `every`-th only, never raises."""
        self._countdown -= 1
        if self._countdown:
            return
        self._countdown = self.every
        try:
            self.frames += 1
            self._frame(loop.t, loop.samples[self.device_finger].twist)
        except Exception as exc:  # a sensor must never take the servo loop with it
            self.errors += 1
            self.last_error = f"{type(exc).__name__}: {exc}"
            self.in_contact = False

    def _contact(self, twist: float) -> bool:
        """Whether the finger has a pushing contact now; latches the pad frame on a new one."""
        f = self.finger
        if not (f.valid and f.body >= 0 and f.normal_force > 0.0 and math.isfinite(twist)):
            return False
        god = f.god
        if not self.in_contact:
            self.frame.touch(god.nx, god.ny, god.nz, twist)
        self.frame.orient(twist)
        return True

    def _frame(self, t: float, twist: float) -> None:
        raise NotImplementedError


class TactileChannel(_Channel):
    """The Inoue–Hirai pressure image of one finger, decimated (see the module docstring).

    Readable after any tick: `image` (cells × cells, Pa, [row = y, column = x] in the pad's
    sensing-plane frame), `total_force` (N), `pressure_centre` ((x, y) m, nan without contact),
    `roll_rad`, `lateral_roll_rad`, `indentation_m`; `history` of the last frames.
    """

    kind = "tactile"

    def __init__(self, finger, spec: TactileSpec, servo_rate_hz: float) -> None:
        super().__init__(finger, spec.rate_hz, servo_rate_hz, spec.pad, spec.distal, spec.history)
        self.spec = spec
        r = spec.radius if spec.radius is not None else finger.params.radius
        if not r > 0.0:
            raise ValueError(f"finger {finger.params.name!r}: a point finger (radius 0) needs tactile.radius")
        side = spec.side if spec.side is not None else 2.0 * r
        self.sensor = TactileSensor(radius=r, youngs_modulus=spec.youngs_modulus, joint_distance=0.0,
                                    cells=spec.cells, side=side, supersample=spec.supersample,
                                    max_substeps=spec.max_substeps, max_tilt_rad=MAX_TILT)
        self._force_to_depth = 1.0 / (math.pi * spec.youngs_modulus)
        self.off_pad = 0  # contact frames whose normal was MAX_TILT or more from the pad
        self.total_force = 0.0
        self.pressure_centre = (math.nan, math.nan)
        self.roll_rad = self.lateral_roll_rad = self.indentation_m = 0.0
        self.max_total_force = 0.0

    @property
    def image(self):
        """The last pressure image, Pa (a copy)."""
        return self.sensor.image

    def _clear(self) -> None:
        if self.in_contact or self.total_force:
            self.sensor.reset()
        self.in_contact = False
        self.total_force = 0.0
        self.pressure_centre = (math.nan, math.nan)
        self.roll_rad = self.lateral_roll_rad = self.indentation_m = 0.0

    def _frame(self, t: float, twist: float) -> None:
        f = self.finger
        P = f.normal_force
        if not self._contact(twist):
            self._clear()
        else:
            god = f.god
            fr = self.frame
            ux, uy, uz = -god.nx, -god.ny, -god.nz  # toward the object
            p, d = fr.pad, fr.distal
            up = ux * p[0] + uy * p[1] + uz * p[2]
            ud = ux * d[0] + uy * d[1] + uz * d[2]
            ul = -(ux * fr.lateral[0] + uy * fr.lateral[1] + uz * fr.lateral[2])  # along +y = p̂ × d̂ = -l̂
            beta = math.atan2(ud, up)
            if up <= 0.0 or abs(beta) >= MAX_TILT:
                self.off_pad += 1
                self._clear()
            else:
                depth = math.sqrt(P * self._force_to_depth) if self.spec.indentation == "force" else god.depth
                self.contact_frames += 1
                self.in_contact = True
                self.sensor.update(depth, 0.0, beta if abs(beta) >= ROLL_DEADBAND else 0.0)
                self.total_force = self.sensor.total_force()
                self.pressure_centre = self.sensor.pressure_centre()
                self.roll_rad, self.lateral_roll_rad, self.indentation_m = beta, math.atan2(ul, up), depth
                if self.total_force > self.max_total_force:
                    self.max_total_force = self.total_force
        self.history.append((t, P if self.in_contact else 0.0, self.total_force, self.pressure_centre))

    def summary(self) -> dict:
        """JSON-ready: frames, the last image's force and centre, the recent history."""
        c = self.pressure_centre
        return {
            "rate_hz": self.rate_hz, "frames": self.frames, "contact_frames": self.contact_frames,
            "off_pad_frames": self.off_pad, "errors": self.errors, "last_error": self.last_error,
            "cells": self.sensor.grid.cells, "side_m": self.sensor.grid.side,
            "last_total_force_N": _r(self.total_force, 6),
            "last_pressure_centre_m": None if math.isnan(c[0]) else [_r(c[0]), _r(c[1])],
            "last_roll_rad": _r(self.roll_rad, 6), "max_total_force_N": _r(self.max_total_force, 6),
            "history": [{"t": _r(t, 6), "normal_force_N": _r(P, 6), "total_force_N": _r(F, 6),
                         "pressure_centre_m": None if math.isnan(cc[0]) else [_r(cc[0]), _r(cc[1])]}
                        for t, P, F, cc in self.history],
        }


class SensingChannel(_Channel):
    """Seed 003's contact sensing on the wrench the proxy produced, checked against its ground truth.

    Readable after any tick: `estimate` (the last ContactEstimate, Nano17 frame), `point_world`
    (its contact point in the world, m, or None), `truth` (the last ground truth, Nano17 frame),
    and running error statistics (`summary()`).
    """

    kind = "sensing"

    def __init__(self, finger, spec: SensingSpec, servo_rate_hz: float, tip: Fingertip | None = None) -> None:
        super().__init__(finger, spec.rate_hz, servo_rate_hz, spec.pad, spec.distal, spec.history)
        self.spec = spec
        self.sensor = ContactSensor(tip, warm_start=True)
        self.tip = self.sensor.tip
        self.mount = self.sensor.mount
        self._rng = random.Random(spec.seed)
        self.estimate = None
        self.truth = None
        self.point_world = None
        self.sensed = 0     # explained wrenches
        self.refused = 0    # contacts whose wrench the sensor did not explain
        self.last_refusal = ""
        self._loc_max = self._loc_sq = 0.0
        self._fn_max = self._fn_sq = 0.0
        self._ft_max = self._tau_max = 0.0

    def _frame(self, t: float, twist: float) -> None:
        if not self._contact(twist):
            self.in_contact = False
            return
        self.in_contact = True
        self.contact_frames += 1
        f = self.finger
        god = f.god
        fr = self.frame
        X, Y, Z = fr.lateral, fr.distal, fr.pad  # ellipsoid axes in the world (columns of R)
        nx, ny, nz = god.nx, god.ny, god.nz
        # outward skin normal -n and everything else in the ellipsoid frame: v_e = Rᵀ v
        ne = (-(X[0] * nx + X[1] * ny + X[2] * nz), -(Y[0] * nx + Y[1] * ny + Y[2] * nz),
              -(Z[0] * nx + Z[1] * ny + Z[2] * nz))
        P = f.normal_force
        dd = self.tip.deformation(P)
        pc = self.tip.point_with_normal(ne, dd)
        fx, fy, fz = f.fx, f.fy, f.fz
        Fe = (X[0] * fx + X[1] * fy + X[2] * fz, Y[0] * fx + Y[1] * fy + Y[2] * fz, Z[0] * fx + Z[1] * fy + Z[2] * fz)
        tx, ty, tz = f.tx, f.ty, f.tz
        Te = (X[0] * tx + X[1] * ty + X[2] * tz, Y[0] * tx + Y[1] * ty + Y[2] * tz, Z[0] * tx + Z[1] * ty + Z[2] * tz)
        Me = (pc[1] * Fe[2] - pc[2] * Fe[1] + Te[0], pc[2] * Fe[0] - pc[0] * Fe[2] + Te[1],
              pc[0] * Fe[1] - pc[1] * Fe[0] + Te[2])
        ft_e = (Fe[0] + P * ne[0], Fe[1] + P * ne[1], Fe[2] + P * ne[2])
        mount = self.mount
        Fs, Ms = mount.wrench_to_sensor(Fe, Me)
        noise = self.spec.noise
        if noise == "gauss":
            g = self._rng.gauss
            Fs = tuple(v + g(0.0, FORCE_LSB) for v in Fs)
            Ms = tuple(v + g(0.0, TORQUE_LSB) for v in Ms)
        elif noise == "quantise":
            Fs = tuple(round(v / FORCE_LSB) * FORCE_LSB for v in Fs)
            Ms = tuple(round(v / TORQUE_LSB) * TORQUE_LSB for v in Ms)
        est = self.sensor.sense(Fs, Ms, sensor_frame=True, checked=True)
        point = mount.point_to_sensor(pc)
        friction = mount.vector_to_sensor(ft_e)
        tau = -f.torque
        self.truth = (point, P, friction, tau)
        self.estimate = est
        if not est.explained:
            self.refused += 1
            self.last_refusal = est.reason
            self.point_world = None
            self.history.append((t, P, None, None, est.reason))
            return
        self.sensed += 1
        q = est.point
        e_loc = math.sqrt((q[0] - point[0]) ** 2 + (q[1] - point[1]) ** 2 + (q[2] - point[2]) ** 2)
        e_fn = abs(est.normal_force - P)
        ef = est.friction
        e_ft = math.sqrt((ef[0] - friction[0]) ** 2 + (ef[1] - friction[1]) ** 2 + (ef[2] - friction[2]) ** 2)
        e_tau = abs(est.local_torque - tau)
        self._loc_sq += e_loc * e_loc
        self._fn_sq += e_fn * e_fn
        self._loc_max = max(self._loc_max, e_loc)
        self._fn_max = max(self._fn_max, e_fn)
        self._ft_max = max(self._ft_max, e_ft)
        self._tau_max = max(self._tau_max, e_tau)
        # the estimate in the world: ellipsoid centre = contact point - R p_c
        qe = mount.point_to_ellipsoid(q)
        w = (qe[0] - pc[0], qe[1] - pc[1], qe[2] - pc[2])
        self.point_world = (f.px + X[0] * w[0] + Y[0] * w[1] + Z[0] * w[2],
                            f.py + X[1] * w[0] + Y[1] * w[1] + Z[1] * w[2],
                            f.pz + X[2] * w[0] + Y[2] * w[1] + Z[2] * w[2])
        self.history.append((t, P, est.normal_force, e_loc, ""))

    def errors_summary(self) -> dict:
        """Running error statistics over the explained frames (SI)."""
        n = self.sensed
        return {
            "location_max_m": self._loc_max if n else None,
            "location_rms_m": math.sqrt(self._loc_sq / n) if n else None,
            "normal_force_max_N": self._fn_max if n else None,
            "normal_force_rms_N": math.sqrt(self._fn_sq / n) if n else None,
            "friction_max_N": self._ft_max if n else None,
            "local_torque_max_Nm": self._tau_max if n else None,
        }

    def summary(self) -> dict:
        """JSON-ready: frames, sensed and refused counts, error statistics, the recent history."""
        return {
            "rate_hz": self.rate_hz, "noise": self.spec.noise, "seed": self.spec.seed, "frames": self.frames,
            "contact_frames": self.contact_frames, "sensed": self.sensed, "refused": self.refused,
            "last_refusal": self.last_refusal, "errors": self.errors, "last_error": self.last_error,
            "error": self.errors_summary(),
            "history": [{"t": round(t, 6), "normal_force_N": round(P, 6),
                         "estimated_normal_force_N": None if fn is None else round(fn, 6),
                         "location_error_m": loc, "refused": reason}
                        for t, P, fn, loc, reason in self.history],
        }


def attach(loop, tactile: list, sensing: list) -> list:
    """Append the channels a scene asks for to `loop.sensors`: `tactile[i]` / `sensing[i]` is a
    spec or None for `loop.fingers[i]`. Returns the channels added (none: the list stays empty)."""
    added = []
    rows = loop.sample_rows  # with several devices a finger's sample is not at its device_finger
    for i, finger in enumerate(loop.fingers):
        t = tactile[i] if i < len(tactile) else None
        s = sensing[i] if i < len(sensing) else None
        if t is not None:
            added.append(TactileChannel(finger, t, loop.rate_hz))
        if s is not None:
            added.append(SensingChannel(finger, s, loop.rate_hz))
        for ch in added:
            if ch.finger is finger:
                ch.device_finger = rows[i]
    loop.sensors.extend(added)
    return added


def summaries(loop) -> dict[int, dict]:
    """Per finger index: {"tactile": ..., "sensing": ...} for the channels attached to it."""
    out: dict[int, dict] = {}
    for ch in getattr(loop, "sensors", ()):
        if isinstance(ch, _Channel):
            i = next(k for k, f in enumerate(loop.fingers) if f is ch.finger)
            out.setdefault(i, {})[ch.kind] = ch.summary()
    return out
