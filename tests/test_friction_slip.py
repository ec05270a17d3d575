"""The slip state of both friction laws (docs/friction.md): the torsion of the soft finger
(`TorsionalFriction`, seed 002 eqs 39-40) and the god-object's friction cone (`GodObject`).

Once slipping, a contact stays in dynamic friction until the motion stops (no slide for
`restick_time`) or reverses (its offset along the slip below RESTICK_FRACTION of the dynamic
limit). Each steady case is also run with `restick_time=0`, the per-tick re-test of the
static limit the engine had before, to show that it chatters where the slip state does not:
the same assertions fail on it. Expected values are computed here from μ_s, μ_d, |P|^γ,
k_τ and the depth, not read from the engine."""

import math

import mujoco
import pytest

from softproxy.compiled.godobject import RESTICK_FRACTION, RESTICK_TIME, RESTICK_TRAVEL
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.geometry import shapes_of
from softproxy.proxy import GodObject
from softproxy.torsion import TorsionalFriction

DT = 1e-3
CH = model("CH")
MU_S = 8.1489e-3                 # seed 002 Table 1, CH: μ'_m (N·m/N^γ)
MU_D = 0.8 * MU_S                # the engine's default dynamic coefficient
P = 1.0                          # N
K_TAU = 2.0                      # N·m/rad
STATIC = MU_S * P ** (4.0 / 3.0)   # the static torque limit μ_s|P|^γ, γ = 4/3 for CH (N·m)
DYNAMIC = MU_D * P ** (4.0 / 3.0)  # the dynamic torque μ_d|P|^γ (N·m)
RATE = 0.1                       # rad/s: the steady twist

BOX = '<mujoco><worldbody><geom type="box" size=".05 .05 .05"/></worldbody></mujoco>'
RADIUS, DEPTH = 0.005, 0.002     # m: a 5 mm proxy, the device 2 mm under the top face's proxy level
LEVEL = 0.05 + RADIUS            # height of the proxy's centre on the top face (m)
CONE_S, CONE_D = 0.5, 0.4        # μ_s, μ_d of the box face
SPEED = 0.05                     # m/s: the steady slide


def transitions(states: list) -> int:
    """How many times a sequence of slip states (True: slipping) changes, from stuck."""
    return sum(a != b for a, b in zip([False] + states, states))


def twist(t: TorsionalFriction, angles) -> tuple[list, list]:
    """Step the torsion through device twists at P; (torques, slip states) per tick."""
    torques, states = [], []
    for a in angles:
        torques.append(t.step(a, P, DT))
        states.append(t.slipping)
    return torques, states


def fresh_torsion(restick_time: float = RESTICK_TIME) -> TorsionalFriction:
    t = TorsionalFriction(CH, K_TAU, restick_time=restick_time)
    t.touch(0.0)
    return t


@pytest.mark.parametrize("restick_time, steady", [(RESTICK_TIME, True), (0.0, False)])
def test_steady_twist_renders_a_steady_dynamic_torque(restick_time, steady):
    """A steady twist of 0.1 rad/s at P = 1 N, k_τ = 2, for 3 s: with the slip state the
    contact slips once and the torque stays at -μ_d|P|^γ (no ripple); eq 39 re-tested every
    tick (restick_time 0) saw-tooths between μ_d|P|^γ and μ_s|P|^γ, one slip per
    (μ_s - μ_d)|P|^γ / k_τ of twist (~110 a second), which the same assertions reject."""
    torques, states = twist(fresh_torsion(restick_time), [RATE * k * DT for k in range(3000)])
    first = states.index(True)
    assert first == pytest.approx(STATIC / K_TAU / (RATE * DT), abs=1)  # slips at the static limit
    after = torques[first:]
    ripple = max(after) - min(after)
    if steady:
        assert transitions(states) == 1
        assert ripple <= 1e-12 * DYNAMIC and after[-1] == pytest.approx(-DYNAMIC, rel=1e-12)
    else:
        period = (STATIC - DYNAMIC) / K_TAU / (RATE * DT)  # ticks between slips, ~8.1
        assert transitions(states) / 2 == pytest.approx((3000 - first) / math.ceil(period), rel=0.15)
        assert ripple == pytest.approx(STATIC - DYNAMIC, rel=0.1)


def test_torsion_resticks_when_the_twist_stops():
    """Slipping under a steady twist, then the twist held still: the contact stays in
    dynamic friction (torque unchanged) for restick_time, then sticks, the torque still
    -μ_d|P|^γ; twisting on, the torque climbs as a spring to the static limit before the
    contact slips again (a second slip event), and then it is back at -μ_d|P|^γ."""
    t = fresh_torsion()
    angles = [RATE * k * DT for k in range(300)]
    twist(t, angles)
    assert t.slipping and t.slip_events == 1
    hold = angles[-1]
    torques, states = twist(t, [hold] * 100)
    still = states.index(False)  # ticks held still until the re-stick
    # the stop watch started when α_p last completed RESTICK_TRAVEL of the offset: up to that
    # many ticks of the twist before the stop
    lead = math.ceil(RESTICK_TRAVEL * DYNAMIC / K_TAU / (RATE * DT))
    assert RESTICK_TIME / DT - lead <= still <= RESTICK_TIME / DT + 1
    assert not any(states[still:])
    assert max(torques) - min(torques) <= 1e-12 * DYNAMIC and torques[-1] == pytest.approx(-DYNAMIC, rel=1e-12)
    # on again: a spring from -μ_d to -μ_s (the breakaway), then dynamic friction
    torques, states = twist(t, [hold + RATE * k * DT for k in range(1, 200)])
    again = states.index(True)
    assert again == pytest.approx((STATIC - DYNAMIC) / K_TAU / (RATE * DT), abs=1)
    assert min(torques) == pytest.approx(-STATIC, rel=2 * RATE * DT * K_TAU / STATIC)
    assert t.slip_events == 2 and transitions(states) == 1 and torques[-1] == pytest.approx(-DYNAMIC, rel=1e-12)


def test_torsion_resticks_when_the_twist_reverses_and_slips_the_other_way():
    """Slipping forward, then the twist turned back at the same rate: the contact re-sticks
    once the goal has come back by (1 - RESTICK_FRACTION) of the dynamic offset, turns as a
    spring through zero torque, and slips the other way at +μ_d|P|^γ once it reaches the
    static limit: slip, stick, slip, three transitions in all."""
    t = fresh_torsion()
    forward = [RATE * k * DT for k in range(300)]
    torques, states = twist(t, forward)
    back = [forward[-1] - RATE * k * DT for k in range(1, 400)]
    torques, states = twist(t, back)
    restick = states.index(False)
    back_by = (1.0 - RESTICK_FRACTION) * DYNAMIC / K_TAU  # rad
    assert restick == pytest.approx(back_by / (RATE * DT), abs=1)
    slips = restick + states[restick:].index(True)
    assert slips == pytest.approx((DYNAMIC + STATIC) / K_TAU / (RATE * DT), abs=1)
    assert transitions([True] + states) == 3 and t.slip_events == 2
    assert torques[-1] == pytest.approx(DYNAMIC, rel=1e-12)


def test_torsion_jitter_within_the_band_keeps_slipping():
    """The hysteresis band: while slipping, a back-step of the twist smaller than
    (1 - RESTICK_FRACTION) of the dynamic offset does not re-stick, so twisting on slides on
    at -μ_d|P|^γ with no breakaway bump to the static limit; eq 39 every tick (restick_time
    0) re-sticks on it and has to climb to -μ_s|P|^γ again."""
    slack = DYNAMIC / K_TAU
    for restick_time, bump in ((RESTICK_TIME, False), (0.0, True)):
        t = fresh_torsion(restick_time)
        forward = [RATE * k * DT for k in range(300)]
        twist(t, forward)
        jitter = forward[-1] - 0.3 * slack
        torques, states = twist(t, [jitter] + [jitter + RATE * k * DT for k in range(1, 60)])
        if bump:
            assert min(torques) < -0.99 * STATIC and t.slip_events > 1
        else:
            assert all(states) and t.slip_events == 1
            assert min(torques) >= -DYNAMIC * (1 + 1e-12) and torques[-1] == pytest.approx(-DYNAMIC, rel=1e-12)


def test_torsion_slip_state_rides_over_encoder_counts_and_force_noise():
    """What the stop watch is for. A twist read in encoder counts of 0.5 mrad (0.1 rad/s: one
    count every 5 ticks, the goal still in between) keeps slipping at -μ_d|P|^γ, one
    transition, where eq 39 every tick sticks between counts, climbing a count's worth of
    torque (k_τ × 0.5 mrad) before it slips again; and held
    still with P jittering by ±2 % (which nudges a slipping α_p whenever the dynamic offset
    reaches a new low), the contact still re-sticks within the re-stick time."""
    count = 0.5e-3
    angles = [count * math.floor(RATE * k * DT / count) for k in range(3000)]
    for restick_time in (RESTICK_TIME, 0.0):
        torques, states = twist(fresh_torsion(restick_time), angles)
        first = states.index(True)
        if restick_time > 0.0:
            assert transitions(states) == 1 and max(torques[first:]) - min(torques[first:]) <= 1e-12
        else:
            assert transitions(states) > 100
            assert max(torques[first:]) - min(torques[first:]) == pytest.approx(K_TAU * count, rel=1e-6)

    t = fresh_torsion()
    twist(t, [RATE * k * DT for k in range(300)])
    hold = RATE * 299 * DT
    states = []
    for k in range(100):
        t.step(hold, P * (1.0 + 0.02 * math.sin(1.3 * k) * math.cos(0.7 * k)), DT)
        states.append(t.slipping)
    assert not states[-1] and states.index(False) <= RESTICK_TIME / DT + 1 and t.slip_events == 1


def box_god(restick_time: float = RESTICK_TIME) -> tuple[GodObject, float]:
    """A god-object pressed DEPTH into the top face of a box at x = -0.03; returns it and x_d."""
    m = mujoco.MjModel.from_xml_string(BOX)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    god = GodObject(shapes_of(m, d), RADIUS, CONE_S, CONE_D, (-0.03, 0.0, 0.07), restick_time=restick_time)
    god.update(-0.03, 0.0, LEVEL - DEPTH, DT)
    assert god.contact and god.sticking
    return god, -0.03


def slide(god: GodObject, xs) -> tuple[list, list]:
    """Move the device along x on the face; (lag x_d - x of the proxy, slip states) per tick."""
    lags, states = [], []
    for x in xs:
        god.update(x, 0.0, LEVEL - DEPTH, DT)
        assert god.contact
        lags.append(x - god.x)
        states.append(not god.sticking)
    return lags, states


@pytest.mark.parametrize("restick_time, steady", [(RESTICK_TIME, True), (0.0, False)])
def test_steady_slide_trails_at_the_dynamic_cone(restick_time, steady):
    """A steady slide at 50 mm/s along a box face, 2 mm deep, μ_s = 0.5, μ_d = 0.4, for 1000
    ticks: with the slip state the proxy breaks away at μ_s·depth (1 mm) once and then trails
    the device at μ_d·depth (0.8 mm) with no ripple, two transitions at most (CHAI3D's finger
    proxy: 2 in 2500 ticks); the per-tick cone (restick_time 0) sticks and slips every few
    ticks, its lag cycling between the two cones."""
    god, x0 = box_god(restick_time)
    lags, states = slide(god, [x0 + SPEED * k * DT for k in range(1, 1001)])
    first = states.index(True)
    assert first == pytest.approx(CONE_S * DEPTH / (SPEED * DT), abs=1)
    after = lags[first:]
    ripple = max(after) - min(after)
    if steady:
        assert transitions(states) <= 2
        assert ripple < 1e-9 and after[-1] == pytest.approx(CONE_D * DEPTH, abs=1e-9)
    else:
        assert transitions(states) > 100
        assert ripple == pytest.approx((CONE_S - CONE_D) * DEPTH, abs=SPEED * DT + 1e-9)


def test_slide_resticks_when_the_device_stops_and_breaks_away_again():
    """Sliding, then the device held still: the proxy stays slipping (not moving, the lag
    μ_d·depth) for restick_time, then sticks; moving on, it holds until the lag reaches the
    static cone's μ_s·depth, and slips back to μ_d·depth."""
    god, x0 = box_god()
    xs = [x0 + SPEED * k * DT for k in range(1, 200)]
    slide(god, xs)
    assert not god.sticking
    x_stop = god.x
    lags, states = slide(god, [xs[-1]] * 100)
    still = states.index(False)
    lead = math.ceil(RESTICK_TRAVEL * CONE_D * DEPTH / (SPEED * DT))  # as for the torsion
    assert RESTICK_TIME / DT - lead <= still <= RESTICK_TIME / DT + 1
    assert god.x == x_stop and lags[-1] == pytest.approx(CONE_D * DEPTH, abs=1e-9)
    lags, states = slide(god, [xs[-1] + SPEED * k * DT for k in range(1, 100)])
    again = states.index(True)
    assert again == pytest.approx((CONE_S - CONE_D) * DEPTH / (SPEED * DT), abs=1)
    assert max(lags) == pytest.approx(CONE_S * DEPTH, abs=SPEED * DT)
    assert transitions(states) == 1 and lags[-1] == pytest.approx(CONE_D * DEPTH, abs=1e-9)


def test_slide_reversal_resticks_then_slips_the_other_way():
    """Sliding +x, then the device turned back at the same speed: the proxy re-sticks once
    the device has come back (1 - RESTICK_FRACTION)·μ_d·depth, holds while the device
    crosses it, and slips -x once the device is μ_s·depth past it, trailing at -μ_d·depth;
    a back-step within the band (0.3 μ_d·depth) keeps it slipping with no breakaway bump."""
    god, x0 = box_god()
    xs = [x0 + SPEED * k * DT for k in range(1, 200)]
    slide(god, xs)
    lags, states = slide(god, [xs[-1] - SPEED * k * DT for k in range(1, 200)])
    restick = states.index(False)
    assert restick == pytest.approx((1.0 - RESTICK_FRACTION) * CONE_D * DEPTH / (SPEED * DT), abs=1)
    slips = restick + states[restick:].index(True)
    assert slips == pytest.approx((CONE_D + CONE_S) * DEPTH / (SPEED * DT), abs=1)
    assert transitions([True] + states) == 3 and lags[-1] == pytest.approx(-CONE_D * DEPTH, abs=1e-9)

    god, x0 = box_god()
    slide(god, xs)
    jitter = xs[-1] - 0.3 * CONE_D * DEPTH
    lags, states = slide(god, [jitter] + [jitter + SPEED * k * DT for k in range(1, 60)])
    assert all(states) and max(lags) <= CONE_D * DEPTH + 1e-9


@pytest.mark.parametrize("restick_time, steady", [(RESTICK_TIME, True), (0.0, False)])
def test_the_finger_twisting_and_sliding_renders_steady_friction(restick_time, steady):
    """In the finger's tick (`SoftFingerProxy`, FingerParams.restick_time, the coupling's
    damping included): pressing a floor at P = 2 N and sliding along it at 50 mm/s while
    twisting at 0.1 rad/s, the slip state gives one slide and one torsional slip and a steady
    force and torque; the per-tick tests chatter in both."""
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    params = FingerParams(radius=RADIUS, stiffness=1000.0, damping=0.0, torsion_stiffness=K_TAU,
                          soft_start=0.0, mu_s=CONE_S, mu_d=CONE_D, restick_time=restick_time)
    f = SoftFingerProxy(params, shapes_of(m, d), CH, (0.0, 0.0, 0.02))
    f.place(0.0, 0.0, 0.02)
    z = RADIUS - 0.002  # 2 mm in: P = 2 N
    forces, torques = [], []
    for k in range(1500):
        assert f.update(SPEED * k * DT, 0.0, z, RATE * k * DT, DT)
        forces.append(f.fx)
        torques.append(f.torque)
    assert f.normal_force == pytest.approx(2.0, rel=1e-9)
    tail_f, tail_t = forces[-500:], torques[-500:]
    if steady:
        assert f.slide_events == 1 and f.torsion.slip_events == 1
        assert max(tail_f) - min(tail_f) < 1e-6 and tail_f[-1] == pytest.approx(-CONE_D * 2.0, rel=1e-6)
        dynamic = MU_D / MU_S * CH.piecewise_torque(2.0)  # the default limit: eq 26 (2 N is above P*)
        assert max(tail_t) - min(tail_t) < 1e-9 and tail_t[-1] == pytest.approx(-dynamic, rel=1e-6)
    else:
        assert f.slide_events > 50 and f.torsion.slip_events > 50
        assert max(tail_f) - min(tail_f) > 0.1 and max(tail_t) - min(tail_t) > 1e-3


def test_restick_time_is_a_checked_setting():
    """restick_time is a finger setting in s, >= 0: a negative, non-finite or absurd value is
    refused with a message naming it; GodObject and TorsionalFriction check it too."""
    assert FingerParams().restick_time == RESTICK_TIME
    for bad in (-1.0, math.nan, 1e9):
        with pytest.raises(ValueError, match="restick_time"):
            FingerParams(restick_time=bad)
        with pytest.raises(ValueError, match="restick_time"):
            TorsionalFriction(CH, 1.0, restick_time=-1.0 if bad == 1e9 else bad)
        with pytest.raises(ValueError, match="restick_time"):
            GodObject([], 0.005, 0.5, 0.4, restick_time=-1.0 if bad == 1e9 else bad)
