"""Intrinsic contact sensing: from one 6-axis force/torque reading under an ellipsoidal soft
skin to the contact point, normal, normal and friction force, local torque and skin
deformation.

Source: Liu et al., *Finger contact sensing and the application in dexterous hand
manipulation*, §2–3: the skin law (eq 1), the deformed
ellipsoid (eq 2), the sensor mounting (eqs 3–4), the equilibrium (eqs 5–6), the normal /
tangential split (eqs 7–8), the system g(x) = 0 (eqs 9–10) and its Levenberg–Marquardt
solution (eqs 11–13, Algorithm 1). Everything here is SI (N, m, N·m); the paper's mm and
N·mm constants pass through `softproxy.units` once, in the block of seed constants below.

Model (eqs 1, 2, 6, 9). The wrench (F, M) that a single contact exerts on the fingertip,
taken about the ellipsoid centre in the ellipsoid frame, is a force F through the contact
point p plus a pure torque τ about the outward unit normal n̂(p):

    M = p × F + τ n̂,   p on S: x²/(a-Δd)² + y²/(b-Δd)² + z²/(c-Δd)² = 1,   ‖F_n‖ = E(Δd)

with ‖F_n‖ = -F·n̂ > 0 for a contact that pushes on the skin, E(Δd) = E1 Δd (default) or
E2 Δd² (eq 1), and S the ellipsoid whose semi-axes are reduced by Δd (eq 2). The paper's
k∇S(p) is τ n̂ (k = τ/‖∇S‖).

Formulation actually solved (equivalent to eq 10, better conditioned, pulling root excluded
by construction). Let F̂ = F/‖F‖, (u, v, F̂) a right-handed orthonormal basis, h = M·F/‖F‖²
the pitch of the wrench and q = F × M/‖F‖² the point of its central axis nearest the centre.
Parametrise the outward normal by the gnomonic chart centred on -F̂:

    m(α, β) = -F̂ + α u + β v,   n̂ = m/‖m‖.

Every m has m·F̂ = -1 < 0: the chart covers exactly the open hemisphere of pushing normals,
and the pulling root of eq 8 (where F·n̂ > 0) has no coordinates in it. The friction ratio is
‖F_t‖/‖F_n‖ = ‖(α, β)‖ and the normal force is ‖F_n‖ = ‖F‖/‖m‖, so Δd = E⁻¹(‖F‖/‖m‖) is an
explicit function of (α, β). On an ellipsoid the point with outward normal ∝ m is
p(m) = B m / √(mᵀBm), B = diag((a-Δd)², (b-Δd)², (c-Δd)²) (∇S ∝ B⁻¹p), so eq 2 and the
third row of eq 9 hold by construction. Splitting eq 6 along F and across it gives
τ = h‖F‖/(n̂·F̂) and, across F, the two equations

    g1 = u·p(m) - u·q + h β = 0,     g2 = v·p(m) - v·q - h α = 0     (residual in metres)

which with τ are exactly the three torque rows of eq 10. Two unknowns instead of five, and:
(g1, g2) = ∇ψ(α, β) + h R (α, β) - (u·q, v·q), where ψ(α, β) = √(mᵀBm) is the support
function of the ellipsoid (convex, ∇_m ψ = p) and R = [[0, 1], [-1, 0]] is skew. For a rigid
skin (Δd fixed) that map is strictly monotone, so its Jacobian (symmetric positive definite
plus h·skew, det ≥ det G + h² > 0) is never singular and there is at most one pushing root:
χ² (eq 11) has no stationary point other than the root, so LM cannot be trapped. For
M·F ≠ 0 the map is also proper, hence onto: every such wrench has exactly one pushing
explanation somewhere on the ellipsoid, possibly with an absurd friction ratio. With the skin
law the ellipsoid shrinks by Δd(α, β); that perturbation is small (Δd ≤ 0.6 mm at 10 N with
E1, against radii of curvature ≥ a²/b = 5.3 mm) and is carried exactly in the Jacobian.

A wrench is **explained** when a pushing contact reproduces it *and* lies in the skin's
envelope; otherwise the estimate says `explained=False`, gives the reason and the residual,
and carries no contact point (never a wrong one). Refused: ‖F‖ < `min_force` (no contact);
no pushing root (M·F = 0 and the force line misses the ellipsoid: the iterates head for the
chart's rim and the residual is the moment the last candidate cannot explain; with a small
M·F ≠ 0 the root exists but needs a friction ratio ≈ miss distance / pitch, refused as
below); friction ratio > `mu_max`; contact below `z_min` (off the skin — how a pulling force
shows: for τ = 0 its pushing twin is the far intersection of the force line, on the other
side of the fingertip); deformation beyond the skin thickness.

Readings chosen where the seed is ambiguous:
- eq 3's R_oc is misprinted: it is the rotation about z by θ, third column (0, 0, 1). In eq 4
  and Algorithm 1, d is the ellipsoid centre in the sensor frame, so p_c = d + R_oc p_o
  (Algorithm 1's locations A and B follow from it). d = [-sin 60°, cos 60°, 0] is read in mm
  like the semi-axes it is added to in Algorithm 1; θ = -120°.
- Sign: eq 5 (F - f = m ẍ) makes the reading the wrench the contact exerts on the fingertip;
  a push has F·n̂ < 0 with n̂ outward. Quasi-static (eq 6): inertia is ignored.
- eq 7's three rows are ∂S/∂x, ∂S/∂y, ∂S/∂z; Algorithm 1 line 11's F - F_r is F - F_n.
- eq 8's norm admits the pulling root; the chart above excludes it (see DESIGN "003").
- Levenberg–Marquardt (eqs 12–13) on (α, β): step h = -(JᵀJ + λ diag JᵀJ)⁻¹ Jᵀg as eq 12.
  Eq 13's test ε1 hᵀ(λh - Jᵀg) is (twice) Madsen's predicted decrease for an *identity*-damped
  step (JᵀJ + λI); for eq 12's diagonal scaling the consistent predicted decrease of χ² = ½gᵀg is
  L(0) - L(h) = ½ hᵀ(λ diag(JᵀJ) h - Jᵀg), and a step is accepted when the actual decrease
  exceeds ε1 = 1e-2 (as printed) times it; λ is then divided by 10, else multiplied by 10
  (as printed). Initial λ0 = 1e-3 (Marquardt's; the Jacobian is never singular here, so a
  nearly Gauss–Newton start is safe). Start: α = β = 0, i.e. n̂ = -F̂, the frictionless
  contact — for μ ≤ 1 the root lies within ‖(α, β)‖ ≤ 1 of it (Algorithm 1's two fixed
  starting points A/B are not needed). `ContactSensor(warm_start=True)` starts from the last
  explained normal instead, and retries from n̂ = -F̂ if that run is refused (from a far
  start LM can wander towards grazing before it comes back, and be cut off by the rule below).
  Stop: ‖g‖ ≤ `tol` (1e-12 m, i.e. ~1e-10 of the fingertip), or a step shorter than
  1e-15(1+‖y‖), or `max_iter` (60) trial steps per start (accepted or not: the `iterations`
  reported), or an accepted iterate with friction ratio ‖(α, β)‖ > 10 `mu_max`
  (the contact it heads for would be refused anyway; this is how a force line that misses
  the ellipsoid ends, in a few steps). Trial steps that leave the chart (‖(α, β)‖ > 1e4,
  within 0.1 mrad of grazing) are rejected like any failed step. Δd is frozen at 0.9 × the
  smallest semi-axis while an iterate would need more (such a contact is refused as too deep).
- Sensor noise (benchmarks/sensing.py, tests): the Nano17's resolution is read as uniform
  quantisation, each channel rounded to 1/160 N or 1/32 N·mm (error uniform in ±½ LSB);
  Gaussian noise of σ = 1 LSB per channel is reported alongside as the harsher reading.
- The reported local torque is τ = (M - p × F)·n̂ about the outward unit normal (signed);
  `residual` is ‖M - p × F - τ n̂‖ in N·m at the returned point.
- Skin envelope defaults: `z_min` = -0.55 mm (the upper half z ≥ 0 of the brief, widened by
  the paper's largest location error, Fig 9c, so that noise at the equator is not refused);
  `mu_max` = 2 (the paper's estimates broke down at friction coefficient ≈ 2.2, §4.3);
  deformation ≤ the 2 mm skin thickness (§2.1); `min_force` = 1/160 N, one count of the
  seed's Nano17 (§2.1).
- E2 (quadratic law) is offered; the paper saw LM diverge with it, here Δd is explicit in
  (α, β) and it converges like E1. `law="rigid"` (Δd = 0) is Bicchi's rigid fingertip.

`solve_algorithm1` is the paper's own five-unknown system (eq 10) with Algorithm 1's starting
points, solved in the paper's units, kept as a reference for the benchmark: it takes ~50×
longer in Python and returns the pulling root for about a third of random upper-half contacts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from softproxy import units
from softproxy.input_error import check_count, check_finite

# ---------------------------------------------------------------------------
# Seed 003 constants, in the paper's units, converted to SI once.
# ---------------------------------------------------------------------------
SEMI_A = units.mm(9.5)
"""Semi-axis a along the ellipsoid's x (§2.1, §3.1), m."""
SEMI_B = units.mm(17.0)
"""Semi-axis b along y, the finger's long axis (§2.1), m."""
SEMI_C = units.mm(10.5)
"""Semi-axis c along z (§2.1), m."""
SKIN_THICKNESS = units.mm(2.0)
"""Thickness of the polyurethane skin (§2.1), m."""
E1 = 16.5 / units.MM
"""Linear skin law ‖F_n‖ = E1 Δd (eq 1): 16.5 N/mm, in N/m."""
E2 = units.per_mm_power(43.38, 2.0)
"""Quadratic skin law ‖F_n‖ = E2 Δd² (eq 1): 43.38 N/mm², in N/m²."""
FORCE_LSB = 1.0 / 160.0
"""Nano17 force resolution (§2.1), N."""
TORQUE_LSB = units.nmm(1.0 / 32.0)
"""Nano17 torque resolution (§2.1): 1/32 N·mm, in N·m."""
SENSOR_THETA = math.radians(-120.0)
"""Angle θ of the sensor's x axis from the ellipsoid's x axis (eq 3, §2.1), rad."""
SENSOR_ALPHA = math.radians(60.0)
"""α of §2.1 / Algorithm 1, rad."""
SENSOR_CENTRE = (units.mm(-math.sin(SENSOR_ALPHA)), units.mm(math.cos(SENSOR_ALPHA)), 0.0)
"""d = OC of eqs 3–4: the ellipsoid centre in the sensor frame, [-sin α, cos α, 0] mm, in m."""

TABLE_1 = {
    # condition: (ranges, (mean, max) errors of f_n N, f_t N, q N·m)
    "condition-1": {
        "fn_N": (0.0, 8.5), "ft_N": (0.0, 4.0), "q_Nm": (0.0, units.nmm(1.2)),
        "error_fn_N": (0.217, 0.332), "error_ft_N": (0.182, 0.393),
        "error_q_Nm": (units.nmm(0.563), units.nmm(0.855)),
    },
    "condition-2": {
        "fn_N": (0.0, 6.0), "ft_N": (0.0, 0.4), "q_Nm": (units.nmm(-10.0), units.nmm(10.0)),
        "error_fn_N": (0.137, 0.182), "error_ft_N": (0.097, 0.237),
        "error_q_Nm": (units.nmm(0.583), units.nmm(0.783)),
    },
    "condition-3": {
        "fn_N": (0.0, 10.0), "ft_N": (0.0, 3.0), "q_Nm": (units.nmm(-10.0), 0.0),
        "error_fn_N": (0.347, 0.396), "error_ft_N": (0.353, 0.612),
        "error_q_Nm": (units.nmm(1.014), units.nmm(2.012)),
    },
}
"""Seed 003 Table 1: the hardware's mean (max) estimation errors, SI."""
LOCATION_RMSE = units.mm(0.33)
"""Hardware contact location RMSE (§4.1, Fig 9), m; largest error < 0.55 mm."""

_LAWS = ("E1", "E2", "rigid")
_CHART_LIMIT = 1e4  # ‖(α, β)‖ beyond which the normal is within 1e-4 rad of grazing


def _check_vector(name: str, value, n: int = 3) -> tuple:
    """Return `value` as a tuple of `n` finite floats or raise ValueError naming the parameter."""
    try:
        items = tuple(value)
    except TypeError:
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {value!r}") from None
    if len(items) != n:
        raise ValueError(f"{name} must have {n} components, got {len(items)}")
    out = []
    for i, x in enumerate(items):
        try:
            x = float(x)
        except (TypeError, ValueError):
            raise ValueError(f"{name}[{i}] must be a number, got {x!r}") from None
        if not math.isfinite(x):
            raise ValueError(f"{name}[{i}] must be finite, got {x!r}")
        out.append(x)
    return tuple(out)


# ---------------------------------------------------------------------------
# Fingertip geometry and skin law, sensor mounting
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Fingertip:
    """An ellipsoidal soft fingertip (seed 003 §2, eqs 1–2), SI units.

    `law` is "E1" (‖F_n‖ = E1 Δd, the paper's choice), "E2" (‖F_n‖ = E2 Δd²) or "rigid"
    (Δd = 0). The envelope of explainable contacts: `z_min` (skin covers z ≥ z_min in the
    ellipsoid frame; None = everywhere), `mu_max` (largest friction ratio ‖F_t‖/‖F_n‖),
    `skin_thickness` (largest Δd), `min_force` (smaller ‖F‖ is no contact).
    """

    a: float = SEMI_A
    b: float = SEMI_B
    c: float = SEMI_C
    law: str = "E1"
    E1: float = E1
    E2: float = E2
    skin_thickness: float = SKIN_THICKNESS
    z_min: float | None = -units.mm(0.55)
    mu_max: float = 2.0
    min_force: float = FORCE_LSB

    def __post_init__(self) -> None:
        for name in ("a", "b", "c", "E1", "E2", "skin_thickness", "mu_max"):
            check_finite(name, getattr(self, name), positive=True)
        check_finite("min_force", self.min_force, non_negative=True)
        if self.z_min is not None:
            check_finite("z_min", self.z_min)
        if self.law not in _LAWS:
            raise ValueError(f"law must be one of {', '.join(_LAWS)}, got {self.law!r}")
        if self.skin_thickness >= min(self.a, self.b, self.c):
            raise ValueError(f"skin_thickness must be < the smallest semi-axis, got {self.skin_thickness!r}")

    def deformation(self, normal_force: float) -> float:
        """Δd for a normal force magnitude (eq 1 inverted), m."""
        fn = check_finite("normal_force", normal_force, non_negative=True)
        if self.law == "E1":
            return fn / self.E1
        if self.law == "E2":
            return math.sqrt(fn / self.E2)
        return 0.0

    def point_with_normal(self, normal, deformation: float = 0.0) -> tuple:
        """The point of the deformed ellipsoid S (eq 2) whose outward normal is `normal`, m.

        On an ellipsoid ∇S ∝ B⁻¹p, so p = B n / √(nᵀBn) with B = diag((a-Δd)², …).
        """
        nx, ny, nz = _check_vector("normal", normal)
        dd = check_finite("deformation", deformation, non_negative=True)
        A = self.a - dd, self.b - dd, self.c - dd
        if min(A) <= 0.0:
            raise ValueError(f"deformation must be < the smallest semi-axis, got {deformation!r}")
        bx, by, bz = A[0] * A[0] * nx, A[1] * A[1] * ny, A[2] * A[2] * nz
        s2 = nx * bx + ny * by + nz * bz
        if not s2 > 0.0:
            raise ValueError(f"normal must be non-zero, got {normal!r}")
        s = math.sqrt(s2)
        return (bx / s, by / s, bz / s)


@dataclass(frozen=True)
class SensorMount:
    """Pose of the force/torque sensor frame (eqs 3–4, §2.1): p_c = d + R_oc p_o.

    R_oc is the rotation by `theta` about z (eq 3 with its third column read (0, 0, 1));
    `centre` is d, the ellipsoid centre in the sensor frame (m).
    """

    theta: float = SENSOR_THETA
    centre: tuple = SENSOR_CENTRE

    def __post_init__(self) -> None:
        check_finite("theta", self.theta)
        object.__setattr__(self, "centre", _check_vector("centre", self.centre))

    def vector_to_ellipsoid(self, v) -> tuple:
        """R_ocᵀ v: a free vector from sensor to ellipsoid axes."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2])

    def vector_to_sensor(self, v) -> tuple:
        """R_oc v: a free vector from ellipsoid to sensor axes."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return (c * v[0] - s * v[1], s * v[0] + c * v[1], v[2])

    def point_to_ellipsoid(self, p) -> tuple:
        """Eq 4: p_o = R_ocᵀ (p_c - d)."""
        d = self.centre
        return self.vector_to_ellipsoid((p[0] - d[0], p[1] - d[1], p[2] - d[2]))

    def point_to_sensor(self, p) -> tuple:
        """Eq 3: p_c = d + R_oc p_o."""
        d = self.centre
        r = self.vector_to_sensor(p)
        return (r[0] + d[0], r[1] + d[1], r[2] + d[2])

    def wrench_to_ellipsoid(self, F, M) -> tuple:
        """A wrench (F, M about the sensor origin, sensor axes) -> (F, M about the ellipsoid
        centre, ellipsoid axes): M_o = R_ocᵀ (M_c - d × F_c)."""
        d = self.centre
        Mx = M[0] - (d[1] * F[2] - d[2] * F[1])
        My = M[1] - (d[2] * F[0] - d[0] * F[2])
        Mz = M[2] - (d[0] * F[1] - d[1] * F[0])
        return self.vector_to_ellipsoid(F), self.vector_to_ellipsoid((Mx, My, Mz))

    def wrench_to_sensor(self, F, M) -> tuple:
        """Inverse of `wrench_to_ellipsoid`."""
        Fc = self.vector_to_sensor(F)
        Mc = self.vector_to_sensor(M)
        d = self.centre
        return Fc, (Mc[0] + (d[1] * Fc[2] - d[2] * Fc[1]), Mc[1] + (d[2] * Fc[0] - d[0] * Fc[2]),
                    Mc[2] + (d[0] * Fc[1] - d[1] * Fc[0]))


# ---------------------------------------------------------------------------
# The estimate
# ---------------------------------------------------------------------------
class UnexplainedWrench(ValueError):
    """Raised by `ContactEstimate.require()` when no pushing contact on the skin explains a wrench."""

    def __init__(self, estimate: "ContactEstimate"):
        super().__init__(f"wrench not explained by a pushing contact: {estimate.reason} "
                         f"(residual {estimate.residual:.3g} N·m)")
        self.estimate = estimate


class ContactEstimate:
    """One contact-sensing result (Algorithm 1's output), SI units, in the frame of the input.

    When `explained` is False the geometric fields are None, `reason` says why, and
    `residual` is the moment (N·m) the best pushing candidate leaves unexplained (0 when a
    pushing contact exists but lies outside the skin's envelope).
    """

    __slots__ = ("explained", "reason", "point", "normal", "normal_force", "friction", "local_torque",
                 "deformation", "friction_ratio", "iterations", "residual", "frame")

    def __init__(self, explained, reason, point, normal, normal_force, friction, local_torque, deformation,
                 friction_ratio, iterations, residual, frame="ellipsoid"):
        self.explained = explained
        self.reason = reason
        self.point = point
        self.normal = normal
        self.normal_force = normal_force
        self.friction = friction
        self.local_torque = local_torque
        self.deformation = deformation
        self.friction_ratio = friction_ratio
        self.iterations = iterations
        self.residual = residual
        self.frame = frame

    def require(self) -> "ContactEstimate":
        """Return self, or raise UnexplainedWrench if the wrench was not explained."""
        if not self.explained:
            raise UnexplainedWrench(self)
        return self

    def to_dict(self) -> dict:
        """JSON-ready dict (the keys of `sense_main`)."""
        return {
            "explained": self.explained,
            "reason": self.reason,
            "frame": self.frame,
            "contact_point_m": None if self.point is None else list(self.point),
            "normal": None if self.normal is None else list(self.normal),
            "normal_force_N": self.normal_force,
            "friction_force_N": None if self.friction is None else list(self.friction),
            "local_torque_Nm": self.local_torque,
            "deformation_m": self.deformation,
            "friction_ratio": self.friction_ratio,
            "iterations": self.iterations,
            "residual": self.residual,
        }

    def __repr__(self) -> str:
        if not self.explained:
            return f"ContactEstimate(explained=False, reason={self.reason!r}, residual={self.residual:.3g})"
        return (f"ContactEstimate(point={self.point}, normal={self.normal}, normal_force={self.normal_force:.6g}, "
                f"local_torque={self.local_torque:.6g}, deformation={self.deformation:.6g}, "
                f"iterations={self.iterations})")


def _refused(reason: str, iterations: int, residual: float, frame: str) -> ContactEstimate:
    return ContactEstimate(False, reason, None, None, None, None, None, None, None, iterations, residual, frame)


# ---------------------------------------------------------------------------
# The solver
# ---------------------------------------------------------------------------
class ContactSensor:
    """Contact sensing for one fingertip (seed 003, eqs 1–13, Algorithm 1).

    `sense(F, M)` takes the wrench the contact exerts on the fingertip (N, N·m); with
    `sensor_frame=True` it is read in the sensor frame of `mount` (about the sensor origin)
    and the estimate is returned in the sensor frame too, otherwise both are in the
    ellipsoid frame (origin at the centre, axes along a, b, c).
    """

    __slots__ = ("tip", "mount", "tol", "max_iter", "lambda0", "eps1", "warm_start", "_last_normal", "_k")

    def __init__(self, tip: Fingertip | None = None, mount: SensorMount | None = None, *, tol: float = 1e-12,
                 max_iter: int = 60, lambda0: float = 1e-3, eps1: float = 1e-2, warm_start: bool = False):
        self.tip = Fingertip() if tip is None else tip
        if not isinstance(self.tip, Fingertip):
            raise ValueError(f"tip must be a Fingertip, got {tip!r}")
        self.mount = SensorMount() if mount is None else mount
        if not isinstance(self.mount, SensorMount):
            raise ValueError(f"mount must be a SensorMount, got {mount!r}")
        self.tol = check_finite("tol", tol, positive=True)
        self.lambda0 = check_finite("lambda0", lambda0, non_negative=True)
        self.eps1 = check_finite("eps1", eps1, non_negative=True)
        self.max_iter = check_count("max_iter", max_iter)
        self.warm_start = bool(warm_start)
        self._last_normal = None
        t = self.tip
        # law code: 1 linear, 2 quadratic, 0 rigid; inverse stiffness for Δd
        law = {"E1": 1, "E2": 2, "rigid": 0}[t.law]
        inv = 1.0 / t.E1 if law == 1 else (1.0 / t.E2 if law == 2 else 0.0)
        self._k = (t.a, t.b, t.c, law, inv, min(t.a, t.b, t.c), t.skin_thickness,
                   -math.inf if t.z_min is None else t.z_min, t.mu_max, t.min_force)

    def reset(self) -> None:
        """Forget the warm-start normal."""
        self._last_normal = None

    def sense_wrench(self, wrench, sensor_frame: bool = False) -> ContactEstimate:
        """`sense` for a 6-sequence (FX, FY, FZ, MX, MY, MZ)."""
        w = _check_vector("wrench", wrench, 6)
        return self.sense(w[:3], w[3:], sensor_frame=sensor_frame, checked=True)

    def sense(self, F, M, *, sensor_frame: bool = False, checked: bool = False) -> ContactEstimate:
        """Estimate the contact from the force F (N) and moment M (N·m) on the fingertip."""
        if not checked:
            F = _check_vector("F", F)
            M = _check_vector("M", M)
        if sensor_frame:
            F, M = self.mount.wrench_to_ellipsoid(F, M)
            est = self._solve(F[0], F[1], F[2], M[0], M[1], M[2], "sensor")
            if est.explained:
                mnt = self.mount
                est.point = mnt.point_to_sensor(est.point)
                est.normal = mnt.vector_to_sensor(est.normal)
                est.friction = mnt.vector_to_sensor(est.friction)
            return est
        return self._solve(F[0], F[1], F[2], M[0], M[1], M[2], "ellipsoid")

    def _solve(self, fx, fy, fz, mx, my, mz, frame) -> ContactEstimate:
        a, b, c, law, inv, amin, thick, z_min, mu_max, min_force = self._k
        sqrt = math.sqrt
        f2 = fx * fx + fy * fy + fz * fz
        f = sqrt(f2)
        if not f >= min_force or f == 0.0:
            return _refused("no contact force (|F| below min_force)", 0, sqrt(mx * mx + my * my + mz * mz), frame)
        ex, ey, ez = fx / f, fy / f, fz / f
        # u ⟂ F̂ from the axis least aligned with F̂; v = F̂ × u, so (u, v, F̂) is right-handed
        aex, aey, aez = abs(ex), abs(ey), abs(ez)
        if aex <= aey and aex <= aez:
            ux, uy, uz = 0.0, ez, -ey  # F̂ × x̂
        elif aey <= aez:
            ux, uy, uz = -ez, 0.0, ex  # F̂ × ŷ
        else:
            ux, uy, uz = ey, -ex, 0.0  # F̂ × ẑ
        nu = sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / nu, uy / nu, uz / nu
        vx, vy, vz = ey * uz - ez * uy, ez * ux - ex * uz, ex * uy - ey * ux
        # central axis: pitch h and the point q = F × M / |F|²
        h = (fx * mx + fy * my + fz * mz) / f2
        qx, qy, qz = (fy * mz - fz * my) / f2, (fz * mx - fx * mz) / f2, (fx * my - fy * mx) / f2
        qu = qx * ux + qy * uy + qz * uz
        qv = qx * vx + qy * vy + qz * vz
        tol = self.tol
        tol2 = tol * tol

        def evaluate(al, be):
            """Residual (g1, g2) in m, its Jacobian, and the candidate contact."""
            m1, m2, m3 = -ex + al * ux + be * vx, -ey + al * uy + be * vy, -ez + al * uz + be * vz
            mm2 = 1.0 + al * al + be * be
            if law == 1:
                dd = f * inv / sqrt(mm2)
                ddk = -dd / mm2  # ∂Δd/∂α = ddk α
            elif law == 2:
                dd = sqrt(f * inv / sqrt(mm2))
                ddk = -0.5 * dd / mm2
            else:
                dd = ddk = 0.0
            if dd > dd_cap:  # far outside the envelope: freeze Δd (refused later as too deep)
                dd, ddk = dd_cap, 0.0
            A1, A2, A3 = a - dd, b - dd, c - dd
            B1, B2, B3 = A1 * A1, A2 * A2, A3 * A3
            b1, b2, b3 = B1 * m1, B2 * m2, B3 * m3
            s = sqrt(m1 * b1 + m2 * b2 + m3 * b3)
            p1, p2, p3 = b1 / s, b2 / s, b3 / s
            pu = p1 * ux + p2 * uy + p3 * uz
            pv = p1 * vx + p2 * vy + p3 * vz
            r1 = pu - qu + h * be
            r2 = pv - qv - h * al
            if r1 * r1 + r2 * r2 <= tol2:  # converged: the Jacobian is not needed
                return r1, r2, 0.0, 0.0, 0.0, 0.0, m1, m2, m3, mm2, p1, p2, p3, dd
            # ∂p/∂m = (B - p pᵀ)/s
            G11 = (B1 * ux * ux + B2 * uy * uy + B3 * uz * uz - pu * pu) / s
            G12 = (B1 * ux * vx + B2 * uy * vy + B3 * uz * vz - pu * pv) / s
            G22 = (B1 * vx * vx + B2 * vy * vy + B3 * vz * vz - pv * pv) / s
            J11, J12, J21, J22 = G11, G12 + h, G12 - h, G22
            if law:
                # ∂p/∂Δd = (dB m - p (mᵀ dB m)/(2s))/s with dB = -2 diag(a-Δd, …)
                d1, d2, d3 = -2.0 * A1 * m1, -2.0 * A2 * m2, -2.0 * A3 * m3
                w = (m1 * d1 + m2 * d2 + m3 * d3) / (2.0 * s)
                q1, q2, q3 = (d1 - p1 * w) / s, (d2 - p2 * w) / s, (d3 - p3 * w) / s
                du = (q1 * ux + q2 * uy + q3 * uz) * ddk
                dv = (q1 * vx + q2 * vy + q3 * vz) * ddk
                J11 += du * al
                J12 += du * be
                J21 += dv * al
                J22 += dv * be
            return r1, r2, J11, J12, J21, J22, m1, m2, m3, mm2, p1, p2, p3, dd

        dd_cap = 0.9 * amin
        y_abort = 10.0 * mu_max
        al = be = 0.0
        if self.warm_start and self._last_normal is not None:
            n1, n2, n3 = self._last_normal
            cosn = -(n1 * ex + n2 * ey + n3 * ez)
            if cosn > 0.2:
                al = (n1 * ux + n2 * uy + n3 * uz) / cosn
                be = (n1 * vx + n2 * vy + n3 * vz) / cosn
        # a warm start that fails (LM wandering off from a stale normal) is retried cold
        starts = ((al, be), (0.0, 0.0)) if (al or be) else ((0.0, 0.0),)
        eps1 = self.eps1
        max_iter = self.max_iter
        it = 0
        for al, be in starts:
            cur = evaluate(al, be)
            lam = self.lambda0
            reason = None
            k = 0
            while True:
                r1, r2, J11, J12, J21, J22 = cur[:6]
                rr = r1 * r1 + r2 * r2
                if rr <= tol2:
                    break
                if k >= max_iter:
                    reason = "did not converge within max_iter"
                    break
                it += 1
                k += 1
                # eq 12: (JᵀJ + λ diag JᵀJ) h = -Jᵀ g
                A11 = J11 * J11 + J21 * J21
                A12 = J11 * J12 + J21 * J22
                A22 = J12 * J12 + J22 * J22
                g1 = J11 * r1 + J21 * r2
                g2 = J12 * r1 + J22 * r2
                D11, D22 = A11 * (1.0 + lam), A22 * (1.0 + lam)
                det = D11 * D22 - A12 * A12
                if not det > 0.0:
                    lam = lam * 10.0 if lam > 0.0 else 1e-3
                    if lam > 1e16:
                        reason = "singular step"
                        break
                    continue
                h1 = (-g1 * D22 + g2 * A12) / det
                h2 = (-g2 * D11 + g1 * A12) / det
                na, nb = al + h1, be + h2
                if na * na + nb * nb > _CHART_LIMIT * _CHART_LIMIT:  # off the chart: reject the step
                    lam = lam * 10.0 if lam > 0.0 else 1e-6
                    continue
                new = evaluate(na, nb)
                # consistent predicted decrease of ½gᵀg for the diagonal-scaled step
                pred = 0.5 * (lam * (A11 * h1 * h1 + A22 * h2 * h2) - (h1 * g1 + h2 * g2))
                actual = 0.5 * (rr - new[0] * new[0] - new[1] * new[1])
                small = h1 * h1 + h2 * h2 <= 1e-30 * (1.0 + na * na + nb * nb)
                if actual > eps1 * pred:
                    al, be, cur = na, nb, new
                    lam = lam * 0.1 if lam > 1e-12 else 0.0
                    if na * na + nb * nb > y_abort * y_abort:
                        reason = (f"no pushing contact with friction ratio <= mu_max {mu_max:g}: the normal heads "
                                  "for grazing (the force line misses the skin)")
                        break
                else:
                    lam = lam * 10.0 if lam > 0.0 else 1e-6
                if small:
                    break
            if reason is None and cur[0] * cur[0] + cur[1] * cur[1] <= (1e3 * tol) ** 2:
                break
        r1, r2, _, _, _, _, m1, m2, m3, mm2, p1, p2, p3, dd = cur
        nm = sqrt(mm2)
        n1, n2, n3 = m1 / nm, m2 / nm, m3 / nm
        # moment about p, split along n̂ (local torque) and across (residual)
        t1 = mx - (p2 * fz - p3 * fy)
        t2 = my - (p3 * fx - p1 * fz)
        t3 = mz - (p1 * fy - p2 * fx)
        tau = t1 * n1 + t2 * n2 + t3 * n3
        e1, e2, e3 = t1 - tau * n1, t2 - tau * n2, t3 - tau * n3
        residual = sqrt(e1 * e1 + e2 * e2 + e3 * e3)
        if reason is None and r1 * r1 + r2 * r2 > (1e3 * tol) ** 2:
            reason = "did not converge"
        if reason is not None:
            return _refused(reason, it, residual, frame)
        mu = sqrt(al * al + be * be)
        if mu > mu_max:
            return _refused(f"friction ratio {mu:.3g} above mu_max {mu_max:g} (near-grazing contact)",
                            it, residual, frame)
        if p3 < z_min:
            return _refused(f"the only pushing contact, at z = {p3:.4g} m, lies below the skin (z_min {z_min:g} m): "
                            "e.g. a pulling force", it, residual, frame)
        if dd > thick:
            return _refused(f"deformation {dd:.3g} m beyond the skin thickness {thick:g} m", it, residual, frame)
        fn = f / nm
        if self.warm_start:
            self._last_normal = (n1, n2, n3)
        return ContactEstimate(True, "", (p1, p2, p3), (n1, n2, n3), fn, (fx + fn * n1, fy + fn * n2, fz + fn * n3),
                               tau, dd, mu, it, residual, frame)


_DEFAULT = None


def default_sensor() -> ContactSensor:
    """A shared ContactSensor for the paper's fingertip and mount (no warm start)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = ContactSensor()
    return _DEFAULT


def sense(F, M, *, sensor_frame: bool = False, tip: Fingertip | None = None) -> ContactEstimate:
    """One-shot contact sensing with the paper's fingertip (or `tip`); see ContactSensor.sense."""
    sensor = default_sensor() if tip is None else ContactSensor(tip)
    return sensor.sense(F, M, sensor_frame=sensor_frame)


def sense_main(wrench: list[float], sensor_frame: bool = False) -> dict:
    """For `softproxy sense --wrench FX FY FZ MX MY MZ [--sensor-frame]`: a JSON-ready dict.

    `wrench` is the force (N) and moment (N·m) the contact exerts on the fingertip, about the
    ellipsoid centre in the ellipsoid frame, or about the sensor origin in the sensor frame
    with `sensor_frame` (the estimate is then in the sensor frame too). Raises ValueError
    naming `wrench` if it is not six finite numbers.
    """
    return default_sensor().sense_wrench(wrench, sensor_frame=sensor_frame).to_dict()


# ---------------------------------------------------------------------------
# Synthetic wrenches (tests, benchmarks)
# ---------------------------------------------------------------------------
def wrench_from_contact(normal, normal_force: float, friction=(0.0, 0.0, 0.0), local_torque: float = 0.0,
                        tip: Fingertip | None = None) -> tuple:
    """The wrench (F, M) a pushing contact exerts on the fingertip, ellipsoid frame (eq 6).

    `normal` is the outward normal at the contact (normalised here), `normal_force` ‖F_n‖ > 0,
    `friction` a force tangent to the skin (its normal component is removed), `local_torque`
    τ about the outward normal. The contact point is on the ellipsoid shrunk by Δd = E⁻¹(‖F_n‖)
    (eq 2). Returns (F, M, point, deformation).
    """
    tip = Fingertip() if tip is None else tip
    nx, ny, nz = _check_vector("normal", normal)
    nn = math.sqrt(nx * nx + ny * ny + nz * nz)
    if not nn > 0.0:
        raise ValueError("normal must be non-zero")
    nx, ny, nz = nx / nn, ny / nn, nz / nn
    fn = check_finite("normal_force", normal_force, positive=True)
    tx, ty, tz = _check_vector("friction", friction)
    tn = tx * nx + ty * ny + tz * nz
    tx, ty, tz = tx - tn * nx, ty - tn * ny, tz - tn * nz
    tau = check_finite("local_torque", local_torque)
    dd = tip.deformation(fn)
    p = tip.point_with_normal((nx, ny, nz), dd)
    F = (-fn * nx + tx, -fn * ny + ty, -fn * nz + tz)
    M = (p[1] * F[2] - p[2] * F[1] + tau * nx, p[2] * F[0] - p[0] * F[2] + tau * ny,
         p[0] * F[1] - p[1] * F[0] + tau * nz)
    return F, M, p, dd


# ---------------------------------------------------------------------------
# Reference: the paper's own formulation (eq 10, Algorithm 1), for the benchmark
# ---------------------------------------------------------------------------
def solve_algorithm1(F, M, tip: Fingertip | None = None, *, tol: float = 1e-12, max_iter: int = 200,
                     lambda0: float = 1e-3, eps1: float = 1e-2) -> dict:
    """Seed 003 Algorithm 1 as printed: LM (eqs 11–13) on x = [p, k, Δd] of eq 10, ellipsoid frame.

    Starting point: location B (0, b, 0) if F_z > 0 or F_y > 0.5‖F‖, else location A (0, 0, c),
    with k = Δd = 0 (Algorithm 1 lines 1–7, mapped from the sensor frame). The last row uses
    eq 8's ‖F_n‖ = |Qᵀ F|/‖Q‖, so the pulling root also solves it. Returns a dict with the
    point, k, Δd, the unit normal, whether the root pushes (F·n̂ < 0), iterations and ‖g‖.
    Slow (numpy on 5×5) and not used by `ContactSensor`; kept to measure against.
    """
    import numpy as np

    tip = Fingertip() if tip is None else tip
    # solved in the paper's units (mm, N, N·mm), as the paper did; converted back at the end
    F = np.array(_check_vector("F", F))
    M = np.array([units.to_nmm(v) for v in _check_vector("M", M)])
    ax = np.array([units.to_mm(tip.a), units.to_mm(tip.b), units.to_mm(tip.c)])
    fnorm = float(np.linalg.norm(F))
    E = tip.E1 * units.MM if tip.law == "E1" else tip.E2 * units.MM**2
    quad = tip.law == "E2"
    Fx = np.array([[0.0, -F[2], F[1]], [F[2], 0.0, -F[0]], [-F[1], F[0], 0.0]])
    if F[2] > 0.0 or F[1] > 0.5 * fnorm:
        x = np.array([0.0, ax[1], 0.0, 0.0, 0.0])
    else:
        x = np.array([0.0, 0.0, ax[2], 0.0, 0.0])

    def g_and_J(x):
        p, k, dd = x[:3], x[3], x[4]
        A = ax - dd
        Q = 2.0 * p / A**2
        dQ_dd = 4.0 * p / A**3
        qf = float(Q @ F)
        qn = float(np.linalg.norm(Q))
        Efun = E * dd * dd if quad else E * dd
        g = np.empty(5)
        g[:3] = np.cross(p, F) + k * Q - M
        g[3] = float(np.sum(p * p / A**2)) - 1.0
        g[4] = abs(qf) / qn - Efun
        J = np.zeros((5, 5))
        J[:3, :3] = -Fx + np.diag(k * 2.0 / A**2)
        J[:3, 3] = Q
        J[:3, 4] = k * dQ_dd
        J[3, :3] = Q
        J[3, 4] = float(np.sum(2.0 * p * p / A**3))
        dphi_dQ = np.sign(qf) * F / qn - abs(qf) * Q / qn**3
        J[4, :3] = dphi_dQ * 2.0 / A**2
        J[4, 4] = float(dphi_dQ @ dQ_dd) - (2.0 * E * dd if quad else E)
        return g, J

    g, J = g_and_J(x)
    lam = lambda0
    it = 0
    tol_paper = tol / units.MM  # tolerance on ‖g‖ in the paper's mixed units (mm, N·mm, N)
    while it < max_iter and float(g @ g) > tol_paper * tol_paper:
        it += 1
        JtJ = J.T @ J
        Jtg = J.T @ g
        D = np.diag(np.diag(JtJ))
        try:
            h = -np.linalg.solve(JtJ + lam * D, Jtg)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        xn = x + h
        if np.any(ax - xn[4] <= 0.0):
            lam *= 10.0
            continue
        gn, Jn = g_and_J(xn)
        pred = 0.5 * float(h @ (lam * (D @ h) - Jtg))
        if 0.5 * (float(g @ g) - float(gn @ gn)) > eps1 * pred:
            x, g, J = xn, gn, Jn
            lam = max(lam * 0.1, 1e-15)
        else:
            lam *= 10.0
            if lam > 1e20:
                break
    p, k, dd = x[:3], float(x[3]), float(x[4])
    Q = 2.0 * p / (ax - dd) ** 2
    n = Q / np.linalg.norm(Q)
    tau = k * float(np.linalg.norm(Q))  # N·mm
    return {"point": tuple(units.mm(float(v)) for v in p), "local_torque": units.nmm(tau),
            "deformation": units.mm(dd), "normal": tuple(float(v) for v in n),
            "pushing": bool(float(F @ n) < 0.0), "iterations": it,
            "converged": bool(float(np.linalg.norm(g)) <= tol_paper), "residual": float(np.linalg.norm(g))}
