"""`softproxy.compiled.body_response.mobility`: J_a M⁻¹ J_bᵀ against MuJoCo's own functions called
from Python, against the acceleration MuJoCo gives a body pushed through xfrc_applied, and the
same source run as Python (ctypes); plus the `mj_jac` / `mj_solveM` bindings of
`softproxy.compiled.native`."""

import mujoco
import numpy as np
import pytest

from softproxy.compiled import native
from softproxy.compiled.body_response import mobility, workspace

# Contacts off: the physical oracle compares free (unconstrained) accelerations.
XML = """<mujoco>
  <option integrator="Euler"><flag contact="disable"/></option>
  <worldbody>
    <geom type="plane" size="1 1 .1"/>
    <body name="box" pos="0 0 .3" euler="10 20 30">
      <freejoint/>
      <geom type="box" size=".02 .03 .04" mass=".1"/>
      <site name="box_p" pos=".02 -.01 .03"/>
    </body>
    <body name="knob" pos=".3 0 .2" euler="0 30 0">
      <joint name="knob" type="hinge" axis="0 .6 .8" damping="1e-4"/>
      <geom type="cylinder" size=".01 .005" mass=".001"/>
      <site name="knob_p" pos=".01 0 .005"/>
    </body>
    <body name="link1" pos="-.3 0 .5">
      <joint type="hinge" axis="0 1 0" armature=".002" damping=".05"/>
      <geom type="capsule" fromto="0 0 0 .2 0 0" size=".015" mass=".2"/>
      <site name="link1_p" pos=".15 .015 0"/>
      <body name="link2" pos=".2 0 0">
        <joint type="hinge" axis="0 0 1"/>
        <geom type="capsule" fromto="0 0 0 .15 0 0" size=".012" mass=".1"/>
        <site name="link2_p" pos=".14 0 .012"/>
        <body name="tip" pos=".15 0 0">
          <geom type="sphere" size=".02" mass=".05"/>
          <site name="tip_p" pos="0 .02 0"/>
        </body>
      </body>
    </body>
    <body name="slider" pos="0 .4 .2" euler="0 0 40">
      <joint type="slide" axis="1 0 .3"/>
      <geom type="box" size=".03 .03 .03" mass=".5"/>
      <site name="slider_p" pos=".03 .01 -.02"/>
    </body>
    <body name="fixed" pos="0 -.4 .2">
      <geom type="box" size=".03 .03 .03"/>
      <site name="fixed_p" pos=".03 0 0"/>
    </body>
  </worldbody>
</mujoco>"""

SAME_TREE = [("box", "box"), ("knob", "knob"), ("link1", "link1"), ("link2", "link2"), ("tip", "tip"),
             ("link1", "link2"), ("link2", "link1"), ("tip", "link1"), ("slider", "slider")]
"""(a, b): a body with itself, and the cross terms of a chain (a child, a grandchild welded to it)."""

NO_RESPONSE = [("box", "knob"), ("knob", "box"), ("link2", "slider"), ("box", "fixed"), ("fixed", "fixed"),
               ("world", "box"), ("box", "world")]
"""(a, b) with no response: different trees, a body welded to the world, the world itself."""


def body(model, name):
    return 0 if name == "world" else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)


def point(model, data, name):
    """The world position (m) of the body's site `<name>_p`, or of a point 5 cm above the world origin."""
    if name == "world":
        return np.array([0.0, 0.0, 0.05])
    return data.site_xpos[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{name}_p")].copy()


@pytest.fixture
def world():
    """The model at a configuration away from its reference one, at rest, after mj_forward."""
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(46)
    mujoco.mj_resetData(model, data)
    data.qvel[:] = rng.normal(0.0, 1.0, model.nv)
    mujoco.mj_integratePos(model, data.qpos, data.qvel, 0.3)  # rotates the box's quaternion too
    data.qvel[:] = 0.0
    mujoco.mj_forward(model, data)
    return model, data


def oracle(model, data, a, pa, b, pb):
    """J_a M⁻¹ J_bᵀ from mujoco's own Python functions."""
    jacs = []
    for bid, p in ((a, pa), (b, pb)):
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        if bid > 0:
            mujoco.mj_jac(model, data, jacp, jacr, p, bid)
        jacs.append(np.vstack([jacp, jacr]))
    solved = np.zeros((6, model.nv))
    mujoco.mj_solveM(model, data, solved, jacs[1])
    return jacs[0] @ solved.T


def run(model, data, a, pa, b, pb, kernel=mobility):
    out, jac_a, jac_b, work = workspace(model.nv)
    out[:] = np.nan  # every entry must be written
    kernel(*native.addresses(model, data), a, pa, b, pb, out, jac_a, jac_b, work)
    return out


@pytest.mark.parametrize("a_name,b_name", SAME_TREE)
def test_mobility_matches_mujocos_jacobian_and_solve(world, a_name, b_name):
    """Each entry equals mujoco.mj_jac / mujoco.mj_solveM's product, and the mobility is reciprocal:
    A(a, pa; b, pb) = A(b, pb; a, pa)ᵀ (M⁻¹ is symmetric)."""
    model, data = world
    a, b = body(model, a_name), body(model, b_name)
    pa, pb = point(model, data, a_name), point(model, data, b_name)
    got = run(model, data, a, pa, b, pb)
    expected = oracle(model, data, a, pa, b, pb)
    assert np.abs(expected).max() > 0.0
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_allclose(run(model, data, b, pb, a, pa), got.T, rtol=1e-12,
                               atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("a_name,b_name", NO_RESPONSE)
def test_no_response_across_trees_or_from_the_world(world, a_name, b_name):
    """Bodies in different trees, a body welded to the world, and the world give exact zeros."""
    model, data = world
    got = run(model, data, body(model, a_name), point(model, data, a_name), body(model, b_name),
              point(model, data, b_name))
    assert np.array_equal(got, np.zeros((6, 6)))


def test_light_knob_answers_with_its_inertia(world):
    """The 1 g knob's angular mobility about its axis is 1/I_axis, its inertia about the hinge
    (from MuJoCo's mass matrix, which holds it as a 1×1 block)."""
    model, data = world
    knob = body(model, "knob")
    got = run(model, data, knob, point(model, data, "knob"), knob, point(model, data, "knob"))
    dof = model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knob")]
    M = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, M)
    axis = data.xaxis[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "knob")]
    assert axis @ got[3:, 3:] @ axis == pytest.approx(1.0 / M[dof, dof], rel=1e-12)
    assert 1.0 / M[dof, dof] > 1e5  # a light body: mobility above 1e5 1/(kg·m²)


PUSHES = SAME_TREE + [("box", "knob"), ("link2", "slider")]


@pytest.mark.parametrize("a_name,b_name", PUSHES)
def test_mobility_predicts_the_acceleration_of_a_pushed_body(world, a_name, b_name):
    """A force f and torque τ on body b at point pb (through xfrc_applied, moved to the COM as
    MuJoCo expects: τ + (pb − xipos) × f) change the acceleration of body a at pa by A·(f, τ):
    at rest the velocity-product terms are zero, so Δ(α, a) = M⁻¹-response exactly."""
    model, data = world
    a, b = body(model, a_name), body(model, b_name)
    pa, pb = point(model, data, a_name), point(model, data, b_name)
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{a_name}_p")
    A = run(model, data, a, pa, b, pb)

    def site_acceleration(force, torque):
        data.xfrc_applied[:] = 0.0
        data.xfrc_applied[b, :3] = force
        data.xfrc_applied[b, 3:] = torque + np.cross(pb - data.xipos[b], force)
        mujoco.mj_forward(model, data)
        mujoco.mj_rnePostConstraint(model, data)  # fills cacc, which mj_objectAcceleration reads
        acc = np.zeros(6)  # (angular, linear), world frame
        mujoco.mj_objectAcceleration(model, data, mujoco.mjtObj.mjOBJ_SITE, site, acc, 0)
        return np.concatenate([acc[3:], acc[:3]])

    rng = np.random.default_rng(7)
    force, torque = rng.normal(0.0, 0.01, 3), rng.normal(0.0, 1e-4, 3)  # N, N·m
    change = site_acceleration(force, torque) - site_acceleration(np.zeros(3), np.zeros(3))
    predicted = A @ np.concatenate([force, torque])
    scale = max(np.abs(predicted).max(), 1e-300)
    np.testing.assert_allclose(change, predicted, rtol=1e-7, atol=1e-7 * scale)
    if (a_name, b_name) in (("box", "knob"), ("link2", "slider")):
        assert np.array_equal(A, np.zeros((6, 6)))
    else:
        assert np.abs(change).max() > 1e-4  # the push moved something measurable


@pytest.mark.parametrize("a_name,b_name", SAME_TREE + NO_RESPONSE)
def test_python_path_gives_the_same_numbers(world, a_name, b_name):
    """The kernel's source run as Python (ctypes calls, as under NUMBA_DISABLE_JIT=1) gives the
    compiled kernel's numbers, bit for bit."""
    model, data = world
    args = (body(model, a_name), point(model, data, a_name), body(model, b_name), point(model, data, b_name))
    assert np.array_equal(run(model, data, *args, kernel=mobility.py_func), run(model, data, *args))


@pytest.mark.parametrize("integrator", ["Euler", "implicitfast", "implicit"])
def test_valid_between_mj_step1_and_mj_step2(integrator):
    """After mj_step1 (what the servo tick calls before the fingers) the mobility of a moving,
    damped chain equals the oracle on a fresh mjData of the same state after mj_forward: mj_step1
    leaves the Jacobian inputs and the factorisation of M current, and mj_step2's damped matrix
    (qH) does not enter."""
    model = mujoco.MjModel.from_xml_string(XML.replace('integrator="Euler"', f'integrator="{integrator}"'))
    data = mujoco.MjData(model)
    data.qvel[:] = np.linspace(-2.0, 2.0, model.nv)
    for _ in range(30):
        native.mj_step(*native.addresses(model, data))
    native.mj_step1(*native.addresses(model, data))
    fresh = mujoco.MjData(model)
    fresh.qpos[:], fresh.qvel[:] = data.qpos, data.qvel
    mujoco.mj_forward(model, fresh)
    for a_name, b_name in (("link2", "tip"), ("box", "box")):
        a, b = body(model, a_name), body(model, b_name)
        pa, pb = point(model, fresh, a_name), point(model, fresh, b_name)
        expected = oracle(model, fresh, a, pa, b, pb)
        np.testing.assert_allclose(run(model, data, a, pa, b, pb), expected, rtol=1e-12,
                                   atol=1e-12 * np.abs(expected).max())


def test_valid_for_a_tree_asleep():
    """A box that fell asleep on the floor (MuJoCo's sleep enabled) keeps a valid factorisation
    of M after mj_step1: its mobility equals the oracle on a fresh, awake mjData of its state."""
    model = mujoco.MjModel.from_xml_string("""<mujoco><option><flag sleep="enable"/></option><worldbody>
      <geom type="plane" size="1 1 .1"/>
      <body name="box" pos="0 0 .05" euler="0 0 30"><freejoint/><geom type="box" size=".05 .02 .03"/>
        <site name="box_p" pos=".05 0 .03"/></body></worldbody></mujoco>""")
    data = mujoco.MjData(model)
    for _ in range(3000):
        mujoco.mj_step(model, data)
    native.mj_step1(*native.addresses(model, data))
    assert not data.tree_awake[0]
    fresh = mujoco.MjData(model)
    fresh.qpos[:], fresh.qvel[:] = data.qpos, data.qvel
    mujoco.mj_forward(model, fresh)
    box = body(model, "box")
    p = point(model, fresh, "box")
    expected = oracle(model, fresh, box, p, box, p)
    np.testing.assert_allclose(run(model, data, box, p, box, p), expected, rtol=1e-12,
                               atol=1e-12 * np.abs(expected).max())


def test_points_of_any_stride_are_read(world):
    """pa and pb may be strided views (a column of a larger array): the kernel copies them."""
    model, data = world
    link2, tip = body(model, "link2"), body(model, "tip")
    points = np.zeros((3, 4))
    points[:, 1], points[:, 3] = point(model, data, "link2"), point(model, data, "tip")
    got = run(model, data, link2, points[:, 1], tip, points[:, 3])
    np.testing.assert_allclose(got, oracle(model, data, link2, points[:, 1].copy(), tip, points[:, 3].copy()),
                               rtol=1e-12, atol=1e-12 * np.abs(got).max())


@pytest.mark.parametrize("kernel", [mobility, mobility.py_func], ids=["compiled", "python"])
def test_arrays_of_the_wrong_shape_are_refused(world, kernel):
    """Scratch of the wrong size or layout raises ValueError before MuJoCo writes anything."""
    model, data = world
    box = body(model, "box")
    p = point(model, data, "box")
    out, jac_a, jac_b, work = workspace(model.nv)
    m, d = native.addresses(model, data)
    for bad in ((np.zeros((6, 6)).T, jac_a, jac_b, work),  # out transposed: not C-contiguous
                (out, np.zeros((6, model.nv + 1)), jac_b, work),
                (out, jac_a, np.zeros((3, model.nv)), work),
                (out, jac_a, jac_b, np.zeros((6, 2 * model.nv))[:, ::2])):
        with pytest.raises(ValueError, match="mobility"):
            kernel(m, d, box, p, box, p, *bad)
    with pytest.raises(ValueError, match="mobility"):
        kernel(m, d, box, p[:2], box, p, out, jac_a, jac_b, work)


def test_bindings_match_mujoco_from_python(world):
    """native.mj_jac and native.mj_solveM on raw addresses equal mujoco.mj_jac and mujoco.mj_solveM,
    a NULL jacr included, and mj_solveM solves in place."""
    model, data = world
    m, d = native.addresses(model, data)
    tip = body(model, "tip")
    p = point(model, data, "tip")
    jacp, jacr = np.full((3, model.nv), np.nan), np.full((3, model.nv), np.nan)
    native.mj_jac(m, d, jacp.ctypes.data, jacr.ctypes.data, p.ctypes.data, tip)
    expected_p, expected_r = np.zeros((3, model.nv)), np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, expected_p, expected_r, p, tip)
    assert np.array_equal(jacp, expected_p) and np.array_equal(jacr, expected_r)
    only_p = np.full((3, model.nv), np.nan)
    native.mj_jac(m, d, only_p.ctypes.data, 0, p.ctypes.data, tip)
    assert np.array_equal(only_p, expected_p)

    y = np.random.default_rng(3).normal(size=(2, model.nv))
    x = np.full_like(y, np.nan)
    native.mj_solveM(m, d, x.ctypes.data, y.ctypes.data, 2)
    expected = np.zeros_like(y)
    mujoco.mj_solveM(model, data, expected, y)
    assert np.array_equal(x, expected)
    native.mj_solveM(m, d, y.ctypes.data, y.ctypes.data, 2)
    assert np.array_equal(y, expected)
