"""Fingertip contact models: how much torque a soft fingertip resists about the contact normal.

Source: Barbagli et al., *Simulating human fingers: a Soft Finger Proxy Model and
Algorithm*, §4–6 and Table 1. Every law here takes and
returns SI units (N, m, N·m); the paper's mm and N·mm constants are converted once, in
the block of seed constants below, through `softproxy.units`.

The engine's torsional friction limit is, by default, the saturating piecewise law of
eq 26 (`FingertipModel.piecewise_torque(P)`: μ'|P|^γ up to P*, then linear with slope r0);
a finger with `saturate=False` uses the pure power law μ'|P|^γ of eq 39
(`FingertipModel.torque_limit(P)`). Eq 26 is the default because it is the closer of the
two to the measured fingertip (E3) over 0.1–3 N (`softproxy bench peer`, docs/peer.md).
The other functions are the laws the paper derives those exponents from; they are
here so the models can be checked, plotted and calibrated, not because the tick needs
them.

Readings chosen where the extracted seed is ambiguous (README, "Decisions the seeds leave open"):
- eq 14 is read a = (3PR/4E*)^(1/3) (the printed 3π/16·P factor belongs to eq 28);
- eq 18's φ is arcsin(a/R);
- eq 26/27: μ_m is the linear slope r0 of eq 24 and Table 1's column is μ'_m; P* is
  derived from eq 27, P* = (r0 / (n μ'_m))^(1/(n-1));
- eq 36 fits the *normalised* contact radius a/a_max of eq 23 (q1 ≈ 1 at P ≈ 1 N, where
  eq 23 has saturated), so it is exposed as a ratio, not in mm as printed;
- the printed fitted constants (p1, p2, q1, q2, k', n) are used as printed, even where
  they cannot all be reproduced from the stated fit ranges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from softproxy import units
from softproxy.compiled.guard import P_MAX
from softproxy.input_error import check_finite

# ---------------------------------------------------------------------------
# Seed 002 constants, in the paper's units, converted to SI once.
# ---------------------------------------------------------------------------
R0 = units.mm(8.7855)
"""E3 saturation radius r0 (eq 24) = slope μ_m of the linear branch of eq 26 (m)."""
E3_TAU = 0.3907
"""E3 force constant τ (eq 24), N."""
E1_B = 0.19 / units.MM
"""E1 stiffness b (eq 22): 0.19 N/mm, in N/m."""
E1_M = 2.1 / units.MM
"""E1 exponent rate m (eq 22): 2.1 /mm, in 1/m."""
E2_P0 = 0.1101
"""E2 force constant P'_0 (eq 23), N."""
MH_P2 = 3.4897
"""MH power-law exponent p2 (eq 32)."""
MH_P1 = units.per_mm_power(0.5118, MH_P2)
"""MH power-law coefficient p1 (eq 32): 0.5118 N/mm^p2, in N/m^p2."""
LFM_Q1 = 0.9809
"""LFM coefficient q1 (eq 36) of the normalised radius a/a_max, 1/N^q2."""
LFM_Q2 = 0.0949
"""LFM exponent q2 (eq 36)."""
VS_N = 1.5753
"""VS spring-law exponent n (eq 17, §6.3)."""
VS_K1 = units.per_mm_power(0.0242, 3.0 + VS_N)
"""VS spring coefficient k' (§6.3): 0.0242 N/mm^(3+n), in N/m^(3+n)."""
VS_RADIUS = units.mm(7.0)
"""Fingertip radius R for the VS law. Not printed in the seed: 7.0 mm is the R for which
eq 17 with the printed k', n best fits E1 (eq 22) over 0–2 N (tests/test_fingertip.py
re-derives it)."""


# Table 1: exponent γ (eqs 30, 34, 35, 37) and μ'_m in N·mm/N^γ.
_TABLE_1 = {
    "CH": (4.0 / 3.0, 8.1489, "Classic Hertz (eqs 6-12, 28-30)"),
    "MH": (1.1433, 8.8327, "Modified Hertz (eqs 13-14, 31-34)"),
    "VS": (1.1289, 8.8836, "Viscous sphere (eqs 15-18, 35)"),
    "LFM": (1.0949, 9.0028, "Liquid-filled membrane (eqs 19-21, 36-37)"),
}


def _check_force(name: str, P: float) -> float:
    """Validate a normal-force magnitude for the model laws (not the tick): finite and >= 0."""
    return check_finite(name, P, non_negative=True)


@dataclass(frozen=True)
class FingertipModel:
    """A torsional friction law M_max = μ'|P|^γ (seed 002 eq 26/39), SI units.

    `mu_prime` is μ'_m in N·m/N^γ (Table 1's N·mm value × 1e-3). `r0` is the slope of the
    linear branch that eq 26 switches to above P*. A model with `mu_prime == 0` renders
    no torsion (the plain point contact).
    """

    name: str
    gamma: float
    mu_prime: float
    r0: float = R0
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        check_finite("gamma", self.gamma, positive=True)
        check_finite("mu_prime", self.mu_prime, non_negative=True)
        check_finite("r0", self.r0, positive=True)

    @property
    def has_torsion(self) -> bool:
        """False for the point contact: no fourth DOF, no torsion work in the tick."""
        return self.mu_prime > 0.0

    @property
    def p_star(self) -> float:
        """Transition force P* of eq 26, from slope continuity (eq 27), N.

        μ'_m γ P*^(γ-1) = r0  =>  P* = (r0 / (γ μ'_m))^(1/(γ-1)). Undefined (inf) for
        γ = 1 or no torsion: the power law is then used at every force.
        """
        if not self.has_torsion or self.gamma == 1.0:
            return math.inf
        return (self.r0 / (self.gamma * self.mu_prime)) ** (1.0 / (self.gamma - 1.0))

    def torque_limit(self, P: float) -> float:
        """Static torsional friction limit μ'|P|^γ (eq 39), N·m. Never raises, never NaN."""
        P = abs(P)
        if not P <= P_MAX:  # also catches NaN
            P = P_MAX if P == P else 0.0
        return self.mu_prime * P**self.gamma

    def piecewise_torque(self, P: float) -> float:
        """Saturating law of eq 26: μ'|P|^γ below P*, linear with slope r0 above, N·m.

        Continuous in value and slope at P* (eq 27). Never raises, never NaN.
        """
        P = abs(P)
        if not P <= P_MAX:
            P = P_MAX if P == P else 0.0
        p_star = self.p_star
        if P <= p_star:
            return self.mu_prime * P**self.gamma
        return self.r0 * (P - p_star) + self.mu_prime * p_star**self.gamma

    def as_dict(self) -> dict:
        """Constants and derived constants, SI plus the paper's N·mm for comparison."""
        p_star = self.p_star
        return {
            "name": self.name,
            "description": self.description,
            "gamma": self.gamma,
            "mu_prime_Nmm": units.to_nmm(self.mu_prime),
            "mu_prime_SI": self.mu_prime,
            "r0_mm": units.to_mm(self.r0),
            "p_star_N": p_star if math.isfinite(p_star) else None,
            "torque_limit_at_1N_Nmm": units.to_nmm(self.torque_limit(1.0)),  # the power law (eq 39)
            "torque_limit_at_3N_Nmm": units.to_nmm(self.torque_limit(3.0)),
            "saturating_limit_at_1N_Nmm": units.to_nmm(self.piecewise_torque(1.0)),  # eq 26
            "saturating_limit_at_3N_Nmm": units.to_nmm(self.piecewise_torque(3.0)),
        }


MODELS: dict[str, FingertipModel] = {
    name: FingertipModel(name, gamma, units.nmm(mu_nmm), description=text)
    for name, (gamma, mu_nmm, text) in _TABLE_1.items()
}
MODELS["point"] = FingertipModel("point", 1.0, 0.0, description="Point contact: no torsional friction")


def model(name: str) -> FingertipModel:
    """The fingertip model called `name` (CH, MH, VS, LFM or point)."""
    try:
        return MODELS[name]
    except KeyError:
        raise ValueError(f"unknown fingertip model {name!r}; expected one of {', '.join(MODELS)}") from None


# ---------------------------------------------------------------------------
# Measured laws E1–E3 (seed 002 §5)
# ---------------------------------------------------------------------------
def e1_force(delta: float, delta0: float = 0.0) -> float:
    """E1 (eq 22): normal force P = b/m (e^{m(δ-δ0)} - 1) for indentation δ (m), N."""
    delta = check_finite("delta", delta)
    return E1_B / E1_M * math.expm1(E1_M * (delta - delta0))


def e1_indentation(P: float) -> float:
    """Inverse of E1: indentation δ (m) at normal force P (N)."""
    P = _check_force("P", P)
    return math.log1p(P * E1_M / E1_B) / E1_M


def e2_radius_ratio(P: float) -> float:
    """E2 (eq 23): normalised contact radius a/a_max = 1 - e^{-P/P'_0}."""
    P = _check_force("P", P)
    return -math.expm1(-P / E2_P0)


def e3_radius(P: float) -> float:
    """E3 (eq 24): friction-equivalent radius r_m = r0 (1 - e^{-P/τ}), m."""
    P = _check_force("P", P)
    return R0 * -math.expm1(-P / E3_TAU)


def e3_torque(P: float) -> float:
    """E3: measured friction moment M = P r_m(P) (eqs 3, 24), N·m. Slope -> r0 at large P."""
    return P * e3_radius(P)


# ---------------------------------------------------------------------------
# The four model laws (seed 002 §4, §6)
# ---------------------------------------------------------------------------
def hertz_contact_radius(P: float, R: float, E_star: float) -> float:
    """Hertz contact radius a = (3PR / 4E*)^(1/3) (eq 14 as corrected), m."""
    P = _check_force("P", P)
    R = check_finite("R", R, positive=True)
    E_star = check_finite("E_star", E_star, positive=True)
    return (3.0 * P * R / (4.0 * E_star)) ** (1.0 / 3.0)


def ch_torque_ratio(a: float, mu: float) -> float:
    """CH and MH: M/P = (3π/16) μ a (eq 12), m."""
    return 3.0 * math.pi / 16.0 * check_finite("mu", mu, non_negative=True) * check_finite("a", a, non_negative=True)


def ch_torque(P: float, mu: float, R: float, E_star: float) -> float:
    """CH: M = (3π/16) μ (3R/4E*)^(1/3) P^(4/3) (eqs 28–29), N·m."""
    return P * ch_torque_ratio(hertz_contact_radius(P, R, E_star), mu)


def lfm_torque_ratio(a: float, mu: float) -> float:
    """LFM: M/P = (2/3) μ a (eq 21), m (uniform pressure over the contact disc)."""
    return 2.0 / 3.0 * check_finite("mu", mu, non_negative=True) * check_finite("a", a, non_negative=True)


def lfm_radius_ratio(P: float) -> float:
    """LFM (eq 36): power-law fit a/a_max = q1 P^q2 of the normalised E2 curve."""
    P = _check_force("P", P)
    return LFM_Q1 * P**LFM_Q2


def mh_force(delta: float) -> float:
    """MH (eq 31): P = p1 δ^p2 for indentation δ (m), N."""
    delta = check_finite("delta", delta, non_negative=True)
    return MH_P1 * delta**MH_P2


def mh_force_from_radius(a: float, R: float) -> float:
    """MH (eq 33): P = p1 / R^p2 · a^(2 p2), using a² = Rδ (eq 6), N."""
    a = check_finite("a", a, non_negative=True)
    R = check_finite("R", R, positive=True)
    return MH_P1 / R**MH_P2 * a ** (2.0 * MH_P2)


def vs_force(delta: float, R: float = VS_RADIUS, k1: float = VS_K1, n: float = VS_N) -> float:
    """VS (eq 17): P = (π/3) k δ² (3R - δ) with k = k' δ^n, N. Requires 0 <= δ <= R."""
    delta = check_finite("delta", delta, non_negative=True)
    R = check_finite("R", R, positive=True)
    if delta > R:
        raise ValueError(f"delta must be <= R ({R} m), got {delta}")
    return math.pi / 3.0 * k1 * delta**n * delta**2 * (3.0 * R - delta)


def vs_torque(delta: float, mu: float, R: float = VS_RADIUS, k1: float = VS_K1, n: float = VS_N) -> float:
    """VS (eq 18): friction moment of the spring-bed sphere at indentation δ, N·m.

    M = μπk[(R-δ) a (R²/4 - 2a²/3) - (a/2)(R² - a²)^{3/2} + (R⁴/4) φ], with a² = R² - (R-δ)²
    (eq 15), k = k' δ^n and φ = arcsin(a/R) (the seed leaves φ undefined; this reading
    makes eq 18 equal the integral of μ k z(r) 2π r² dr over the contact disc).
    """
    delta = check_finite("delta", delta, non_negative=True)
    mu = check_finite("mu", mu, non_negative=True)
    R = check_finite("R", R, positive=True)
    if delta > R:
        raise ValueError(f"delta must be <= R ({R} m), got {delta}")
    a = math.sqrt(max(R * R - (R - delta) ** 2, 0.0))
    phi = math.asin(min(a / R, 1.0))
    k = k1 * delta**n
    return mu * math.pi * k * (
        (R - delta) * a * (R * R / 4.0 - 2.0 * a * a / 3.0)
        - a / 2.0 * (R * R - a * a) ** 1.5
        + R**4 / 4.0 * phi
    )


# ---------------------------------------------------------------------------
# Fidelity to the measured fingertip (E3, seed 002 §5.3) and the constant the paper leaves free
# ---------------------------------------------------------------------------
MEASURED_GRIPS = (0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
"""Grips (N) at which a law is compared with the measured fingertip: seed 002's measured range
0.1–3 N, the same grips `softproxy bench peer` measures each engine's limit at."""


def errors_against_measured(values, grips=MEASURED_GRIPS) -> dict:
    """RMS and largest relative error |value / E3(P) - 1| of torques `values` (N·m) at `grips` (N),
    and the grip of the largest (N)."""
    rel = [v / e3_torque(P) - 1.0 for v, P in zip(values, grips, strict=True)]
    worst = max(range(len(rel)), key=lambda i: abs(rel[i]))
    return {"rms": math.sqrt(sum(r * r for r in rel) / len(rel)), "max": abs(rel[worst]), "max_at_N": grips[worst]}


def law(m: FingertipModel, saturate: bool = True):
    """The torsional limit a finger with model `m` gets: eq 26 (saturate, the engine's default)
    or the power law of eq 39; a function of the grip P (N) returning N·m."""
    return m.piecewise_torque if saturate else m.torque_limit


def fit_to_measured(m: FingertipModel, saturate: bool = True, grips=MEASURED_GRIPS) -> dict:
    """How well model `m`'s law follows the measured fingertip at `grips`: its RMS and largest
    relative error as printed (Table 1's μ'_m), and the same with μ'_m refitted.

    μ'_m is the one constant of eq 26 the paper leaves free: γ is the model's (eqs 30, 34,
    35, 37), the linear slope is E3's r0 (eq 24), and P* follows from eq 27 once μ'_m is
    chosen. The refit minimises the RMS relative error over `grips` (a log grid over
    0.1–100 N·mm, then a bounded scalar search around its best). A model without torsion
    has no fit (empty dict)."""
    if not m.has_torsion:
        return {}
    from scipy.optimize import minimize_scalar

    def rms(log_mu: float) -> float:
        trial = FingertipModel(m.name, m.gamma, units.nmm(math.exp(log_mu)), m.r0, m.description)
        return errors_against_measured([law(trial, saturate)(P) for P in grips], grips)["rms"]

    grid = [math.log(0.1) + k * (math.log(100.0) - math.log(0.1)) / 400 for k in range(401)]
    k = min(range(len(grid)), key=lambda i: rms(grid[i]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    best = minimize_scalar(rms, bounds=(lo, hi), method="bounded", options={"xatol": 1e-9}).x
    fitted = FingertipModel(m.name, m.gamma, units.nmm(math.exp(best)), m.r0, m.description)
    p_star = fitted.p_star
    return {
        **errors_against_measured([law(m, saturate)(P) for P in grips], grips),
        "refitted_mu_prime_Nmm": units.to_nmm(fitted.mu_prime),
        "refitted_p_star_N": p_star if math.isfinite(p_star) else None,
        "refitted": errors_against_measured([law(fitted, saturate)(P) for P in grips], grips),
        "refitted_model": fitted,
    }


def refitted(name: str, saturate: bool = True) -> FingertipModel:
    """Model `name` with μ'_m refitted to the measured fingertip (`fit_to_measured`): for an
    application that wants MH, VS or LFM as close to the measured fingertip as their exponent
    allows, `SoftFingerProxy(params, shapes, refitted("LFM"))`."""
    fit = fit_to_measured(model(name), saturate)
    if not fit:
        raise ValueError(f"fingertip model {name!r} has no torsion to fit")
    return fit["refitted_model"]
