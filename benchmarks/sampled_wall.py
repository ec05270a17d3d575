"""The sampled virtual wall's analytic bounds: where a spring-damper wall rendered at period T on a
hand-held handle is stable, and where it is passive (docs/coupling.md, "The sampled wall").

The loop (as `softproxy.compiled.finger.update` renders a static wall, in contact): the handle's
position z_k is sampled at tick k, the wall's force

    F_k = −K z_k − (B/T)(z_k − z_{k−1})

(the spring to the surface at z = 0, the damper on the device's backward-difference velocity,
unfiltered) is held over [kT, (k+1)T], and the handle (mass m, damping b, held by a hand K_h,
b_h; `device_models`) moves under it exactly. With s_k = (z_k, v_k) and the exact ZOH step
s_{k+1} = Φ s_k + Γ_F F_k (+ the hand's constant target), the closed loop on x_k = (z_k, v_k, z_{k−1}) is

    x_{k+1} = M x_k,   M = [[Φ − Γ_F (K + B/T) e₁ᵀ,  Γ_F B/T], [e₁ᵀ, 0]],

and the wall is stable iff every eigenvalue of M lies inside the unit circle. `stability_boundary`
finds the largest K for which it does (for a given B); the small-period expansion of the same
loop gives Gil et al.'s closed form K < 2(b + b_h + B)/T, and Colgate & Schenkel's passivity
condition b > KT/2 + |B| gives K < 2(b − |B|)/T.
"""

from __future__ import annotations

import math

import numpy as np

from .device_models import handle_matrices

K_SCAN = np.logspace(0.0, 8.0, 161)
"""Stiffnesses (N/m) scanned for the first unstable one before bisecting: 1 N/m to 1e8 N/m, 12 % apart."""


def closed_loop(K: float, B: float, period: float, Phi: np.ndarray, Gam: np.ndarray) -> np.ndarray:
    """The 3×3 closed-loop matrix M of the sampled wall (K N/m, B N·s/m) on a handle whose exact
    ZOH step is Φ, Γ (`device_models.handle_matrices`; the force's column is used)."""
    g = Gam[:, 0]
    M = np.zeros((3, 3))
    M[:2, :2] = Phi
    M[:2, 0] -= g * (K + B / period)
    M[:2, 2] = g * (B / period)
    M[2, 0] = 1.0
    return M


def spectral_radius(K: float, B: float, period: float, mass: float, damping: float, hand_stiffness: float,
                    hand_damping: float) -> float:
    """The largest |eigenvalue| of the sampled wall's closed loop; < 1: the oscillation decays."""
    Phi, Gam = handle_matrices(mass, damping, hand_stiffness, hand_damping, period)
    return float(max(abs(np.linalg.eigvals(closed_loop(K, B, period, Phi, Gam)))))


def stability_boundary(B: float, period: float, mass: float, damping: float, hand_stiffness: float,
                       hand_damping: float, rtol: float = 1e-6) -> float:
    """The largest wall stiffness K (N/m) below which the sampled wall with damper B is stable
    on this handle (every K in (1 N/m, K) is); 0 when it is unstable already at 1 N/m (a
    damper too large for the period, B ≳ 2m/T), inf when stable up to 1e8 N/m."""
    Phi, Gam = handle_matrices(mass, damping, hand_stiffness, hand_damping, period)

    def radius(K):
        return max(abs(np.linalg.eigvals(closed_loop(K, B, period, Phi, Gam))))

    prev = None
    for K in K_SCAN:
        if radius(K) >= 1.0:
            if prev is None:
                return 0.0
            lo, hi = prev, K
            while hi / lo > 1.0 + rtol:
                mid = math.sqrt(lo * hi)
                lo, hi = (mid, hi) if radius(mid) < 1.0 else (lo, mid)
            return lo
        prev = K
    return math.inf


def colgate_boundary(B: float, damping: float, period: float) -> float:
    """Colgate & Schenkel's passivity bound solved for K: passive iff b > KT/2 + |B|, i.e.
    K < 2(b − |B|)/T (N/m; 0 where |B| ≥ b). b: the device's own damping."""
    return max(0.0, 2.0 * (damping - abs(B)) / period)


def small_period_boundary(B: float, damping: float, period: float) -> float:
    """The closed-form stability bound for T small against the handle's time scales (Gil,
    Avello, Rubio & Flórez 2004): the ZOH and the backward difference lag the spring by T/2,
    a negative damping KT/2, so the wall is stable while b + B > KT/2: K < 2(b + B)/T (N/m;
    b: all the physical damping on the handle, the hand's included)."""
    return max(0.0, 2.0 * (damping + B) / period)
