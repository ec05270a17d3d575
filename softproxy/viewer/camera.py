"""Orbit camera: view and projection matrices, mouse orbit/zoom/pan, framing, projection of points.

Angles follow MuJoCo's free camera: azimuth (deg) turns about world z, elevation (deg)
is negative when looking down; the camera looks along
(cos el cos az, cos el sin az, sin el). Matrices are 4x4 float32, column vectors
(p_clip = P V p), so upload them transposed to GL (column-major).
"""

from __future__ import annotations

import math

import numpy as np

from softproxy.viewer.meshes import PLANE
from softproxy.viewer.state import F_DEVICE, F_PROXY, F_RADIUS


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    f = target - eye
    f = f / np.linalg.norm(f)
    s = np.cross(f, up)
    if np.linalg.norm(s) < 1e-9:
        s = np.cross(f, (0.0, 1.0, 0.0))
    s = s / np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    f = 1.0 / math.tan(math.radians(fovy_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


class OrbitCamera:
    """Looks at `lookat` from `distance` (m) at `azimuth` / `elevation` (deg); `reset()` goes home."""

    def __init__(self, lookat=(0.0, 0.0, 0.0), distance: float = 1.0, azimuth: float = 90.0,
                 elevation: float = -40.0, fovy: float = 45.0) -> None:
        self.fovy = float(fovy)
        self.home = (np.array(lookat, dtype=float), float(distance), float(azimuth), float(elevation))
        self.reset()

    def reset(self) -> None:
        lookat, self.distance, self.azimuth, self.elevation = self.home
        self.lookat = lookat.copy()

    # -- matrices ----------------------------------------------------------------------
    def forward(self) -> np.ndarray:
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])

    def eye(self) -> np.ndarray:
        return self.lookat - self.distance * self.forward()

    def view(self) -> np.ndarray:
        return look_at(self.eye(), self.lookat)

    def projection(self, aspect: float) -> np.ndarray:
        return perspective(self.fovy, aspect, self.distance * 0.01, self.distance * 100.0)

    def view_projection(self, width: int, height: int) -> np.ndarray:
        return self.projection(width / max(height, 1)) @ self.view()

    def project(self, point, width: int, height: int) -> tuple[float, float, float]:
        """Pixel (x right, y down from the top-left) and NDC depth of a world point."""
        p = self.view_projection(width, height) @ np.array([*point, 1.0])
        ndc = p[:3] / p[3]
        return (ndc[0] + 1.0) * 0.5 * width, (1.0 - ndc[1]) * 0.5 * height, ndc[2]

    # -- mouse -------------------------------------------------------------------------
    def orbit(self, dx: float, dy: float) -> None:
        """Drag by (dx, dy) pixels: turn about the look-at point."""
        self.azimuth = (self.azimuth - 0.3 * dx) % 360.0
        self.elevation = min(89.0, max(-89.0, self.elevation - 0.3 * dy))

    def pan(self, dx: float, dy: float, height: int) -> None:
        """Drag by (dx, dy) pixels: move the look-at point in the view plane."""
        scale = 2.0 * self.distance * math.tan(math.radians(self.fovy) / 2.0) / max(height, 1)
        v = self.view()
        right, up = v[0, :3], v[1, :3]
        self.lookat = self.lookat - right * dx * scale + up * dy * scale

    def zoom(self, steps: float) -> None:
        """Scroll: positive steps move closer."""
        self.distance = min(1e3, max(1e-4, self.distance * 0.9 ** steps))


def frame_points(model, frame) -> tuple[np.ndarray, float]:
    """Centre and radius (m) of what there is to see: every non-plane geom and every finger."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for g in range(model.ngeom):
        if int(model.geom_type[g]) == PLANE or int(model.geom_group[g]) > 2:
            continue
        r = float(model.geom_rbound[g]) or 0.05
        p = frame.geom_xpos[g]
        lo, hi = np.minimum(lo, p - r), np.maximum(hi, p + r)
    for f in frame.fingers if frame.ticks > 0 else ():  # fingers are placed at the first tick
        r = float(f[F_RADIUS]) or 0.01
        for p in (f[F_PROXY:F_PROXY + 3], f[F_DEVICE:F_DEVICE + 3]):
            if np.all(np.isfinite(p)) and np.any(p != 0.0):
                lo, hi = np.minimum(lo, p - r), np.maximum(hi, p + r)
    if not np.all(np.isfinite(lo)):
        c = np.array(model.stat.center, dtype=float)
        return c, max(float(model.stat.extent), 0.05)
    return (lo + hi) / 2.0, max(float(np.linalg.norm(hi - lo)) / 2.0, 0.02)


def framing(model, frame, azimuth: float = 90.0, elevation: float = -40.0, fovy: float = 45.0,
            margin: float = 1.0, aspect: float = 4 / 3) -> OrbitCamera:
    """A camera (and its home) that shows the whole scene of `frame`."""
    centre, radius = frame_points(model, frame)
    half = math.radians(fovy) / 2.0
    half = min(half, math.atan(math.tan(half) * aspect))
    return OrbitCamera(centre, margin * radius / math.sin(half), azimuth, elevation, fovy)
