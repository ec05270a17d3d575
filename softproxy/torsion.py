"""The fourth DOF of the soft-finger proxy: stick/slip torsional friction about the contact normal.

The paper *Simulating human fingers: a Soft Finger Proxy Model and Algorithm*, §7, eqs 38–42, with two errata fixed (docs/physics.md):
- eq 40 lacks sign(α_g - α_p): without it a slip in the negative direction overshoots the
  goal and flips the torque. Here a slip leaves the proxy exactly μ_d|P|^γ / k_τ from the goal
  on the side it came from, so after a slip |M| = μ_d|P|^γ with the sign of the twist;
- eq 41 takes |ω·n|, which throws away the direction the object turned. α_c = (ω·n)Δt is
  kept signed: an object turning backwards must drag the proxy backwards.

The goal is the device twist measured from where contact began (DESIGN's reading of §7's
α_g): α_p starts at the device twist α_s when contact is made, so M starts at zero and
M = k_τ(α_p - α_s) thereafter.

A choice beyond the seed: a slip state. Eq 39 read literally re-tests the static limit every
tick, so a steady twist saw-tooths between μ_d|P|^γ and μ_s|P|^γ (~110 Hz at 0.1 rad/s,
P = 1 N, k_τ = 2: a buzz in the finger). By default a slipping contact stays in dynamic
friction, |M| = μ_d|P|^γ, until the twist stops (no slide for `restick_time`, 0.05 s) or
reverses (the torque along the slip falls below 0.6 μ_d|P|^γ), as in Karnopp's model;
`restick_time=0` is eq 39 as printed. Constants and figures: docs/friction.md. All angles are right-handed about the contact normal n
(pointing out of the object, toward the finger). M is the torque on the finger; the object
gets -M about n. Units: rad, N, N·m, N·m/rad.

The law runs in the compiled kernels (`softproxy.compiled.finger`, `torsion_*`);
`TorsionalFriction` is a view onto a finger's records (`softproxy.finger_rows`).
"""

from __future__ import annotations

from softproxy.compiled import finger as kernel
from softproxy.compiled.godobject import RESTICK_TIME
from softproxy.fingertip import FingertipModel
from softproxy.input_error import check_finite
from softproxy.finger_rows import Field, FingerRows, RecordView


class TorsionalFriction(RecordView):
    """Stick/slip state of one finger's twist proxy α_p. `step` never returns NaN.

    `mu_s` and `mu_d` scale the model's law: the static limit is mu_s·|P|^γ and the dynamic
    torque mu_d·|P|^γ (N·m/N^γ). By default mu_s is the model's Table 1 μ'_m and mu_d is
    0.8·mu_s (the seed leaves μ_d to experiment; 0.8 is a typical static-to-kinetic ratio
    for skin). With `saturate=True` the static limit follows the piecewise law of eq 26
    (linear above P*) and the dynamic one is scaled by mu_d/mu_s.

    `restick_time` (s): a slipping contact that has not had to slip for this long sticks
    again (RESTICK_TIME by default); 0 re-tests the static limit every tick, eq 39 as printed.
    `slipping` is the slip state: True from a slip until the contact re-sticks.
    """

    k_tau = Field("torsion_stiffness")
    mu_s = Field("torsion_mu_s")
    mu_d = Field("torsion_mu_d")
    gamma = Field()
    saturate = Field(kind=bool)
    in_contact = Field(kind=bool)
    alpha_0 = Field()
    alpha_p = Field()
    alpha_g = Field()
    torque = Field("spring_torque")
    limit = Field()
    slipping = Field(kind=bool)
    slip_events = Field(kind=int)
    restick_time = Field("torsion_restick")

    def __init__(self, model: FingertipModel, k_tau: float, mu_s: float | None = None, mu_d: float | None = None,
                 saturate: bool = False, rows: FingerRows | None = None, i: int = 0,
                 restick_time: float = RESTICK_TIME) -> None:
        """`rows`, `i`: the finger to live in (a table of its own by default)."""
        k_tau = check_finite("k_tau", k_tau, positive=True)
        restick_time = check_finite("restick_time", restick_time, non_negative=True)
        mu_s = model.mu_prime if mu_s is None else check_finite("mu_s", mu_s, non_negative=True)
        mu_d = 0.8 * mu_s if mu_d is None else check_finite("mu_d", mu_d, non_negative=True)
        if mu_d > mu_s:
            raise ValueError(f"mu_d ({mu_d}) must be <= mu_s ({mu_s})")
        self._bind(rows if rows is not None else FingerRows(None, 1), i)
        self.model = model
        fm, fd = self._recs
        fm["has_torsion"] = True
        fm["torsion_stiffness"], fm["torsion_mu_s"], fm["torsion_mu_d"] = k_tau, mu_s, mu_d
        fm["gamma"], fm["saturate"] = model.gamma, bool(saturate)
        fm["ratio"] = mu_d / mu_s if mu_s > 0.0 else 0.0
        fm["mu_prime"], fm["r0"], fm["p_star"] = model.mu_prime, model.r0, model.p_star
        fm["torsion_restick"] = restick_time
        fd["slip_events"] = 0
        self.release()

    def touch(self, alpha_s: float) -> None:
        """Contact made: the proxy twist starts at the finger's current twist α_s (rad)."""
        self._rows.run(kernel.torsion_touch_row, self._rows.tables, self._i, float(alpha_s))

    def release(self) -> None:
        """Contact broken: torsion state cleared, no torque."""
        self._rows.run(kernel.torsion_release_row, self._rows.tables, self._i)

    def step(self, alpha_s: float, P: float, dt: float = 1e-3) -> float:
        """One servo tick of dt s (eqs 38-40, with the slip state): new α_p from device twist
        α_s (rad) and normal force P (N); returns M = k_τ(α_p - α_g) on the finger about n (N·m)."""
        return self._rows.run(kernel.torsion_step_row, self._rows.tables, self._i, float(alpha_s), float(P), float(dt))

    def follow_object(self, omega_n: float, dt: float) -> None:
        """Eqs 41-42: α_p += (ω·n)Δt, the object's signed spin about n (rad/s) over Δt (s)."""
        self._rows.run(kernel.torsion_follow_row, self._rows.tables, self._i, float(omega_n), float(dt))
