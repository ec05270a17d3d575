"""The stability bench's device model and the sampled wall's analytic bounds (benchmarks/device_models.py,
benchmarks/sampled_wall.py): exact integration against closed-form motions, the encoder, the bounds."""

import dataclasses
import math

import numpy as np
import pytest

from softproxy.benchmarks.device_models import PROFILES, Hand, HandHeldHandle
from softproxy.benchmarks.sampled_wall import (colgate_boundary, small_period_boundary, spectral_radius,
                                               stability_boundary)
from softproxy.device import DeviceSample

FREE = Hand(stiffness_Npm=0.0, damping_Nspm=0.0, ramp_s=0.0)


def drive(handle, times, force):
    """Hold `force` from t = 0 and read the handle at `times`; the exact positions and velocities."""
    samples = [DeviceSample()]
    handle.read(0.0, samples)
    handle.send(0, 0.0, 0.0, force, 0.0, 0.0, 0.0)
    zs, vs = [], []
    for t in times:
        handle.read(t, samples)
        zs.append(handle.z)
        vs.append(handle.v)
    return np.array(zs), np.array(vs)


def test_a_free_mass_damper_under_a_held_force_moves_as_the_closed_form():
    """m z'' = F − b z' from rest: v = F/b (1 − e^{−bt/m}), z = F/b t − F m/b² (1 − e^{−bt/m});
    read at irregular times (each read integrates exactly from the last), to 1e-12."""
    profile = dataclasses.replace(PROFILES["Falcon"], mass_kg=0.15, damping_Nspm=0.7)
    m, b, F = 0.15, 0.7, 2.5
    times = np.cumsum([1e-3, 3.7e-4, 0.05, 2e-3, 0.3, 1e-5, 0.8])
    z, v = drive(HandHeldHandle(profile, 1e-3, FREE, encoder=False), times, F)
    decay = 1.0 - np.exp(-b * times / m)
    np.testing.assert_allclose(v, F / b * decay, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(z, F / b * times - F * m / b ** 2 * decay, rtol=1e-12, atol=1e-15)


def test_the_hand_spring_swings_the_undamped_handle_as_a_cosine():
    """No damping, the hand's spring K_h towards its target z_t, released at rest at 0 with no
    force: z = z_t (1 − cos ωt), ω = √(K_h/m) — the hand's input is exact too."""
    profile = dataclasses.replace(PROFILES["Touch"], damping_Nspm=0.0)
    hand = Hand(stiffness_Npm=300.0, damping_Nspm=0.0, depth_m=-5e-3, ramp_s=0.0)
    omega = math.sqrt(300.0 / profile.mass_kg)
    times = np.arange(1, 400) * 2.5e-4
    z, _ = drive(HandHeldHandle(profile, 2.5e-4, hand, encoder=False), times, 0.0)
    np.testing.assert_allclose(z, -5e-3 * (1.0 - np.cos(omega * times)), rtol=0, atol=1e-14)


def test_the_work_of_the_held_force_is_force_times_travel():
    """Under a constant held force the work the handle records is exactly F·(z − z0)."""
    profile = PROFILES["omega.3"]
    handle = HandHeldHandle(profile, 1e-3, FREE, encoder=False, start_m=0.01)
    z, _ = drive(handle, np.arange(1, 50) * 1e-3, 1.3)
    assert handle.work == pytest.approx(1.3 * (z[-1] - 0.01), rel=1e-12)


def test_the_encoder_reports_whole_counts_within_half_a_count():
    """With the encoder on the position read is a multiple of the resolution, within half a
    count of the true one; off, it is the true position."""
    profile = PROFILES["Touch"]
    for encoder in (True, False):
        handle = HandHeldHandle(profile, 1e-3, Hand(), encoder=encoder, start_m=0.0)
        samples = [DeviceSample()]
        handle.read(0.0, samples)
        handle.send(0, 0.0, 0.0, 0.4, 0.0, 0.0, 0.0)
        for k in range(1, 60):
            handle.read(k * 1e-3, samples)
            if encoder:
                counts = samples[0].z / profile.resolution_m
                assert counts == pytest.approx(round(counts), abs=1e-9)
                assert abs(samples[0].z - handle.z) <= profile.resolution_m / 2 * (1 + 1e-9)
            else:
                assert samples[0].z == handle.z


def test_the_tap_lands_inside_a_period_at_its_time():
    """A tap at 2.5 ms, between the ticks at 2 and 3 ms: at 3 ms the free handle (no force, no
    damping) has moved for 0.5 ms at the tapped velocity, exactly kick·(t − t_kick)."""
    profile = dataclasses.replace(PROFILES["Falcon"], damping_Nspm=0.0)
    handle = HandHeldHandle(profile, 1e-3, FREE, encoder=False, kick_s=2.5e-3, kick_mps=0.2)
    z, v = drive(handle, [1e-3, 2e-3, 3e-3], 0.0)
    assert z[:2].tolist() == [0.0, 0.0]
    assert z[2] == pytest.approx(0.2 * 0.5e-3, rel=1e-12) and v[2] == pytest.approx(0.2, rel=1e-12)


@pytest.mark.parametrize("name", sorted(PROFILES))
@pytest.mark.parametrize("rate", [250.0, 1000.0, 4000.0, 10000.0])
def test_the_stability_boundary_is_where_a_pole_leaves_the_unit_circle(name, rate):
    """Just below the computed boundary every closed-loop pole is inside the unit circle, just
    above one is outside; Colgate & Schenkel's passivity bound (1997, b > KT/2 + |B|) lies
    below it (passive ⇒ stable), and for B = 0 the small-period closed form 2(b + b_h)/T
    (Gil et al. 2004) is within 5 %."""
    p, hand, T = PROFILES[name], Hand(), 1.0 / rate
    args = (T, p.mass_kg, p.damping_Nspm, hand.stiffness_Npm, hand.damping_Nspm)
    for B in (0.0, 2.0, 10.0):
        K = stability_boundary(B, *args)
        assert 0.0 < K < math.inf
        assert spectral_radius(K * 0.999, B, *args) < 1.0 < spectral_radius(K * 1.001, B, *args)
        assert colgate_boundary(B, p.damping_Nspm, T) < K
    K0 = stability_boundary(0.0, *args)
    assert K0 == pytest.approx(small_period_boundary(0.0, p.damping_Nspm + hand.damping_Nspm, T), rel=0.05)


def test_a_damper_too_large_for_the_period_is_unstable_at_any_stiffness():
    """B ≳ 2m/T: the backward-difference damper alone drives the Nyquist mode unstable, so the
    stable range of K is empty (the Touch, 45 g, at 250 Hz: 2m/T = 22.5 N·s/m)."""
    p, hand = PROFILES["Touch"], Hand()
    assert stability_boundary(30.0, 1 / 250, p.mass_kg, p.damping_Nspm, hand.stiffness_Npm, hand.damping_Nspm) == 0.0


def test_every_profile_says_where_each_figure_comes_from():
    """Each figure of a device profile has a source or the reason it was assumed."""
    for name, p in PROFILES.items():
        for figure in ("mass_kg", "damping_Nspm", "resolution_m", "max_force_N", "vendor_stiffness_Npm",
                       "driver_stiffness_Npm"):
            assert len(p.sources.get(figure, "")) > 20, (name, figure)


def test_the_wall_grid_runs_the_passivity_controller_on_and_off_when_the_engine_has_one(monkeypatch):
    """`bench stability` asks ServoLoop's signature once: with a `passivity` parameter every wall
    cell and boundary runs with it on and off and passes it through; without, once, as is."""
    from softproxy.benchmarks import stability

    seen = []
    engine = stability.ServoLoop

    class WithController(engine):
        def __init__(self, *args, passivity: bool = True, **kwargs):
            seen.append(passivity)
            kwargs.pop("passivity", None)
            super().__init__(*args, **kwargs)

    class WithoutController(engine):
        def __init__(self, world, fingers, device, rate_hz=1000.0, **kwargs):
            super().__init__(world, fingers, device, rate_hz, **kwargs)

    monkeypatch.setattr(stability, "ServoLoop", WithoutController)
    stability.passivity_modes.cache_clear()
    try:
        assert stability.passivity_modes() == (None,)
        walls = [c for c in stability.grid() if c["kind"] in ("wall", "boundary")]
        assert {c["passivity"] for c in walls} == {None}
        monkeypatch.setattr(stability, "ServoLoop", WithController)
        stability.passivity_modes.cache_clear()
        assert stability.passivity_modes() == (True, False)
        walls_on_off = [c for c in stability.grid() if c["kind"] in ("wall", "boundary")]
        assert len(walls_on_off) == 2 * len(walls)
        assert {c["passivity"] for c in walls_on_off} == {True, False}
        stability.wall_run("Falcon", 1000.0, 2.0, 250.0, passivity=False)
        assert seen == [False]
    finally:
        stability.passivity_modes.cache_clear()
