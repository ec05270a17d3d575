"""Tactile output of a soft finger: the Inoue–Hirai virtual-spring pressure image.

Source: Inoue & Hirai, *Rotational Contact Model of Soft Fingertip for Tactile Sensing*
(eqs 1–19 rotational contact, eqs 20–30 rolling contact, §III
simulation) and *Contact Model of 1 D.O.F. Finger Having Rotational Joint with Soft Tip*
(the same authors' earlier paper: the pose
transform ⁰T_k and eqs 2–8). A hemispherical soft fingertip of radius r sits on a sensing
plane on a one-joint finger; the joint axis lies in the sensing plane at distance L from the
fingertip's axis. Rotating the finger presses the fingertip into a rigid flat object; every
point R of the sensing plane carries a virtual spring along the plane's normal, and the
pressure at R is E × (the spring's accumulated compression) / (its natural length). Every
function takes and returns SI units (m, rad, Pa = N/m², N); the paper's mm and degrees are
converted once, in the block of seed constants and in the report (through `softproxy.units`).

The extraction garbles every equation, so they were rebuilt from the geometry. The
derivation follows; each choice between readings is marked **Choice**.

Frame (**Choice**: the seeds do not fix +x relative to the joint)
    Σ_θ is the finger's sensing-plane frame at finger angle θ: origin at the centre of the
    hemisphere's base (the sensor centre), +z out of the plane toward the object, +x
    *distal* — pointing away from the joint, whose axis is the line {x = -L, z = 0}, parallel
    to y; y = z × x. 001's ⁰T_k puts the joint at x = +L: x here = -x there. This is the frame
    in which 000's rolling eqs 24–29 are printed (s_pl = r − (x + L) sin θ_k puts the joint at
    x = −L), and it is the one in which the model reproduces the paper's Fig. 8 (the centre
    of pressure moves to +x while the finger rotates and to −x while the object rolls by
    −15°); in 001's orientation both moves would have the opposite sign. Sensor cell (i, j),
    1-based, has its centre at x = (i − (n+1)/2)·pitch, y = (j − (n+1)/2)·pitch, so the
    paper's cell coordinate (5.5, 5.5) is the origin; images are indexed [j−1, i−1] (row y,
    column x).

Pose (001 ⁰T_k, mirrored)
    Σ_0 (θ = 0) is the object's frame. A point (x, y, z) of Σ_θ is at
        x0 = −L + (x + L) cos θ − z sin θ,   y0 = y,   z0 = (x + L) sin θ + z cos θ,
    so θ > 0 lifts the fingertip toward the object (the fingertip centre goes to
    C(θ) = (−L + L cos θ, 0, L sin θ)). The finger axes in Σ_0 are e_x(θ) = (cos θ, sin θ)
    and e_z(θ) = (−sin θ, cos θ) in (x0, z0) components.

Object plane (000 eq 1 and eq 20)
    The object is the plane z0 = r − d: it touches the undeformed tip at θ = d = 0; d is the
    prismatic indentation of 000 eq 1 (the paper's simulation has d = 0; `TactileSensor` uses
    it). In Σ_θ it is n·X = p with n(θ) = (sin θ, 0, cos θ) and p = r − d − L sin θ, the
    distance from the fingertip centre (000 eq 20 with θ_obj = θ and its p = r − L sin θ_k).

Springs (eqs 2–4, 15)
    The spring at R = (x, y, 0) runs along +z to the hemisphere at Q = (x, y, h),
    h = √(r² − x² − y²), stiffness k(x, y) = E dS / h (eq 15). The line meets the object at
    P, s_P = (p − x sin θ)/cos θ = (r − d − (x + L) sin θ)/cos θ above R (001 eq 2 prints the
    x0-coordinate of the same point, r tan θ + L − (L − x)/cos θ, in 001's orientation). The
    point is in contact when h > s_P.

Increment per step (eqs 5–9; 001 eq 7)
    V_k is where the spring line of step k meets the previous hemisphere (pose k−1). A sphere
    is unchanged by a rotation about its own centre, so seen from Σ_k the previous hemisphere
    is the same sphere centred at c = ᵏT_{k−1}·0, which for a rotation step φ = θ_k − θ_{k−1}
    is c = (−L(1 − cos φ), 0, −L sin φ). Hence
        t_k = c_z + √(r² − y² − (x − c_x)²),    |V_k Q_k| = h − t_k  (eq 9),
    the same quadratic as 001 eq 7 solved in the shifted frame; to first order t_k = h − Lφ
    (000 eq 7), i.e. every spring in contact shortens by Lφ per step. For a general pose step
    (θ, d) → (θ', d') the previous centre is c = ((C_prev − C)·e_x(θ'), (C_prev − C)·e_z(θ'))
    with C(θ, d) = (−L + L cos θ, 0, L sin θ + d) in Σ_0.

History (eqs 10–16; 001 eq 8) — **Choice**: 001 eq 8's projections
    A point first touches at step k' with the partial segment |P_k' Q_k'| = h − s_P(θ_k')
    (eqs 10–12) and gains |V_k Q_k| at every later step, each segment along the spring
    direction of its own step. 001 eq 8 projects each segment on the current spring
    direction,
        c_n = Σ_{k=k'+1..n} |V_k Q_k| cos(θ_n − θ_k) + |P_k' Q_k'| cos(θ_n − θ_k'),
    while 000 eq 16 adds the lengths without the cosines. 001's reading is used (a spring
    force along an old direction loads the sensing plane only through its normal component;
    `project_history=False` gives 000's). At the paper's 7° they differ by 0.15 % in total
    force. It is kept as the vector sum S = Σ seg_k e_z(θ_k) in Σ_0 per point, c = S·e_z(θ_n):
    two numbers per point, exact for any step. The P'Q' term, which 000 eq 19 drops as
    O(LΔθ), is kept (001 eq 8 keeps it): without it the compression is quantised to the
    step grid.

Pressure (eqs 17–19) — **Choice**: the Δθ → 0 limit of eq 19
    dF = k c = E c dS / h. Eq 17's constant-volume section dS' = (h / t) dS is printed with
    the per-step length t of eq 7, so eq 19 reads dP = E Σ (1 − t/h)(t/h), where
    t/h = 1 − LΔθ/h + O(Δθ²) (≥ 0.9986 over the 12 mm sensor at the paper's Δθ = 0.01°).
    The limit dP = E c / h is used: it makes the image independent of the step size. Not
    used: taking t in eq 17 to be the spring's total compressed length h − c, which would
    multiply the pressure by (1 − c/h) (≈ 0.5 at the centre at 7°) — that is not the t eqs 7
    and 17 define.

Unloading (extension; the paper only loads)
    A step that moves the sphere away gives a negative |V_k Q_k|. A point whose compression
    falls to ≤ 0, or that leaves geometric contact (h ≤ s_P), loses its history. c is
    clipped to [0, h] (a spring cannot be shorter than zero), so 0 ≤ dP ≤ E everywhere and
    dP = 0 outside the contact.

Rolling (eqs 20–30)
    With the finger held at θ_obj = θ_n, the object rolls by β about the fingertip keeping its
    distance p from the fingertip centre (eq 21, "retaining a certain displacement"). For
    this part the springs run from R along the object normal n(φ) = (sin φ, 0, cos φ):
        s_pl(φ)  = p − x sin φ                                (eqs 24, 28)
        s_sph(φ) = −x sin φ + √(r² − x² − y² + x² sin² φ)     (eqs 25, 29)
        q(φ)     = E (1 − s_pl / s_sph) cos φ  if s_sph > s_pl, else 0,
    the normal component on the sensing plane of an instantaneous spring (eq 26's terms).
    δdP = q(θ_obj + β) − q(θ_obj) (eqs 26–27) and dP_new = dP + δdP (eq 30).
    **Choice**: a point the rolled plane no longer reaches along its own spring (h ≤ the
    rolled plane's height (p − x sin(θ_obj + β)) / cos(θ_obj + β) above R) reads 0, and
    dP_new is clipped at 0 (the printed sum can go negative near the rim, where the history
    and the instantaneous springs disagree). At β = 0 this is exactly the rotation's image.
    **Choice** of sign: the paper gives θ_obj = 7°, β = 15° and says θ_obj + β reaches −8°;
    β is signed here (positive tilts the object's normal toward +x) and the paper's roll is
    β = −15°.

Sensor
    A cell reads the mean pressure over its area: each cell is sampled on supersample ×
    supersample points. Total force = Σ cell pressure × cell area (what the sensor sees: the
    12 mm sensor is smaller than the 20 mm fingertip base, so at large tilt it sees only part
    of the contact; `inoue_hirai` also reports the force over the whole base). Centre of
    pressure = pressure-weighted mean of the cell centres (the paper's Fig. 8, in cells).

The engine's use: `TactileSensor(...).update(indentation_m, tilt_rad)` from a decimated
loop (see its docstring). `inoue_hirai()` reproduces the paper's simulation (§III: L = 40 mm,
r = 10 mm, E = 0.3636 MPa, Δθ = 0.01°, tilt 0 → 7°, roll β = −15°, 10 × 10 cells on 12 mm),
`write_png` draws it and `tactile_main` is the CLI entry (`softproxy tactile inoue-hirai`).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from softproxy import units
from softproxy.input_error import check_count, check_finite

# ---------------------------------------------------------------------------
# Seed 000 §III / §IV constants, in the paper's units, converted to SI once.
# ---------------------------------------------------------------------------
PAPER_JOINT_DISTANCE = units.mm(40.0)
"""Finger length L from the joint axis to the fingertip axis (000 §III: 40 mm), m."""
PAPER_RADIUS = units.mm(10.0)
"""Fingertip radius r (000 §IV-A: 10 mm), m."""
PAPER_YOUNGS_MODULUS = 0.3636e6
"""Young's modulus E of the polyurethane gel (000 §IV-A: 0.3636 MPa), Pa."""
PAPER_STEP = math.radians(0.01)
"""Infinitesimal rotation θ_k − θ_{k−1} (000 §III: 0.01°), rad."""
PAPER_TILT = math.radians(7.0)
"""Final finger angle of the rotation phase (000 §III: 7°), rad."""
PAPER_ROLL = math.radians(-15.0)
"""Signed roll β of the object (000 §III: 15°, taking θ_obj + β to −8°), rad."""
PAPER_CELLS = 10
"""Cells per side of the tactile sensor (000 §III, §IV-A: 10 × 10)."""
PAPER_SIDE = units.mm(12.0)
"""Side of the sensing area (000 Fig. 9: 12 mm × 12 mm), m."""

FRAME = (
    "sensing-plane frame of the finger: origin at the fingertip axis (centre of the hemisphere's "
    "base = sensor centre); +x distal, pointing away from the joint, whose axis crosses the plane "
    "at x = -L parallel to y (seed 001's 0T_k has it at x = +L: x here = -x there); +z out of the "
    "plane toward the object; y = z cross x. Cell i (1-based) along x has its centre at "
    "x = (i - (n+1)/2) * pitch, so the paper's (5.5, 5.5) is the origin; images are indexed "
    "[row = y cell, column = x cell]. Positive finger angle presses the tip into the object; "
    "positive roll tilts the object's normal toward +x."
)


class SensorGrid:
    """A square tactile sensor of `cells` × `cells` cells on a side `side` (m), centred on the
    fingertip axis, sampled on `supersample` × `supersample` points per cell.

    `margin` (m) extends the sampled square beyond the sensor (whole cells of sub-points) so
    the model can also integrate the contact outside the sensor (e.g. the whole fingertip
    base); the cells only ever read the points inside the sensor.
    """

    def __init__(self, cells: int = PAPER_CELLS, side: float = PAPER_SIDE, supersample: int = 4,
                 margin: float = 0.0) -> None:
        self.cells = check_count("cells", cells)
        self.side = check_finite("side", side, positive=True)
        self.supersample = check_count("supersample", supersample)
        margin = check_finite("margin", margin, non_negative=True)
        self.pitch = self.side / self.cells
        self.spacing = self.pitch / self.supersample
        self.pad = int(math.ceil(margin / self.spacing - 1e-9)) if margin > 0.0 else 0
        n = self.cells * self.supersample + 2 * self.pad
        half = self.side / 2.0 + self.pad * self.spacing
        axis = -half + self.spacing * (np.arange(n) + 0.5)
        self.x, self.y = np.meshgrid(axis, axis)  # [row = y, column = x]
        self.point_area = self.spacing**2
        self.cell_area = self.pitch**2
        self.centres = (np.arange(self.cells) - (self.cells - 1) / 2.0) * self.pitch
        s = slice(self.pad, self.pad + self.cells * self.supersample)
        self._inner = (s, s)

    def cell_image(self, point_pressure: np.ndarray) -> np.ndarray:
        """Mean pressure per cell, shape (cells, cells), [row = y, column = x]."""
        inner = point_pressure[self._inner]
        n, s = self.cells, self.supersample
        return inner.reshape(n, s, n, s).mean(axis=(1, 3))

    def total_force(self, image: np.ndarray) -> float:
        """Force the sensor reads: Σ cell pressure × cell area, N."""
        return float(image.sum() * self.cell_area)

    def pressure_centre(self, image: np.ndarray) -> tuple[float, float]:
        """Pressure-weighted mean of the cell centres (x, y), m; (nan, nan) with no pressure."""
        total = float(image.sum())
        if total <= 0.0:
            return (math.nan, math.nan)
        x = float((image.sum(axis=0) * self.centres).sum() / total)
        y = float((image.sum(axis=1) * self.centres).sum() / total)
        return (x, y)

    def to_cell_units(self, xy_m: tuple[float, float]) -> tuple[float, float]:
        """A sensing-plane point (m) in the paper's 1-based cell coordinates (centre (n+1)/2)."""
        c = (self.cells + 1) / 2.0
        return (c + xy_m[0] / self.pitch, c + xy_m[1] / self.pitch)


class VirtualSpringFingertip:
    """The virtual springs of one hemispherical fingertip on a rotating finger (000 eqs 1–19).

    Holds the deformation history per sample point of `grid` (the vector sum S of seed 001
    eq 8 in the object frame) and the finger pose (θ, d) relative to the object. Each
    `move_to` integrates the history step by step, in steps of at most `max_step_rad` and
    `max_step_m`. `point_pressure()` is dP = E c / h per point (Pa), zero outside the contact.
    """

    def __init__(self, grid: SensorGrid, joint_distance: float = PAPER_JOINT_DISTANCE,
                 radius: float = PAPER_RADIUS, youngs_modulus: float = PAPER_YOUNGS_MODULUS,
                 project_history: bool = True, max_step_rad: float = PAPER_STEP,
                 max_step_m: float = units.mm(0.01)) -> None:
        if not isinstance(grid, SensorGrid):
            raise ValueError(f"grid must be a SensorGrid, got {grid!r}")
        self.grid = grid
        self.L = check_finite("joint_distance", joint_distance, non_negative=True)
        self.r = check_finite("radius", radius, positive=True)
        self.E = check_finite("youngs_modulus", youngs_modulus, positive=True)
        self.project_history = bool(project_history)
        self.max_step_rad = check_finite("max_step_rad", max_step_rad, positive=True)
        self.max_step_m = check_finite("max_step_m", max_step_m, positive=True)
        x, y = grid.x, grid.y
        rho2 = x * x + y * y
        self._inside = rho2 < self.r * self.r
        self._h = np.sqrt(np.clip(self.r * self.r - rho2, 0.0, None))
        self._h_safe = np.where(self._h > 0.0, self._h, 1.0)
        self.reset()

    def reset(self) -> None:
        """Undeformed fingertip at θ = 0, d = 0 (just touching the object)."""
        shape = self.grid.x.shape
        self._sx = np.zeros(shape)
        self._sz = np.zeros(shape)
        self._contact = np.zeros(shape, dtype=bool)
        self.theta = 0.0
        self.indentation = 0.0
        self.steps = 0

    def _centre(self, theta: float, d: float) -> tuple[float, float]:
        """Fingertip centre relative to the object, (x0, z0) in Σ_0."""
        return (-self.L + self.L * math.cos(theta), self.L * math.sin(theta) + d)

    def plane_height(self, theta: float, d: float) -> np.ndarray:
        """s_P: height of the object plane above each point along +z (001 eq 2), m."""
        p = self.r - d - self.L * math.sin(theta)
        return (p - self.grid.x * math.sin(theta)) / math.cos(theta)

    def _step(self, theta: float, d: float) -> None:
        """One step of eqs 7–16 from the current pose to (theta, d)."""
        cx0, cz0 = self._centre(self.theta, self.indentation)
        nx0, nz0 = self._centre(theta, d)
        dx0, dz0 = cx0 - nx0, cz0 - nz0
        ct, st = math.cos(theta), math.sin(theta)
        # previous sphere centre in the current finger frame (e_x = (c, s), e_z = (-s, c))
        c_x = dx0 * ct + dz0 * st
        c_z = -dx0 * st + dz0 * ct
        x, y, h = self.grid.x, self.grid.y, self._h
        t = c_z + np.sqrt(np.clip(self.r * self.r - y * y - (x - c_x) ** 2, 0.0, None))
        s_p = self.plane_height(theta, d)
        now = self._inside & (h > s_p)
        # |V_k Q_k| for springs already in contact, |P_k' Q_k'| for new ones (eqs 9, 12)
        seg = np.where(self._contact, h - t, h - s_p)
        ez_x, ez_z = (-st, ct) if self.project_history else (0.0, 1.0)
        sx = self._sx + seg * ez_x
        sz = self._sz + seg * ez_z
        c = sx * ez_x + sz * ez_z
        keep = now & (c > 0.0)
        self._sx = np.where(keep, sx, 0.0)
        self._sz = np.where(keep, sz, 0.0)
        self._contact = keep
        self.theta, self.indentation = theta, d
        self.steps += 1

    def move_to(self, theta: float, d: float = 0.0, max_substeps: int | None = None) -> int:
        """Integrate the history to finger angle `theta` (rad) and indentation `d` (m).

        Returns the number of steps taken (≥ 1 unless the pose is unchanged). With
        `max_substeps` the step count is capped (larger, less accurate steps).
        """
        theta = check_finite("theta", theta)
        d = check_finite("d", d)
        if abs(theta) >= math.pi / 2.0:
            raise ValueError(f"theta must be within ±90°, got {theta!r}")
        dt, dd = theta - self.theta, d - self.indentation
        n = max(math.ceil(abs(dt) / self.max_step_rad - 1e-9), math.ceil(abs(dd) / self.max_step_m - 1e-9))
        if n <= 0:
            return 0
        if max_substeps is not None:
            n = min(n, max(1, int(max_substeps)))
        t0, d0 = self.theta, self.indentation
        for k in range(1, n + 1):
            self._step(t0 + dt * k / n, d0 + dd * k / n)
        return n

    def compression(self) -> np.ndarray:
        """Accumulated compression c per point along the current spring direction, m, in [0, h]."""
        st, ct = math.sin(self.theta), math.cos(self.theta)
        ez_x, ez_z = (-st, ct) if self.project_history else (0.0, 1.0)
        c = self._sx * ez_x + self._sz * ez_z
        return np.where(self._contact, np.clip(c, 0.0, self._h), 0.0)

    def point_pressure(self) -> np.ndarray:
        """dP = E c / h per point (eq 19 in the Δθ → 0 limit), Pa; 0 outside the contact."""
        return np.where(self._contact, self.E * self.compression() / self._h_safe, 0.0)

    def rolled_pressure(self, beta: float) -> np.ndarray:
        """dP_new = dP + δdP after the object rolls by `beta` (rad) about the tip (eqs 20–30), Pa."""
        beta = check_finite("beta", beta)
        phi0 = self.theta
        phi1 = phi0 + beta
        if abs(phi1) >= math.pi / 2.0:
            raise ValueError(f"theta + beta must be within ±90°, got {phi1!r}")
        q0 = self._instantaneous(phi0)
        q1 = self._instantaneous(phi1)
        # the rolled plane along each spring (+z): same p, normal n(φ1)
        p = self.r - self.indentation - self.L * math.sin(self.theta)
        touching = self._inside & (self._h > (p - self.grid.x * math.sin(phi1)) / math.cos(phi1))
        p_new = self.point_pressure() + q1 - q0
        return np.where(touching, np.clip(p_new, 0.0, None), 0.0)

    def _instantaneous(self, phi: float) -> np.ndarray:
        """q(φ) of eqs 24–29: instantaneous spring along the object normal, normal component, Pa."""
        p = self.r - self.indentation - self.L * math.sin(self.theta)
        x, y = self.grid.x, self.grid.y
        s = math.sin(phi)
        s_pl = p - x * s
        s_sph = -x * s + np.sqrt(np.clip(self.r * self.r - x * x - y * y + (x * s) ** 2, 0.0, None))
        touching = self._inside & (s_sph > s_pl) & (s_sph > 0.0)
        q = self.E * (1.0 - s_pl / np.where(s_sph > 0.0, s_sph, 1.0)) * math.cos(phi)
        return np.where(touching, np.clip(q, 0.0, None), 0.0)


# ---------------------------------------------------------------------------
# Servo-side sensor
# ---------------------------------------------------------------------------
class TactileSensor:
    """A tactile image of one soft fingertip for the engine, meant to be *decimated*.

    Call `update(indentation_m, tilt_rad)` from outside the servo tick's hot path, at a lower
    rate than the tick (e.g. every 10th tick): each call integrates the Inoue–Hirai history
    from the last pose to the new one (sub-steps of at most `max_step_rad` / `max_step_m`,
    at most `max_substeps` of them, so a call costs O(max_substeps × points) at worst) and
    returns the pressure image, a (cells × cells) numpy array in N/m², [row = y, column = x]
    in the frame of `FRAME`. The sensor owns no thread or timer: between calls it does no work.
    Cost with the defaults (10 × 10 cells, 4 × 4 points each): ~0.2 ms for a call that moves
    less than one sub-step, ~18 ms for the worst case of 200 sub-steps.

    `indentation_m` is the object's displacement toward the sensing plane along its normal
    (the prismatic d of 000 eq 1), `tilt_rad` the finger's rotation θ about the joint at
    `joint_distance` (0 puts the joint under the fingertip axis: θ is then the tilt of the
    contact normal); `roll_rad` optionally rolls the object by β about the tip (eqs 20–30).
    Non-finite inputs are not applied: the last image is returned, `rejected` counts them
    and `last_error` says why. |tilt| and |tilt + roll| are clamped to `max_tilt_rad` and the
    indentation to [−r, r].
    """

    def __init__(self, radius: float = PAPER_RADIUS, youngs_modulus: float = PAPER_YOUNGS_MODULUS,
                 joint_distance: float = PAPER_JOINT_DISTANCE, cells: int = PAPER_CELLS,
                 side: float = PAPER_SIDE, supersample: int = 4, project_history: bool = True,
                 max_step_rad: float = math.radians(0.1), max_step_m: float = units.mm(0.05),
                 max_substeps: int = 200, max_tilt_rad: float = math.radians(60.0)) -> None:
        grid = SensorGrid(cells, side, supersample)
        self.model = VirtualSpringFingertip(grid, joint_distance, radius, youngs_modulus, project_history,
                                            max_step_rad, max_step_m)
        self.max_substeps = check_count("max_substeps", max_substeps)
        self.max_tilt_rad = check_finite("max_tilt_rad", max_tilt_rad, positive=True)
        if self.max_tilt_rad >= math.pi / 2.0:
            raise ValueError(f"max_tilt_rad must be < π/2, got {max_tilt_rad!r}")
        self.grid = grid
        self.updates = 0
        self.rejected = 0
        self.last_error = ""
        self._image = np.zeros((grid.cells, grid.cells))

    def update(self, indentation_m: float, tilt_rad: float, roll_rad: float = 0.0) -> np.ndarray:
        """Advance to the new pose and return the pressure image (N/m² per cell, a new array)."""
        values = (indentation_m, tilt_rad, roll_rad)
        try:
            d, theta, beta = (float(v) for v in values)
        except (TypeError, ValueError):
            d = theta = beta = math.nan
        if not all(math.isfinite(v) for v in (d, theta, beta)):
            self.rejected += 1
            self.last_error = f"non-finite input (indentation_m, tilt_rad, roll_rad) = {values!r}; kept last image"
            return self._image.copy()
        lim = self.max_tilt_rad
        theta = min(max(theta, -lim), lim)
        beta = min(max(beta, -lim - theta), lim - theta)
        d = min(max(d, -self.model.r), self.model.r)
        self.model.move_to(theta, d, self.max_substeps)
        points = self.model.rolled_pressure(beta) if beta != 0.0 else self.model.point_pressure()
        self._image = self.grid.cell_image(points)
        self.updates += 1
        return self._image.copy()

    @property
    def image(self) -> np.ndarray:
        """The last image returned by `update` (zeros before the first call), N/m²."""
        return self._image.copy()

    def total_force(self) -> float:
        """Force on the sensor in the last image, N."""
        return self.grid.total_force(self._image)

    def pressure_centre(self) -> tuple[float, float]:
        """Centre of pressure of the last image (x, y) in m, (nan, nan) with no contact."""
        return self.grid.pressure_centre(self._image)

    def reset(self) -> None:
        """Forget the deformation history (the fingertip left the object)."""
        self.model.reset()
        self._image = np.zeros_like(self._image)


# ---------------------------------------------------------------------------
# The paper's simulation (000 §III, Figs. 7–8)
# ---------------------------------------------------------------------------
def _record(grid: SensorGrid, points: np.ndarray, base: bool) -> tuple[np.ndarray, float, tuple, float]:
    image = grid.cell_image(points)
    force_base = float(points.sum() * grid.point_area) if base else math.nan
    return image, grid.total_force(image), grid.pressure_centre(image), force_base


def _power_fit(angles: list[float], forces: list[float]) -> float | None:
    """Exponent n of F = a θ^n fitted in log–log over the points with θ > 0 and F > 0."""
    pts = [(math.log(a), math.log(f)) for a, f in zip(angles, forces) if a > 0.0 and f > 0.0]
    if len(pts) < 2:
        return None
    lx, lf = np.array(pts).T
    return float(np.polyfit(lx, lf, 1)[0])


def inoue_hirai(joint_distance: float = PAPER_JOINT_DISTANCE, radius: float = PAPER_RADIUS,
                youngs_modulus: float = PAPER_YOUNGS_MODULUS, step: float = PAPER_STEP,
                tilt: float = PAPER_TILT, roll: float = PAPER_ROLL, cells: int = PAPER_CELLS,
                side: float = PAPER_SIDE, supersample: int = 8, record_every: float = math.radians(0.25),
                roll_step: float = math.radians(0.5), project_history: bool = True,
                image_angles_deg: tuple[float, ...] = (1.0, 3.0, 5.0, 7.0, -0.5, -8.0)) -> dict:
    """Reproduce 000 §III: rotate the finger 0 → `tilt` in steps `step`, then roll the object by `roll`.

    Returns {"rotation": {...}, "rolling": {...}, "frame": FRAME, "parameters": ..., "images": ...,
    "force_exponent": ...}. Each phase holds `angle_deg` (the finger angle θ while rotating, the
    object angle θ_obj + β on the sensing plane while rolling, as in the paper's Fig. 8),
    `pressure_centre` ([x, y] in mm on the sensing plane), `pressure_centre_cell` (the paper's
    1-based cell units), `total_force_N` (on the sensor) and `total_force_base_N` (over the whole
    fingertip base, not clipped by the sensor). `images` are the cell images (Pa) at the phase
    angles nearest `image_angles_deg` (positive: rotation; the last two: rolling).
    """
    step = check_finite("step", step, positive=True)
    tilt = check_finite("tilt", tilt, positive=True)
    roll = check_finite("roll", roll)
    record_every = check_finite("record_every", record_every, positive=True)
    roll_step = check_finite("roll_step", roll_step, positive=True)
    if tilt >= math.pi / 2.0:
        raise ValueError(f"tilt must be < 90°, got {tilt!r}")
    if abs(tilt + roll) >= math.pi / 2.0:
        raise ValueError(f"tilt + roll must be within ±90°, got {tilt + roll!r}")
    radius = check_finite("radius", radius, positive=True)
    side = check_finite("side", side, positive=True)
    grid = SensorGrid(cells, side, supersample, margin=max(0.0, radius - side / 2.0))
    tip = VirtualSpringFingertip(grid, joint_distance, radius, youngs_modulus, project_history,
                                 max_step_rad=step)

    def phase() -> dict:
        return {"angle_deg": [], "pressure_centre": [], "pressure_centre_cell": [], "total_force_N": [],
                "total_force_base_N": []}

    def add(out: dict, angle: float, points: np.ndarray) -> np.ndarray:
        image, force, centre, force_base = _record(grid, points, True)
        out["angle_deg"].append(round(math.degrees(angle), 6))
        if math.isfinite(centre[0]):
            out["pressure_centre"].append([units.to_mm(centre[0]), units.to_mm(centre[1])])
            out["pressure_centre_cell"].append(list(grid.to_cell_units(centre)))
        else:
            out["pressure_centre"].append(None)
            out["pressure_centre_cell"].append(None)
        out["total_force_N"].append(force)
        out["total_force_base_N"].append(force_base)
        return image

    rotation, rolling = phase(), phase()
    images_rot, images_roll = [], []
    n_steps = max(1, int(round(tilt / step)))
    every = max(1, int(round(record_every / step)))
    images_rot.append((0.0, add(rotation, 0.0, tip.point_pressure())))
    for k in range(1, n_steps + 1):
        tip.move_to(tilt * k / n_steps, max_substeps=1)
        if k % every == 0 or k == n_steps:
            images_rot.append((tip.theta, add(rotation, tip.theta, tip.point_pressure())))
    n_roll = max(1, int(math.ceil(abs(roll) / roll_step - 1e-9))) if roll != 0.0 else 0
    rolling_beta = []
    for k in range(0, n_roll + 1):
        beta = roll * k / n_roll if n_roll else 0.0
        rolling_beta.append(round(math.degrees(beta), 6))
        images_roll.append((tip.theta + beta, add(rolling, tip.theta + beta, tip.rolled_pressure(beta))))
    rolling["beta_deg"] = rolling_beta

    images = []
    wanted_rot = [a for a in image_angles_deg if a > 0.0]
    wanted_roll = [a for a in image_angles_deg if a <= 0.0]
    for wanted, phase_name, pool in ((wanted_rot, "rotation", images_rot), (wanted_roll, "rolling", images_roll)):
        for a in wanted:
            angle, image = min(pool, key=lambda item: abs(math.degrees(item[0]) - a))
            images.append({"phase": phase_name, "angle_deg": round(math.degrees(angle), 6),
                           "pressure_Pa": image.tolist()})

    forces = rolling["total_force_N"]
    return {
        "rotation": rotation,
        "rolling": rolling,
        "frame": FRAME,
        "parameters": {
            "joint_distance_mm": units.to_mm(tip.L), "radius_mm": units.to_mm(tip.r),
            "youngs_modulus_MPa": tip.E * 1e-6, "step_deg": math.degrees(step),
            "tilt_deg": math.degrees(tilt), "roll_deg": math.degrees(roll), "cells": grid.cells,
            "side_mm": units.to_mm(grid.side), "supersample": grid.supersample,
            "project_history": tip.project_history, "cell_area_mm2": grid.cell_area / units.MM**2,
        },
        "images": images,
        "force_exponent": {
            "sensor": _power_fit(rotation["angle_deg"], rotation["total_force_N"]),
            "base": _power_fit(rotation["angle_deg"], rotation["total_force_base_N"]),
        },
        "rolling_force_variation": (max(forces) - min(forces)) / max(max(forces), 1e-300) if forces else None,
    }


def write_png(result: dict, path: str | Path) -> Path:
    """Draw the pressure images at a few angles, the centre-of-pressure path and force vs angle."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    images = result["images"]
    side = result["parameters"]["side_mm"]
    n = max(len(images), 2)
    fig = plt.figure(figsize=(2.4 * n + 1.0, 6.4), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.0, 1.3])
    axes = top.subplots(1, n, squeeze=False)[0]
    vmax = max((max(max(row) for row in im["pressure_Pa"]) for im in images), default=0.0) / 1e3 or 1.0
    shown = None
    for i, ax in enumerate(axes):
        if i >= len(images):
            ax.set_axis_off()
            continue
        im = images[i]
        shown = ax.imshow(np.array(im["pressure_Pa"]) / 1e3, origin="lower", cmap="viridis", vmin=0.0, vmax=vmax,
                          extent=(-side / 2, side / 2, -side / 2, side / 2))
        ax.set_title(f"{im['phase']} {im['angle_deg']:+.2f}°", fontsize=9)
        ax.set_xlabel("x (mm, distal →)", fontsize=8)
        if i == 0:
            ax.set_ylabel("y (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    if shown is not None:
        top.colorbar(shown, ax=list(axes), shrink=0.8, label="pressure (kPa)")
    a, b = bottom.subplots(1, 2)
    for name, style in (("rotation", "o-"), ("rolling", "s-")):
        ph = result[name]
        pts = [(c[0], c[1]) for c in ph["pressure_centre_cell"] if c is not None]
        if pts:
            xs, ys = zip(*pts)
            a.plot(xs, ys, style, ms=3, label=name)
        b.plot(ph["angle_deg"], ph["total_force_N"], style, ms=3, label=f"{name}: on the sensor")
        b.plot(ph["angle_deg"], ph["total_force_base_N"], "--", lw=1, label=f"{name}: whole base")
    centre = (result["parameters"]["cells"] + 1) / 2.0
    a.set_ylim(centre - 0.5, centre + 0.5)
    a.ticklabel_format(useOffset=False)
    a.set_xlabel("x (cells, distal →)")
    a.set_ylabel("y (cells)")
    a.set_title("centre of pressure (cf. the paper's Fig. 8b)", fontsize=10)
    a.legend(fontsize=8)
    b.set_xlabel("angle (deg): θ while rotating, θ_obj + β while rolling")
    b.set_ylabel("total force (N)")
    exp = result.get("force_exponent", {}).get("sensor")
    b.set_title("total force (cf. Fig. 8d)" + (f"; F ∝ θ^{exp:.2f} on the sensor" if exp else ""), fontsize=10)
    b.legend(fontsize=7)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def tactile_main(as_json: bool, out_dir: str) -> int:
    """CLI entry: `softproxy tactile inoue-hirai [--json]`. Prints a table or JSON, writes the PNG."""
    try:
        result = inoue_hirai()
    except ValueError as exc:
        print(f"softproxy tactile: {exc}", file=sys.stderr)
        return 2
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        png = write_png(result, out / "tactile_inoue_hirai.png")
    except OSError as exc:
        print(f"softproxy tactile: cannot write to {out}: {exc}", file=sys.stderr)
        return 1
    result["png"] = str(png)
    if as_json:
        print(json.dumps(result))
        return 0
    p = result["parameters"]
    print(f"Inoue–Hirai virtual-spring fingertip (Rotational Contact Model of Soft Fingertip, §III): L = {p['joint_distance_mm']:g} mm, "
          f"r = {p['radius_mm']:g} mm, E = {p['youngs_modulus_MPa']:g} MPa, Δθ = {p['step_deg']:g}°, "
          f"{p['cells']}×{p['cells']} cells on {p['side_mm']:g} mm")
    print("frame: +x distal (away from the joint), cell (5.5, 5.5) = fingertip axis")
    print(f"{'phase':9s}{'angle°':>8s}{'x (mm)':>9s}{'y (mm)':>9s}{'x cell':>8s}{'y cell':>8s}"
          f"{'F sensor (N)':>14s}{'F base (N)':>12s}")
    for name, stride in (("rotation", 4), ("rolling", 3)):
        ph = result[name]
        for i in range(0, len(ph["angle_deg"]), stride):
            c, cc = ph["pressure_centre"][i], ph["pressure_centre_cell"][i]
            cs = f"{c[0]:9.3f}{c[1]:9.3f}{cc[0]:8.3f}{cc[1]:8.3f}" if c else f"{'-':>9s}{'-':>9s}{'-':>8s}{'-':>8s}"
            print(f"{name:9s}{ph['angle_deg'][i]:8.2f}{cs}{ph['total_force_N'][i]:14.3f}"
                  f"{ph['total_force_base_N'][i]:12.3f}")
    e = result["force_exponent"]
    print(f"force ∝ θ^n while rotating: n = {e['sensor']:.3f} on the sensor, {e['base']:.3f} over the whole base; "
          f"force varies by {result['rolling_force_variation'] * 100:.2f} % while rolling")
    print(f"wrote {png}")
    return 0
