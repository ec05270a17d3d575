"""The torsional DOF of the soft-finger proxy, seed 002_36b58acb2f958b03.txt §7, eqs 38–42."""

import math

import pytest
from hypothesis import given, settings, strategies as st

from softproxy.fingertip import model
from softproxy.torsion import TorsionalFriction

CH = model("CH")


def make(k_tau=1.0, **kw):
    t = TorsionalFriction(CH, k_tau, **kw)
    t.touch(0.3)
    return t


def test_contact_starts_at_current_twist_with_zero_torque():
    """§7: on contact α_p is set to the finger's current twist α_0, so M = 0."""
    t = make()
    assert t.alpha_p == 0.3 and t.alpha_0 == 0.3
    assert t.step(0.3, 2.0) == 0.0


def test_sticks_below_static_limit():
    """Eq 39: β = 0 while μ_s|P|^γ > |M|: α_p stays, M = k_τ(α_p - α_g) is the spring torque."""
    t = make(k_tau=1.0)
    P = 2.0
    limit = CH.mu_prime * P ** (4 / 3)
    twist = 0.9 * limit  # k_τ = 1 N·m/rad, so |M| = 0.9 limit
    M = t.step(0.3 + twist, P)
    assert not t.slipping
    assert t.alpha_p == 0.3
    assert M == pytest.approx(-twist)


@pytest.mark.parametrize("direction", [+1, -1])
def test_slips_above_limit_with_torque_clamped_to_dynamic(direction):
    """Eqs 39–40 (with the sign erratum fixed): above μ_s|P|^γ, |M| = μ_d|P|^γ, sign of the twist kept."""
    t = make(k_tau=1.0, mu_s=CH.mu_prime, mu_d=0.5 * CH.mu_prime)
    P = 2.0
    limit = CH.mu_prime * P ** (4 / 3)
    M = t.step(0.3 + direction * 1.5 * limit, P)
    assert t.slipping and t.slip_events == 1
    assert M == pytest.approx(-direction * 0.5 * limit, rel=1e-12)
    # the proxy moved toward the goal but stayed behind it, on the side it came from
    assert direction * (t.alpha_g - t.alpha_p) == pytest.approx(0.5 * limit, rel=1e-9)
    # twisting further keeps slipping at the same torque, one slip event
    M2 = t.step(0.3 + direction * 3.0 * limit, P)
    assert M2 == pytest.approx(M, rel=1e-12) and t.slip_events == 1


def test_limit_grows_as_power_gamma():
    """Eq 39: the slip threshold scales as |P|^γ (γ = 4/3 for CH), not linearly."""
    thresholds = []
    for P in (1.0, 8.0):
        lo, hi = 0.0, 1.0
        for _ in range(60):  # bisection on the twist that first slips
            mid = 0.5 * (lo + hi)
            t = make(k_tau=1.0)
            t.step(0.3 + mid, P)
            lo, hi = (mid, hi) if not t.slipping else (lo, mid)
        thresholds.append(hi)
    assert thresholds[1] / thresholds[0] == pytest.approx(8 ** (4 / 3), rel=1e-9)


@pytest.mark.parametrize("omega", [+2.0, -2.0])
def test_object_rotation_correction_keeps_sign(omega):
    """Eqs 41–42 with the signed α_c = (ω·n)Δt: the proxy turns with the object both ways."""
    t = make()
    t.follow_object(omega, 1e-3)
    assert t.alpha_p == pytest.approx(0.3 + omega * 1e-3)
    M = t.step(0.3, 3.0)  # finger held still: the object turned, the spring resists it
    assert math.copysign(1.0, M) == math.copysign(1.0, omega)


def test_release_clears_state():
    t = make()
    t.step(0.5, 2.0)
    t.release()
    assert not t.in_contact and t.alpha_p == 0.0 and t.torque == 0.0
    assert t.step(1.0, 2.0) == 0.0


@pytest.mark.parametrize(
    "P, mu, k_tau",
    [(0.0, None, 1.0), (1e-300, None, 1.0), (1e4, None, 1e6), (1e4, 0.0, 1e6), (3.0, 0.0, 1.0), (1e308, None, 1e6)],
)
def test_extremes_are_finite(P, mu, k_tau):
    """P → 0, P = 1e4 N, μ = 0, k_τ = 1e6: outputs finite; μ = 0 and P = 0 give M = 0."""
    t = TorsionalFriction(CH, k_tau, mu_s=mu, mu_d=mu)
    t.touch(0.0)
    for alpha in (0.0, 1e-3, -2.0, 50.0):
        M = t.step(alpha, P)
        assert math.isfinite(M) and math.isfinite(t.alpha_p)
        if mu == 0.0 or P == 0.0:
            assert M == 0.0


def test_saturating_law_above_p_star():
    """Eq 26: with saturate=True the static limit grows linearly (slope r0) above P*."""
    t = TorsionalFriction(CH, 1.0, saturate=True)
    t.touch(0.0)
    t.step(0.0, 10.0)
    assert t.limit == pytest.approx(CH.piecewise_torque(10.0))
    assert t.limit < CH.torque_limit(10.0)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        (dict(k_tau=0.0), "k_tau"),
        (dict(k_tau=float("nan")), "k_tau"),
        (dict(k_tau=1.0, mu_s=-1.0), "mu_s"),
        (dict(k_tau=1.0, mu_d=float("inf")), "mu_d"),
        (dict(k_tau=1.0, mu_s=0.1, mu_d=0.2), "mu_d"),
    ],
)
def test_bad_parameters_name_the_parameter(kwargs, word):
    with pytest.raises(ValueError, match=word):
        TorsionalFriction(CH, **kwargs)


finite_or_not = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=300)
@given(
    st.lists(st.tuples(finite_or_not, finite_or_not, finite_or_not), min_size=1, max_size=30),
    st.sampled_from(["CH", "MH", "VS", "LFM", "point"]),
    st.floats(min_value=1e-6, max_value=1e9),
    st.booleans(),
)
def test_never_nan(samples, name, k_tau, saturate):
    """Whatever the device twist, normal force and object spin, the torque is never NaN or Inf."""
    t = TorsionalFriction(model(name), k_tau, saturate=saturate)
    t.touch(samples[0][0])
    for alpha_s, P, omega in samples:
        M = t.step(alpha_s, P)
        assert math.isfinite(M)
        t.follow_object(omega, 1e-3)
        assert math.isfinite(t.alpha_p)
