"""Passive by construction: the coupling renders no energy a hand or a body did not put in.

What is tested here: the friction laws' slip state under steady slow motion (a steady
dynamic torque or lag, not a saw-tooth that pumps the hand), the torsional damper on the
relative twist rate (a slip renders no reversal), and one wrench for both sides of the
coupling (the body gets the reaction of exactly what the device is sent).
"""

import math

import mujoco
import numpy as np
import pytest

from conftest import Holding, ScriptedDevice, nudged
from mesh_oracle import point_triangle
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.geometry import hfield_triangles
from softproxy.servo import ServoLoop
from softproxy.world import World

FLOOR = '<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>'
DT = 1e-3
RUN_S = 5.0


def finger_on_floor(**params):
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    params = {"radius": 0.008, "soft_start": 0.0, **params}
    f = SoftFingerProxy(FingerParams(**params), world.shapes, model("CH"))
    f.place(0.0, 0.0, 0.02)
    return f


def transitions(flags) -> int:
    """How many times a boolean series changes value."""
    flags = np.asarray(flags, dtype=bool)
    return int(np.count_nonzero(flags[1:] != flags[:-1]))


@pytest.mark.parametrize("grip", [0.3, 1.0, 3.0, 10.0])
@pytest.mark.parametrize("rate", [0.02, 0.1, 1.0])
def test_a_steady_twist_slips_steadily(grip, rate):
    """A finger pressing with a steady grip P while the device twists at a steady rate: after
    the break-away it slips at the dynamic limit μ_d·L(P) (soft-finger proxy paper, eq 40 with
    its sign) for the 5 s that follow: at most 2 stick-slip transitions and a torque ripple within
    5 % of the dynamic limit, from 0.3 to 10 N and 0.02 to 1 rad/s."""
    f = finger_on_floor()
    k = f.params.stiffness
    depth = grip / k
    slipping, torque = [], []
    i, end = 0, 10 ** 6
    while i < end:  # until 5 s after the break-away
        assert f.update(0.0, 0.0, f.params.radius - depth, rate * i * DT, DT)
        slipping.append(f.torsion.slipping)
        torque.append(f.torque)
        if f.torsion.slipping and end == 10 ** 6:
            end = i + int(RUN_S / DT)
        i += 1
    assert f.normal_force == pytest.approx(grip, rel=1e-6)
    dynamic = f.torsion.limit * 0.8  # μ_d = 0.8 μ_s, the default
    first = slipping.index(True)
    tail = np.array(torque[first + 10:])
    ripple = (tail.max() - tail.min()) / dynamic
    print(f"P {grip} N, {rate} rad/s: slips at tick {first}, {transitions(slipping)} transitions, "
          f"torque {tail.mean():.4g} N·m (dynamic limit {dynamic:.4g}), ripple {ripple:.2%}")
    assert transitions(slipping) <= 2
    assert ripple <= 0.05
    assert tail.mean() == pytest.approx(-dynamic, rel=0.05)  # the twist's way, at the dynamic limit


@pytest.mark.parametrize("grip", [0.3, 1.0, 3.0, 10.0])
@pytest.mark.parametrize("speed", [0.001, 0.01, 0.1])
def test_a_steady_slide_slips_steadily(grip, speed):
    """A finger pressing with a steady grip while the device slides along the floor at 1 to
    100 mm/s: after the break-away the proxy trails at the dynamic cone's edge (tangential
    force μ_d·P) for the 5 s that follow, with at most 2 stick-slip transitions and a ripple
    within 5 % of μ_d·P."""
    f = finger_on_floor()
    depth = grip / f.params.stiffness
    sticking, lateral = [], []
    i, end = 0, 10 ** 6
    while i < end:  # until 5 s after the break-away
        assert f.update(speed * i * DT, 0.0, f.params.radius - depth, 0.0, DT)
        sticking.append(f.god.sticking)
        lateral.append(f.fx)
        if not f.god.sticking and end == 10 ** 6:
            end = i + int(RUN_S / DT)
        i += 1
    first = sticking.index(False)
    tail = np.array(lateral[first + 10:])
    dynamic = f.params.mu_d * grip
    print(f"P {grip} N, {speed * 1e3:g} mm/s: slides at tick {first}, {transitions(sticking)} transitions, "
          f"Fx {tail.mean():.4g} N (μ_d P {dynamic:.4g}), ripple {(tail.max() - tail.min()) / dynamic:.2%}")
    assert transitions(sticking) <= 2
    assert (tail.max() - tail.min()) / dynamic <= 0.05
    assert tail.mean() == pytest.approx(-dynamic, rel=0.05)  # the proxy trails: the finger is pulled back (-x)


def test_a_slip_renders_no_torque_reversal():
    """Eq 39 re-tested every tick (restick_time 0), a steady twist slips again and again: the
    torsional damper acts on the device's twist rate relative to the touched body, never on
    the proxy's jump at a slip, so the torque keeps the twist's sign on every tick (it
    flipped to -0.2× the static limit for a tick at every slip when the damper saw the jump)."""
    f = finger_on_floor(restick_time=0.0, torsion_damping=0.01)
    depth = 1.0 / f.params.stiffness
    torque = []
    for i in range(2000):
        f.update(0.0, 0.0, f.params.radius - depth, 0.1 * i * DT, DT)
        torque.append(f.torque)
    torque = np.array(torque)
    print(f"{f.torsion.slip_events} slips, torque from {torque.min():.4g} to {torque.max():.4g} N·m")
    assert f.torsion.slip_events > 20  # the per-tick law slips often
    assert torque.max() <= 0.0  # never against the twist


BOX = """<mujoco><option gravity="0 0 0"/><worldbody><geom type="plane" size="1 1 .1"/>
<body name="box" pos="0 0 0.05"><freejoint/><geom type="box" size="0.05 0.05 0.05" mass="10"/></body>
</worldbody></mujoco>"""


class Pressing:
    fingers, max_force, max_torque = 1, 20.0, 0.05

    def __init__(self):
        self.sent = []

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.01, 0.0, 0.12 - min(t, 0.05) * 0.8, 2.0 * t, True

    def send(self, finger, *w):
        self.sent.append(w)

    def close(self):
        pass


def test_the_body_gets_the_reaction_of_exactly_what_the_device_is_sent():
    """A finger whose own clamp (40 N, 1 N·m) is above the device's (20 N, 0.05 N·m) presses
    and twists on a free box: each tick the box's applied wrench is the reaction of the wrench
    the device was sent, after every clamp, so both sides exchange the same energy."""
    world = World(mujoco.MjModel.from_xml_string(BOX))
    finger = SoftFingerProxy(FingerParams(radius=0.008, soft_start=0.0), world.shapes, model("CH"))
    device = Pressing()
    body = world.model.body("box").id
    compared = 0
    with ServoLoop(world, [finger], device, 1000.0) as loop:
        for _ in range(150):
            loop.tick()
            xfrc = world.data.xfrc_applied[body]
            if not finger.valid or finger.body != body:
                continue
            w = np.array(device.sent[-1])
            assert np.allclose(xfrc[:3], -w[:3], rtol=1e-12, atol=1e-12)
            # the torque about the box's centre: the pure torque -M·n plus the lever of -F at the contact
            lever = np.array([finger.px, finger.py, finger.pz]) - world.data.xipos[body]
            assert np.allclose(xfrc[3:], -w[3:] + np.cross(lever, -w[:3]), rtol=1e-9, atol=1e-12)
            compared += 1
        assert max(np.linalg.norm(np.array(device.sent)[:, :3], axis=1)) == pytest.approx(20.0)
        assert math.hypot(finger.fx, finger.fy, finger.fz) > 20.0  # the finger's own force is past the device's
    assert compared > 100


# -- light objects nudged at rest: the coupling gives them no energy ------------------------------

KNOB = """<mujoco><option gravity="0 0 -9.81"/><worldbody>
<body name="knob" pos="0 0 0.01"><joint name="spin" type="hinge" axis="0 0 1"/>
<geom type="cylinder" size="0.015 0.01" mass="{mass}"/></body></worldbody></mujoco>"""

CUBE = """<mujoco><option gravity="0 0 0"/><worldbody>
<body name="cube" pos="0 0 0.1"><freejoint/><geom type="box" size="{half} {half} {half}" mass="{mass}"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("rate", [1000.0, 4000.0])
@pytest.mark.parametrize("mass", [0.001, 0.005, 0.05])
def test_a_light_knob_under_a_finger_stays_at_rest(mass, rate):
    """A hinged knob of 1-50 g under one default soft finger pressing with ~1 N, nudged at
    0.01 rad/s: its kinetic energy never rises above the nudge's and it comes to rest (the
    explicit coupling spun a 5 g knob up to 17-28 rad/s, a 1 g one to 379-607 rad/s)."""
    world = World(mujoco.MjModel.from_xml_string(KNOB.format(mass=mass)))
    finger = SoftFingerProxy(FingerParams(radius=0.008, soft_start=0.0), world.shapes, model("CH"))
    depth = 1.0 / finger.params.stiffness
    with ServoLoop(world, [finger], Holding([(0.0, 0.0, 0.02 + 0.008 - depth)]), rate) as loop:
        start, energy = nudged(world, loop, [0.01], 1.0)
        spin = float(world.data.qvel[0])
        print(f"{mass * 1e3:g} g knob at {rate:g} Hz: nudge {start:.3g} J, largest after {energy.max():.3g} J, "
              f"last {energy[-1]:.3g} J, spin {spin:.2g} rad/s, {finger.torsion.slip_events} slips")
        assert finger.normal_force == pytest.approx(1.0, rel=0.05)
    assert energy.max() <= start * (1 + 1e-9)
    assert energy[-1] <= 1e-3 * start  # held: the torsion spring stops it


@pytest.mark.parametrize("finger_model", ["CH", "point"])
@pytest.mark.parametrize("rate", [1000.0, 4000.0])
@pytest.mark.parametrize("mass, half", [(0.008, 0.01), (0.015, 0.02), (0.04, 0.02), (0.1, 0.02)])
def test_a_light_cube_pinched_by_two_fingers_stays_at_rest(mass, half, rate, finger_model):
    """A free cube of 8-100 g pinched at 3 N between two fingers, nudged at 0.01 rad/s about
    the grasp axis and 1 mm/s across it: soft fingers stop it, point fingers leave it turning
    about the axis they cannot hold; neither ever gives it more energy than the nudge (two
    default fingers spun an 8 g cube to 55-75 rad/s when the coupling was explicit)."""
    world = World(mujoco.MjModel.from_xml_string(CUBE.format(half=half, mass=mass)))
    fingers = [SoftFingerProxy(FingerParams(name=f"f{i}", radius=0.008, soft_start=0.0, device_finger=i),
                               world.shapes, model(finger_model)) for i in range(2)]
    press = 3.0 / fingers[0].params.stiffness
    reach = half + 0.008 - press
    device = Holding([(reach, 0.0, 0.1), (-reach, 0.0, 0.1)])
    with ServoLoop(world, fingers, device, rate) as loop:
        start, energy = nudged(world, loop, [0, 0.001, 0, 0.01, 0, 0], 1.0)
        world_spin = world.data.qvel[3:].copy()
        print(f"{mass * 1e3:g} g cube, {finger_model}, {rate:g} Hz: nudge {start:.3g} J, "
              f"largest after {energy.max():.3g} J, last {energy[-1]:.3g} J, spin {np.round(world_spin, 4)} rad/s")
        assert all(f.normal_force == pytest.approx(3.0, rel=0.05) for f in fingers)
    assert energy.max() <= start * (1 + 1e-6)
    if finger_model != "point":
        assert energy[-1] <= 1e-3 * start


# -- the device side: a hand-held handle on a stiff wall -------------------------------------------

from scipy.linalg import expm  # noqa: E402


class HandHeldHandle:
    """A one-axis handle (mass 0.1 kg, 0.5 N·s/m of its own friction) held by a hand (300 N/m,
    2 N·s/m) pulling it 1 cm below the wall's surface, integrated exactly between ticks with
    the rendered force held (what a device under a zero-order hold is). Keeps the work the
    rendered force did on the handle (J)."""

    fingers, max_torque = 1, 0.0
    MASS, DAMPING, HAND_K, HAND_B, TARGET = 0.1, 0.5, 300.0, 2.0, -0.01

    def __init__(self, period, max_force=200.0, start=0.012):
        self.max_force = max_force
        self.z, self.v, self.force = start, 0.0, 0.0
        self.work = 0.0
        m, b = self.MASS, self.DAMPING + self.HAND_B
        # x' = A x + B u, x = (z, v), u = (F + K_h·target): exact over one period
        a = np.zeros((3, 3))
        a[0, 1] = 1.0
        a[1, 0], a[1, 1], a[1, 2] = -self.HAND_K / m, -b / m, 1.0 / m
        self.step = expm(a * period)

    def read(self, t, samples):
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, self.z, 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.force = fz  # held until the next send
        z0 = self.z
        u = fz + self.HAND_K * self.TARGET
        self.z, self.v = (self.step @ np.array([self.z, self.v, u]))[:2]
        self.work += fz * (self.z - z0)

    def close(self):
        pass


def wall_work(rate, passivity, stiffness, damping, seconds=1.0):
    """The work the wall did on the hand-held handle (J) over `seconds`, the largest force (N),
    and the loop's finger after the run."""
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=stiffness, damping=damping, soft_start=0.0,
                                          max_force=200.0), world.shapes, model("point"))
    handle = HandHeldHandle(1.0 / rate)
    forces = []
    with ServoLoop(world, [finger], handle, rate, passivity=passivity) as loop:
        for _ in range(int(seconds * rate)):
            loop.tick()
            forces.append(handle.force)
    return handle.work, max(forces), finger


@pytest.mark.parametrize("rate, stiffness, damping", [
    (1000.0, 2000.0, 5.0), (250.0, 2000.0, 5.0), (1000.0, 1e4, 0.0), (250.0, 1e4, 0.0)])
def test_a_stiff_wall_gives_the_hand_no_net_energy(rate, stiffness, damping):
    """A hand-held handle (integrated exactly under the held force) pulled onto a wall. At the
    default settings (k 2000 N/m, b 5 N·s/m) the wall's work on the hand over 1 s is never
    positive, with the passivity controller (Hannaford & Ryu's time-domain passivity) or
    without. At K = 1e4 N/m undamped (Colgate's bound b > KT/2 + |B| asks 5 N·s/m at 1 kHz,
    20 at 250 Hz; the handle has 2.5) the sampled spring pumps energy into the hand; the
    controller cuts it more than tenfold (1,600× at 1 kHz, 20× at 250 Hz, where the handle
    stays on the wall two or three ticks per bounce, less than a sampled controller needs to
    see it turn), but not to nothing: docs/coupling.md."""
    work_on, peak_on, finger = wall_work(rate, True, stiffness, damping)
    work_off, peak_off, off = wall_work(rate, False, stiffness, damping)
    print(f"{rate:g} Hz, K {stiffness:g}, B {damping:g}: controller on: work on the hand {work_on:.4g} J, "
          f"peak {peak_on:.3g} N, acted {finger.pc_ticks} ticks; off: {work_off:.4g} J, peak {peak_off:.3g} N, "
          f"owed {-off.energy_min:.3g} J")
    if stiffness > 5000.0:
        assert work_off > 0.0  # the case the controller is for
        assert work_on < work_off / 10
    else:
        assert work_on <= 0.0 and work_off <= 0.0


class Pressing2mm(ScriptedDevice):
    """Presses a finger slowly 2 mm into the floor over 2 s and withdraws it over 2 s."""

    fingers, max_force, max_torque = 1, 100.0, 1.0

    def read(self, t, samples):
        depth = 0.002 * (t / 2.0 if t < 2.0 else max(0.0, 2.0 - (t - 2.0)) / 2.0)
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, 0.008 - depth, 0.0, True


def test_the_observer_counts_a_lossless_spring_exactly():
    """A finger pressed slowly 2 mm into a static floor and withdrawn, no damping: the energy the
    coupling took in at the deepest point is the spring's ½k d² (within the sampling's first
    order: one tick's step in 2000), and after the withdrawal it has given it all back and
    owes nothing (an analytic case of the observer, Hannaford & Ryu's E_obs)."""
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    finger = SoftFingerProxy(FingerParams(radius=0.008, damping=0.0, soft_start=0.0), world.shapes, model("point"))
    with ServoLoop(world, [finger], Pressing2mm(), 1000.0) as loop:
        for _ in range(2001):
            loop.tick()
        deepest = finger.energy_in
        for _ in range(2100):
            loop.tick()
    k = finger.params.stiffness
    print(f"taken in at 2 mm: {deepest:.6g} J (½kd² {0.5 * k * 0.002 ** 2:.6g} J); after: {finger.energy_in:.3g} J, "
          f"lowest E {finger.energy_min:.3g} J, controller ticks {finger.pc_ticks}")
    assert deepest == pytest.approx(0.5 * k * 0.002 ** 2, rel=2e-3)
    assert abs(finger.energy_in) < 2e-3 * deepest
    assert finger.energy_min > -2e-3 * deepest


# -- a proxy caught between a moving and a static surface --------------------------------------------

SQUEEZE = """<mujoco><option gravity="0 0 -9.81"/><worldbody><geom name="floor" type="plane" size="1 1 .1"/>
<body name="box" pos="0 0 0.3"><joint type="slide" axis="0 0 1"/><geom type="box" size="0.1 0.1 0.02" mass="{mass}"/>
</body></worldbody></mujoco>"""


class HeldBelow(ScriptedDevice):
    """A device held still at (x, y, z) (m), e.g. 3 mm below where its proxy rests on a floor (a
    finger pressing 3 N)."""

    fingers, max_force, max_torque = 1, 40.0, 1.0

    def __init__(self, x=0.0, y=0.0, z=0.005):
        self.at = (x, y, z)

    def read(self, t, samples):
        s = samples[0]
        (s.x, s.y, s.z), s.twist, s.valid = self.at, 0.0, True


@pytest.mark.parametrize("mass", [0.1, 1.0, 10.0])
def test_a_proxy_squeezed_by_a_falling_box_stays_out_of_the_floor(mass):
    """A box on a vertical slide falls onto a finger resting on the floor (radius 8 mm,
    k = 1000 N/m, its device 3 mm below the resting proxy): the proxy is never pushed through
    the floor, the finger says it is squeezed, and the force stays the floor's, out of it and
    within the clamp: never a pull into the floor nor a reversal (it went 19 mm through the
    floor pulling the hand down at 29 N, then jumped 55 mm onto the box and pushed at 27 N).
    The tick the box lands, the damper renders the box's speed (b·v, up) once; then the
    floor's 3 N."""
    world = World(mujoco.MjModel.from_xml_string(SQUEEZE.format(mass=mass)))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=1000.0, soft_start=0.0), world.shapes, model("point"))
    z, fz, squeezed = [], [], 0
    with ServoLoop(world, [finger], HeldBelow(), 1000.0) as loop:
        for _ in range(600):
            loop.tick()
            z.append(finger.god.z)
            fz.append(finger.fz)
            squeezed += finger.god.squeezed
    z, fz = np.array(z), np.array(fz)
    print(f"{mass:g} kg box: proxy z {z.min() * 1e3:.3f} to {z.max() * 1e3:.3f} mm, Fz {fz.min():.2f} to "
          f"{fz.max():.2f} N, squeezed {squeezed} ticks, largest step {np.abs(np.diff(fz)).max():.2f} N")
    assert z.min() >= 0.008 - 1e-6  # never inside the floor
    assert fz.min() >= 0.0 and fz.max() <= finger.params.max_force  # never into the floor, within the clamp
    assert squeezed > 0 and finger.god.squeeze_ticks == squeezed
    assert fz[-1] == pytest.approx(3.0, rel=1e-6)  # the floor's spring force, the box lying over the finger


@pytest.mark.parametrize("depth", [0.003, 0.008])
def test_a_finger_placed_inside_an_object_renders_only_its_spring(depth):
    """A finger with no soft start whose device sits still `depth` inside the floor: from the
    first tick it renders the spring's k·d and nothing more. The damper acts on the device's
    motion only, and a device that did not move has none (it rendered 18 N at 3 mm, six times
    the spring, on the first tick: the damper took the proxy's placement for a move)."""
    world = World(mujoco.MjModel.from_xml_string(FLOOR))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=1000.0, soft_start=0.0), world.shapes, model("point"))
    with ServoLoop(world, [finger], HeldBelow(0.01, 0.01, 0.008 - depth), 1000.0) as loop:
        fz = []
        for _ in range(5):
            loop.tick()
            fz.append(finger.fz)
    print(f"{depth * 1e3:g} mm inside: Fz {fz} N")
    assert fz == pytest.approx([1000.0 * depth] * 5, rel=1e-5)


HEIGHT_FIELD = """<mujoco><option gravity="0 0 -9.81"/>
<asset><hfield name="ground" nrow="16" ncol="16" size="0.2 0.2 0.02 0.015" elevation="{elevation}"/></asset>
<default><geom friction="0.4"/></default>
<worldbody><geom name="ground" type="hfield" hfield="ground"/>
<body name="lens" pos="0 0 0.3">
<joint type="slide" axis="1 0 0" damping="1"/><joint type="slide" axis="0 1 0" damping="1"/><joint type="slide" axis="0 0 1"/>
<joint axis="1 0 0" springdamper="0.2 1"/><joint axis="0 1 0" springdamper="0.2 1"/>
<geom type="ellipsoid" size=".3 .5 .1" mass="{mass}"/></body></worldbody></mujoco>"""


def distance_to_triangles(points, vertices, faces):
    """Each point's distance (m) to the nearest of the triangles, by brute force over all
    (`mesh_oracle.point_triangle`)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return np.array([point_triangle(p[None], a, b, c)[0].min() for p in points])


@pytest.mark.parametrize("mass", [0.1, 1.0])
def test_a_finger_on_a_height_field_under_a_falling_ellipsoid_stays_out_of_the_ground(mass):
    """The case of MuJoCo's touch-grid sensor model (an ellipsoid on slide joints and sprung
    hinges falling onto a height field), with a finger resting on the rough ground, its device
    3 mm below the resting proxy: the ellipsoid lands on the finger and pushes it down the
    slope, and the proxy never enters the ground (its centre one radius or more from every
    ground triangle, by brute force), says it is squeezed, and renders the ground's spring
    force only: up, within the clamp, no step over 1 N (the landing shoves the proxy 0.7 mm
    down the slope in one tick: 0.7 N sideways; it went 23 mm into the ground pulling the hand
    down at 40 N)."""
    elevation = " ".join(f"{v:.3f}" for v in np.random.default_rng(3).uniform(0.0, 1.0, 16 * 16))
    mj = mujoco.MjModel.from_xml_string(HEIGHT_FIELD.format(elevation=elevation, mass=mass))
    world = World(mj)
    under = np.zeros(1, np.int32)
    x0, y0 = 0.01, 0.013
    ground = 0.2 - mujoco.mj_ray(mj, world.data, np.array([x0, y0, 0.2]), np.array([0.0, 0.0, -1.0]), None, 1, 1, under)
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=1000.0, soft_start=0.0), world.shapes, model("point"))
    p, f, squeezed = [], [], 0
    with ServoLoop(world, [finger], HeldBelow(x0, y0, ground + 0.005), 1000.0) as loop:
        for _ in range(700):
            loop.tick()
            p.append((finger.god.x, finger.god.y, finger.god.z))
            f.append((finger.fx, finger.fy, finger.fz))
            squeezed += finger.god.squeezed
    p, f = np.array(p), np.array(f)
    gap = distance_to_triangles(p, *hfield_triangles(mj, 0))
    step = np.abs(np.diff(f, axis=0)).max()
    print(f"{mass:g} kg: nearest ground {gap.min() * 1e3:.6f} mm from the centre, proxy slid "
          f"{np.ptp(p[:, 0]) * 1e3:.2f} × {np.ptp(p[:, 1]) * 1e3:.2f} mm, Fz {f[:, 2].min():.2f} to {f[:, 2].max():.2f} N, "
          f"squeezed {squeezed} ticks, largest step {step:.3f} N")
    assert under[0] == 0
    assert gap.min() >= finger.params.radius - 1e-6
    assert squeezed > 0
    assert f[:, 2].min() > 0.0 and np.linalg.norm(f, axis=1).max() <= finger.params.max_force
    assert step <= 1.0


BELT = """<mujoco><option gravity="0 0 -9.81"/>
<asset><mesh name="bag" builtin="supersphere" params="32 {shape}" scale=".2 .13 .085"/></asset>
<worldbody><geom name="floor" type="plane" size="3 3 .1"/>
<geom name="belt" type="box" pos="0 0 .29" size=".74 .3 .06" surfacevel=".7 0 0 0 0 0"/>
<body name="bag" pos="-0.4 {y} 0.44"><freejoint/><geom type="mesh" mesh="bag" mass="{mass}"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("mass, shape, y", [(3.0, ".3 .4", 0.0), (0.3, ".3 .4", 0.0), (3.0, ".6 .45", 0.05)])
def test_a_bag_on_a_moving_belt_runs_over_a_resting_finger(mass, shape, y):
    """The case of MuJoCo's luggage-carousel model: a bag (a supersphere mesh) carried at
    0.7 m/s by a static belt that moves its surface runs over a finger resting on the belt, its
    device 3 mm below the resting proxy. The proxy never enters the belt, says it is squeezed
    while the bag is over it, and renders the belt's spring force only, up and steady (it was
    pushed 2.1 mm into the belt)."""
    world = World(mujoco.MjModel.from_xml_string(BELT.format(mass=mass, shape=shape, y=y)))
    finger = SoftFingerProxy(FingerParams(radius=0.008, stiffness=1000.0, soft_start=0.0), world.shapes, model("point"))
    top = 0.29 + 0.06
    z, f, squeezed, bag = [], [], 0, []
    with ServoLoop(world, [finger], HeldBelow(0.2, 0.0, top + 0.005), 1000.0) as loop:
        for _ in range(1500):
            loop.tick()
            z.append(finger.god.z)
            f.append((finger.fx, finger.fy, finger.fz))
            squeezed += finger.god.squeezed
            bag.append(world.data.qpos[0])
    z, f = np.array(z), np.array(f)
    print(f"{mass:g} kg bag from x {bag[0]:.2f} to {bag[-1]:.2f} m: proxy z {(z.min() - top) * 1e3:.4f} to "
          f"{(z.max() - top) * 1e3:.4f} mm over the belt, Fz {f[:, 2].min():.3f} to {f[:, 2].max():.3f} N, "
          f"squeezed {squeezed} ticks, largest step {np.abs(np.diff(f, axis=0)).max():.3f} N")
    assert bag[-1] > 0.3  # the bag went over the finger at x = 0.2 m
    assert z.min() >= top + finger.params.radius - 1e-6
    assert squeezed > 0
    assert f[:, 2] == pytest.approx(3.0, rel=1e-3) and np.abs(f[:, :2]).max() < 0.5
