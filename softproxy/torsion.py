"""The fourth DOF of the soft-finger proxy: stick/slip torsional friction about the contact normal.

Seed `002_36b58acb2f958b03.txt`, §7, eqs 38–42, with two errata fixed (../shared/DESIGN.md):
- eq 40 lacks sign(α_g - α_p): without it a slip in the negative direction overshoots the
  goal and flips the torque. Here a slip leaves the proxy exactly μ_d|P|^γ / k_τ from the goal
  on the side it came from, so after a slip |M| = μ_d|P|^γ with the sign of the twist;
- eq 41 takes |ω·n|, which throws away the direction the object turned. α_c = (ω·n)Δt is
  kept signed: an object turning backwards must drag the proxy backwards.

The goal is the device twist measured from where contact began (DESIGN's reading of §7's
α_g): α_p starts at the device twist α_s when contact is made, so M starts at zero and
M = k_τ(α_p - α_s) thereafter. All angles are right-handed about the contact normal n
(pointing out of the object, toward the finger). M is the torque on the finger; the object
gets -M about n. Units: rad, N, N·m, N·m/rad.
"""

from __future__ import annotations

import math

from softproxy.fingertip import P_MAX, FingertipModel, _check_finite


class TorsionalFriction:
    """Stick/slip state of one finger's twist proxy α_p. Allocation-free `step`, never NaN.

    `mu_s` and `mu_d` scale the model's law: the static limit is mu_s·|P|^γ and the dynamic
    torque mu_d·|P|^γ (N·m/N^γ). By default mu_s is the model's Table 1 μ'_m and mu_d is
    0.8·mu_s (the seed leaves μ_d to experiment; 0.8 is a typical static-to-kinetic ratio
    for skin). With `saturate=True` the static limit follows the piecewise law of eq 26
    (linear above P*) and the dynamic one is scaled by mu_d/mu_s.
    """

    __slots__ = (
        "k_tau", "mu_s", "mu_d", "gamma", "saturate", "_model", "_ratio",
        "in_contact", "alpha_0", "alpha_p", "alpha_g", "torque", "limit", "slipping", "slip_events",
    )

    def __init__(
        self,
        model: FingertipModel,
        k_tau: float,
        mu_s: float | None = None,
        mu_d: float | None = None,
        saturate: bool = False,
    ) -> None:
        self.k_tau = _check_finite("k_tau", k_tau, positive=True)
        self.mu_s = model.mu_prime if mu_s is None else _check_finite("mu_s", mu_s, non_negative=True)
        self.mu_d = 0.8 * self.mu_s if mu_d is None else _check_finite("mu_d", mu_d, non_negative=True)
        if self.mu_d > self.mu_s:
            raise ValueError(f"mu_d ({self.mu_d}) must be <= mu_s ({self.mu_s})")
        self.gamma = model.gamma
        self.saturate = bool(saturate)
        self._model = model
        self._ratio = self.mu_d / self.mu_s if self.mu_s > 0.0 else 0.0
        self.slip_events = 0
        self.release()

    def touch(self, alpha_s: float) -> None:
        """Contact made: the proxy twist starts at the finger's current twist α_s (rad)."""
        if alpha_s != alpha_s or alpha_s in (math.inf, -math.inf):
            alpha_s = 0.0
        self.in_contact = True
        self.alpha_0 = alpha_s
        self.alpha_p = alpha_s
        self.alpha_g = alpha_s
        self.torque = 0.0
        self.limit = 0.0
        self.slipping = False

    def release(self) -> None:
        """Contact broken: torsion state cleared, no torque."""
        self.in_contact = False
        self.alpha_0 = 0.0
        self.alpha_p = 0.0
        self.alpha_g = 0.0
        self.torque = 0.0
        self.limit = 0.0
        self.slipping = False

    def step(self, alpha_s: float, P: float) -> float:
        """One servo tick (eqs 38–40): new α_p from device twist α_s (rad) and normal force P (N).

        Returns M = k_τ(α_p - α_g), the torque on the finger about n (N·m). A non-finite α_s
        holds the state and returns 0; a non-finite P counts as no normal force.
        """
        if not self.in_contact:
            return 0.0
        if alpha_s != alpha_s or alpha_s in (math.inf, -math.inf):
            self.torque = 0.0
            return 0.0
        P = abs(P)
        if not P <= P_MAX:
            P = P_MAX if P == P else 0.0
        if self.saturate:
            limit = self.mu_s / self._model.mu_prime * self._model.piecewise_torque(P) if self._model.mu_prime > 0.0 else 0.0
        else:
            limit = self.mu_s * P**self.gamma
        self.alpha_g = alpha_s
        k_tau = self.k_tau
        stretch = self.alpha_p - alpha_s
        # eq 39: the proxy sticks while the static limit exceeds the spring torque.
        if limit > abs(k_tau * stretch):
            self.slipping = False
        else:
            # eq 40 with its missing sign: stay mu_d|P|^γ/k_τ behind the goal, on the side
            # the proxy was on, so the slipping torque keeps the twist's direction.
            slack = limit * self._ratio / k_tau
            if stretch > 0.0:
                self.alpha_p = alpha_s + slack
            elif stretch < 0.0:
                self.alpha_p = alpha_s - slack
            else:
                self.alpha_p = alpha_s
            if not self.slipping and stretch != 0.0:
                self.slip_events += 1
            self.slipping = stretch != 0.0
        self.limit = limit
        self.torque = k_tau * (self.alpha_p - alpha_s)
        return self.torque

    def follow_object(self, omega_n: float, dt: float) -> None:
        """Eqs 41–42: α_p += (ω·n)Δt, the object's signed spin about n (rad/s) over Δt (s).

        The seed's |ω·n| would drag the proxy forwards whichever way the object turned; the
        signed value makes a stuck proxy turn with the object, in either direction.
        """
        if not self.in_contact:
            return
        alpha_p = self.alpha_p + omega_n * dt
        if alpha_p == alpha_p and alpha_p not in (math.inf, -math.inf):
            self.alpha_p = alpha_p
