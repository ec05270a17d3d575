"""Fingertip laws against the paper *Simulating human fingers: a Soft Finger Proxy Model and Algorithm* (Barbagli et al.)."""

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st
from scipy import integrate, optimize

from softproxy import fingertip as ft
from softproxy import units


def test_table_1_exponents_and_coefficients():
    """Seed 002 Table 1 and eqs 30, 34, 35, 37: γ and μ'_m (N·mm/N^γ) of the four models."""
    expected = {"CH": (4 / 3, 8.1489), "MH": (1.1433, 8.8327), "VS": (1.1289, 8.8836), "LFM": (1.0949, 9.0028)}
    for name, (gamma, mu_nmm) in expected.items():
        m = ft.model(name)
        assert m.gamma == pytest.approx(gamma, rel=1e-12)
        assert units.to_nmm(m.mu_prime) == pytest.approx(mu_nmm, rel=1e-12)
        # SI: the limit at 1 N is μ'_m N·mm = μ'_m·1e-3 N·m.
        assert m.torque_limit(1.0) == pytest.approx(mu_nmm * 1e-3, rel=1e-12)
    assert not ft.model("point").has_torsion
    assert ft.model("point").torque_limit(5.0) == 0.0


@pytest.mark.parametrize("name", ["CH", "MH", "VS", "LFM"])
def test_piecewise_law_continuous_at_p_star(name):
    """Seed 002 eqs 26–27: value and first derivative of M(P) continuous at P* within 1e-9."""
    m = ft.model(name)
    p = m.p_star
    assert 0.0 < p < 2.0, "P* lies in the 0–2 N non-linear range of §6"
    # eq 27 holds at the derived P*
    assert m.mu_prime * m.gamma * p ** (m.gamma - 1) == pytest.approx(ft.R0, rel=1e-12)
    h = p * 1e-6
    below, at, above = m.piecewise_torque(p - h), m.piecewise_torque(p), m.piecewise_torque(p + h)
    assert m.mu_prime * p**m.gamma == pytest.approx(at, rel=1e-12)
    # left and right one-sided slopes, each against the analytic slope r0
    left = (at - below) / h
    right = (above - at) / h
    assert right == pytest.approx(ft.R0, rel=1e-9)
    # the left slope of a power law differs from r0 by O(h): bound it by the curvature
    curvature = m.mu_prime * m.gamma * (m.gamma - 1) * p ** (m.gamma - 2)
    assert abs(left - ft.R0) <= curvature * h
    # beyond P* the law is linear with slope r0 = μ_m (eq 26)
    assert m.piecewise_torque(10.0) - m.piecewise_torque(9.0) == pytest.approx(ft.R0, rel=1e-12)


def test_e3_slope_tends_to_r0():
    """Seed 002 eq 24 and §6: M = P·r_m(P) becomes linear with slope r0 = 8.7855 mm."""
    P = 20.0
    slope = (ft.e3_torque(P + 1e-3) - ft.e3_torque(P - 1e-3)) / 2e-3
    assert slope == pytest.approx(units.mm(8.7855), rel=1e-9)
    # and at small force it is well below r0·P (the contact has not yet spread)
    assert ft.e3_torque(0.2) < 0.5 * ft.R0 * 0.2


def test_e1_and_inverse():
    """Seed 002 eq 22: P = b/m (e^{mδ}-1), b = 0.19 N/mm, m = 2.1 /mm."""
    assert ft.e1_force(units.mm(1.0)) == pytest.approx(0.19 / 2.1 * (math.exp(2.1) - 1), rel=1e-12)
    for P in (0.01, 0.5, 2.0, 10.0):
        assert ft.e1_force(ft.e1_indentation(P)) == pytest.approx(P, rel=1e-12)


def test_e2_saturates():
    """Seed 002 eq 23: a/a_max = 1 - e^{-P/P'_0}, P'_0 = 0.1101 N; 1 - e^{-1} at P'_0."""
    assert ft.e2_radius_ratio(0.1101) == pytest.approx(1 - math.exp(-1), rel=1e-12)
    assert ft.e2_radius_ratio(2.0) > 0.9999


def test_ch_law_is_power_four_thirds():
    """Seed 002 eqs 12, 14 (corrected), 28–29: M = (3π/16)μ(3R/4E*)^{1/3} P^{4/3}."""
    mu, R, E = 1.0, 0.008, 1e5
    for P in (0.1, 1.0, 3.0):
        a = (3 * P * R / (4 * E)) ** (1 / 3)
        assert ft.ch_torque(P, mu, R, E) == pytest.approx(3 * math.pi / 16 * mu * a * P, rel=1e-12)
    ratio = ft.ch_torque(2.0, mu, R, E) / ft.ch_torque(1.0, mu, R, E)
    assert ratio == pytest.approx(2 ** (4 / 3), rel=1e-12)


def test_lfm_ratio_and_radius():
    """Seed 002 eqs 21 and 36: M/P = (2/3)μa; a/a_max = q1 P^q2 (q1 = 0.9809, q2 = 0.0949)."""
    assert ft.lfm_torque_ratio(0.01, 0.5) == pytest.approx(2 / 3 * 0.5 * 0.01)
    assert ft.lfm_radius_ratio(1.0) == pytest.approx(0.9809)
    # eq 36 is a fit of eq 23 over 0-2 N: within 0.25 of it over 0.1-2 N
    for P in np.linspace(0.1, 2.0, 20):
        assert abs(ft.lfm_radius_ratio(P) - ft.e2_radius_ratio(P)) < 0.25


def test_mh_power_law_fits_e1_and_eq33_matches_eq31():
    """Seed 002 eqs 31–33: P = p1 δ^p2 approximates E1 over 0–2 N; P(a) with a² = Rδ."""
    forces = np.linspace(0.01, 2.0, 200)
    errors = [ft.mh_force(ft.e1_indentation(P)) - P for P in forces]
    assert math.sqrt(np.mean(np.square(errors))) < 0.1  # an L2 fit, loose at small P
    R, delta = 0.008, units.mm(1.2)
    assert ft.mh_force_from_radius(math.sqrt(R * delta), R) == pytest.approx(ft.mh_force(delta), rel=1e-12)


def test_vs_torque_closed_form_equals_integral():
    """Seed 002 eqs 16–18: eq 18 (φ = arcsin(a/R)) equals ∫ μ k z(r) 2π r² dr; eq 17 equals ∫ k z 2π r dr."""
    R, mu = ft.VS_RADIUS, 0.7
    for delta in (units.mm(0.3), units.mm(1.0), units.mm(3.0), R):
        a = math.sqrt(R * R - (R - delta) ** 2)
        k = ft.VS_K1 * delta**ft.VS_N
        z = lambda r: math.sqrt(R * R - r * r) - R + delta
        M = integrate.quad(lambda r: mu * k * z(r) * 2 * math.pi * r * r, 0, a)[0]
        P = integrate.quad(lambda r: k * z(r) * 2 * math.pi * r, 0, a)[0]
        assert ft.vs_torque(delta, mu) == pytest.approx(M, rel=1e-9)
        assert ft.vs_force(delta) == pytest.approx(P, rel=1e-9)


def test_vs_radius_is_best_fit_to_e1():
    """Seed 002 §6.3: with k' = 0.0242, n = 1.5753 printed, R = 7 mm best fits eq 17 to E1 (eq 22) over 0–2 N."""
    forces = np.linspace(0.01, 2.0, 200)
    deltas = [ft.e1_indentation(P) for P in forces]

    def cost(R_mm):
        return sum((ft.vs_force(d, R=units.mm(R_mm)) - P) ** 2 for d, P in zip(deltas, forces))

    best = optimize.minimize_scalar(cost, bounds=(2.0, 20.0), method="bounded").x
    assert units.mm(best) == pytest.approx(ft.VS_RADIUS, abs=units.mm(0.1))


@pytest.mark.parametrize(
    "kwargs, word",
    [
        (dict(name="X", gamma=0.0, mu_prime=1.0), "gamma"),
        (dict(name="X", gamma=-1.0, mu_prime=1.0), "gamma"),
        (dict(name="X", gamma=float("nan"), mu_prime=1.0), "gamma"),
        (dict(name="X", gamma=1.2, mu_prime=-1.0), "mu_prime"),
        (dict(name="X", gamma=1.2, mu_prime=float("inf")), "mu_prime"),
        (dict(name="", gamma=1.2, mu_prime=1.0), "name"),
    ],
)
def test_bad_model_parameters_name_the_parameter(kwargs, word):
    with pytest.raises(ValueError, match=word):
        ft.FingertipModel(**kwargs)


def test_laws_reject_bad_input():
    with pytest.raises(ValueError, match="P"):
        ft.e3_torque(-1.0)
    with pytest.raises(ValueError, match="P"):
        ft.e2_radius_ratio(float("nan"))
    with pytest.raises(ValueError, match="mu"):
        ft.ch_torque(1.0, -0.1, 0.01, 1e5)
    with pytest.raises(ValueError, match="delta"):
        ft.vs_force(1.0)
    with pytest.raises(ValueError, match="unknown fingertip model 'XYZ'"):
        ft.model("XYZ")


@given(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(list(ft.MODELS)))
def test_torque_limits_never_nan(P, name):
    """The per-tick laws take any float: finite, non-negative, and 0 at P = 0 (also for γ < 1)."""
    m = ft.model(name)
    for value in (m.torque_limit(P), m.piecewise_torque(P)):
        assert math.isfinite(value) and value >= 0.0


def test_zero_force_gives_zero_torque_for_sublinear_law():
    m = ft.FingertipModel("soft", 0.5, 1e-3)
    assert m.torque_limit(0.0) == 0.0
    assert m.piecewise_torque(0.0) == 0.0
    assert m.torque_limit(-4.0) == pytest.approx(2e-3)
