"""`SoftFingerProxy`: the 4-DOF soft-finger proxy of one finger (seed 002 §7).

A god-object position (`softproxy.proxy`) plus the torsional angle α (`softproxy.torsion`),
coupled to the device by a virtual spring-damper: F = k(x_p - x_d) + b d/dt(x_p - x_d) and
M = k_τ(α_p - α_g) + b_τ d/dt(α_p - α_g) about the contact normal n. F and M are what the
finger feels; the touched object gets -F at the contact point and -M·n.

The twist α_s read from the device is taken about the finger's own axis pointing from the
fingertip back toward the hand, which is +n when the finger presses straight on a surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from softproxy.fingertip import MODELS, FingertipModel, _check_finite
from softproxy.geometry import Shape
from softproxy.proxy import WORKSPACE_LIMIT, GodObject
from softproxy.torsion import TorsionalFriction

SPIKE_PATIENCE = 3
"""Consecutive ticks a position jump is held back as a spike before it is believed."""


@dataclass
class FingerParams:
    """Per-finger settings of a scene (SI units). Validated on construction: every number
    finite and within `LIMITS`, so no setting can drive a force to overflow (Inf, then NaN
    at the clamp); ValueError naming the field, its range and its unit otherwise."""

    name: str = "finger"
    radius: float = 0.008           # proxy sphere radius, m
    stiffness: float = 2000.0       # k, N/m
    damping: float = 5.0            # b, N·s/m
    torsion_stiffness: float = 2.0  # k_τ, N·m/rad
    torsion_damping: float = 0.002  # b_τ, N·m·s/rad
    model: str = "CH"               # fingertip model: CH, MH, VS, LFM or point
    mu_s: float = 1.0               # translational static friction
    mu_d: float = 0.8               # translational dynamic friction
    torsion_mu_s: float | None = None  # static torsional coefficient, N·m/N^γ (default: Table 1)
    torsion_mu_d: float | None = None  # dynamic torsional coefficient (default: 0.8 static)
    saturate: bool = False          # torsion limit follows eq 26 above P*
    max_force: float = 40.0         # clamp on |F|, N
    max_torque: float = 1.0         # clamp on |M|, N·m
    max_speed: float = 20.0         # a device sample farther than max_speed·dt from the last is a spike, m/s
    soft_start: float = 0.1         # after placement the force clamp ramps from 0 to max_force over this, s
    device_finger: int = 0          # which finger of the device drives this one
    offset: tuple = (0.0, 0.0, 0.0)  # device-to-world offset, m
    scale: float = 1.0              # device-to-world workspace scale

    LIMITS: ClassVar[dict[str, tuple[float, float, str]]] = {
        # field: (lowest, highest, unit). Why the highest: a device position is believed
        # within ±WORKSPACE_LIMIT (1 km) and a tick is at least 10 µs (100 kHz), so the
        # spring stretch is < ~2e6 m (with `scale`) and its rate < ~2e11 m/s; at these
        # bounds k·stretch + b·rate stays below ~1e17 N, far from float overflow (a
        # damping of 1e308 made b·rate Inf and the clamp Inf·0 = NaN). Each bound is also
        # orders of magnitude past any real setting, so it only catches mistakes (mm typed
        # as m, an exponent slip) and admits the extremes the tests and benchmarks drive
        # (k = 1e7 N/m, b = 1e3 N·s/m, k_τ = 1e6 N·m/rad, a 1e4 N clamp).
        "radius": (0.0, 0.1, "m"),                 # a fingertip or a tool tip (shipped: 5–50 mm)
        "stiffness": (0.0, 1e8, "N/m"),            # devices render ≤ ~1e4 N/m; tests 1e7
        "damping": (0.0, 1e5, "N·s/m"),            # devices render ≤ ~1e2 N·s/m; tests 1e3
        "torsion_stiffness": (0.0, 1e7, "N·m/rad"),  # shipped 0.5–2; tests 1e6
        "torsion_damping": (0.0, 1e4, "N·m·s/rad"),  # shipped ≤ 0.01
        "mu_s": (0.0, 10.0, ""),                   # a friction cone of 84°; skin is ~0.5–3
        "mu_d": (0.0, 10.0, ""),
        "torsion_mu_s": (0.0, 1.0, "N·m/N^γ"),     # ~100 × Table 1's μ' (~0.008 N·m/N^γ)
        "torsion_mu_d": (0.0, 1.0, "N·m/N^γ"),
        "max_force": (0.0, 1e5, "N"),              # devices render ≤ ~1e2 N; the wall benchmark 200 N, tests 1e4
        "max_torque": (0.0, 1e3, "N·m"),           # devices render ≤ ~1 N·m
        "max_speed": (0.0, 1e4, "m/s"),            # a hand moves at ≤ ~5 m/s; the spike test is off well below this
        "soft_start": (0.0, 60.0, "s"),            # a ramp of a minute is already no force at all to a user
        "scale": (0.0, 1e3, ""),                   # device workspace (cm) to world; 1e3 maps 1 mm to 1 m
        "offset": (-WORKSPACE_LIMIT, WORKSPACE_LIMIT, "m"),  # each component: inside the workspace
    }
    """Allowed range of every numeric field, (lowest, highest, unit); see the comments for why."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        if self.model not in MODELS:
            raise ValueError(f"model must be one of {', '.join(MODELS)}, got {self.model!r}")
        if not isinstance(self.saturate, bool):
            raise ValueError(f"saturate must be true or false, got {self.saturate!r}")
        for name in ("radius", "damping", "torsion_damping", "mu_s", "mu_d", "soft_start"):
            self._check_range(name, _check_finite(name, getattr(self, name), non_negative=True))
        for name in ("stiffness", "torsion_stiffness", "max_force", "max_torque", "scale", "max_speed"):
            self._check_range(name, _check_finite(name, getattr(self, name), positive=True))
        for name in ("torsion_mu_s", "torsion_mu_d"):
            if getattr(self, name) is not None:
                self._check_range(name, _check_finite(name, getattr(self, name), non_negative=True))
        if self.mu_d > self.mu_s:
            raise ValueError(f"mu_d ({self.mu_d}) must be <= mu_s ({self.mu_s})")
        if (self.torsion_mu_s is not None and self.torsion_mu_d is not None
                and self.torsion_mu_d > self.torsion_mu_s):
            raise ValueError(f"torsion_mu_d ({self.torsion_mu_d}) must be <= torsion_mu_s ({self.torsion_mu_s})")
        if isinstance(self.device_finger, bool) or not isinstance(self.device_finger, int) or self.device_finger < 0:
            raise ValueError(f"device_finger must be an integer >= 0, got {self.device_finger!r}")
        try:
            if len(self.offset) != 3:
                raise TypeError
        except TypeError:
            raise ValueError(f"offset must be 3 numbers (m), got {self.offset!r}") from None
        self.offset = tuple(self._check_range("offset", _check_finite("offset", v)) for v in self.offset)

    def _check_range(self, name: str, value: float) -> float:
        """`value` if within LIMITS[name], else ValueError naming the field, the range and the unit."""
        low, high, unit = self.LIMITS[name]
        if not low <= value <= high:
            unit = f" {unit}" if unit else ""
            raise ValueError(f"{name} must be at most {high:g}{unit}"
                             f"{f' and at least {low:g}{unit}' if low < 0.0 else ''}, got {value!r}")
        return value


class SoftFingerProxy:
    """One finger: god-object + torsion + virtual coupling. `update(...)` (or `hold()`) once
    per tick, after mj_step1: it first turns α_p with the body it touched last tick.

    Outputs after `update`: fx, fy, fz (force on the finger, world, N), torque (M about n,
    N·m), tx, ty, tz (M·n, N·m), px, py, pz (contact point on the object, m), body (touched
    body id or -1), normal_force (P = F·n, N), valid (False when the device sample was bad).
    """

    # Slots, not an instance dict: with more than 30 attributes CPython gives each instance a
    # dict of its own keys, and two fingers read in turn then defeat the interpreter's
    # attribute caches (a finger's update measured 14 µs instead of 7 µs with two fingers).
    __slots__ = (
        "params", "god", "placed", "model", "torsion", "k", "b", "b_tau", "max_force", "max_torque",
        "ox", "oy", "oz", "scale", "max_speed", "soft_start", "dt", "_ramp", "xd", "yd", "zd",
        "_sx", "_sy", "_sz", "_stwist", "fx", "fy", "fz", "torque", "tx", "ty", "tz", "px", "py", "pz",
        "body", "normal_force", "valid", "max_force_seen", "penetration_max", "slide_events",
        "spikes_rejected", "_spike_run", "_was_sticking",
    )

    def __init__(self, params: FingerParams, shapes: list[Shape], model: FingertipModel,
                 start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        self.params = params
        self.god = GodObject(shapes, params.radius, params.mu_s, params.mu_d, start)
        self.placed = True
        self.model = model
        self.torsion = TorsionalFriction(model, params.torsion_stiffness, params.torsion_mu_s,
                                         params.torsion_mu_d, params.saturate) if model.has_torsion else None
        self.k, self.b = params.stiffness, params.damping
        self.b_tau = params.torsion_damping
        self.max_force, self.max_torque = params.max_force, params.max_torque
        self.ox, self.oy, self.oz = params.offset
        self.scale = params.scale
        self.max_speed = params.max_speed
        self.soft_start = params.soft_start
        self.dt = 1e-3  # the last tick's period (s), for a hold() that has none of its own
        self._ramp = 1.0  # soft start: fraction of the clamps in force; 0 right after placement
        self.xd = self.yd = self.zd = 0.0
        self._sx = self._sy = self._sz = 0.0    # last spring stretch, for damping
        self._stwist = 0.0
        self.clear_output()
        self.max_force_seen = 0.0
        self.penetration_max = 0.0
        self.slide_events = 0  # translational stick -> slide transitions
        self.spikes_rejected = 0
        self._spike_run = 0
        self._was_sticking = False

    def place(self, x: float, y: float, z: float) -> bool:
        """Put the proxy at a device position (device frame, m), out of contact.

        Returns False, and leaves the finger unplaced, for a position outside the workspace.
        An unplaced finger places itself at its first good sample and renders nothing then.
        """
        xd, yd, zd = self.ox + self.scale * x, self.oy + self.scale * y, self.oz + self.scale * z
        try:
            self.god.reset(xd, yd, zd)
        except ValueError:
            self.placed = False
            return False
        self.placed = True
        self._ramp = 0.0 if self.soft_start > 0.0 else 1.0
        self.xd, self.yd, self.zd = xd, yd, zd
        if self.torsion is not None:
            self.torsion.release()
        return True

    def hold(self) -> None:
        """No usable device sample this tick: zero force, the proxy only follows its body.
        The soft start's ramp winds down as fast as it winds up, so after an outage of T s
        (a device error, invalid samples) the clamps come back from max·(1 − T/soft_start):
        a finger that moved into an object meanwhile gets no kick; one lost sample costs
        a hundredth of the clamp at 1 kHz (0.1 s soft start), not the grip."""
        if self.body >= 0:
            self._follow_body()
        if self.soft_start > 0.0:
            ramp = self._ramp - self.dt / self.soft_start
            self._ramp = ramp if ramp > 0.0 else 0.0
        self._rest()

    def _rest(self) -> None:
        """Zero force; the proxy stays on its body and out of anything that moved into it."""
        if self.placed:
            self.god.follow()
        self.clear_output()

    def _follow_body(self) -> None:
        """Eqs 41–42: the touched body's spin about n (rad/s, world) drags α_p, signed."""
        tors = self.torsion
        if tors is not None and tors.in_contact:
            god = self.god
            wx, wy, wz, _, _, _ = god.shape.cvel.tolist()
            tors.follow_object(wx * god.nx + wy * god.ny + wz * god.nz, self.dt)

    def clear_output(self) -> None:
        """Zero force and torque: the safe state."""
        self.fx = self.fy = self.fz = 0.0
        self.torque = self.tx = self.ty = self.tz = 0.0
        self.px = self.py = self.pz = 0.0
        self.body = -1
        self.normal_force = 0.0
        self.valid = False

    def update(self, x: float, y: float, z: float, twist: float, dt: float) -> bool:
        """One tick from a device sample (device frame, m and rad) over period dt (s).

        Returns False when the sample was unusable (out of the workspace, non-finite twist):
        the finger then renders zero force and its proxy stays where it was.
        """
        self.dt = dt
        if self.body >= 0:  # in contact last tick: the body it touches turns α_p with it
            self._follow_body()
        if not self.placed:
            ok = self.place(x, y, z) and twist == twist and twist not in (math.inf, -math.inf)
            self.clear_output()
            return ok
        xd = self.ox + self.scale * x
        yd = self.oy + self.scale * y
        zd = self.oz + self.scale * z
        # velocity-spike filter: a jump no hand makes in one period is held back for up to
        # SPIKE_PATIENCE ticks; a device that really moved that far is followed after that.
        ex, ey, ez = xd - self.xd, yd - self.yd, zd - self.zd
        reach = self.max_speed * dt
        if ex * ex + ey * ey + ez * ez > reach * reach and self._spike_run < SPIKE_PATIENCE:
            self._spike_run += 1
            self.spikes_rejected += 1
            self._rest()
            return False
        self._spike_run = 0
        god = self.god
        if not god.update(xd, yd, zd) or twist != twist or twist in (math.inf, -math.inf):
            self.clear_output()
            return False
        self.xd, self.yd, self.zd = xd, yd, zd
        self.valid = True
        if not god.contact:
            self._was_sticking = False
            self._sx = self._sy = self._sz = 0.0
            self._stwist = 0.0
            if self.torsion is not None and self.torsion.in_contact:
                self.torsion.release()
            self.fx = self.fy = self.fz = 0.0
            self.torque = self.tx = self.ty = self.tz = 0.0
            self.body = -1
            self.normal_force = 0.0
            return True

        if self._was_sticking and not god.sticking:
            self.slide_events += 1
        self._was_sticking = god.sticking
        # translational virtual coupling
        sx, sy, sz = god.x - xd, god.y - yd, god.z - zd
        c = self.b / dt
        fx = self.k * sx + c * (sx - self._sx)
        fy = self.k * sy + c * (sy - self._sy)
        fz = self.k * sz + c * (sz - self._sz)
        self._sx, self._sy, self._sz = sx, sy, sz
        ramp = self._ramp
        if ramp < 1.0:  # soft start: no kick when a finger starts inside an object
            ramp = self._ramp = min(1.0, ramp + dt / self.soft_start)
        fmax = self.max_force * ramp
        f2 = fx * fx + fy * fy + fz * fz
        if f2 > fmax * fmax:
            s = fmax / math.sqrt(f2) if f2 > 0.0 else 0.0
            fx, fy, fz = fx * s, fy * s, fz * s
        nx, ny, nz = god.nx, god.ny, god.nz
        P = fx * nx + fy * ny + fz * nz
        if P < 0.0:  # damping pulling the finger into the surface: contact carries no pull
            fx, fy, fz = fx - P * nx, fy - P * ny, fz - P * nz
            P = 0.0
        self.fx, self.fy, self.fz = fx, fy, fz
        self.normal_force = P
        r = self.params.radius
        self.px, self.py, self.pz = god.x - r * nx, god.y - r * ny, god.z - r * nz
        self.body = god.shape.body
        fmag = math.sqrt(fx * fx + fy * fy + fz * fz)
        if fmag > self.max_force_seen:
            self.max_force_seen = fmag

        # torsional DOF (eqs 38–40)
        tors = self.torsion
        if tors is None:
            return True
        if not tors.in_contact:
            tors.touch(twist)
            self._stwist = 0.0
        M = tors.step(twist, P)
        stretch = tors.alpha_p - twist
        M += self.b_tau / dt * (stretch - self._stwist)
        self._stwist = stretch
        bound = tors.limit if tors.limit > abs(tors.torque) else abs(tors.torque)
        if bound > self.max_torque * ramp:
            bound = self.max_torque * ramp
        M = bound if M > bound else -bound if M < -bound else M
        self.torque = M
        self.tx, self.ty, self.tz = M * nx, M * ny, M * nz
        return True

    @property
    def slip_events(self) -> int:
        """Torsional slips plus translational stick-to-slide transitions."""
        return self.slide_events + (self.torsion.slip_events if self.torsion is not None else 0)

    def audit(self) -> float:
        """Deepest the proxy sits inside any shape now (m, >= 0); updates penetration_max.

        An unplaced finger has no proxy in the world yet: nothing to audit.
        """
        if not self.placed:
            return 0.0
        god = self.god
        worst = 0.0
        for s in god.shapes:
            inside = god.radius - s.distance(god.x, god.y, god.z)[0]
            if inside > worst:
                worst = inside
        if worst > self.penetration_max:
            self.penetration_max = worst
        return worst
