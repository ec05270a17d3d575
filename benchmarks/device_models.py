"""Simulated haptic devices for the stability bench: the vendors' figures, and a handle held by a hand.

A device is modelled along one axis (z, the wall's normal) as what an impedance-type haptic
device is: a moving (apparent) mass m with viscous damping b, driven by the force the servo
loop sends, which the amplifier holds over each period (zero-order hold), and read through an
encoder of resolution Δ (the position is quantised to multiples of Δ). The hand holding it is
a spring-damper (K_h, b_h) pulling the handle towards a target.

Between two ticks the handle's dynamics are linear with constant inputs (the held force, the
hand's target), so they are integrated exactly: with the state s = (z, v) and the inputs
u = (F, z_t),

    ṡ = A s + G u,   A = [[0, 1], [−K_h/m, −(b + b_h)/m]],   G = [[0, 0], [1/m, K_h/m]],
    s(t + T) = Φ s(t) + Γ u,   Φ = e^{AT},   Γ = ∫₀ᵀ e^{Aτ} dτ G,

both read off one matrix exponential of the augmented matrix [[A, G], [0, 0]]·T (Van Loan's
method; `scipy.linalg.expm`). The position is sampled at the tick, after the force of the
previous tick has acted over the whole period: the sampled-data loop Colgate and Schenkel
analysed. (The bench used to integrate the handle with one semi-implicit Euler step per tick,
which leads the force by half a sample and hides the ZOH's destabilising lag.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm

from softproxy.device import DeviceSample


@dataclass(frozen=True)
class DeviceProfile:
    """One haptic device along one axis: what the bench simulates, and what its vendor promises.

    mass_kg: moving (apparent) mass at the handle; damping_Nspm: its viscous damping (N·s/m);
    resolution_m: the encoder's position resolution at the handle (m); max_force_N: the largest
    force it renders (N), the clamp; vendor_stiffness_Npm: the largest wall stiffness the vendor
    states it renders (N/m; None: not published); driver_stiffness_Npm: CHAI3D's driver's
    m_maxLinearStiffness for the model (N/m), what that framework lets an application render.
    sources: where each figure comes from, or what was assumed and why."""

    name: str
    mass_kg: float
    damping_Nspm: float
    resolution_m: float
    max_force_N: float
    vendor_stiffness_Npm: float | None
    driver_stiffness_Npm: float
    sources: dict = field(default_factory=dict)


CHAI3D_PHANTOM = "CHAI3D 3.2 src/devices/CPhantomDevices.cpp, the model's m_specifications (github.com/chai3d/chai3d)"
CHAI3D_DELTA = "CHAI3D 3.2 src/devices/CDeltaDevices.cpp, the model's m_specifications (github.com/chai3d/chai3d)"
TOUCH_SHEET = ("3D Systems, 'Touch haptic device' specifications "
               "(https://www.3dsystems.com/haptics-devices/touch/specifications), the figures it shares with "
               "the PHANTOM Omni data sheet")
FALCON_SHEET = "Novint, 'Novint Falcon technical specifications' (https://www.novint.com, Falcon product page)"
OMEGA_SHEET = "Force Dimension, 'omega.3' specifications (https://www.forcedimension.com/products/omega)"
SIGMA_SHEET = "Force Dimension, 'sigma.7' specifications (https://www.forcedimension.com/products/sigma)"
NO_DAMPING = ("not published by the vendor: assumed 0.1 N·s/m, the order of the viscous friction of a "
              "back-drivable direct-drive or capstan device; small against the hand's 2 N·s/m, so the "
              "stability boundary barely depends on it (±0.1 N·s/m moves it ±4 %), while Colgate's "
              "device-only passivity bound is proportional to it")

PROFILES = {
    "Touch": DeviceProfile(
        "3D Systems Touch", mass_kg=0.045, damping_Nspm=0.1, resolution_m=0.055e-3, max_force_N=3.3,
        vendor_stiffness_Npm=1020.0, driver_stiffness_Npm=400.0, sources={
            "mass_kg": TOUCH_SHEET + ": inertia (apparent mass at tip) ~45 g",
            "damping_Nspm": NO_DAMPING + " (the sheet gives only Coulomb backdrive friction, < 0.26 N)",
            "resolution_m": TOUCH_SHEET + ": nominal position resolution > 450 dpi, ~0.055 mm",
            "max_force_N": TOUCH_SHEET + ": maximum exertable force 3.3 N (continuous 0.88 N)",
            "vendor_stiffness_Npm": TOUCH_SHEET + ": stiffness X 1.26, Y 2.31, Z 1.02 N/mm (the least, Z, here)",
            "driver_stiffness_Npm": CHAI3D_PHANTOM + ": 400 N/m for \"Touch\""}),
    "Falcon": DeviceProfile(
        "Novint Falcon", mass_kg=0.15, damping_Nspm=0.1, resolution_m=0.0635e-3, max_force_N=8.9,
        vendor_stiffness_Npm=None, driver_stiffness_Npm=3000.0, sources={
            "mass_kg": ("not published: assumed 0.15 kg, three plastic delta arms and the grip, about three "
                        "times the Touch's 45 g stylus"),
            "damping_Nspm": NO_DAMPING,
            "resolution_m": FALCON_SHEET + ": position resolution > 400 dpi, 0.0635 mm",
            "max_force_N": FALCON_SHEET + ": force capabilities > 2 lbf, 8.9 N (CHAI3D's driver says 8 N)",
            "vendor_stiffness_Npm": "not published by Novint",
            "driver_stiffness_Npm": CHAI3D_DELTA + ": 3000 N/m for DHD_DEVICE_FALCON"}),
    "omega.3": DeviceProfile(
        "Force Dimension omega.3", mass_kg=0.2, damping_Nspm=0.1, resolution_m=0.01e-3, max_force_N=12.0,
        vendor_stiffness_Npm=14500.0, driver_stiffness_Npm=5000.0, sources={
            "mass_kg": ("not published: assumed 0.2 kg, a delta base with larger motors and longer arms "
                        "than the Falcon's"),
            "damping_Nspm": NO_DAMPING,
            "resolution_m": OMEGA_SHEET + ": translation resolution < 0.01 mm",
            "max_force_N": OMEGA_SHEET + ": continuous force 12.0 N (CHAI3D's driver: 12 N)",
            "vendor_stiffness_Npm": OMEGA_SHEET + ": closed-loop stiffness 14.5 N/mm (at its 4 kHz refresh rate)",
            "driver_stiffness_Npm": CHAI3D_DELTA + ": 5000 N/m for DHD_DEVICE_OMEGA3"}),
    "sigma.7": DeviceProfile(
        "Force Dimension sigma.7", mass_kg=0.4, damping_Nspm=0.1, resolution_m=0.0015e-3, max_force_N=20.0,
        vendor_stiffness_Npm=None, driver_stiffness_Npm=4000.0, sources={
            "mass_kg": ("not published: assumed 0.4 kg, the delta base carries the 3-DOF wrist and the "
                        "gripper, about twice the omega.3's moving parts"),
            "damping_Nspm": NO_DAMPING,
            "resolution_m": SIGMA_SHEET + ": translation resolution < 0.0015 mm",
            "max_force_N": SIGMA_SHEET + ": continuous translational force 20.0 N (CHAI3D's driver: 12 N)",
            "vendor_stiffness_Npm": "not found in the sheet available here; CHAI3D's figure is shown instead",
            "driver_stiffness_Npm": CHAI3D_DELTA + ": 4000 N/m for DHD_DEVICE_SIGMA331"}),
}
"""The four devices of the bench, by short name. Figures a vendor publishes cite its sheet; the
rest say what was assumed and why. The sheets' figures could not be re-read from a stored copy
when this was written: check them against the current sheet before relying on one."""


@dataclass(frozen=True)
class Hand:
    """The hand holding the handle: a spring-damper pulling it towards a target that sinks from
    the wall's surface (z = 0) to `depth_m` below it over `ramp_s` on a half-cosine (the push
    builds without a jolt), then presses the wall with stiffness·|depth| N. 300 N/m and
    2 N·s/m: a light pinch grip (Hajian & Howe 1997 measured 50–400 N/m and 1.5–4 N·s/m at
    the fingertip)."""

    stiffness_Npm: float = 300.0
    damping_Nspm: float = 2.0
    depth_m: float = -5e-3
    ramp_s: float = 0.05

    @property
    def push_N(self) -> float:
        """The steady force the hand presses the wall with, N."""
        return -self.stiffness_Npm * self.depth_m

    def target(self, t: float) -> float:
        """Where the hand pulls the handle at time t (s), m."""
        s = min(max(t / self.ramp_s, 0.0), 1.0) if self.ramp_s > 0.0 else 1.0
        return 0.5 * (1.0 - math.cos(math.pi * s)) * self.depth_m

    def rest(self, K: float) -> float:
        """Where the handle rests on a wall of stiffness K N/m once the push has built: the
        hand's pull and the wall's spring balance (m; < 0: inside)."""
        return self.stiffness_Npm * self.depth_m / (K + self.stiffness_Npm)


def handle_matrices(mass: float, damping: float, hand_stiffness: float, hand_damping: float,
                    dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Φ (2×2) and Γ (2×2: columns for the held force F and the hand's held target z_t) of the
    handle's exact zero-order-hold step over dt s (Van Loan: one expm of [[A, G], [0, 0]]·dt)."""
    A = np.array([[0.0, 1.0], [-hand_stiffness / mass, -(damping + hand_damping) / mass]])
    G = np.array([[0.0, 0.0], [1.0 / mass, hand_stiffness / mass]])
    M = np.zeros((4, 4))
    M[:2, :2], M[:2, 2:] = A * dt, G * dt
    E = expm(M)
    return E[:2, :2], E[:2, 2:]


class HandHeldHandle:
    """A one-axis (z) handle of a `DeviceProfile`, held by a `Hand`; the Device protocol.

    The force sent in a tick is held until the next (ZOH) and the handle is integrated exactly
    between the ticks' times (`handle_matrices`); `read(t)` reports the position at t, quantised
    by the encoder when `encoder` is on. At `kick_s` the handle's velocity jumps by `kick_mps`
    (a tap that starts the oscillation whose growth the bench measures). Keeps the exact state
    (z, v) and the force at every tick, and the work the rendered force did on the handle.
    It starts at rest at `start_m`."""

    fingers, max_torque = 1, 0.0

    def __init__(self, profile: DeviceProfile, period: float, hand: Hand = Hand(), encoder: bool = True,
                 kick_s: float = math.inf, kick_mps: float = 0.0, start_m: float = 0.0) -> None:
        self.profile, self.hand, self.period = profile, hand, period
        self.max_force = profile.max_force_N
        self.resolution = profile.resolution_m if encoder else 0.0
        self.kick_s, self.kick_mps = kick_s, kick_mps
        self.t, self.z, self.v, self.force = 0.0, start_m, 0.0, 0.0
        self.work = 0.0  # J: the work the rendered (held) force did on the handle, Σ F·Δz, exact under ZOH
        self.times: list[float] = []
        self.positions: list[float] = []  # the exact z at each read, m
        self.velocities: list[float] = []
        self.forces: list[float] = []  # what each tick sent, N
        self._steps = {}

    def _matrices(self, dt: float):
        key = round(dt * 1e12)
        if key not in self._steps:
            p, h = self.profile, self.hand
            self._steps[key] = handle_matrices(p.mass_kg, p.damping_Nspm, h.stiffness_Npm, h.damping_Nspm, dt)
        return self._steps[key]

    def _advance(self, t: float) -> None:
        """Integrate from self.t to t under the held force and the hand's target held at self.t's
        (the target is constant once the push has built, before anything is measured)."""
        dt = t - self.t
        if dt <= 0.0:
            return
        Phi, Gam = self._matrices(dt)
        z_t = self.hand.target(self.t)
        z = Phi[0, 0] * self.z + Phi[0, 1] * self.v + Gam[0, 0] * self.force + Gam[0, 1] * z_t
        v = Phi[1, 0] * self.z + Phi[1, 1] * self.v + Gam[1, 0] * self.force + Gam[1, 1] * z_t
        self.work += self.force * (z - self.z)
        self.z, self.v, self.t = z, v, t

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        if self.t < self.kick_s <= t:  # the tap lands inside this period: integrate up to it
            self._advance(self.kick_s)
            self.v += self.kick_mps
        self._advance(t)
        if not self.times or t > self.times[-1]:
            self.times.append(t)
            self.positions.append(self.z)
            self.velocities.append(self.v)
        s = samples[0]
        z = self.z if self.resolution <= 0.0 else self.resolution * round(self.z / self.resolution)
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, z, 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz) -> None:
        self.force = fz
        self.forces.append(fz)

    def close(self) -> None:
        self.force = 0.0
