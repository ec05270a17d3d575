"""The torsional DOF of the soft-finger proxy (`TorsionalFriction`, and inside `SoftFingerProxy`)
against `SeedLaw`, the paper *Simulating human fingers: a Soft Finger Proxy Model and Algorithm* §7 eqs 38–42 written out here with DESIGN's
errata, and the seed's Table 1 and eqs 26–27 for the limits."""

import math

import mujoco
import pytest
from hypothesis import given, settings, strategies as st

from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import P_MAX, model
from softproxy.geometry import shapes_of
from softproxy.torsion import TorsionalFriction

CH = model("CH")
TABLE_1 = {"CH": 8.1489e-3, "MH": 8.8327e-3, "VS": 8.8836e-3, "LFM": 9.0028e-3}
"""Seed 002 Table 1: μ'_m per model, N·mm/N^γ given as N·m/N^γ."""
R0 = 8.7855e-3
"""Seed 002 eqs 24–27: the slope r0 of the linear branch of the saturating law, m."""


def seed_limit(name: str, P: float, saturate: bool) -> float:
    """The static limit of seed 002 with μ = μ'_m: eq 39, μ'|P|^γ; saturating (eq 26), linear
    with slope r0 above P*, where slope continuity (eq 27) puts P* = (r0 / (γ μ'))^(1/(γ-1))."""
    mu, gamma = TABLE_1[name], model(name).gamma
    if not saturate:
        return mu * P ** gamma
    p_star = (R0 / (gamma * mu)) ** (1.0 / (gamma - 1.0))
    return mu * P ** gamma if P <= p_star else R0 * (P - p_star) + mu * p_star ** gamma


class SeedLaw:
    """002 soft-finger proxy, eq 39/40, written out independently of the engine.

    Contact made at twist α_0: α_p = α_0 (§7), so M starts at zero. Each tick, with the goal
    α_g = α_s, the device twist (DESIGN's reading of §7's α_g, measured from α_0 through α_p)
    and M = k_τ(α_p(K-1) - α_g(K)): eq 39, the proxy sticks (β = 0) while the static limit
    exceeds |M|; otherwise eq 40 with DESIGN's erratum sign(α_g - α_p(K-1)) on the μ_d term:
    α_p(K) = α_g(K) - sign(α_g - α_p(K-1))·μ_d|P|^γ/k_τ, so a slip leaves |M| = μ_d|P|^γ with
    the twist's sign. The torque on the finger is k_τ(α_p(K) - α_g(K)). Eqs 41-42 with the
    erratum: α_p += (ω·n)Δt, signed. `limit(P)` is the static limit, `ratio` μ_d/μ_s.
    """

    def __init__(self, k_tau: float, limit, ratio: float) -> None:
        self.k_tau, self.limit, self.ratio = k_tau, limit, ratio
        self.alpha_p = 0.0
        self.slipping = False
        self.slips = 0

    def touch(self, alpha_0: float) -> None:
        self.alpha_p = alpha_0
        self.slipping = False

    def margin(self, alpha_s: float, P: float) -> float:
        """How far this tick is from eq 39's tie (N·m): |static limit - |M||."""
        return abs(self.limit(P) - abs(self.k_tau * (self.alpha_p - alpha_s)))

    def step(self, alpha_s: float, P: float) -> float:
        M = self.k_tau * (self.alpha_p - alpha_s)
        if self.limit(P) > abs(M):  # eq 39: β = 0
            self.slipping = False
        else:  # eq 40, signed
            slipped = M != 0.0
            self.alpha_p = alpha_s + math.copysign(self.ratio * self.limit(P) / self.k_tau, M) if slipped else alpha_s
            self.slips += slipped and not self.slipping
            self.slipping = slipped
        return self.k_tau * (self.alpha_p - alpha_s)

    def follow(self, omega_n: float, dt: float) -> None:
        self.alpha_p += omega_n * dt


def make(k_tau=1.0, **kw):
    t = TorsionalFriction(CH, k_tau, **kw)
    t.touch(0.3)
    return t


def test_contact_starts_at_current_twist_with_zero_torque():
    """§7: on contact α_p is set to the finger's current twist α_0, so M = 0."""
    t = make()
    assert t.in_contact and t.alpha_p == 0.3 and t.alpha_0 == 0.3
    assert t.step(0.3, 2.0) == 0.0 and not t.slipping


def test_the_default_coefficients_are_table_1():
    """By default μ_s is the model's μ'_m (Table 1) and μ_d 0.8 μ_s; γ is the model's."""
    for name, mu in TABLE_1.items():
        t = TorsionalFriction(model(name), 1.0)
        assert t.mu_s == pytest.approx(mu, rel=1e-12) and t.mu_d == pytest.approx(0.8 * mu, rel=1e-12)
        assert t.gamma == model(name).gamma


def test_sticks_below_static_limit():
    """002 soft-finger proxy, eq 39: β = 0 while μ_s|P|^γ > |M|: α_p stays and
    M = k_τ(α_p - α_g) is the spring torque."""
    t = make(k_tau=1.0)
    P = 2.0
    limit = seed_limit("CH", P, False)
    twist = 0.9 * limit  # k_τ = 1 N·m/rad, so |M| = 0.9 limit
    M = t.step(0.3 + twist, P)
    assert not t.slipping and t.slip_events == 0
    assert t.alpha_p == 0.3 and t.limit == pytest.approx(limit, rel=1e-12)
    assert M == pytest.approx(-twist, rel=1e-12) and t.torque == M


@pytest.mark.parametrize("direction", [+1, -1])
def test_slips_above_limit_with_torque_clamped_to_dynamic(direction):
    """002 soft-finger proxy, eq 39/40 with the sign erratum: above μ_s|P|^γ, |M| = μ_d|P|^γ,
    the twist's sign kept, whichever way the finger turns (eq 39 every tick: restick_time 0)."""
    t = make(k_tau=1.0, mu_s=TABLE_1["CH"], mu_d=0.5 * TABLE_1["CH"], restick_time=0.0)
    P = 2.0
    limit = seed_limit("CH", P, False)
    M = t.step(0.3 + direction * 1.5 * limit, P)
    assert t.slipping and t.slip_events == 1
    assert M == pytest.approx(-direction * 0.5 * limit, rel=1e-12)
    # the proxy moved toward the goal but stayed behind it, on the side it came from
    assert direction * (t.alpha_g - t.alpha_p) == pytest.approx(0.5 * limit, rel=1e-9)
    # twisting further keeps slipping at the same torque, one slip event
    M2 = t.step(0.3 + direction * 3.0 * limit, P)
    assert M2 == pytest.approx(M, rel=1e-12) and t.slip_events == 1
    # holding still after the slip: the spring torque is below the limit, it sticks again
    assert t.step(0.3 + direction * 3.0 * limit, P) == pytest.approx(M, rel=1e-12) and not t.slipping


def test_limit_grows_as_power_gamma():
    """002 soft-finger proxy, eq 39: the slip threshold scales as |P|^γ (γ = 4/3 for CH), not linearly."""
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
    assert thresholds[0] == pytest.approx(TABLE_1["CH"], rel=1e-9)  # μ' × 1 N^γ


@pytest.mark.parametrize("omega", [+2.0, -2.0])
def test_object_rotation_correction_keeps_sign(omega):
    """002 soft-finger proxy, eqs 41–42 with the signed α_c = (ω·n)Δt: the proxy turns with
    the object both ways."""
    t = make()
    t.follow_object(omega, 1e-3)
    assert t.alpha_p == pytest.approx(0.3 + omega * 1e-3)
    M = t.step(0.3, 3.0)  # finger held still: the object turned, the spring resists it
    assert math.copysign(1.0, M) == math.copysign(1.0, omega)


def test_release_clears_state():
    """Contact broken: no torque, and nothing followed or stepped until the next touch."""
    t = make()
    t.step(0.5, 2.0)
    t.release()
    assert not t.in_contact and t.alpha_p == 0.0 and t.torque == 0.0 and not t.slipping
    assert t.step(1.0, 2.0) == 0.0
    t.follow_object(5.0, 1e-3)
    assert t.alpha_p == 0.0


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


def test_garbage_normal_force_and_twist():
    """A non-finite P counts as no normal force (any twist slips to M = 0); a P beyond
    P_MAX as P_MAX; a non-finite twist holds α_p and renders no torque; a non-finite twist
    at contact starts from 0."""
    t = make()
    assert t.step(0.4, math.nan) == 0.0 and t.limit == 0.0 and t.alpha_p == 0.4
    t.step(0.4, math.inf)
    assert t.limit == pytest.approx(seed_limit("CH", P_MAX, False), rel=1e-12)
    before = t.alpha_p
    for bad in (math.nan, math.inf, -math.inf):
        assert t.step(bad, 2.0) == 0.0 and t.torque == 0.0 and t.alpha_p == before
    t.touch(math.nan)
    assert t.alpha_p == t.alpha_0 == 0.0
    t.follow_object(math.inf, 1e-3)
    assert t.alpha_p == 0.0


@pytest.mark.parametrize("name", sorted(TABLE_1))
def test_saturating_law_above_p_star(name):
    """Eq 26: with saturate=True the static limit is μ'|P|^γ up to P* and grows linearly
    (slope r0) above it, P* where the two meet with one slope (eq 27); scaled by μ_s/μ'."""
    t = TorsionalFriction(model(name), 1.0, mu_s=2.0 * TABLE_1[name], saturate=True)
    t.touch(0.0)
    gamma = model(name).gamma
    p_star = (R0 / (gamma * TABLE_1[name])) ** (1.0 / (gamma - 1.0))
    for P in (0.5, 0.9 * p_star, p_star, 1.1 * p_star, 3.0 * p_star, 1e3):
        t.step(0.0, P)
        assert t.limit == pytest.approx(2.0 * seed_limit(name, P, True), rel=1e-9), P
    t.step(0.0, 3.0 * p_star)
    above = t.limit
    t.step(0.0, 3.0 * p_star + 1.0)
    assert t.limit - above == pytest.approx(2.0 * R0, rel=1e-6)
    assert t.limit < 2.0 * seed_limit(name, 3.0 * p_star + 1.0, False)


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


@settings(max_examples=200, deadline=None)
@given(
    st.sampled_from(sorted(TABLE_1)),
    st.floats(0.01, 100.0),
    st.floats(0.0, 1.0),
    st.floats(0.0, 1.0),
    st.booleans(),
    st.lists(st.tuples(st.floats(-3.0, 3.0), st.floats(0.0, 50.0), st.floats(-30.0, 30.0)), min_size=1, max_size=40),
)
def test_the_engine_follows_the_seed_law(name, k_tau, scale, ratio, saturate, ticks):
    """002 soft-finger proxy, eq 39/40 (and 41-42): whatever the model, k_τ, μ_s, μ_d <= μ_s,
    the saturating limit or not, and the sequence of device twists, normal forces and object
    spins, every tick the engine's torque, α_p, limit, slipping and slip count are `SeedLaw`'s
    (where a tick falls on eq 39's tie, to rounding, either answer is the law's: the
    reference then takes the engine's). Eq 39 every tick: restick_time 0."""
    mu_s = scale * 2.0 * TABLE_1[name]
    t = TorsionalFriction(model(name), k_tau, mu_s=mu_s, mu_d=ratio * mu_s, saturate=saturate, restick_time=0.0)
    law = SeedLaw(k_tau, lambda P: mu_s / TABLE_1[name] * seed_limit(name, P, saturate), ratio)
    t.touch(ticks[0][0])
    law.touch(ticks[0][0])
    for alpha_s, P, omega in ticks:
        t.follow_object(omega, 1e-3)
        law.follow(omega, 1e-3)
        assert t.alpha_p == pytest.approx(law.alpha_p, rel=1e-12, abs=1e-15)
        tie = law.margin(alpha_s, P) <= 1e-12 * (1.0 + law.limit(P))
        M, expected = t.step(alpha_s, P), law.step(alpha_s, P)
        if tie:
            law.alpha_p, law.slipping, law.slips = t.alpha_p, t.slipping, t.slip_events
            continue
        assert M == pytest.approx(expected, rel=1e-9, abs=1e-15) and t.torque == M
        assert t.alpha_p == pytest.approx(law.alpha_p, rel=1e-12, abs=1e-15)
        assert t.limit == pytest.approx(law.limit(P), rel=1e-12)
        assert t.slipping == law.slipping and t.slip_events == law.slips
        assert t.alpha_g == alpha_s


finite_or_not = st.floats(allow_nan=True, allow_infinity=True)


@settings(max_examples=200, deadline=None)
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
        assert math.isfinite(M) and math.isfinite(t.torque) and math.isfinite(t.limit)
        t.follow_object(omega, 1e-3)
        assert math.isfinite(t.alpha_p)


def test_the_finger_renders_the_seed_law_about_the_contact_normal():
    """002 soft-finger proxy, eq 39/40 in the finger: pressing on a floor (n = +z) while the
    device twists back and forth past the limit, the finger's torque every tick is SeedLaw's
    spring torque for the finger's own normal force P, plus, on a tick it does not slip, the
    damping -b_τ·α̇_s of the device's twist rate relative to the floor (which does not turn;
    never of the proxy's own jump), bounded by the larger of the limit and the spring (and
    max_torque); the
    twist proxy starts at the twist contact was made with; tx, ty, tz is M·n; leaving the
    floor ends the torque and the contact. Eq 39 every tick: restick_time 0."""
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    params = FingerParams(radius=0.005, stiffness=1000.0, damping=0.0, torsion_stiffness=0.5,
                          torsion_damping=0.001, soft_start=0.0, max_torque=0.02, restick_time=0.0)
    f = SoftFingerProxy(params, shapes_of(m, d), CH, (0.0, 0.0, 0.02))
    f.place(0.0, 0.0, 0.02)
    dt = 1e-3
    law = SeedLaw(0.5, lambda P: seed_limit("CH", P, params.saturate), 0.8)  # the default limit: eq 26
    f.update(0.0, 0.0, 0.003, 0.1, dt)  # contact made at twist 0.1 with P = 2 N
    assert f.torsion.in_contact and f.torsion.alpha_0 == 0.1 and f.torque == 0.0
    law.touch(0.1)
    law.step(0.1, f.normal_force)
    last = 0.1
    slips = 0
    for k in range(1, 200):
        twist = 0.1 + 0.05 * math.sin(0.05 * k)
        P = 2.0 + 0.5 * math.sin(0.03 * k)  # the device pressing harder and softer
        assert f.update(0.0, 0.0, 0.005 - P / 1000.0, twist, dt)
        assert f.normal_force == pytest.approx(P, rel=1e-9)
        spring = law.step(twist, f.normal_force)
        damping = 0.0 if law.slipping else -params.torsion_damping / dt * (twist - last)
        bound = min(max(law.limit(f.normal_force), abs(spring)), params.max_torque)
        M = max(-bound, min(bound, spring + damping))
        last = twist
        assert f.torque == pytest.approx(M, rel=1e-9, abs=1e-15), k
        assert (f.tx, f.ty, f.tz) == (0.0, 0.0, f.torque)
        slips = law.slips
    assert slips >= 2 and f.torsion.slip_events == slips  # it slipped both ways
    f.update(0.0, 0.0, 0.02, 0.1, dt)
    assert not f.torsion.in_contact and f.torque == 0.0 and (f.tx, f.ty, f.tz) == (0.0, 0.0, 0.0)
