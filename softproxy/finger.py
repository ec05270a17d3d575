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
view onto the finger's records (`softproxy.finger_rows`): its god-object and torsion views
read the same records.
"""

from __future__ import annotations

from dataclasses import replace

from softproxy.compiled import finger as kernel
from softproxy.finger_rows import Field, FingerRows, RecordView, vector
from softproxy.fingertip import MODELS, FingertipModel
from softproxy.fingertip import model as fingertip_model
from softproxy.geometry import Shape, ShapeSet
from softproxy.proxy import GodObject
from softproxy.schema import FingerParams  # noqa: F401 (declared, with its bounds, in softproxy.schema)
from softproxy.torsion import TorsionalFriction


class SoftFingerProxy(RecordView):
    """One finger: god-object + torsion + virtual coupling. `update(...)` (or `hold()`) once
    per tick, after mj_step1: it first turns α_p with the body it touched last tick.

    Outputs after `update`: fx, fy, fz (force on the finger, world, N), torque (M about n,
    N·m), tx, ty, tz (M·n, N·m), px, py, pz (contact point on the object, m), body (touched
    body id or -1), normal_force (P = F·n, N), valid (False when the device sample was bad).
    """

    placed = Field(kind=bool)
    k = Field("stiffness")
    b = Field("damping")
    b_tau = Field("torsion_damping")
    max_force = Field()
    max_torque = Field()
    ox, oy, oz = vector("origin")
    scale = Field()
    max_speed = Field()
    soft_start = Field()
    dt = Field()
    """The last tick's period (s), for a hold() that has none of its own."""
    ramp = Field()
    """Soft start: the fraction of the clamps in force; 0 right after placement."""
    xd, yd, zd = vector("device_pos")
    fx, fy, fz = vector("force")
    torque = Field("torque_n")
    tx, ty, tz = vector("torque")
    px, py, pz = vector("contact_pos")
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
        fm, fd = self._recs
        fm["stiffness"], fm["damping"], fm["torsion_damping"] = params.stiffness, params.damping, params.torsion_damping
        fm["max_force"], fm["max_torque"] = params.max_force, params.max_torque
        fm["origin"] = params.offset
        fm["scale"], fm["max_speed"], fm["soft_start"] = params.scale, params.max_speed, params.soft_start
        fm["magnets"] = bool((self.god.shapes.S.magnet[:, 0] > 0.0).any()) if len(self.god.shapes) else False
        fd["placed"] = True
        fd["dt"] = 1e-3
        fd["ramp"] = 1.0
        self.clear_output()

    def _bind(self, rows: FingerRows, i: int) -> None:
        """Live in record i of `rows` (its god-object and torsion views too)."""
        super()._bind(rows, i)
        if getattr(self, "god", None) is not None and self.god._rows is not rows:
            self.god._bind(rows, i)
        if getattr(self, "torsion", None) is not None:
            self.torsion._bind(rows, i)

    def place(self, x: float, y: float, z: float) -> bool:
        """Put the proxy at a device position (device frame, m), out of contact.

        Returns False, and leaves the finger unplaced, for a position outside the workspace.
        An unplaced finger places itself at its first good sample and renders nothing then.
        """
        r = self._rows
        return r.run(kernel.place_row, r.shapes.tables, r.tables, self._i, float(x), float(y), float(z))

    def hold(self) -> None:
        """No usable device sample this tick: zero force, the proxy only follows its body.
        The soft start's ramp winds down as fast as it winds up, so after an outage of T s
        (a device error, invalid samples) the clamps come back from max·(1 − T/soft_start):
        a finger that moved into an object meanwhile gets no kick."""
        r = self._rows
        r.run(kernel.hold_row, r.shapes.tables, r.tables, self._i)

    def clear_output(self) -> None:
        """Zero force and torque: the safe state."""
        self._rows.run(kernel.clear_output_row, self._rows.tables, self._i)

    def update(self, x: float, y: float, z: float, twist: float, dt: float) -> bool:
        """One tick from a device sample (device frame, m and rad) over period dt (s).

        Returns False when the sample was unusable (out of the workspace, non-finite twist):
        the finger then renders zero force and its proxy stays where it was.
        """
        r = self._rows
        return r.run(kernel.update_row, r.shapes.tables, r.tables, self._i, float(x), float(y),
                     float(z), float(twist), float(dt))

    def use_torsion(self, model: FingertipModel | None) -> None:
        """Between ticks: make the finger a soft finger with `model`'s torsion law (a fresh
        torsion, out of contact, slip count kept) or, with None, a point contact; either way
        the torque is zero until the next tick computes one."""
        slips = self.torsion.slip_events if self.torsion is not None else 0
        fm, fd = self._recs
        fd["torque_n"] = 0.0
        fd["torque"] = 0.0
        fd["twist_prev"] = fd["body_turn"] = 0.0
        if model is None:
            if self.torsion is not None:
                self.torsion.release()
            fm["has_torsion"] = False
            self.torsion = None
            return
        p = self.params
        self.model = model
        self.torsion = TorsionalFriction(model, p.torsion_stiffness, p.torsion_mu_s, p.torsion_mu_d, p.saturate,
                                         rows=self._rows, i=self._i, restick_time=p.restick_time)
        fd["slip_events"] = slips

    @property
    def slip_events(self) -> int:
        """Torsional slips plus translational stick-to-slide transitions."""
        return self.slide_events + (self.torsion.slip_events if self.torsion is not None else 0)

    def audit(self) -> float:
        """Deepest the proxy sits inside any shape now (m, >= 0); updates penetration_max.
        An unplaced finger has no proxy in the world yet: nothing to audit."""
        r = self._rows
        return r.run(kernel.audit_row, r.shapes.tables, r.tables, self._i)
