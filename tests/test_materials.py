"""Materials (softproxy.material, softproxy.compiled.material; docs/materials.md): what the
touched geom's material and its MJCF friction change in what a finger renders, each against
an analytic value computed here from the material's fields, never read from the engine."""

import math

import mujoco
import numpy as np
import pytest

from conftest import Holding, ScriptedDevice, nudged
from softproxy import Material
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.input_error import InputError
from softproxy.scene import SceneError, load_scene
from softproxy.servo import ServoLoop
from softproxy.world import World

DT = 1e-3
R, DEPTH = 0.005, 0.002          # m: the proxy's radius, the device under the proxy's level
LEVEL = 0.05 + R                 # the proxy's height on the boxes' top faces (m)
K = 2000.0                       # N/m: the finger's coupling
MU = (0.8, 0.6)                  # the finger's own cone
SPEED = 0.05                     # m/s: a steady slide
BOXES = """<mujoco><worldbody>
  <geom name="plain" type="box" size=".1 .1 .05"/>
  <geom name="mjcf_half" type="box" size=".1 .1 .05" pos="0.3 0 0" friction="0.5"/>
  <geom name="priority" type="box" size=".1 .1 .05" pos="0.6 0 0" friction="0.3" priority="1"/>
  <body name="tile"><geom name="tile_geom" type="box" size=".1 .1 .05" pos="0.9 0 0"/></body>
</worldbody></mujoco>"""
"""Four static boxes, top faces at z = 0.05 m, 0.3 m apart in x."""


def pressed(materials, x0=0.0, *, damping=0.0, mu=MU, torsion=True):
    """A finger pressed DEPTH into the box at x0 (over 10 ticks, then 10 still)."""
    world = World(mujoco.MjModel.from_xml_string(BOXES), materials=materials)
    params = FingerParams(radius=R, stiffness=K, damping=damping, mu_s=mu[0], mu_d=mu[1], soft_start=0.0)
    finger = SoftFingerProxy(params, world.shapes, model("CH" if torsion else "point"))
    finger.place(x0, 0.0, LEVEL + 0.001)
    for i in range(20):
        finger.update(x0, 0.0, LEVEL - DEPTH * min(1.0, (i + 1) / 10), 0.0, DT)
    return finger


def slide(finger, x0, ticks=400):
    """The device slid along +x at SPEED, DEEP: the lag of the proxy behind it per tick (m)."""
    lags = []
    for i in range(1, ticks + 1):
        x = x0 + SPEED * i * DT
        finger.update(x, 0.0, LEVEL - DEPTH, 0.0, DT)
        lags.append(x - finger.god.x)
    return np.array(lags)


@pytest.mark.parametrize("surface, expected", [(None, K), (500.0, 500.0), (5000.0, K)])
def test_the_softer_of_surface_and_finger_renders(surface, expected):
    """Pressed DEEP and held: F = k d with k the lesser of the finger's coupling and the
    surface's stiffness (a device never renders stiffer than its finger was tuned)."""
    finger = pressed({"plain": Material(stiffness=surface)} if surface else {})
    assert finger.fz == pytest.approx(expected * DEPTH, rel=1e-9)


@pytest.mark.parametrize("x0, materials, cone", [
    (0.0, {}, MU),                                                  # the finger's own
    (0.0, {"plain": Material(mu_s=0.2, mu_d=0.1)}, (0.2, 0.1)),     # the pair's, as given
    (0.3, {}, (0.5 * MU[0], 0.5 * MU[1])),                          # MJCF friction 0.5: the product
    (0.6, {}, (0.3, 0.3 * MU[1] / MU[0])),                          # priority: the geom's own
    (0.9, {"tile": Material(mu_s=0.4)}, (0.4, 0.8 * 0.4)),          # by body name; mu_d 0.8 mu_s
])
def test_friction_cone_is_the_touched_geoms(x0, materials, cone):
    """A steady slide DEEP along each box: the proxy breaks away at μ_s·depth and trails at
    μ_d·depth, with (μ_s, μ_d) the finger's, the material's, or the finger's combined with the
    geom's MJCF friction (Bullet's product rule; MuJoCo's priority)."""
    lags = slide(pressed(materials, x0), x0)
    assert lags.max() == pytest.approx(cone[0] * DEPTH, abs=SPEED * DT + 1e-12)
    assert lags[-1] == pytest.approx(cone[1] * DEPTH, abs=1e-9)


def test_an_mjcf_friction_changes_what_the_finger_feels():
    """The same slide on the plain box and on the box of MJCF friction 0.5: the sliding force
    k·lag halves."""
    plain = slide(pressed({}, 0.0), 0.0)[-1]
    half = slide(pressed({}, 0.3), 0.3)[-1]
    assert half == pytest.approx(0.5 * plain, rel=1e-6)


@pytest.mark.parametrize("material, factor", [(Material(), 1.0), (Material(mu_s=0.4, mu_d=0.32), 0.5),
                                              (Material(mu_s=0.4, mu_d=0.32, torsion=3.0), 1.5)])
def test_torsional_limit_scales_with_the_pairs_friction(material, factor):
    """Twisted under the same grip until it slips: the static torsional limit is the finger's
    law (Simulating human fingers, eq 26) times μ_s(pair) / μ_s(finger) times `torsion`."""
    base = pressed({})
    finger = pressed({"plain": material})
    for f in (base, finger):
        for i in range(300):
            f.update(0.0, 0.0, LEVEL - DEPTH, 0.5 * i * DT, DT)
    assert finger.torsion.limit == pytest.approx(factor * base.torsion.limit, rel=1e-9)
    assert finger.torsion.slipping


def test_viscosity_resists_the_motion_relative_to_the_surface():
    """Pressing on at a steady 10 mm/s, no coupling damper: F_z = k·stretch + η v."""
    eta, v = 20.0, 0.01
    finger = pressed({"plain": Material(viscosity=eta)})
    for i in range(1, 50):
        z = LEVEL - DEPTH - v * i * DT
        finger.update(0.0, 0.0, z, 0.0, DT)
        assert finger.fz - K * (finger.god.z - z) == pytest.approx(eta * v, rel=1e-6)


def spectrum(signal):
    """One-sided amplitude spectrum of a 1 kHz signal: (frequencies (Hz), amplitudes)."""
    x = np.asarray(signal) - np.mean(signal)
    return np.fft.rfftfreq(len(x), DT), np.abs(np.fft.rfft(x)) * 2.0 / len(x)


def test_vibration_along_the_normal():
    """Held pressed: the normal force carries a 100 Hz, 1 N sine over its k·d (4 N)."""
    finger = pressed({"plain": Material(vibration_hz=100.0, vibration_amplitude=1.0)})
    fz = []
    for _ in range(1000):
        finger.update(0.0, 0.0, LEVEL - DEPTH, 0.0, DT)
        fz.append(finger.fz)
    freq, amp = spectrum(fz)
    assert freq[amp.argmax()] == pytest.approx(100.0)
    assert amp.max() == pytest.approx(1.0, rel=1e-3)
    assert np.mean(fz) == pytest.approx(K * DEPTH, rel=1e-3)


@pytest.mark.parametrize("speed", [0.05, 0.02])
def test_texture_force_spectrum_peaks_at_speed_over_period(speed):
    """Sliding frictionless over a height grating h = A sin(2π x / λ) (λ 2 mm, A 0.1 mm): the
    lateral force -P dh/dx has its spectrum's peak at v/λ (25 or 10 Hz) with amplitude
    P·A·2π/λ (P = k d, 4 N)."""
    period, height = 0.002, 1e-4
    finger = pressed({"plain": Material(texture_period=period, texture_height=height)}, mu=(0.0, 0.0))
    fx = []
    for i in range(1, 2001):
        finger.update(-0.05 + speed * i * DT, 0.0, LEVEL - DEPTH, 0.0, DT)
        fx.append(finger.fx)
    freq, amp = spectrum(fx)
    assert freq[amp.argmax()] == pytest.approx(speed / period, abs=0.5)
    assert amp.max() == pytest.approx(K * DEPTH * height * 2.0 * math.pi / period, rel=0.02)


def test_stick_slip_saw_tooth():
    """Sliding frictionless at 50 mm/s on a stick-slip surface (break 0.5 N, 500 N/m): the
    anchor spring's force saws between 0 and the break force, slipping every F / (k v) s
    (20 ms: 100 slips in 2 s)."""
    brk, k_ss = 0.5, 500.0
    finger = pressed({"plain": Material(stick_slip_force=brk, stick_slip_stiffness=k_ss)}, mu=(0.0, 0.0))
    fx = []
    for i in range(1, 2001):
        finger.update(-0.05 + SPEED * i * DT, 0.0, LEVEL - DEPTH, 0.0, DT)
        fx.append(finger.fx)
    fx = np.array(fx)
    assert fx.min() == pytest.approx(-brk, abs=k_ss * SPEED * DT)
    assert fx.max() <= 1e-12
    slips = int((np.diff(fx) > 0.5 * brk).sum())
    assert abs(slips - 2.0 * SPEED * k_ss / brk) <= 2


class Approach(ScriptedDevice):
    """A device moved down onto, and back up from, a magnetic box's top face (device frame =
    world), `cycles` times over 1 s each, from 20 mm above the proxy's level to 2 mm above."""

    fingers, max_force, max_torque = 1, 40.0, 1.0

    def __init__(self, cycles=1):
        self.cycles = cycles
        self.sent = []

    def read(self, t, samples):
        phase = (t % 1.0)
        gap = 0.002 + 0.018 * abs(1.0 - 2.0 * phase)
        s = samples[0]
        s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, LEVEL + gap, 0.0, True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.sent.append(fz)


def test_magnet_pulls_within_its_reach_and_gives_the_hand_no_energy():
    """Out of contact, a magnet (5 N, 10 mm reach) pulls the finger down with 5 (1 - gap /
    reach) N within reach and not at all beyond; over in-and-out cycles the work the pull did
    on the hand, Σ F·Δx_d, is not positive: the sampled field grows toward the surface, so
    it takes back more on the way out than it gave on the way in."""
    pull, reach = 5.0, 0.01
    world = World(mujoco.MjModel.from_xml_string(BOXES), materials={"plain": Material(magnet_force=pull,
                                                                                       magnet_reach=reach)})
    finger = SoftFingerProxy(FingerParams(radius=R, stiffness=K, soft_start=0.0), world.shapes, model("point"))
    device = Approach()
    with ServoLoop(world, [finger], device, 1000.0, overrun_watchdog=False) as loop:
        heights, forces = [], []
        for _ in range(3000):
            loop.tick()
            heights.append(finger.zd)
            forces.append(finger.fz)
    gaps = np.array(heights) - LEVEL
    fz = np.array(forces)
    expected = np.where(gaps < reach, -pull * (1.0 - gaps / reach), 0.0)
    assert np.allclose(fz[5:], expected[5:], atol=1e-9)
    assert fz.min() < -0.5 * pull  # the pull was felt
    work = float(np.sum(fz[:-1] * np.diff(heights)))  # on the hand: F held over the move
    assert work <= 0.0


def test_magnet_pulls_the_body_it_comes_from():
    """The pulled finger's reaction goes to the magnetic body: a free magnetic block under a
    finger held 5 mm above it (gravity off) is pulled up, its momentum the sum of the pulls the
    finger felt."""
    xml = """<mujoco><option gravity="0 0 0"/><worldbody>
      <body name="block" pos="0 0 0"><freejoint/><geom name="block" type="box" size=".05 .05 .05" mass="1"/></body>
    </worldbody></mujoco>"""

    class Held(ScriptedDevice):
        fingers, max_force, max_torque = 1, 40.0, 1.0

        def read(self, t, samples):
            s = samples[0]
            s.x, s.y, s.z, s.twist, s.valid = 0.0, 0.0, LEVEL + 0.005, 0.0, True

    world = World(mujoco.MjModel.from_xml_string(xml), materials={"block": Material(magnet_force=2.0,
                                                                                     magnet_reach=0.01)})
    finger = SoftFingerProxy(FingerParams(radius=R, soft_start=0.0), world.shapes, model("point"))
    with ServoLoop(world, [finger], Held(), 1000.0, overrun_watchdog=False) as loop:
        pulls = []
        for _ in range(10):
            loop.tick()
            pulls.append(finger.fz)
        vz = world.data.qvel[2]
    assert min(pulls) < -0.5
    assert vz == pytest.approx(-sum(pulls) * DT / 1.0, rel=1e-6)  # 1 kg: the momentum the finger's pulls gave it


def test_no_material_leaves_the_finger_its_own():
    """A geom with MuJoCo's default friction and no material: its record says so, and the
    kernels read the finger's own coupling and cone (the shipped scenes unchanged)."""
    world = World(mujoco.MjModel.from_xml_string(BOXES))
    S = world.shapes.S
    rows = {s.name: k for k, s in enumerate(world.shapes)}
    assert not S[rows["plain"]].material and not S[rows["tile_geom"]].material
    assert S[rows["mjcf_half"]].material and S[rows["mjcf_half"]].friction_scale == 0.5
    assert S[rows["priority"]].material and S[rows["priority"]].friction[0] == 0.3


def test_material_fields_are_checked():
    """Out-of-range or half-given fields are one-line errors naming the field."""
    with pytest.raises(InputError, match="stiffness must be .* N/m, got 2.0 .*2 N/mm is 2000 N/m"):
        Material(stiffness=2.0)
    with pytest.raises(InputError, match="mu_d must be <= mu_s"):
        Material(mu_s=0.2, mu_d=0.5)
    with pytest.raises(InputError, match="magnet_reach must be given with the other"):
        Material(magnet_force=1.0)
    with pytest.raises(ValueError, match="materials.nothing names no geom or body"):
        World(mujoco.MjModel.from_xml_string(BOXES), materials={"nothing": Material()})


SCENE = """
[scene]
mjcf = "boxes.xml"
duration_s = 0.1

[[finger]]
radius = 0.005

[materials.rubbery]
mu_s = 1.5
[materials.tile]
mu_s = 0.2
[materials.tile_geom]
mu_s = 0.1
"""


def test_scene_materials_by_class_body_and_geom(tmp_path):
    """[materials.NAME] names a default class, a body or a geom; a geom takes its own name's
    first, then its body's, then its class's; a name that is none of them is one line."""
    xml = BOXES.replace("<worldbody>", '<default><default class="rubbery"><geom/></default></default><worldbody>')
    xml = xml.replace('name="plain" type="box"', 'name="plain" class="rubbery" type="box"')
    (tmp_path / "boxes.xml").write_text(xml)
    (tmp_path / "s.toml").write_text(SCENE)
    scene = load_scene(tmp_path / "s.toml")
    world_model = scene.load_model()
    world = World(world_model, **scene.world_options())
    by_name = {s.name: world.shapes.S[k] for k, s in enumerate(world.shapes)}
    assert by_name["plain"].friction[0] == 1.5          # its class's
    assert by_name["tile_geom"].friction[0] == 0.1      # its own name's before its body's
    (tmp_path / "bad.toml").write_text(SCENE.replace("[materials.tile]", "[materials.tiles]"))
    with pytest.raises(SceneError, match=r"bad.toml: materials.tiles names no geom, body or default class"):
        load_scene(tmp_path / "bad.toml").load_model()


def test_materials_tour_pads_feel_as_their_materials_say():
    """The shipped `materials_tour`, lockstep: the finger strokes each pad 1.5 mm deep. On the
    foam (250 N/m under the finger's 1000) the normal force is a quarter of the plain pad's;
    on the glass (MJCF friction 0.2) the sliding force a fifth; the honey (15 N·s/m) adds about
    η v to it (v the device's mean speed); the paper gives way at 1 N; and the passivity observer owes no more than the vibration's few µJ."""
    from softproxy.run import build, open_device

    scene = load_scene("materials_tour")
    loop = build(scene, open_device("sim", scene), realtime=False)
    finger = loop.fingers[0]
    forces = []
    with loop:
        for _ in range(int(scene.duration_s * scene.rate_hz)):
            loop.tick()
            forces.append((finger.fy, finger.fz, finger.yd))
    pads = {name: np.array(forces[k * 1000 + 300:k * 1000 + 700]) for k, name in
            enumerate(["plain", "foam", "glass", "rubber", "honey", "ridges", "buzz", "magnet", "sticky", "paper"])}
    plain = pads["plain"].mean(axis=0)
    assert pads["foam"][:, 1].mean() == pytest.approx(0.25 * plain[1], rel=1e-6)
    assert pads["glass"][:, 0].mean() == pytest.approx(0.2 * plain[0], rel=0.02)
    honey = pads["honey"]
    speed = (honey[-1, 2] - honey[0, 2]) / ((len(honey) - 1) * DT)  # the device's mean speed along y (m/s)
    assert honey[:, 0].mean() == pytest.approx(plain[0] - 15.0 * speed, rel=0.05)
    assert finger.energy_min > -1e-4
    paper = np.array(forces[9000:9800])
    assert paper[:, 1].max() <= 1.0 + 1e-9 and paper[-100:, 1].max() == 0.0  # gives way at 1 N


def test_friction_grating_modulates_the_sliding_force():
    """Sliding at a steady speed along a friction grating μ × (1 + m sin(2π x / λ)) (λ 4 mm,
    m 0.5): the trailing lag, μ_d(x)·depth, follows the grating, its spectrum's peak at v/λ."""
    period = 0.004
    finger = pressed({"plain": Material(texture_period=period, texture_friction=0.5)})
    lags = slide(finger, 0.0, ticks=2000)[400:]
    freq, amp = spectrum(lags)
    assert freq[amp.argmax()] == pytest.approx(SPEED / period, abs=1.0)
    assert lags.max() > 1.3 * MU[1] * DEPTH and lags.min() < 0.7 * MU[1] * DEPTH


def test_popthrough():
    """Pressed ever deeper into a surface that gives way at 3 N: the force rises as k·d to 3 N,
    then the finger is through (nothing rendered, the proxy inside the box, no penetration
    counted); drawn back out above it, the surface is felt again and holds up to 3 N."""
    world = World(mujoco.MjModel.from_xml_string(BOXES), materials={"plain": Material(popthrough_force=3.0)})
    finger = SoftFingerProxy(FingerParams(radius=R, stiffness=K, damping=0.0, soft_start=0.0), world.shapes,
                             model("point"))
    finger.place(0.0, 0.0, LEVEL + 0.001)
    forces = []
    for i in range(40):  # 0.1 mm a tick: 3 N at 1.5 mm
        finger.update(0.0, 0.0, LEVEL - 1e-4 * i, 0.0, DT)
        forces.append(finger.fz)
    through = next(i for i, f in enumerate(forces) if i > 5 and f == 0.0)
    assert 3.0 - K * 1e-4 - 1e-9 <= max(forces) <= 3.0 + 1e-9  # within a tick's step under 3 N
    assert all(f == 0.0 for f in forces[through:])
    assert finger.god.z == pytest.approx(LEVEL - 3.9e-3)  # free with the device, 3.9 mm into the box's top
    assert finger.audit() == 0.0
    for i in range(40):  # back out above the top and down again
        finger.update(0.0, 0.0, LEVEL - 4e-3 + 2e-4 * i, 0.0, DT)
    finger.update(0.0, 0.0, LEVEL - 1e-3, 0.0, DT)
    assert finger.fz == pytest.approx(K * 1e-3, rel=1e-6)


CUBE = """<mujoco><option gravity="0 0 0"/><worldbody>
<body name="cube" pos="0 0 0.1"><freejoint/><geom name="cube" type="box" size="0.01 0.01 0.01" mass="0.008"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize("material", [
    Material(stiffness=300.0, damping=1.0), Material(viscosity=10.0),
    Material(texture_period=0.002, texture_height=1e-4, texture_friction=0.5, texture_axis=(0.0, 1.0, 0.0)),
    Material(mu_s=0.3, stick_slip_force=0.5, stick_slip_stiffness=500.0), Material(magnet_force=2.0, magnet_reach=0.01)],
    ids=["soft", "viscous", "textured", "stick-slip", "magnetic"])
def test_a_light_cube_of_any_material_pinched_stays_at_rest(material):
    """An 8 g cube of each dissipative material (and a magnetic one) pinched at 3 N between
    two soft fingers, nudged at 0.01 rad/s about the grasp axis and 1 mm/s across it: its
    kinetic energy never rises above the nudge's (Passive by construction: the materials'
    effects create no energy in a body, however light)."""
    world = World(mujoco.MjModel.from_xml_string(CUBE), materials={"cube": material})
    fingers = [SoftFingerProxy(FingerParams(name=f"f{i}", radius=0.008, soft_start=0.0, device_finger=i),
                               world.shapes, model("CH")) for i in range(2)]
    k = min(fingers[0].params.stiffness, material.stiffness or math.inf)
    reach = 0.01 + 0.008 - 3.0 / k
    with ServoLoop(world, fingers, Holding([(reach, 0.0, 0.1), (-reach, 0.0, 0.1)]), 1000.0) as loop:
        start, energy = nudged(world, loop, [0, 0.001, 0, 0.01, 0, 0], 1.0)
        grips = [f.normal_force for f in fingers]
    print(f"{material}: grips {grips} N, nudge {start:.3g} J, largest after {energy.max():.3g} J")
    assert all(g == pytest.approx(3.0, rel=0.05) for g in grips)
    assert energy.max() <= start * (1 + 1e-6)
