"""`softproxy bench peer`: the two-finger grasp in MuJoCo alone, in PyBullet, in Drake, and in softproxy.

The same grasp in every engine: two 8 mm sphere fingers that translate but do not turn
(three slide joints), a 3 N squeeze per finger, the scene's scripted device path in y and z
through PD servos (kp = 2000 N/m, kv = 5 N·s/m, softproxy's coupling), a 0.1 kg box held
2 cm off its centre of mass. Each peer runs as a newcomer would set it (defaults) and as
its documentation and an expert would (MuJoCo: elliptic cone, impratio 100, the no-slip
post-solver, condim 4 and 6; PyBullet: spinning friction, friction anchors, more solver
iterations). The peers' torsional coefficient is softproxy's default limit at 3 N ÷ 3 N,
so every engine resists the same torque at the grip the grasp uses.

Measured, for each: the box's rotation over a 20 s hold and its creep rate; the torsional
limit per contact against grip (zero gravity, a slowly rising external torque; the limit is
the largest torque the contacts transmit, read off the box's angular momentum balance) with
its exponent over 0.1–2 N (seed 002's non-linear range) and 0.5–8 N; static vs dynamic
(the torque of a steady slide at 1 rad/s over the break-away torque, beside the fingers'
setting; slip, then unload: the torque at which the contact re-sticks, as a fraction of
the break-away torque); the cost of a step, as ratios to MuJoCo's default
step in the same run; and the fidelity of each limit to the fingertip measured in seed 002
(E3, eq 24) over 0.1–3 N, the peers with their best single coefficient. PyBullet is the
optional extra `softproxy[peers]`; without it its rows are skipped. Drake (the extra
`softproxy[drake]`) runs every part too: hydroelastic contact with the SAP solver at 1 ms, each
finger a soft sphere whose modulus is fitted to a measured fingertip's contact radii (no
torsional law written anywhere: the limit comes from the pressure over the contact patch), its
friction coefficient set by the peers' rule; without Drake its rows are skipped. Writes
peer.json and peer.png.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from .report import Progress, figure, publish
from softproxy import fingertip
from softproxy.device import DeviceSample
from softproxy.finger import FingerParams
from softproxy.run import _rotation_about, build, open_device
from softproxy.scene import load_scene

SCENE = "two_finger_grasp"
GRIP_N = 3.0                 # the grasp's grip per finger, N
AXIS = (1.0, 0.0, 0.0)       # the grasp axis
SQUEEZE_END_S = 0.8          # rotation is measured from here
FINGER_RADIUS = 0.008        # m
FINGER_MASS = 0.01           # kg
KP, KV = 2000.0, 5.0         # the peers' finger servos, N/m and N·s/m (softproxy's coupling)
X_DAMPING = 5.0              # N·s/m on the squeezing joint
BOX_HALF = (0.02, 0.05, 0.03)  # m
BOX_MASS = 0.1               # kg
BOX_DAMPING = 0.001          # N·m·s/rad on the box's free joint, as the grasp scene has it
CREEP_WINDOW_S = 2.0         # creep: slope of the rotation over the last 2 s
HELD_HEIGHT = 0.05           # m: the box's centre is lifted to ~0.08 m (0.06 m hanging turned 90°
                             # in the fingers); back on the floor it is at 0.03 m: dropped
PYBULLET_EXTRA = "peers"


def default_law() -> fingertip.FingertipModel:
    """The fingertip law a finger gets when the scene says nothing but its model (CH)."""
    return fingertip.model(FingerParams().model)


def default_limit(P: float) -> float:
    """softproxy's default torsional limit per contact at normal force P (N·m)."""
    law = default_law()
    return law.piecewise_torque(P) if FingerParams().saturate else law.torque_limit(P)


def peer_coefficient() -> float:
    """The peers' linear torsional coefficient (m): softproxy's default limit at the grip."""
    return default_limit(GRIP_N) / GRIP_N


# ---------------------------------------------------------------------------------
# Peer settings
# ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class MujocoSetup:
    """One way to set MuJoCo's contact up: `condim` (4: torsion, 6: torsion and rolling),
    friction cone, impratio (friction-to-normal impedance ratio), no-slip iterations."""

    condim: int = 4
    cone: str = "pyramidal"
    impratio: float = 1.0
    noslip_iterations: int = 0

    def options(self) -> str:
        return (f"condim {self.condim}, cone {self.cone}, impratio {self.impratio:g}, "
                f"noslip_iterations {self.noslip_iterations}")


@dataclass(frozen=True)
class PybulletSetup:
    """One way to set PyBullet's contact up: friction anchors, solver iterations, cone."""

    friction_anchor: bool = False
    solver_iterations: int = 50   # PyBullet's default
    cone_friction: int = 1        # PyBullet's default (implicit cone)

    def options(self) -> str:
        return (f"spinningFriction, frictionAnchor {int(self.friction_anchor)}, "
                f"numSolverIterations {self.solver_iterations}, enableConeFriction {self.cone_friction}")


@dataclass(frozen=True)
class SoftproxySetup:
    """The grasp scene's fingers with fingertip `model`, `saturate` (the saturating law or the
    power law) and, if given, a dynamic torsional coefficient of `dynamic_ratio` × the static
    one (None: the finger's default, torsion_mu_d = 0.8 × static)."""

    model: str = "CH"
    saturate: bool = False
    dynamic_ratio: float | None = None

    def options(self) -> str:
        if self.model == "point":
            return "point contact (no torsion)"
        law = "saturating law (saturate=true)" if self.saturate else "power law (saturate=false)"
        ratio = "" if self.dynamic_ratio is None else f", torsion_mu_d = {self.dynamic_ratio:g} x torsion_mu_s"
        return f"{self.model}, {law}{ratio}"


MUJOCO_NEWCOMER = MujocoSetup()
MUJOCO_BEST_4 = MujocoSetup(4, "elliptic", 100.0, 3)
MUJOCO_BEST_6 = MujocoSetup(6, "elliptic", 100.0, 3)
PYBULLET_NEWCOMER = PybulletSetup()
PYBULLET_BEST = PybulletSetup(friction_anchor=True, solver_iterations=150)

SETUPS = {
    "mujoco newcomer": MUJOCO_NEWCOMER,
    "mujoco elliptic, no noslip": MujocoSetup(4, "elliptic", 100.0, 0),
    "mujoco best condim 4": MUJOCO_BEST_4,
    "mujoco best condim 6": MUJOCO_BEST_6,
    "pybullet newcomer": PYBULLET_NEWCOMER,
    "pybullet best": PYBULLET_BEST,
    "softproxy power law": SoftproxySetup("CH", False),
    "softproxy saturating law": SoftproxySetup("CH", True),
    "softproxy point": SoftproxySetup("point"),
}
LIMIT_RUNS = ("mujoco newcomer", "mujoco best condim 4", "mujoco best condim 6", "pybullet best",
              "drake hydroelastic", "softproxy power law", "softproxy saturating law")
"""Whose torsional limit is measured against grip (point contacts have none)."""


def pybullet_available() -> bool:
    try:
        import pybullet  # noqa: F401
    except ImportError:
        return False
    return True


# ---------------------------------------------------------------------------------
# Rigs: one grasp in one engine, stepped 1 ms at a time. Every rig offers the same handles:
# step(t) (timed), quat() (w, x, y, z), height(), spin() (rad/s about the grasp axis),
# apply(torque) (N·m about the grasp axis, held until changed), inertia (kg·m² about it),
# damping (N·m·s/rad: the box joint's own viscous damping, the scene's 0.001).
# ---------------------------------------------------------------------------------
def _finger_start(gravity: bool) -> tuple[float, float]:
    """Where the right finger starts (x, y; the left mirrors it in x), m. The hold starts as
    the scene does (6 cm out, 2 cm off the centre of mass). The torsion tests (no gravity)
    start 0.5 mm from the box, so that a light grip is in contact by the end of the squeeze,
    and pinch on the centre of mass: the external torque then turns the box about the grasp
    line itself, the contacts do not move sideways, and only their torsion resists it."""
    if gravity:
        return 0.06, 0.02
    return BOX_HALF[0] + FINGER_RADIUS + 0.0005, 0.0


def _grip_ramp(t: float, grip: float) -> float:
    """The squeeze: 0 until 0.2 s, up to `grip` at 0.5 s (N)."""
    return grip * min(max((t - 0.2) / 0.3, 0.0), 1.0)


class _Path:
    """The scene's scripted device path (y, z per finger), or the fingers kept still."""

    def __init__(self, still: bool):
        self.still = still
        if not still:
            scene = load_scene(SCENE)
            self.device = open_device("sim", scene)
            self.samples = [DeviceSample(), DeviceSample()]

    def targets(self, t: float) -> tuple[float, float, float, float]:
        """(y, z) displacements of the right and left finger from their start (m)."""
        if self.still:
            return 0.0, 0.0, 0.0, 0.0
        self.device.read(t, self.samples)
        r, l = self.samples
        return r.y - 0.02, r.z - 0.03, l.y - 0.02, l.z - 0.03


class _MujocoBox:
    """A rig whose box MuJoCo simulates: the box's orientation, height, spin about the grasp
    axis (rad/s) and a torque on it (N·m), read from and written to its mjData."""

    def _find_box(self, model, data) -> None:
        self.data = data
        box = model.body("box").id
        self.box, self.dof = box, model.body_dofadr[box] + 3  # the free joint's spin about the box's x
        self.inertia = float(model.body_inertia[box][0])
        self.damping = float(model.dof_damping[self.dof])

    def quat(self):
        return self.data.xquat[self.box].copy()

    def height(self) -> float:
        return float(self.data.xpos[self.box][2])

    def spin(self) -> float:
        return float(self.data.qvel[self.dof])  # local x = the grasp axis while the box turns about it

    def apply(self, torque: float) -> None:
        self.data.qfrc_applied[self.dof] = torque


class MujocoRig(_MujocoBox):
    """The grasp as a MuJoCo user builds it: slide-jointed sphere fingers, MuJoCo's contact."""

    def __init__(self, setup: MujocoSetup, grip: float, gravity: bool, coefficient: float):
        self.m = mujoco.MjModel.from_xml_string(mujoco_xml(setup, gravity, coefficient))
        self._find_box(self.m, mujoco.MjData(self.m))
        self.grip, self.path = grip, _Path(still=not gravity)

    def step(self, t: float) -> float:
        g = _grip_ramp(t, self.grip)
        ry, rz, ly, lz = self.path.targets(t)
        self.data.ctrl[:] = (-g, ry, rz, g, ly, lz)
        start = time.perf_counter()
        mujoco.mj_step(self.m, self.data)
        return time.perf_counter() - start


def mujoco_xml(setup: MujocoSetup, gravity: bool, coefficient: float) -> str:
    """The grasp scene rebuilt with MuJoCo fingers instead of softproxy proxies."""
    friction = f'condim="{setup.condim}" friction="1 {coefficient:.6g} 0.0001"'
    bodies, actuators = "", ""
    x0, y0 = _finger_start(gravity)
    for name, x in (("right", x0), ("left", -x0)):
        bodies += (
            f'<body name="{name}" pos="{x} {y0} 0.03" gravcomp="1">'
            f'<joint name="{name}_x" type="slide" axis="1 0 0" damping="{X_DAMPING}"/>'
            f'<joint name="{name}_y" type="slide" axis="0 1 0"/><joint name="{name}_z" type="slide" axis="0 0 1"/>'
            f'<geom type="sphere" size="{FINGER_RADIUS}" mass="{FINGER_MASS}" {friction}/></body>'
        )
        actuators += (f'<motor joint="{name}_x"/><position joint="{name}_y" kp="{KP}" kv="{KV}"/>'
                      f'<position joint="{name}_z" kp="{KP}" kv="{KV}"/>')
    # without gravity the floor is out of play: no contact, so only the fingers hold the box
    g, floor = ("0 0 -9.81", "") if gravity else ("0 0 0", ' contype="0" conaffinity="0"')
    bx, by, bz = BOX_HALF
    return (
        f'<mujoco><option timestep="0.001" cone="{setup.cone}" impratio="{setup.impratio}" '
        f'noslip_iterations="{setup.noslip_iterations}" integrator="implicitfast" gravity="{g}"/>'
        f'<worldbody><geom name="floor" type="plane" size=".4 .4 .01"{floor}/>'
        f'<body name="box" pos="0 0 {bz}"><joint type="free" damping="{BOX_DAMPING}"/><geom name="box" type="box" size="{bx} {by} {bz}" '
        f'mass="{BOX_MASS}" {friction}/></body>'
        f"{bodies}</worldbody><actuator>{actuators}</actuator></mujoco>"
    )


class PybulletRig:
    """The same grasp in PyBullet: each finger a chain of three prismatic joints ending in the
    sphere, driven by joint forces (the squeeze, and a PD servo like MuJoCo's `position`)."""

    def __init__(self, setup: PybulletSetup, grip: float, gravity: bool, coefficient: float):
        import pybullet as pb

        self.pb, self.grip, self.path = pb, grip, _Path(still=not gravity)
        self.client = c = pb.connect(pb.DIRECT)
        pb.setTimeStep(0.001, physicsClientId=c)
        pb.setGravity(0, 0, -9.81 if gravity else 0.0, physicsClientId=c)
        pb.setPhysicsEngineParameter(numSolverIterations=setup.solver_iterations,
                                     enableConeFriction=setup.cone_friction, physicsClientId=c)
        anchor = int(setup.friction_anchor)
        if gravity:
            plane = pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=c), physicsClientId=c)
            pb.changeDynamics(plane, -1, lateralFriction=1.0, physicsClientId=c)
        shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=list(BOX_HALF), physicsClientId=c)
        self.box = pb.createMultiBody(BOX_MASS, shape, basePosition=[0, 0, BOX_HALF[2]], physicsClientId=c)
        # Bullet combines spinning friction as s_a·f_b + s_b·f_a: with the box's lateral friction
        # 1 and spinning 0, a contact's torsional coefficient is the finger's spinning friction
        pb.changeDynamics(self.box, -1, lateralFriction=1.0, spinningFriction=0.0, rollingFriction=0.0,
                          frictionAnchor=anchor, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
        self.inertia = float(pb.getDynamicsInfo(self.box, -1, physicsClientId=c)[2][0])
        self.damping = BOX_DAMPING  # Bullet has no joint damping on a free body: added in step()
        sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=FINGER_RADIUS, physicsClientId=c)
        self.fingers = []
        x0, y0 = _finger_start(gravity)
        for x in (x0, -x0):
            f = pb.createMultiBody(
                0, -1, -1, basePosition=[x, y0, 0.03],
                linkMasses=[0.005, 0.005, FINGER_MASS], linkCollisionShapeIndices=[-1, -1, sphere],
                linkVisualShapeIndices=[-1] * 3, linkPositions=[[0, 0, 0]] * 3, linkOrientations=[[0, 0, 0, 1]] * 3,
                linkInertialFramePositions=[[0, 0, 0]] * 3, linkInertialFrameOrientations=[[0, 0, 0, 1]] * 3,
                linkParentIndices=[0, 1, 2], linkJointTypes=[pb.JOINT_PRISMATIC] * 3,
                linkJointAxis=[[1, 0, 0], [0, 1, 0], [0, 0, 1]], physicsClientId=c)
            pb.changeDynamics(f, 2, lateralFriction=1.0, spinningFriction=coefficient, rollingFriction=0.0,
                              frictionAnchor=anchor, physicsClientId=c)
            for link in range(3):
                pb.changeDynamics(f, link, linearDamping=0.0, angularDamping=0.0, physicsClientId=c)
            # joint motors are on by default in PyBullet: off, so only our forces act
            pb.setJointMotorControlArray(f, [0, 1, 2], pb.VELOCITY_CONTROL, forces=[0, 0, 0], physicsClientId=c)
            self.fingers.append(f)
        self.weight = FINGER_MASS * (9.81 if gravity else 0.0)  # what the z joint holds up (gravcomp)
        self.torque = 0.0

    def step(self, t: float) -> float:
        pb, c = self.pb, self.client
        g = _grip_ramp(t, self.grip)
        ry, rz, ly, lz = self.path.targets(t)
        for f, sign, (ty, tz) in ((self.fingers[0], -1.0, (ry, rz)), (self.fingers[1], 1.0, (ly, lz))):
            (qx, vx, *_), (qy, vy, *_), (qz, vz, *_) = pb.getJointStates(f, [0, 1, 2], physicsClientId=c)
            forces = [sign * g - X_DAMPING * vx, KP * (ty - qy) - KV * vy, KP * (tz - qz) - KV * vz + self.weight]
            pb.setJointMotorControlArray(f, [0, 1, 2], pb.TORQUE_CONTROL, forces=forces, physicsClientId=c)
        w = pb.getBaseVelocity(self.box, physicsClientId=c)[1]
        torque = [self.torque - self.damping * w[0], -self.damping * w[1], -self.damping * w[2]]
        pb.applyExternalTorque(self.box, -1, torque, pb.WORLD_FRAME, physicsClientId=c)
        start = time.perf_counter()
        pb.stepSimulation(physicsClientId=c)
        return time.perf_counter() - start

    def quat(self):
        x, y, z, w = self.pb.getBasePositionAndOrientation(self.box, physicsClientId=self.client)[1]
        return np.array([w, x, y, z])

    def height(self) -> float:
        return float(self.pb.getBasePositionAndOrientation(self.box, physicsClientId=self.client)[0][2])

    def spin(self) -> float:
        return float(self.pb.getBaseVelocity(self.box, physicsClientId=self.client)[1][0])

    def apply(self, torque: float) -> None:
        self.torque = torque  # PyBullet clears external forces after every step: re-applied in step()

    def close(self) -> None:
        self.pb.disconnect(physicsClientId=self.client)


# Drake: hydroelastic contact (the finger a compliant sphere, the box rigid), SAP solver.
DRAKE_EXTRA = "drake"
FINGERTIP_CONTACT = ((0.78, 87.36e-6), (1.03, 124.4e-6), (1.71, 132.8e-6))
"""(force N, contact area m²) of a fingertip pressed on a flat plate, the averages of Tables 1-2
of *A preliminary approach to study the behavior of human fingertip at contact via
experimental test and numerical model*: what Drake's soft sphere is fitted to."""
DRAKE_RESOLUTION = 0.004     # m: the sphere's tessellation hint; 2 mm gives the same limits within 0.3% at 3x the cost
DRAKE_FLOOR_MODULUS = 1e7    # Pa: the floor's hydroelastic modulus, stiff beside the finger
DRAKE_FLOOR_SLAB = 0.02      # m: the floor a compliant box this thick (0.8 m square), its top at z = 0


@dataclass(frozen=True)
class DrakeSetup:
    """Drake's MultibodyPlant, discrete step `time_step` (s), contact approximation `solver`
    ("sap"; "lagged" and "similar" take `stiction_tolerance`, m/s), hydroelastic contact: each
    finger a compliant-hydroelastic sphere of modulus `modulus` (Pa; None: fitted to the
    fingertip's contact radii, `drake_modulus()`), the box rigid-hydroelastic."""

    solver: str = "sap"
    modulus: float | None = None
    time_step: float = 1e-3
    stiction_tolerance: float | None = None

    def options(self) -> str:
        e = drake_modulus() if self.modulus is None else self.modulus
        stiction = "" if self.stiction_tolerance is None else f", stiction_tolerance {self.stiction_tolerance:g}"
        return (f"MultibodyPlant time_step {self.time_step:g}, contact_model hydroelastic, "
                f"discrete_contact_approximation {self.solver}{stiction}; finger: compliant hydroelastic sphere, "
                f"modulus {e / 1e6:.4f} MPa (fitted to a fingertip's contact radii), resolution_hint "
                f"{DRAKE_RESOLUTION * 1e3:g} mm, y and z on PD-controlled actuators; box: rigid hydroelastic; "
                f"floor: compliant hydroelastic slab, {DRAKE_FLOOR_MODULUS:g} Pa")


SETUPS["drake hydroelastic"] = DrakeSetup()


def drake_available() -> bool:
    try:
        import pydrake.multibody.plant  # noqa: F401
    except ImportError:
        return False
    return True


def _sphere_pressed(modulus: float, force: float, radius: float = FINGER_RADIUS):
    """A hydroelastic sphere (pressure E·(1 − |x|/R)) pressed on a rigid plane with `force` (N):
    its penetration (m), contact radius (m) and, per unit friction coefficient, the torque its
    pressure resists about the normal (∫ p r dA, N·m)."""
    from scipy.integrate import quad
    from scipy.optimize import brentq

    def pressure(r, d):
        return modulus * (1.0 - math.hypot(r, radius - d) / radius)

    def load(d):
        a = math.sqrt(max(2 * radius * d - d * d, 0.0))
        return quad(lambda r: pressure(r, d) * 2 * math.pi * r, 0.0, a)[0]

    d = brentq(lambda x: load(x) - force, 1e-12, radius)
    a = math.sqrt(2 * radius * d - d * d)
    return d, a, quad(lambda r: pressure(r, d) * 2 * math.pi * r * r, 0.0, a)[0]


def drake_capacity(modulus: float, radius: float = FINGER_RADIUS) -> float:
    """The largest load (N) the hydroelastic sphere carries on a plane: πER²/3, when the plane
    reaches its centre; pressed harder it goes through."""
    return math.pi * modulus * radius * radius / 3.0


@functools.cache
def drake_modulus(radius: float = FINGER_RADIUS) -> float:
    """Hydroelastic modulus (Pa) for which a sphere of `radius` has the fingertip's measured
    contact radii at the measured forces (`FINGERTIP_CONTACT`; least squares on the radius)."""
    from scipy.optimize import minimize_scalar

    def misfit(log_e):
        return sum((_sphere_pressed(math.exp(log_e), f, radius)[1] - math.sqrt(area / math.pi)) ** 2
                   for f, area in FINGERTIP_CONTACT)

    return math.exp(minimize_scalar(misfit, bounds=(math.log(3e4), math.log(1e6)), method="bounded").x)


def drake_peer_mu(setup: DrakeSetup = DrakeSetup()) -> float:
    """Drake's Coulomb μ by the peers' rule: its soft sphere pressed with the grasp's grip resists
    softproxy's default limit there (the pressure's torque per unit μ, `_sphere_pressed`)."""
    modulus = setup.modulus or drake_modulus()
    return default_limit(GRIP_N) / _sphere_pressed(modulus, GRIP_N)[2]


class DrakeRig:
    """The grasp in Drake, built as its user builds it: each finger a sphere on three prismatic
    joints (links of 5 g, 5 g and the 10 g finger, as in PyBullet), the squeeze a force on the
    x joint (with the peers' joint damping), y and z driven by Drake's own PD-controlled
    actuators (kp, kv as the peers'; SAP takes them implicitly) plus the finger's weight (as
    MuJoCo's gravcomp); the box a free body. With gravity the floor is a compliant-hydroelastic
    slab, so every contact is hydroelastic. The box's own damping (the scene's 0.001
    N·m·s/rad, about every axis) is added to the applied torque."""

    def __init__(self, setup: DrakeSetup, grip: float, gravity: bool, mu: float):
        from pydrake.geometry import (AddCompliantHydroelasticProperties,
                                      AddContactMaterial, AddRigidHydroelasticProperties, Box,
                                      ProximityProperties, Sphere)
        from pydrake.math import RigidTransform
        from pydrake.multibody.plant import (AddMultibodyPlant, CoulombFriction, ExternallyAppliedSpatialForce,
                                             MultibodyPlantConfig)
        from pydrake.multibody.tree import FixedOffsetFrame, PdControllerGains, PrismaticJoint, SpatialInertia
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder

        self.grip, self.path = grip, _Path(still=not gravity)
        builder = DiagramBuilder()
        config = MultibodyPlantConfig(time_step=setup.time_step, contact_model="hydroelastic",
                                      discrete_contact_approximation=setup.solver)
        if setup.stiction_tolerance is not None:
            config.stiction_tolerance = setup.stiction_tolerance
        plant, _ = AddMultibodyPlant(config, builder)
        if not gravity:
            plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, 0.0])
        friction = CoulombFriction(mu, mu)  # one coefficient: SAP reads only the dynamic one anyway
        bx, by, bz = BOX_HALF
        self.body = box = plant.AddRigidBody("box", SpatialInertia.SolidBoxWithMass(BOX_MASS, 2 * bx, 2 * by, 2 * bz))
        rigid = ProximityProperties()
        AddRigidHydroelasticProperties(DRAKE_RESOLUTION, rigid)
        AddContactMaterial(friction=friction, properties=rigid)
        plant.RegisterCollisionGeometry(box, RigidTransform(), Box(2 * bx, 2 * by, 2 * bz), "box", rigid)
        if gravity:  # without gravity the floor is out of play, as in the other rigs
            floor = ProximityProperties()
            AddCompliantHydroelasticProperties(DRAKE_FLOOR_SLAB, DRAKE_FLOOR_MODULUS, floor)
            AddContactMaterial(dissipation=1.0, friction=CoulombFriction(1.0, 1.0), properties=floor)
            plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform([0.0, 0.0, -DRAKE_FLOOR_SLAB / 2]),
                                            Box(0.8, 0.8, DRAKE_FLOOR_SLAB), "floor", floor)
        soft = ProximityProperties()
        AddCompliantHydroelasticProperties(DRAKE_RESOLUTION, setup.modulus or drake_modulus(), soft)
        AddContactMaterial(dissipation=1.0, friction=friction, properties=soft)
        x0, y0 = _finger_start(gravity)
        gains = PdControllerGains(p=KP, d=KV)
        for name, x in (("right", x0), ("left", -x0)):
            parent = plant.AddFrame(FixedOffsetFrame(f"{name}_anchor", plant.world_frame(),
                                                     RigidTransform([x, y0, BOX_HALF[2]])))
            for axis, mass in (("x", 0.005), ("y", 0.005), ("z", FINGER_MASS)):
                link = plant.AddRigidBody(f"{name}_{axis}", SpatialInertia.SolidSphereWithMass(mass, FINGER_RADIUS))
                unit = [float(axis == a) for a in "xyz"]
                joint = plant.AddJoint(PrismaticJoint(f"{name}_{axis}", parent, link.body_frame(), unit,
                                                      damping=X_DAMPING if axis == "x" else 0.0))
                actuator = plant.AddJointActuator(f"{name}_{axis}", joint)
                if axis != "x":
                    actuator.set_controller_gains(gains)
                parent = link.body_frame()
            plant.RegisterCollisionGeometry(link, RigidTransform(), Sphere(FINGER_RADIUS), name, soft)
        plant.Finalize()
        self.plant = plant
        self.simulator = Simulator(builder.Build())
        self.context = plant.GetMyMutableContextFromRoot(self.simulator.get_mutable_context())
        plant.SetFreeBodyPose(self.context, box, RigidTransform([0.0, 0.0, BOX_HALF[2]]))
        self.force = ExternallyAppliedSpatialForce()
        self.force.body_index = box.index()
        self._applied = plant.get_applied_spatial_force_input_port()
        self._actuation = plant.get_actuation_input_port()
        self._desired = plant.get_desired_state_input_port(box.model_instance())
        self.inertia = BOX_MASS * ((2 * by) ** 2 + (2 * bz) ** 2) / 12.0
        self.damping = BOX_DAMPING
        self.weight = FINGER_MASS * (9.81 if gravity else 0.0)  # what the z joint holds up (gravcomp)
        self.torque = 0.0
        self.simulator.Initialize()

    def step(self, t: float) -> float:
        from pydrake.multibody.math import SpatialForce

        g = _grip_ramp(t, self.grip)
        ry, rz, ly, lz = self.path.targets(t)
        # actuators in the order added: right x, y, z, left x, y, z; the desired state is
        # [q (6), v (6)], its x entries unused (the squeeze is a force)
        self._actuation.FixValue(self.context, [-g, 0.0, self.weight, g, 0.0, self.weight])
        self._desired.FixValue(self.context, [0.0, ry, rz, 0.0, ly, lz] + [0.0] * 6)
        wx, wy, wz = self._omega()
        self.force.F_Bq_W = SpatialForce([self.torque - self.damping * wx, -self.damping * wy, -self.damping * wz],
                                         [0.0, 0.0, 0.0])
        self._applied.FixValue(self.context, [self.force])
        start = time.perf_counter()
        self.simulator.AdvanceTo(t + 1e-3)
        return time.perf_counter() - start

    def _omega(self):
        return self.plant.EvalBodySpatialVelocityInWorld(self.context, self.body).rotational()

    def quat(self):
        return self.plant.EvalBodyPoseInWorld(self.context, self.body).rotation().ToQuaternion().wxyz()

    def height(self) -> float:
        return float(self.plant.EvalBodyPoseInWorld(self.context, self.body).translation()[2])

    def spin(self) -> float:
        return float(self._omega()[0])

    def apply(self, torque: float) -> None:
        self.torque = torque


class SoftproxyRig(_MujocoBox):
    """The grasp scene itself: two soft-finger proxies on the simulated device."""

    def __init__(self, setup: SoftproxySetup, grip: float, gravity: bool):
        scene = load_scene(SCENE)
        scene.fingers = [replace(f, model=setup.model, saturate=setup.saturate) for f in scene.fingers]
        if setup.dynamic_ratio is not None:
            mu_s = [f.torsion_mu_s if f.torsion_mu_s is not None else fingertip.model(f.model).mu_prime
                    for f in scene.fingers]
            scene.fingers = [replace(f, torsion_mu_s=s, torsion_mu_d=setup.dynamic_ratio * s)
                             for f, s in zip(scene.fingers, mu_s)]
        if not gravity:
            _zero_gravity_keyframes(scene, grip)
        self.loop = loop = build(scene, open_device("sim", scene), audit=False, realtime=False)
        world = loop.world
        if not gravity:
            world.model.opt.gravity[:] = 0.0
            floor = world.model.geom("floor").id
            world.model.geom_contype[floor] = world.model.geom_conaffinity[floor] = 0  # only the fingers hold it
        self._find_box(world.model, world.data)

    def step(self, t: float) -> float:
        start = time.perf_counter()
        self.loop.tick()
        return time.perf_counter() - start

    @property
    def dynamic_ratio(self) -> float | None:
        """The fingers' setting μ_d/μ_s of torsional friction (the input the slide measures against)."""
        t = self.loop.fingers[0].torsion
        return None if t is None or t.mu_s == 0.0 else t.mu_d / t.mu_s


def _zero_gravity_keyframes(scene, grip: float) -> None:
    """Device keyframes that squeeze the box to `grip` per finger by 0.5 s and stay still,
    pinching on the centre of mass (as `_finger_start` does for the peers)."""
    f0 = scene.fingers[0]
    depth = grip / f0.stiffness
    for finger in scene.device["finger"]:
        sign = 1.0 if finger["keyframes"][0][1] > 0 else -1.0
        x = sign * (BOX_HALF[0] + f0.radius - depth)
        finger["keyframes"] = [[0.0, sign * 0.06, 0.0, 0.03, 0.0], [0.5, x, 0.0, 0.03, 0.0]]


def make_rig(name, grip: float = GRIP_N, gravity: bool = True, coefficient: float | None = None):
    """The rig for SETUPS[name] (or for `name` itself, a setup); `coefficient` overrides a
    peer's torsional coefficient (m)."""
    setup = SETUPS[name] if isinstance(name, str) else name
    c = peer_coefficient() if coefficient is None else coefficient
    if isinstance(setup, MujocoSetup):
        return MujocoRig(setup, grip, gravity, c)
    if isinstance(setup, PybulletSetup):
        return PybulletRig(setup, grip, gravity, c)
    if isinstance(setup, DrakeSetup):  # its coefficient is Coulomb's μ, not a length
        return DrakeRig(setup, grip, gravity, drake_peer_mu(setup) if coefficient is None else coefficient)
    return SoftproxyRig(setup, grip, gravity)


def _close(rig) -> None:
    if hasattr(rig, "close"):
        rig.close()


# ---------------------------------------------------------------------------------
# The hold: gravity on, squeeze, lift 5 cm, hold; rotation about the grasp axis from 0.8 s
# ---------------------------------------------------------------------------------
def hold(name: str, duration: float, coefficient: float | None = None) -> dict:
    """Rotation trace [(s, deg, height m)] every 10 ms, and the p50 cost of a step (µs), each
    engine timed the fastest way its user has: softproxy's compiled servo loop (its tick
    statistics), MuJoCo's `mj_step(m, d, nstep=10)` on the held grasp after the hold (no
    Python call per step), PyBullet's `stepSimulation` and Drake's `Simulator.AdvanceTo` (one
    call per step; their inputs are set in Python, outside the timing). The p50, not the
    mean: on a shared machine the mean carries other processes' preemptions. `coefficient`
    overrides a peer's torsional coefficient (as in `make_rig`)."""
    rig = make_rig(name, coefficient=coefficient)
    n = int(round(duration * 1000))
    try:
        if isinstance(rig, SoftproxyRig):
            quats, heights = _softproxy_run(rig, n)
            step_s = float(np.median(rig.loop.stats.durations()))
        else:
            quats, heights, cost = [], [], []
            for i in range(n):
                cost.append(rig.step(i * 1e-3))
                if i % 10 == 0:
                    quats.append(rig.quat())
                    heights.append(rig.height())
            step_s = _mujoco_step_cost(rig) if isinstance(rig, MujocoRig) else float(np.median(cost))
    finally:
        _close(rig)
    start = int(math.ceil(SQUEEZE_END_S * 100))  # every 10 ms: sample k is t = k / 100 s
    q0 = quats[start]
    trace = [(k / 100.0, _rotation_about(q0, quats[k], AXIS), float(heights[k])) for k in range(start, len(quats))]
    return {"trace": trace, "step_us": step_s * 1e6}


def _mujoco_step_cost(rig: MujocoRig, calls: int = 300, nstep: int = 10) -> float:
    """p50 cost of one MuJoCo step on the grasp as it is now, 10 steps a call (s)."""
    cost = np.empty(calls)
    for k in range(calls):
        start = time.perf_counter()
        mujoco.mj_step(rig.m, rig.data, nstep)
        cost[k] = time.perf_counter() - start
    return float(np.median(cost)) / nstep


def _softproxy_run(rig: SoftproxyRig, n: int):
    """Box orientation and height every 10 ticks from softproxy's servo loop, run in
    compiled blocks of 10 ticks."""
    quats, heights = [rig.quat()], [rig.height()]  # the state before the first tick, like the others

    def on_tick(loop):
        if len(quats) * 10 <= loop.ticks:
            quats.append(rig.quat())
            heights.append(rig.height())

    rig.loop.run(n, on_tick=on_tick, every=10)
    return quats, heights


def summarise(trace: list) -> dict:
    """End and largest rotation (deg), creep (deg/s over the last 2 s), end height (m)."""
    t = np.array([p[0] for p in trace])
    a = np.array([p[1] for p in trace])
    last = t >= t[-1] - CREEP_WINDOW_S
    creep = float(np.polyfit(t[last], a[last], 1)[0]) if last.sum() > 2 else 0.0
    return {"rotation_end_deg": float(a[-1]), "rotation_max_deg": float(np.abs(a).max()),
            "creep_deg_per_s": creep, "height_end_m": float(trace[-1][2])}


# ---------------------------------------------------------------------------------
# Torsional limit: zero gravity, the fingers still, an external torque about the grasp axis
# rising from 0.8 s. The torque the contacts transmit is read off the box's angular momentum
# balance (τ_contacts = I dω/dt + c ω − τ_applied, dω/dt over a 5 ms window), the same measure
# in every engine (in MuJoCo it agrees with mj_contactForce's torsional component within 3%);
# the limit (break-away torque) is its largest value before the box turns faster than
# SLIP_SPEED. Past that a soft contact's resistance grows with the slip speed (MuJoCo's
# does), so the peak over a longer spin would measure viscosity, not the friction limit.
# ---------------------------------------------------------------------------------
RAMP_PER_N = 0.025          # N·m/s of torque rise per N of grip: every grip reaches its limit in ~1 s
WINDOW = 5                  # steps of the dω/dt estimate
SLIP_SPEED = 0.5            # rad/s (29°/s): a contact turning this fast slips
STILL_SPEED = 0.05          # rad/s: slower than this a contact is stuck again (a compliant one still
                            # turns elastically as its load changes: softproxy ~0.02 rad/s here)
STILL_FOR_S = 0.3           # ... for this long


class _Transmitted:
    """The contacts' torque about the grasp axis from the box's momentum balance (N·m):
    I dω/dt = τ_applied − c ω + τ_contacts, with c the box joint's damping."""

    def __init__(self, inertia: float, damping: float):
        self.inertia, self.damping, self.omega, self.applied = inertia, damping, [], []

    def __call__(self, omega: float, applied: float) -> float:
        self.omega.append(omega)
        self.applied.append(applied)
        if len(self.omega) <= WINDOW:
            return 0.0
        rate = (self.omega[-1] - self.omega[-1 - WINDOW]) / (WINDOW * 1e-3)
        applied = float(np.mean(self.applied[-WINDOW:])) - self.damping * float(np.mean(self.omega[-WINDOW:]))
        return abs(self.inertia * rate - applied)


class _Twist:
    """A torsion run: the rig squeezes the box untwisted until SQUEEZE_END_S, then steps 1 ms
    at a time under the torque about the grasp axis set in `torque` (N·m) before each step.
    Iterating gives, after each step past the squeeze, (t s, the box's spin rad/s, the torque
    the contacts transmit N·m)."""

    def __init__(self, rig, seconds: float):
        self.rig, self.seconds, self.torque = rig, seconds, 0.0

    def __iter__(self):
        rig = self.rig
        transmitted = _Transmitted(rig.inertia, rig.damping)
        for i in range(int(round((SQUEEZE_END_S + self.seconds) * 1000))):
            t = i * 1e-3
            torque = self.torque if t > SQUEEZE_END_S else 0.0
            rig.apply(torque)
            rig.step(t)
            if t > SQUEEZE_END_S:
                w = rig.spin()
                yield t, w, transmitted(w, torque)


def limit(name: str, grip: float, coefficient: float | None = None, seconds: float = 4.0) -> float:
    """The largest torque the two contacts transmit at `grip` per finger before they slip (N·m)."""
    rig = make_rig(name, grip, gravity=False, coefficient=coefficient)
    rate = RAMP_PER_N * grip
    twist, peak = _Twist(rig, seconds), 0.0
    twist.torque = rate * 1e-3  # the ramp from SQUEEZE_END_S, at the first step after it
    try:
        for t, w, now in twist:
            if abs(w) > SLIP_SPEED:
                break
            peak = max(peak, now)
            twist.torque = (t + 1e-3 - SQUEEZE_END_S) * rate
    finally:
        _close(rig)
    return peak


def hysteresis(name: str, grip: float = GRIP_N, seconds: float = 6.0) -> dict:
    """Slip, then unload: break-away torque, the sliding torque and the applied torque at
    which the contact re-sticks (still for 0.3 s), as fractions of the break-away torque."""
    rig = make_rig(name, grip, gravity=False)
    rate = RAMP_PER_N * grip
    twist = _Twist(rig, seconds)
    twist.torque = rate * 1e-3  # up at `rate` from SQUEEZE_END_S; down at it once slipping
    peak, slipped_at, sliding, restick, still_since = 0.0, None, [], None, None
    try:
        for t, w, now in twist:
            if slipped_at is None:
                peak = max(peak, now)
                if abs(w) > SLIP_SPEED:
                    slipped_at = t
            elif abs(w) > SLIP_SPEED:
                sliding.append(now)
            elif abs(w) < STILL_SPEED:
                still_since = t if still_since is None else still_since
                if t - still_since >= STILL_FOR_S:
                    restick = still_since
                    break
            else:
                still_since = None
            twist.torque = max(twist.torque + (rate if slipped_at is None else -rate) * 1e-3, 0.0)
    finally:
        _close(rig)
    out = {"breakaway_Nm": peak, "slipped": slipped_at is not None, "resticks": restick is not None,
           "sliding_over_breakaway": None, "restick_over_breakaway": None}
    if sliding and peak > 0:
        out["sliding_over_breakaway"] = float(np.median(sliding)) / peak
    if restick is not None and peak > 0:
        # the applied torque when the contact stopped for good
        out["restick_over_breakaway"] = max(peak - (restick - slipped_at) * rate, 0.0) / peak
    return out


# ---------------------------------------------------------------------------------
# Dynamic friction, measured: the box slides steadily between the still fingers, its spin
# about the grasp axis held at SLIDE_SPEED by a PI servo on the external torque; the torque
# the contacts transmit while it slides (momentum balance, as above) over the break-away
# torque at the same grip (the peak of `hysteresis`'s ramp).
# ---------------------------------------------------------------------------------
SLIDE_SPEED = 1.0            # rad/s (57°/s): well past SLIP_SPEED, a twist a hand makes
SLIDE_SETTLE_S = 1.0         # s of servoed slide before the measurement
SLIDE_MEASURE_S = 0.5        # s measured
SLIDE_TIME_CONSTANT = 0.01   # s: the speed servo's proportional gain is inertia / this
SLIDE_INTEGRAL_S = 0.05      # s: its integral time


def steady_slide(name, grip: float = GRIP_N, speed: float = SLIDE_SPEED) -> dict:
    """Slide the box at `speed` (rad/s) between fingers gripping with `grip` (N each): the
    median torque the two contacts transmit while sliding (N·m), the spin measured (median,
    and its 5th–95th percentile, rad/s), and for softproxy the fingers' setting μ_d/μ_s."""
    rig = make_rig(name, grip, gravity=False)
    kp = rig.inertia / SLIDE_TIME_CONSTANT
    twist = _Twist(rig, SLIDE_SETTLE_S + SLIDE_MEASURE_S)
    integral, torques, spins = 0.0, [], []
    try:
        for t, w, now in twist:
            if t > SQUEEZE_END_S + SLIDE_SETTLE_S:
                torques.append(now)
                spins.append(w)
            error = speed - w
            integral += error * 1e-3
            twist.torque = kp * (error + integral / SLIDE_INTEGRAL_S)
        ratio = getattr(rig, "dynamic_ratio", None)
    finally:
        _close(rig)
    lo, mid, hi = np.percentile(spins, [5, 50, 95])
    return {"speed_set_rad_s": speed, "speed_rad_s": float(mid), "speed_p5_p95_rad_s": [float(lo), float(hi)],
            "sliding_Nm": float(np.median(torques)), "setting_dynamic_over_static": ratio}


def dynamic_friction(name, grip: float = GRIP_N, speed: float = SLIDE_SPEED) -> dict:
    """Break-away torque (ramp until the contact slips) and the torque of a steady slide at
    `speed`, and their ratio: the dynamic friction measured, beside the setting it comes from."""
    h = hysteresis(name, grip)
    slide = steady_slide(name, grip, speed)
    ratio = slide["sliding_Nm"] / h["breakaway_Nm"] if h["breakaway_Nm"] > 0 else None
    return {**h, "steady_slide": slide, "steady_sliding_over_breakaway": ratio}


# ---------------------------------------------------------------------------------
# Fidelity to the measured fingertip (seed 002, E3) over 0.1–3 N
# ---------------------------------------------------------------------------------
def relative_errors(limits, grips, reference=fingertip.e3_torque) -> dict:
    """RMS and largest |limit/reference − 1| over the grips (dimensionless)."""
    rel = np.array([v / reference(g) - 1.0 for v, g in zip(limits, grips)])
    return {"rms": float(np.sqrt(np.mean(rel ** 2))), "max": float(np.max(np.abs(rel)))}


def best_scale(limits, grips, reference=fingertip.e3_torque) -> float:
    """The factor s minimising Σ(s·limit/reference − 1)²: a peer's best single coefficient
    is its coefficient × s (least squares on the relative error, the figure reported)."""
    x = np.array([v / reference(g) for v, g in zip(limits, grips)])
    return float(x.sum() / (x * x).sum())


def exponent(grips, limits, low: float, high: float) -> float | None:
    """Slope of log(limit) against log(grip) over the grips in [low, high]."""
    pts = [(g, v) for g, v in zip(grips, limits) if low <= g <= high and v is not None and v > 0]
    if len(pts) < 2 or min(p[0] for p in pts) > low or max(p[0] for p in pts) < high:
        return None  # the range is not covered
    g, v = np.array(pts).T
    return float(np.polyfit(np.log(g), np.log(v), 1)[0])


LIMIT_GRIPS = (0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 8.0)
FIDELITY_RANGE = (0.1, 3.0)   # N: seed 002's measured range of E3 that the fidelity table covers


def measure(duration: float = 20.0, grips=LIMIT_GRIPS, progress=None, names=None) -> dict:
    """Every figure of the bench in one run (see the module docstring)."""
    names = [n for n in (names or SETUPS) if (pybullet_available() or not isinstance(SETUPS[n], PybulletSetup))
             and (drake_available() or not isinstance(SETUPS[n], DrakeSetup))]
    out = {"duration_s": duration, "grip_N": GRIP_N, "peer_torsion_coefficient_m": peer_coefficient(),
           "default_saturate": FingerParams().saturate, "pybullet": pybullet_available(), "drake": drake_available(),
           "setups": {n: SETUPS[n].options() for n in names}, "hold": {}, "traces": {}}
    for i, name in enumerate(names):
        if progress:
            progress(f"hold {i + 1}/{len(names)}: {name}")
        r = hold(name, duration)
        out["hold"][name] = {**summarise(r["trace"]), "step_us": r["step_us"]}
        out["traces"][name] = r["trace"]
    base = out["hold"].get("mujoco newcomer", {}).get("step_us")
    for h in out["hold"].values():
        h["cost_vs_mujoco_default"] = h["step_us"] / base if base else None
    limit_names = [n for n in LIMIT_RUNS if n in names]
    limits, statics = {}, {}
    for i, name in enumerate(limit_names):
        if progress:
            progress(f"torsion limit {i + 1}/{len(limit_names)}: {name}")
        # Drake's soft sphere carries no more than its capacity: no limit at a grip past 95% of it
        most = 0.95 * drake_capacity(SETUPS[name].modulus or drake_modulus()) \
            if isinstance(SETUPS[name], DrakeSetup) else math.inf
        limits[name] = [limit(name, g) / 2.0 if g < most else None for g in grips]  # per contact
        statics[name] = dynamic_friction(name)
    for name in (n for n in names if isinstance(SETUPS[n], DrakeSetup)):
        modulus = SETUPS[name].modulus or drake_modulus()
        out["drake_settings"] = {"name": name, "modulus_Pa": modulus, "capacity_N": drake_capacity(modulus),
                                 "mu": drake_peer_mu(SETUPS[name]), "time_step_s": SETUPS[name].time_step,
                                 "solver": SETUPS[name].solver}
    out["limit_per_contact_Nm"] = {"grip_N": list(grips), **limits}
    out["limit_exponent"] = {n: {"0.1-2 N": exponent(grips, v, 0.1, 2.0), "0.5-8 N": exponent(grips, v, 0.5, 8.0)}
                             for n, v in limits.items()}
    out["static_dynamic"] = statics
    out["slide_settings"] = {"grip_N": GRIP_N, "speed_rad_s": SLIDE_SPEED, "settle_s": SLIDE_SETTLE_S,
                             "measured_s": SLIDE_MEASURE_S, "gravity": False,
                             "breakaway": f"torque ramped at {RAMP_PER_N * GRIP_N:g} N·m/s until the box turns "
                                          f"faster than {SLIP_SPEED:g} rad/s"}
    out["fidelity"] = fidelity(limits, grips, progress)
    return out


def fidelity(limits: dict, grips, progress=None) -> dict:
    """Each engine's per-contact limit against E3 over 0.1–3 N; the peers refitted with their
    best coefficient and measured again; the laws themselves for reference."""
    lo, hi = FIDELITY_RANGE
    inside = [g for g in grips if lo <= g <= hi]
    rows = {}
    for name, vals in limits.items():
        v = [x for x, g in zip(vals, grips) if lo <= g <= hi]
        if isinstance(SETUPS[name], SoftproxySetup):
            rows[name] = {**relative_errors(v, inside), "coefficient": "Simulating human fingers, Table 1", "limit_Nm": v}
            continue
        if isinstance(SETUPS[name], DrakeSetup):  # Coulomb's μ scales its pressure's torque
            mu = drake_peer_mu(SETUPS[name]) * best_scale(v, inside)
            if progress:
                progress(f"fidelity: {name} at its best friction coefficient {mu:.2f}")
            refit = [limit(name, g, coefficient=mu) / 2.0 for g in inside]
            rows[name] = {**relative_errors(refit, inside), "coefficient_mu": mu, "limit_Nm": refit}
            continue
        c = peer_coefficient() * best_scale(v, inside)
        if progress:
            progress(f"fidelity: {name} at its best coefficient {c * 1e3:.2f} mm")
        refit = [limit(name, g, coefficient=c) / 2.0 for g in inside]
        rows[name] = {**relative_errors(refit, inside), "coefficient_m": c, "limit_Nm": refit}
    law = default_law()  # the laws themselves, on the same grips
    slope = best_scale(list(inside), inside)
    rows["law: power (μ'P^γ)"] = relative_errors([law.torque_limit(g) for g in inside], inside)
    rows["law: saturating"] = relative_errors([law.piecewise_torque(g) for g in inside], inside)
    rows["law: best linear (cP)"] = {**relative_errors([slope * g for g in inside], inside), "coefficient_m": slope}
    return {"range_N": [lo, hi], "grips_N": inside, "rows": rows}


# ---------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------
COLOURS = {"mujoco newcomer": "tab:red", "mujoco elliptic, no noslip": "tab:orange",
           "mujoco best condim 4": "tab:blue", "mujoco best condim 6": "tab:cyan",
           "pybullet newcomer": "tab:brown", "pybullet best": "tab:purple",
           "softproxy power law": "tab:olive", "softproxy saturating law": "tab:green", "softproxy point": "tab:gray",
           "drake hydroelastic": "tab:pink"}


DASHED = {"mujoco best condim 6", "pybullet newcomer", "softproxy power law"}
"""Drawn dashed: each lies on another setup's curve in some panel (condim 4, PyBullet best, eq 26)."""


def chart(result: dict):
    """Hold (|rotation|, log), limit per contact vs grip with E3, and each limit over E3 with
    the peers at their best coefficient; one legend below for all three panels."""
    fig, (a, b, c) = figure(1, 3, (16, 7))
    floor = 1e-10
    for name, trace in result["traces"].items():
        a.semilogy([p[0] for p in trace], [max(abs(p[1]), floor) for p in trace], label=name,
                   color=COLOURS.get(name), ls="--" if name in DASHED else "-")
    a.set_xlabel("time (s)")
    a.set_ylabel("|box rotation| about the grasp axis (deg)")
    a.set_ylim(floor / 3, 1e3)
    a.set_title(f"hold, gravity on, {result['grip_N']:g} N per finger\n(below 1e-10 deg drawn at 1e-10)", fontsize=10)
    lim = result["limit_per_contact_Nm"]
    grips = np.array(lim["grip_N"])
    dense = np.geomspace(grips.min(), grips.max(), 100)
    b.loglog(dense, [fingertip.e3_torque(g) for g in dense], "k-", lw=3, alpha=0.35, label="measured fingertip")
    for name in (n for n in lim if n != "grip_N"):
        b.loglog(grips, [np.nan if v is None else v for v in lim[name]], "o", ms=4, color=COLOURS.get(name),
                 ls="--" if name in DASHED else "-", label=None if name in result["traces"] else name)
    b.set_xlabel("grip per finger (N)")
    b.set_ylabel("torsional limit per contact (N·m)")
    b.set_title(f"torsional limit vs grip\n(peers' coefficient: softproxy's limit at {result['grip_N']:g} N)", fontsize=10)
    fid = result["fidelity"]
    inside = np.array(fid["grips_N"])
    c.axhline(1.0, color="k", lw=3, alpha=0.35)
    for name, row in fid["rows"].items():
        if "limit_Nm" in row:
            c.semilogy(inside, [v / fingertip.e3_torque(g) for v, g in zip(row["limit_Nm"], inside)], "o", ms=4,
                       color=COLOURS.get(name), ls="--" if name in DASHED else "-")
    c.set_xlabel("grip per finger (N)")
    c.set_ylabel("limit / measured fingertip")
    c.set_title(f"fidelity to the measured fingertip, {fid['range_N'][0]:g}–{fid['range_N'][1]:g} N\n"
                "(peers at their best single coefficient)", fontsize=10)
    for ax in (a, b, c):
        ax.grid(True, which="major", alpha=0.3)
    handles, labels = a.get_legend_handles_labels()
    handles += b.get_legend_handles_labels()[0]
    labels += b.get_legend_handles_labels()[1]
    # below the middle panel, outside the axes: the layout (report.save's tight_layout) makes room for it
    b.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3, fontsize=9, frameon=False)
    return fig


def _fmt(v, spec: str, width: int) -> str:
    return f"{'-':>{width}s}" if v is None else f"{v:{width}{spec}}"


def print_report(result: dict) -> None:
    print(f"peer: two-finger grasp held {result['duration_s']:g} s (box 0.1 kg, {result['grip_N']:g} N per finger, "
          f"2 cm off the CoM); peers' torsional coefficient {result['peer_torsion_coefficient_m'] * 1e3:.2f} mm "
          f"(softproxy's default limit at {result['grip_N']:g} N)")
    if not result["pybullet"]:
        print(f"  PyBullet rows skipped: pip install 'softproxy[{PYBULLET_EXTRA}]' to add them")
    if not result.get("drake"):
        print(f"  Drake rows skipped: pip install 'softproxy[{DRAKE_EXTRA}]' to add them")
    lim, st = result["limit_exponent"], result["static_dynamic"]
    print(f"  {'':27s}{'turned (deg)':>13s}{'max (deg)':>10s}{'creep (deg/s)':>14s}{'held':>8s}{'exp 0.1-2N':>11s}"
          f"{'exp 0.5-8N':>11s}{'slide/break':>12s}{'set':>6s}{'re-stick':>10s}{'step (us)':>10s}{'cost':>7s}"
          f"{'  wrench to device'}")
    for name, h in result["hold"].items():
        e = lim.get(name, {})
        s = st.get(name, {})
        restick = "-" if not s else ("no" if not s["resticks"] else f"{s['restick_over_breakaway']:.2f}")
        device = "yes" if name.startswith("softproxy") else "no"
        cost = h["cost_vs_mujoco_default"]
        held = "yes" if h["height_end_m"] > HELD_HEIGHT else "dropped"
        print(f"  {name:27s}{h['rotation_end_deg']:13.2e}{h['rotation_max_deg']:10.2g}{h['creep_deg_per_s']:14.2e}{held:>8s}"
              f"{_fmt(e.get('0.1-2 N'), '.2f', 11)}{_fmt(e.get('0.5-8 N'), '.2f', 11)}"
              f"{_fmt(s.get('steady_sliding_over_breakaway'), '.2f', 12)}"
              f"{_fmt((s.get('steady_slide') or {}).get('setting_dynamic_over_static'), '.2f', 6)}"
              f"{restick:>10s}{h['step_us']:10.1f}"
              f"{_fmt(cost, '.2f', 7)}  {device}")
    d = result.get("drake_settings")
    if d:
        print(f"  ({d['name']}: discrete_contact_approximation {d['solver']}, {d['time_step_s'] * 1e3:g} ms steps, "
              f"one AdvanceTo a step; each finger a soft sphere, E = {d['modulus_Pa'] / 1e6:.4f} MPa fitted to a "
              f"fingertip's contact radii, carrying at most πER²/3 = {d['capacity_N']:.2f} N (no limit at the grips "
              f"past it); friction μ = {d['mu']:.2f}, one coefficient, at which its limit at {result['grip_N']:g} N "
              "is softproxy's)")
    print(f"  (held: the box's centre still above {HELD_HEIGHT * 100:g} cm at the end; re-stick: applied torque at which "
          "a slipping contact sticks again / break-away; cost: step p50 / MuJoCo default step p50, this run)")
    if st:
        ss = result["slide_settings"]
        print(f"  slide/break, measured: the torque the contacts transmit while the box slides steadily at "
              f"{ss['speed_rad_s']:g} rad/s between the fingers ({ss['grip_N']:g} N each, no gravity; median over "
              f"{ss['measured_s']:g} s after {ss['settle_s']:g} s of slide) / the break-away torque at the same grip "
              f"({ss['breakaway']}); set: the fingers' dynamic / static torsional friction (softproxy's default 0.8, "
              "a choice: the paper leaves dynamic friction to experiment; the peers have one coefficient)")
    fid = result["fidelity"]
    lo, hi = fid["range_N"]
    print(f"  torsional limit per contact vs the measured fingertip, {lo:g}-{hi:g} N, relative error:")
    print(f"  {'':27s}{'RMS':>8s}{'max':>8s}  coefficient")
    for name, r in fid["rows"].items():
        coef = r.get("coefficient") or (f"best single coefficient {r['coefficient_m'] * 1e3:.2f} mm"
                                         if "coefficient_m" in r else
                                         f"best single friction coefficient {r['coefficient_mu']:.2f}"
                                         if "coefficient_mu" in r else "analytic, no simulation")
        print(f"  {name:27s}{r['rms']:8.3f}{r['max']:8.3f}  {coef}")


def main(args) -> int:
    # the hold is 20 s by default (a few seconds of compute); a shorter --duration shortens it
    duration = 20.0 if getattr(args, "full", False) else min(max(args.duration * 4, 4.0), 20.0)
    progress = Progress("peer")
    result = measure(duration, progress=progress)
    progress.done()
    shown = {k: v for k, v in result.items() if k != "traces"}  # the JSON printed leaves the traces out
    publish(args, "peer", result, chart(result), print_report, shown)
    return 0
