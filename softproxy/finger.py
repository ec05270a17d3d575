"""`SoftFingerProxy`: the 4-DOF soft-finger proxy of one finger (seed 002 §7).

A god-object position (`softproxy.proxy`) plus the torsional angle α (`softproxy.torsion`),
coupled to the device by a virtual spring-damper: F = k(x_p - x_d) + b d/dt(x_p - x_d) and
M = k_τ(α_p - α_g) + b_τ d/dt(α_p - α_g) about the contact normal n. F and M are what the
finger feels; the touched object gets -F at the contact point and -M·n.

The twist α_s read from the device is taken about the finger's own axis pointing from the
fingertip back toward the hand, which is +n when the finger presses straight on a surface.

Both friction laws (the god-object's cone, the torsion) keep a slip state: a slipping
contact stays in dynamic friction until the motion stops or reverses, so a steady slide or
twist renders a steady force or torque (docs/friction.md); `FingerParams.restick_time = 0`
re-tests the static limits every tick, as the seed prints eq 39.

The tick runs in the compiled kernels (`softproxy.compiled.finger`); `SoftFingerProxy` is a
view onto the finger's record (`softproxy.finger_rows`): its god-object and torsion views
read the same record.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from softproxy.compiled import finger as kernel
from softproxy.compiled.godobject import RESTICK_TIME, WORKSPACE_LIMIT
from softproxy.finger_rows import Field, FingerRows, RecordView
from softproxy.fingertip import MODELS, FingertipModel, _check_finite
from softproxy.fingertip import model as fingertip_model
from softproxy.geometry import Shape, ShapeSet
from softproxy.proxy import GodObject
from softproxy.torsion import TorsionalFriction



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
    saturate: bool = True           # torsion limit follows eq 26 (linear above P*); False: μ'|P|^γ at every P.
                                    # eq 26 is the default: closer to the measured fingertip (docs/peer.md)
    restick_time: float = RESTICK_TIME  # a slipping contact (cone, torsion) stopped this long re-sticks, s;
                                        # 0: static limits re-tested every tick (seed 002 eq 39 as printed)
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
        "restick_time": (0.0, 60.0, "s"),          # shipped 0.05; a minute is already never re-sticking
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
        for name in ("radius", "damping", "torsion_damping", "mu_s", "mu_d", "soft_start", "restick_time"):
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


class SoftFingerProxy(RecordView):
    """One finger: god-object + torsion + virtual coupling. `update(...)` (or `hold()`) once
    per tick, after mj_step1: it first turns α_p with the body it touched last tick.

    Outputs after `update`: fx, fy, fz (force on the finger, world, N), torque (M about n,
    N·m), tx, ty, tz (M·n, N·m), px, py, pz (contact point on the object, m), body (touched
    body id or -1), normal_force (P = F·n, N), valid (False when the device sample was bad).
    """

    placed = Field(kind=bool)
    k = Field()
    b = Field()
    b_tau = Field()
    max_force = Field()
    max_torque = Field()
    ox = Field()
    oy = Field()
    oz = Field()
    scale = Field()
    max_speed = Field()
    soft_start = Field()
    dt = Field()
    """The last tick's period (s), for a hold() that has none of its own."""
    ramp = Field()
    """Soft start: the fraction of the clamps in force; 0 right after placement."""
    xd = Field()
    yd = Field()
    zd = Field()
    fx = Field()
    fy = Field()
    fz = Field()
    torque = Field()
    tx = Field()
    ty = Field()
    tz = Field()
    px = Field()
    py = Field()
    pz = Field()
    body = Field(kind=int)
    normal_force = Field()
    valid = Field(kind=bool)
    max_force_seen = Field()
    penetration_max = Field()
    slide_events = Field(kind=int)
    """Translational stick-to-slide transitions."""
    spikes_rejected = Field(kind=int)
    energy = Field()
    """The passivity observer (J): what the coupling took in from the hand and the body, less
    what it gave back, credit capped at what its springs could give back; < 0 is energy it
    created and has not yet dissipated (`softproxy.compiled.passivity`)."""
    energy_in = Field()
    """All the energy the coupling took in since the finger was built (J): dissipated or stored."""
    energy_min = Field()
    """The observer's lowest value (J): the most energy the coupling ever owed."""
    pc_energy = Field()
    """Energy the passivity controller set out to dissipate (J)."""
    pc_ticks = Field(kind=int)
    """Ticks on which the passivity controller acted."""

    def __init__(self, params: FingerParams, shapes: list[Shape], model: FingertipModel | None = None,
                 start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> None:
        """`model`: the fingertip law; None takes the one `params.model` names. A law given
        with `params.model` left at its default (CH) decides, and `self.params.model` names it
        (a copy: the caller's params are not changed); a law that contradicts a model named
        explicitly in `params` is a ValueError, not a silent choice between the two."""
        if model is None:
            model = fingertip_model(params.model)
        elif params.model != model.name:
            if params.model != FingerParams.model:
                raise ValueError(f"finger {params.name!r}: FingerParams.model is {params.model!r} but the fingertip law "
                                 f"given is {model.name!r}; give one of them (SoftFingerProxy(params, shapes) uses "
                                 "params.model)")
            if model.name in MODELS:  # a law of the user's own keeps the params as given
                params = replace(params, model=model.name)
        self.params = params
        self.model = model
        self.god = GodObject(ShapeSet.of(shapes), params.radius, params.mu_s, params.mu_d, start, params.restick_time)
        self._bind(self.god._rows, 0)
        self.torsion = TorsionalFriction(model, params.torsion_stiffness, params.torsion_mu_s, params.torsion_mu_d,
                                         params.saturate, rows=self._rows,
                                         restick_time=params.restick_time) if model.has_torsion else None
        rec = self._rec
        rec["placed"] = True
        rec["k"], rec["b"], rec["b_tau"] = params.stiffness, params.damping, params.torsion_damping
        rec["max_force"], rec["max_torque"] = params.max_force, params.max_torque
        rec["ox"], rec["oy"], rec["oz"] = params.offset
        rec["scale"], rec["max_speed"], rec["soft_start"] = params.scale, params.max_speed, params.soft_start
        rec["dt"] = 1e-3
        rec["ramp"] = 1.0
        self.clear_output()

    def _bind(self, rows: FingerRows, i: int) -> None:
        """Live in record i of `rows` (its god-object and torsion views too)."""
        super()._bind(rows, i)
        if getattr(self, "god", None) is not None and self.god._rows is not rows:
            self.god._bind(rows, i)
        if getattr(self, "torsion", None) is not None:
            self.torsion._bind(rows, i)

    def _args(self):
        r = self._rows
        s = r.shapes
        return s.S, s.T, s.C, s.xpos, s.xmat

    def place(self, x: float, y: float, z: float) -> bool:
        """Put the proxy at a device position (device frame, m), out of contact.

        Returns False, and leaves the finger unplaced, for a position outside the workspace.
        An unplaced finger places itself at its first good sample and renders nothing then.
        """
        r = self._rows
        return r.run(kernel.place_row, *self._args(), r.F, r.near, self._i, float(x), float(y), float(z))

    def hold(self) -> None:
        """No usable device sample this tick: zero force, the proxy only follows its body.
        The soft start's ramp winds down as fast as it winds up, so after an outage of T s
        (a device error, invalid samples) the clamps come back from max·(1 − T/soft_start):
        a finger that moved into an object meanwhile gets no kick."""
        r = self._rows
        r.run(kernel.hold_row, *self._args(), r.shapes.cvel, r.F, r.near, self._i)

    def clear_output(self) -> None:
        """Zero force and torque: the safe state."""
        self._rows.run(kernel.clear_output_row, self._rows.F, self._i)

    def update(self, x: float, y: float, z: float, twist: float, dt: float) -> bool:
        """One tick from a device sample (device frame, m and rad) over period dt (s).

        Returns False when the sample was unusable (out of the workspace, non-finite twist):
        the finger then renders zero force and its proxy stays where it was.
        """
        r = self._rows
        return r.run(kernel.update_row, *self._args(), r.shapes.cvel, r.F, r.near, self._i, float(x), float(y),
                     float(z), float(twist), float(dt), r.scratch)

    def use_torsion(self, model: FingertipModel | None) -> None:
        """Between ticks: make the finger a soft finger with `model`'s torsion law (a fresh
        torsion, out of contact, slip count kept) or, with None, a point contact; either way
        the torque is zero until the next tick computes one."""
        slips = self.torsion.slip_events if self.torsion is not None else 0
        rec = self._rec
        rec["torque"] = rec["tx"] = rec["ty"] = rec["tz"] = 0.0
        rec["twist_prev"] = rec["body_turn"] = 0.0
        if model is None:
            if self.torsion is not None:
                self.torsion.release()
            rec["has_torsion"] = False
            self.torsion = None
            return
        p = self.params
        self.model = model
        self.torsion = TorsionalFriction(model, p.torsion_stiffness, p.torsion_mu_s, p.torsion_mu_d, p.saturate,
                                         rows=self._rows, i=self._i, restick_time=p.restick_time)
        rec["slip_events"] = slips

    @property
    def slip_events(self) -> int:
        """Torsional slips plus translational stick-to-slide transitions."""
        return self.slide_events + (self.torsion.slip_events if self.torsion is not None else 0)

    def audit(self) -> float:
        """Deepest the proxy sits inside any shape now (m, >= 0); updates penetration_max.
        An unplaced finger has no proxy in the world yet: nothing to audit."""
        r = self._rows
        return r.run(kernel.audit_row, *self._args(), r.F, self._i)
