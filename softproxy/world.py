"""`World`: the MuJoCo side of the coupling — shapes for the proxies, wrenches on the bodies.

MuJoCo is stepped in two halves (mj_step1 / mj_step2) so that each tick sees the bodies
where they are *now*: mj_step1 computes positions and velocities of the current state, the
fingers then move their proxies with the bodies they touch and compute their forces, the
equal and opposite wrenches go into `xfrc_applied`, and mj_step2 integrates. This needs
MuJoCo's Euler or implicit integrator (RK4 has no split step).
"""

from __future__ import annotations

import functools

import mujoco

from softproxy.geometry import Shape, shapes_of


class World:
    """A MuJoCo model and data plus the shapes the fingers touch. SI units, world frame."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData | None = None, mesh_shape=None,
                 force_shading: bool = False) -> None:
        """`force_shading`: mesh contacts report the normal interpolated from the vertex normals
        (smooth feel of a faceted surface); the proxy still stops on the true triangles."""
        if int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
            raise ValueError("the servo loop steps MuJoCo in two halves; RK4 cannot: use Euler or implicitfast")
        self.model = model
        self.data = data if data is not None else mujoco.MjData(model)
        mujoco.mj_forward(self.model, self.data)
        if mesh_shape is None and any(int(t) == int(mujoco.mjtGeom.mjGEOM_MESH) for t in model.geom_type):
            from softproxy.mesh import MeshShape  # trimesh is imported only for scenes with meshes

            mesh_shape = functools.partial(MeshShape, shading=True) if force_shading else MeshShape
        self.shapes: list[Shape] = shapes_of(model, self.data, mesh_shape)
        self.moving = [s for s in self.shapes if not s.static]
        # views into mjData, kept: each attribute access of mjData builds a new array object
        self._xfrc = self.data.xfrc_applied
        self._xipos = self.data.xipos
        self._pushed: list[int] = []  # bodies with a wrench from last tick
        # this tick's wrench per body: force (N) and moment about the world origin (N·m), so a
        # push needs no body position; end_step moves the moment to the body's centre of mass
        self._wrench: list[list[float]] = [[0.0] * 6 for _ in range(model.nbody)]
        self._touched: list[int] = []
        # bodies welded to the world never move: a finger pushing on them moves nothing
        self._fixed = [int(w) == 0 for w in model.body_weldid]

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @timestep.setter
    def timestep(self, dt: float) -> None:
        if not dt > 0.0:
            raise ValueError(f"timestep must be > 0 s, got {dt!r}")
        self.model.opt.timestep = dt

    def begin_step(self, refresh_shapes: bool = True) -> None:
        """First half of mj_step: kinematics and velocities of the current state; refresh the
        moving shapes' poses (not needed by code that reads MuJoCo's poses itself)."""
        mujoco.mj_step1(self.model, self.data)
        if refresh_shapes:
            for s in self.moving:
                s.refresh()

    def push(self, body: int, fx, fy, fz, px, py, pz, tx, ty, tz) -> None:
        """Add force (N) at world point p (m) plus a pure torque (N·m) on `body` for this tick."""
        if self._fixed[body]:
            return
        if body not in self._touched:
            self._touched.append(body)
        w = self._wrench[body]
        w[0] += fx
        w[1] += fy
        w[2] += fz
        w[3] += py * fz - pz * fy + tx
        w[4] += pz * fx - px * fz + ty
        w[5] += px * fy - py * fx + tz

    def end_step(self) -> None:
        """Write this tick's wrenches (and clear last tick's) and run the second half of mj_step."""
        xfrc = self._xfrc
        touched = self._touched
        for body in self._pushed:
            if body not in touched:
                xfrc[body] = 0.0
        for body in touched:
            w = self._wrench[body]
            fx, fy, fz, mx, my, mz = w
            cx, cy, cz = self._xipos[body].tolist()
            # moment about the centre of mass: M_origin - c × F
            xfrc[body] = (fx, fy, fz, mx - (cy * fz - cz * fy), my - (cz * fx - cx * fz), mz - (cx * fy - cy * fx))
            w[0] = w[1] = w[2] = w[3] = w[4] = w[5] = 0.0
        self._pushed = touched
        self._touched = []
        mujoco.mj_step2(self.model, self.data)

    def clear_wrenches(self) -> None:
        """Remove every wrench the fingers put on the bodies (the safe state)."""
        for body in self._touched:
            w = self._wrench[body]
            w[0] = w[1] = w[2] = w[3] = w[4] = w[5] = 0.0
        self._touched = []
        for body in self._pushed:
            self._xfrc[body] = 0.0
        self._pushed = []

    def body_id(self, name: str) -> int:
        """Body id by name; ValueError naming the body if the model has none."""
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if i < 0:
            raise ValueError(f"the model has no body named {name!r}")
        return i
