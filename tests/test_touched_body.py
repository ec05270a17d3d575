"""The body a finger pushes is the body it touches: on every contact tick the geom of the
pushed body (`SoftFingerProxy.body`, which gets -F and carries the proxy along) is within
contact distance of the proxy sphere, checked with MuJoCo's own `mj_geomDistance`, across
the seam of two geoms of different bodies (boxes side by side, a box beside a capsule, a
mesh beside a box) under random pressing and sliding strokes, with and without friction."""

import math

import mujoco
import numpy as np
from hypothesis import given, settings, strategies as st

from softproxy.compiled.godobject import TOUCH_TOL
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.geometry import shapes_of
from softproxy.mesh import MeshShape

DT = 1e-3  # s, one tick at 1 kHz
CONTACT_DISTANCE = 1e-5
"""A proxy sphere this close to a geom (m) touches it. The engine rests a proxy within ~1e-7 m
of what it touches (and drops a slipping proxy that would float over an edge onto the
surface below); a neighbour across a seam sits 0.1 mm and more away. The pushed body must
also be the nearest, within TOUCH_TOL (the tie rule at a seam)."""
PROBE = 1e-6
"""Radius (m) of the oracle's probe sphere at the proxy centre."""

BOX_MESH = (  # a 6 x 6 x 4 cm box as twelve triangles, outward winding
    '<asset><mesh name="brick" vertex="-.03 -.03 -.02  .03 -.03 -.02  .03 .03 -.02  -.03 .03 -.02 '
    '-.03 -.03 .02  .03 -.03 .02  .03 .03 .02  -.03 .03 .02" '
    'face="0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7"/></asset>')


def pair_xml(kind: str, gap: float, step: float, mocap: bool) -> tuple[str, str]:
    """Two bodies meeting at the plane x = 0 (a seam `gap` m wide, the right one's top `step`
    m higher): the left a box, the right a box, a capsule along y or a mesh box. Returns
    (asset, worldbody) MJCF; `mocap` makes the bodies movable (the proxy is then carried in
    the touched geom's frame) though nothing moves them."""
    m = ' mocap="true"' if mocap else ""
    left = f'<body name="left" pos="-.03 0 .02"{m}><geom type="box" size=".03 .03 .02"/></body>'
    h = 0.02 + step
    if kind == "boxes":
        right = f'<body name="right" pos="{0.03 + gap!r} 0 {h!r}"{m}><geom type="box" size=".03 .03 .02"/></body>'
    elif kind == "capsule":
        right = (f'<body name="right" pos="{0.02 + gap!r} 0 {h!r}"{m}>'
                 '<geom type="capsule" size=".02 .03" quat="0.7071068 0.7071068 0 0"/></body>')
    else:
        right = f'<body name="right" pos="{0.03 + gap!r} 0 {h!r}"{m}><geom type="mesh" mesh="brick"/></body>'
    return (BOX_MESH if kind == "mesh" else ""), left + right


class Oracle:
    """The same bodies plus a probe sphere: MuJoCo's distance from the proxy to each body."""

    def __init__(self, asset: str, bodies: str) -> None:
        probe = (f'<body name="probe" mocap="true"><geom type="sphere" size="{PROBE!r}" '
                 'contype="0" conaffinity="0"/></body>')
        self.m = mujoco.MjModel.from_xml_string(f"<mujoco>{asset}<worldbody>{bodies}{probe}</worldbody></mujoco>")
        self.d = mujoco.MjData(self.m)
        self.probe = self.m.ngeom - 1

    def gap(self, body: int, p) -> float:
        """Distance (m) from the point p to the nearest geom of `body`, by mj_geomDistance."""
        self.d.mocap_pos[self.m.body_mocapid[self.m.body("probe").id]] = p
        mujoco.mj_forward(self.m, self.d)
        return min(mujoco.mj_geomDistance(self.m, self.d, g, self.probe, 1.0, None) + PROBE
                   for g in range(self.m.ngeom) if g != self.probe and int(self.m.geom_bodyid[g]) == body)


stroke = st.fixed_dictionaries({
    "kind": st.sampled_from(["boxes", "capsule", "mesh"]),
    "mocap": st.booleans(),
    "gap": st.sampled_from([0.0, 0.0, 1e-4, 3e-4]),   # m between the two bodies
    "step": st.sampled_from([0.0, 0.0, 2e-4, -2e-4]),  # m the right top stands above the left
    "radius": st.floats(0.002, 0.01),
    "mu": st.sampled_from([0.0, 0.3, 1.0, 1.5]),
    "start": st.floats(-0.02, 0.02),                  # x of the press (m)
    "press": st.floats(5e-4, 4e-3),                   # depth of the device below the top (m)
    "heading": st.floats(-0.6, 0.6),                  # rad off the x axis
    "beyond": st.floats(0.003, 0.02),                 # m slid past the seam
    "speed": st.floats(0.02, 0.4),                    # m/s
    "back": st.booleans(),                            # slide back the way it came
})


@settings(max_examples=120, deadline=None)
@given(stroke)
def test_pushed_body_is_the_body_touched(s):
    """Press, slide across the seam (and back): on every tick with a contact, the pushed
    body has a geom within CONTACT_DISTANCE of the proxy sphere, by MuJoCo's distance."""
    asset, bodies = pair_xml(s["kind"], s["gap"], s["step"], s["mocap"])
    model = mujoco.MjModel.from_xml_string(f"<mujoco>{asset}<worldbody>{bodies}</worldbody></mujoco>")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    oracle = Oracle(asset, bodies)
    r = s["radius"]
    params = FingerParams(radius=r, mu_s=s["mu"], mu_d=0.8 * s["mu"], model="point")
    top = 0.04 + max(s["step"], 0.0)  # the higher of the two tops (m)
    above = (s["start"], 0.0, top + r + 0.005)
    finger = SoftFingerProxy(params, shapes_of(model, data, MeshShape), start=above)
    assert finger.place(*above)
    x0, y0, z0 = s["start"], 0.0, top + r - s["press"]
    ux, uy = math.cos(s["heading"]), math.sin(s["heading"])
    if s["start"] > 0.0:
        ux = -ux  # toward the seam
    reach = (abs(s["start"]) + s["beyond"]) / abs(ux)  # m: across the seam, onto the other body
    n = max(1, int(reach / (s["speed"] * DT)))
    path = [(x0, y0, above[2] + (z0 - above[2]) * k / 20) for k in range(1, 21)]
    path += [(x0 + ux * reach * k / n, y0 + uy * reach * k / n, z0) for k in range(1, n + 1)]
    if s["back"]:
        path += path[-2:20:-1]
    contacts = 0
    for p in path:
        assert finger.update(*p, 0.0, DT)
        if finger.body >= 0:
            contacts += 1
            proxy = (finger.god.x, finger.god.y, finger.god.z)
            gap = oracle.gap(finger.body, proxy) - r
            assert gap <= CONTACT_DISTANCE, (
                f"pushed body {model.body(finger.body).name} is {gap * 1e3:.3f} mm from the proxy at {proxy}")
            nearest = min(oracle.gap(b, proxy) - r for b in (1, 2))
            assert gap <= nearest + TOUCH_TOL, (
                f"pushed body {model.body(finger.body).name} is {(gap - nearest) * 1e3:.3f} mm farther than the "
                f"nearest from the proxy at {proxy}")
    assert contacts > 0
