"""`SceneRenderer`: draws one state frame with moderngl — the same code in the window and offscreen.

What is drawn:

- every visible geom of the compiled model (plane, sphere, capsule, ellipsoid, cylinder, box,
  mesh), coloured from `geom_rgba` (or its material's), a plane's 2D texture if it has one,
  posed each frame from the published `geom_xpos` / `geom_xmat`;
- per finger, in its own colour: the proxy sphere (opaque), the device position as a
  translucent ghost of the same radius, the spring between them (a line), the contact force
  on the finger as a red arrow from the contact point (1 cm per N, at most 10 radii);
- the torsion dial of a soft finger in contact: a ring around the contact point in the
  contact plane, a white spoke for the goal α_g and a spoke for the proxy twist α_p turned
  by (α_p − α_g) k_τ / limit × 90°, so the ticks at ±90° are where the finger starts to
  slip (the angles themselves are tiny; their values are in the text overlay). The ring is
  green while the twist sticks, red while it slips. A point-contact finger has no dial;
- a text overlay (Pillow, DejaVu Sans Mono from matplotlib when found): time, servo rate,
  tick p50/p99, faults and misses, and one line per finger.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import moderngl
import numpy as np

from softproxy.viewer import meshes
from softproxy.viewer.state import (
    F_ALPHA_G, F_ALPHA_P, F_CONTACT, F_DEVICE, F_FORCE, F_K_TAU, F_LIMIT, F_MODE, F_MODEL, F_NORMAL, F_NORMAL_FORCE,
    F_ENERGY, F_POINT, F_PROXY, F_RADIUS, F_SLIPPING, F_SLIPS, F_TORQUE, F_TORSION_CONTACT, F_VALID, POINT, S_FAULTS,
    S_MISSES, S_P50_US, S_P99_US, S_RATE, S_RATE_NOMINAL, S_REALTIME, MODEL_NAMES, Frame,
)

FINGER_COLORS = [
    (0.20, 0.45, 0.95),  # blue
    (0.75, 0.30, 0.90),  # purple
    (0.10, 0.75, 0.80),  # teal
    (0.95, 0.40, 0.65),  # pink
    (0.55, 0.55, 0.95),  # lavender
]
BACKGROUND = (0.17, 0.19, 0.23)
FORCE_COLOR = (0.90, 0.12, 0.10)
STICK_COLOR = (0.20, 0.90, 0.30)
SLIP_COLOR = (1.00, 0.25, 0.20)
SPRING_COLOR = (1.00, 0.90, 0.35)
GHOST_ALPHA = 0.30
ARROW_M_PER_N = 0.01

_MESH_VS = """
#version 330
uniform mat4 u_mvp;
uniform mat4 u_model;
uniform mat3 u_normal;
in vec3 in_pos;
in vec3 in_norm;
in vec2 in_uv;
out vec3 v_world;
out vec3 v_norm;
out vec2 v_uv;
void main() {
    v_world = (u_model * vec4(in_pos, 1.0)).xyz;
    v_norm = u_normal * in_norm;
    v_uv = in_uv;
    gl_Position = u_mvp * vec4(in_pos, 1.0);
}
"""

_MESH_FS = """
#version 330
uniform vec4 u_color;
uniform vec3 u_eye;
uniform vec3 u_light;
uniform int u_textured;
uniform sampler2D u_tex;
uniform vec2 u_repeat;
uniform int u_shadow;        // 1: a shadow flattened onto a plane, shaded as that plane, darker
uniform mat4 u_plane_inv;    // world -> plane frame
uniform vec2 u_plane_half;   // plane half-extents
uniform vec3 u_plane_normal;
in vec3 v_world;
in vec3 v_norm;
in vec2 v_uv;
out vec4 f_color;
void main() {
    vec3 n = u_shadow == 1 ? u_plane_normal : normalize(v_norm);
    vec2 uv = v_uv;
    if (u_shadow == 1) uv = (u_plane_inv * vec4(v_world, 1.0)).xy / (2.0 * u_plane_half) + 0.5;
    vec3 v = normalize(u_eye - v_world);
    if (dot(n, v) < 0.0) n = -n;
    vec3 base = u_color.rgb;
    if (u_textured == 1) base *= texture(u_tex, uv * u_repeat).rgb;
    vec3 l = normalize(-u_light);
    float diffuse = 0.30 + 0.45 * max(dot(n, v), 0.0) + 0.35 * max(dot(n, l), 0.0);
    float spec = 0.12 * pow(max(dot(n, normalize(l + v)), 0.0), 40.0);
    vec3 c = u_shadow == 1 ? 0.62 * base * diffuse : base * diffuse + vec3(spec);
    f_color = vec4(min(c, vec3(1.0)), u_color.a);
}
"""

_LINE_VS = """
#version 330
uniform mat4 u_vp;
in vec3 in_pos;
in vec4 in_color;
out vec4 v_color;
void main() { v_color = in_color; gl_Position = u_vp * vec4(in_pos, 1.0); }
"""

_LINE_FS = """
#version 330
in vec4 v_color;
out vec4 f_color;
void main() { f_color = v_color; }
"""

_TEXT_VS = """
#version 330
in vec2 in_pos;
in vec2 in_uv;
out vec2 v_uv;
void main() { v_uv = in_uv; gl_Position = vec4(in_pos, 0.0, 1.0); }
"""

_TEXT_FS = """
#version 330
uniform sampler2D u_tex;
in vec2 v_uv;
out vec4 f_color;
void main() { f_color = texture(u_tex, v_uv); }
"""

MAX_LINE_VERTICES = 8192


def _gl(m: np.ndarray) -> bytes:
    """A row-major numpy matrix as GL's column-major float32 bytes."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def _basis(z: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector z."""
    a = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(a, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _tangent(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents of the plane normal to n, chosen the same way every frame."""
    e = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t1 = np.cross(n, e)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(n, t1)


def finger_color(i: int) -> tuple[float, float, float]:
    return FINGER_COLORS[i % len(FINGER_COLORS)]


def _font_path() -> str | None:
    spec = importlib.util.find_spec("matplotlib")
    for root in (spec.submodule_search_locations or []) if spec else []:
        p = Path(root) / "mpl-data" / "fonts" / "ttf" / "DejaVuSansMono.ttf"
        if p.exists():
            return str(p)
    return None


class TextOverlay:
    """Lines of text rendered with Pillow into a texture, drawn at the top-left corner."""

    def __init__(self, ctx: moderngl.Context, size: int = 15) -> None:
        from PIL import ImageFont

        self.ctx = ctx
        self._font_size = None
        self.size = size
        self._fonts: dict = {}
        self._ImageFont = ImageFont
        self.prog = ctx.program(vertex_shader=_TEXT_VS, fragment_shader=_TEXT_FS)
        self.vbo = ctx.buffer(reserve=4 * 4 * 6)
        self.vao = ctx.vertex_array(self.prog, [(self.vbo, "2f 2f", "in_pos", "in_uv")])
        self.texture = None
        self._key = None

    def _font(self, size: int):
        font = self._fonts.get(size)
        if font is None:
            path = _font_path()
            try:
                font = self._ImageFont.truetype(path, size) if path else self._ImageFont.load_default(size=size)
            except Exception:
                font = self._ImageFont.load_default()
            self._fonts[size] = font
        return font

    def _image(self, lines: list[str], size: int):
        from PIL import Image, ImageDraw

        font = self._font(size)
        pad, step = max(4, size // 2), int(size * 1.35)
        width = max((int(font.getlength(line)) for line in lines), default=0) + 2 * pad
        height = step * len(lines) + 2 * pad
        img = Image.new("RGBA", (max(width, 1), max(height, 1)), (0, 0, 0, 0))
        draw = ImageDraw.Draw(img)
        draw.rounded_rectangle((0, 0, width - 1, height - 1), radius=pad, fill=(10, 12, 16, 170))
        for k, line in enumerate(lines):
            draw.text((pad, pad + k * step), line, font=font, fill=(235, 238, 242, 255))
        return img.transpose(Image.Transpose.FLIP_TOP_BOTTOM)

    def draw(self, lines: list[str], width: int, height: int, scale: float = 1.0, margin: int = 8) -> None:
        if not lines:
            return
        size = max(8, int(round(self.size * scale)))
        key = (tuple(lines), size)
        if key != self._key:
            img = self._image(lines, size)
            if self.texture is not None:
                self.texture.release()
            self.texture = self.ctx.texture(img.size, 4, img.tobytes())
            self.texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._key = key
        tw, th = self.texture.size
        m = margin * scale
        x0, x1 = -1.0 + 2.0 * m / width, -1.0 + 2.0 * (m + tw) / width
        y1, y0 = 1.0 - 2.0 * m / height, 1.0 - 2.0 * (m + th) / height
        quad = np.array([[x0, y0, 0, 0], [x1, y0, 1, 0], [x1, y1, 1, 1],
                         [x0, y0, 0, 0], [x1, y1, 1, 1], [x0, y1, 0, 1]], dtype=np.float32)
        self.vbo.write(quad.tobytes())
        self.texture.use(0)
        self.prog["u_tex"] = 0
        self.vao.render(moderngl.TRIANGLES)

    def release(self) -> None:
        if self.texture is not None:
            self.texture.release()
        self.vao.release()
        self.vbo.release()
        self.prog.release()


class _Geom:
    __slots__ = ("index", "vao", "vbo", "color", "texture", "repeat", "half")

    def __init__(self, index, vao, vbo, color, texture, repeat, half=(1.0, 1.0)):
        self.index, self.vao, self.vbo, self.color, self.texture, self.repeat = index, vao, vbo, color, texture, repeat
        self.half = half  # a plane's drawn half-extents


class SceneRenderer:
    """Draws frames of one model into the framebuffer in use. One per GL context."""

    def __init__(self, ctx: moderngl.Context, model, finger_names: list[str] | None = None) -> None:
        self.ctx = ctx
        self.model = model
        self.finger_names = list(finger_names or [])
        self.prog = ctx.program(vertex_shader=_MESH_VS, fragment_shader=_MESH_FS)
        self.line_prog = ctx.program(vertex_shader=_LINE_VS, fragment_shader=_LINE_FS)
        self._textures: dict[int, moderngl.Texture] = {}
        light = np.array([0.0, 0.3, -1.0])
        if model.nlight > 0:
            d = np.array(model.light_dir[0], dtype=float)
            if np.linalg.norm(d) > 0:
                light = d
        self.light = light / np.linalg.norm(light)
        plane_extent = max(10.0 * float(model.stat.extent), 1.0)
        self.geoms: list[_Geom] = []
        for g in range(model.ngeom):
            if not meshes.geom_visible(model, g):
                continue
            mesh = meshes.geom_mesh(model, g, plane_extent)
            if mesh is None or len(mesh) == 0:
                continue
            vbo = ctx.buffer(mesh.tobytes())
            vao = self._vao(vbo)
            texture, repeat = self._plane_texture(g) if int(model.geom_type[g]) == meshes.PLANE else (None, (1.0, 1.0))
            half = (float(np.abs(mesh[:, 0]).max()), float(np.abs(mesh[:, 1]).max()))
            self.geoms.append(_Geom(g, vao, vbo, meshes.geom_rgba(model, g), texture, repeat, half))
        self._buffers = []
        self.sphere = self._mesh(meshes.sphere(1.0, 32, 16))
        self.shaft = self._mesh(meshes.cylinder(1.0, 0.5, 16, z0=0.0))  # z from 0 to 1
        self.head = self._mesh(meshes.cone(1.0, 1.0, 24))
        self.line_vbo = ctx.buffer(reserve=MAX_LINE_VERTICES * 7 * 4, dynamic=True)
        self.line_vao = ctx.vertex_array(self.line_prog, [(self.line_vbo, "3f 4f", "in_pos", "in_color")])
        self.text = TextOverlay(ctx)
        try:
            ctx.line_width = 2.0
        except Exception:
            pass

    # -- set-up ------------------------------------------------------------------------
    def _vao(self, vbo):
        return self.ctx.vertex_array(self.prog, [(vbo, "3f 3f 2f", "in_pos", "in_norm", "in_uv")])

    def _mesh(self, mesh: np.ndarray):
        vbo = self.ctx.buffer(mesh.tobytes())
        self._buffers.append(vbo)
        return self._vao(vbo)

    def _plane_texture(self, g: int):
        """The plane's material 2D texture (RGB role), uploaded once; its repeat factors."""
        m = self.model
        mat = int(m.geom_matid[g])
        if mat < 0:
            return None, (1.0, 1.0)
        texids = np.atleast_1d(m.mat_texid[mat])
        tex = int(texids[1]) if texids.size > 1 else int(texids[0])  # mjTEXROLE_RGB
        if tex < 0 or int(m.tex_type[tex]) != 0:  # 2D only
            return None, (1.0, 1.0)
        if tex not in self._textures:
            w, h, c = int(m.tex_width[tex]), int(m.tex_height[tex]), int(m.tex_nchannel[tex])
            if c not in (1, 3, 4):
                return None, (1.0, 1.0)
            adr = int(m.tex_adr[tex])
            data = np.ascontiguousarray(m.tex_data[adr:adr + w * h * c], dtype=np.uint8)
            t = self.ctx.texture((w, h), c, data.tobytes())
            t.repeat_x = t.repeat_y = True
            t.build_mipmaps()
            t.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            self._textures[tex] = t
        repeat = np.array(m.mat_texrepeat[mat], dtype=float)
        if bool(m.mat_texuniform[mat]):
            repeat = repeat * 2.0 * np.array(m.geom_size[g][:2])
        return self._textures[tex], (float(repeat[0]), float(repeat[1]))

    # -- drawing -----------------------------------------------------------------------
    def _draw(self, vao, model_m: np.ndarray, normal_m: np.ndarray, color, texture=None, repeat=(1.0, 1.0),
              shadow_on=None) -> None:
        """One mesh; `shadow_on` = (world-to-plane matrix, half-extents, normal) draws it as a
        shadow shaded like that plane."""
        prog = self.prog
        prog["u_mvp"].write(_gl(self._vp @ model_m))
        prog["u_model"].write(_gl(model_m))
        prog["u_normal"].write(_gl(normal_m))
        prog["u_color"].value = tuple(float(c) for c in (color if len(color) == 4 else (*color, 1.0)))
        if shadow_on is not None:
            inv, half, n = shadow_on
            prog["u_shadow"].value = 1
            prog["u_plane_inv"].write(_gl(inv))
            prog["u_plane_half"].value = half
            prog["u_plane_normal"].value = tuple(float(v) for v in n)
        else:
            prog["u_shadow"].value = 0
        if texture is not None:
            texture.use(0)
            prog["u_tex"].value = 0
            prog["u_textured"].value = 1
            prog["u_repeat"].value = repeat
        else:
            prog["u_textured"].value = 0
        vao.render(moderngl.TRIANGLES)

    def _sphere(self, centre, radius: float, color) -> None:
        m = np.eye(4)
        m[:3, :3] *= radius
        m[:3, 3] = centre
        self._draw(self.sphere, m, np.eye(3), color)

    def _arrow(self, start: np.ndarray, vec: np.ndarray, radius: float, color) -> None:
        length = float(np.linalg.norm(vec))
        if length < 1e-9:
            return
        rot = _basis(vec / length)
        head = min(0.8 * radius * 4.0, 0.5 * length)
        shaft = length - head
        for vao, r, z0, zl in ((self.shaft, radius, 0.0, shaft), (self.head, 2.5 * radius, shaft, head)):
            if zl <= 0.0:
                continue
            scale = np.diag([r, r, zl])
            m = np.eye(4)
            m[:3, :3] = rot @ scale
            m[:3, 3] = start + rot[:, 2] * z0
            self._draw(vao, m, rot @ np.diag([1.0 / r, 1.0 / r, 1.0 / zl]), color)

    def render(self, frame: Frame, camera, width: int, height: int, framebuffer=None,
               overlay: list[str] | None = None, text_scale: float = 1.0) -> None:
        """Draw `frame` seen by `camera` into `framebuffer` (default: the one in use), width x height px."""
        ctx = self.ctx
        fbo = framebuffer if framebuffer is not None else ctx.fbo
        fbo.use()
        ctx.viewport = (0, 0, width, height)
        ctx.clear(*BACKGROUND, 1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        ctx.disable(moderngl.BLEND)
        self._vp = camera.view_projection(width, height)
        self.prog["u_eye"].value = tuple(float(v) for v in camera.eye())
        self.prog["u_light"].value = tuple(float(v) for v in self.light)

        translucent = []
        for geom in self.geoms:
            if geom.color[3] < 0.999:
                translucent.append(geom)
                continue
            self._geom(frame, geom)
        self._shadows(frame)

        lines: list = []
        ghosts = []
        for i, f in enumerate(frame.fingers if frame.ticks > 0 else ()):  # no finger before the first tick
            color = finger_color(i)
            r = float(f[F_RADIUS])
            proxy = f[F_PROXY:F_PROXY + 3]
            self._sphere(proxy, r, color)
            if f[F_VALID]:
                device = f[F_DEVICE:F_DEVICE + 3]
                ghosts.append((device, r, (*(0.5 * np.array(color) + 0.5), GHOST_ALPHA)))
                lines.append((device, proxy, (*SPRING_COLOR, 1.0)))
            if f[F_CONTACT]:
                force = f[F_FORCE:F_FORCE + 3]
                fmag = float(np.linalg.norm(force))
                if fmag > 1e-6:
                    length = min(ARROW_M_PER_N * fmag, 10.0 * r)
                    self._arrow(f[F_POINT:F_POINT + 3], force / fmag * length, 0.1 * r, FORCE_COLOR)
                if f[F_MODE] != POINT and f[F_TORSION_CONTACT]:
                    self._torsion_dial(f, r, lines)
        self._lines(lines)

        if translucent or ghosts:
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            fbo.depth_mask = False
            for geom in translucent:
                self._geom(frame, geom)
            for centre, r, color in ghosts:
                self._sphere(centre, r, color)
            fbo.depth_mask = True

        if overlay:
            ctx.disable(moderngl.DEPTH_TEST)
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
            self.text.draw(overlay, width, height, text_scale)
            ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.BLEND)

    def _shadows(self, frame: Frame) -> None:
        """Planar shadows of the geoms and the proxies on every plane facing the light.

        Each shadow is the object flattened onto the plane along the light, a hair above it,
        and shaded as the plane itself (its colour, its texture), only darker: opaque, so
        overlapping shadows and overlapping triangles of one shadow never darken twice."""
        planes = [g for g in self.geoms if int(self.model.geom_type[g.index]) == meshes.PLANE and g.color[3] >= 0.999]
        casters = [g for g in self.geoms if int(self.model.geom_type[g.index]) != meshes.PLANE]
        fingers = frame.fingers if frame.ticks > 0 else ()
        if not planes or not (casters or len(fingers)):
            return
        eps = 1e-3 * max(float(self.model.stat.extent), 1e-3)
        for plane in planes:
            rot = frame.geom_xmat[plane.index]
            n = rot[:, 2]
            nl = float(n @ self.light)
            if nl > -0.2:  # the light grazes the plane or comes from below
                continue
            d = -float(n @ frame.geom_xpos[plane.index]) - eps  # n.x + d = 0, lifted by eps
            shadow = np.eye(4)
            shadow[:3, :3] -= np.outer(self.light, n) / nl
            shadow[:3, 3] = -self.light * d / nl
            inv = np.eye(4)
            inv[:3, :3] = rot.T
            inv[:3, 3] = -rot.T @ frame.geom_xpos[plane.index]
            items = []
            for geom in casters:
                m = np.eye(4)
                m[:3, :3] = frame.geom_xmat[geom.index]
                m[:3, 3] = frame.geom_xpos[geom.index]
                items.append((geom.vao, m))
            for f in fingers:
                m = np.eye(4)
                m[:3, :3] *= float(f[F_RADIUS])
                m[:3, 3] = f[F_PROXY:F_PROXY + 3]
                items.append((self.sphere, m))
            for vao, m in items:
                self._draw(vao, shadow @ m, np.eye(3), plane.color, plane.texture, plane.repeat, (inv, plane.half, n))

    def _geom(self, frame: Frame, geom: _Geom) -> None:
        rot = frame.geom_xmat[geom.index]
        m = np.eye(4)
        m[:3, :3] = rot
        m[:3, 3] = frame.geom_xpos[geom.index]
        self._draw(geom.vao, m, rot, geom.color, geom.texture, geom.repeat)

    def _torsion_dial(self, f: np.ndarray, r: float, lines: list) -> None:
        n = f[F_NORMAL:F_NORMAL + 3]
        if not np.linalg.norm(n) > 0.5:
            return
        color = (*(SLIP_COLOR if f[F_SLIPPING] else STICK_COLOR), 1.0)
        centre = f[F_POINT:F_POINT + 3] + n * 0.08 * r
        radius = 1.4 * r
        t1, t2 = _tangent(n)
        k = 48
        ang = np.linspace(0.0, 2.0 * np.pi, k + 1)
        ring = centre + radius * (np.cos(ang)[:, None] * t1 + np.sin(ang)[:, None] * t2)
        for a, b in zip(ring[:-1], ring[1:]):
            lines.append((a, b, color))
        for side in (1.0, -1.0):  # the slip threshold
            d = side * t2
            lines.append((centre + 0.8 * radius * d, centre + 1.15 * radius * d, color))
        lines.append((centre, centre + 1.1 * radius * t1, (1.0, 1.0, 1.0, 1.0)))  # goal α_g
        stretch = float(f[F_ALPHA_P] - f[F_ALPHA_G])
        limit, k_tau = float(f[F_LIMIT]), float(f[F_K_TAU])
        if limit > 0.0 and k_tau > 0.0:
            ratio = stretch * k_tau / limit
        else:
            ratio = 0.0 if stretch == 0.0 else math.copysign(1.0, stretch)
        theta = max(-1.5, min(1.5, ratio)) * (np.pi / 2.0)
        d = math.cos(theta) * t1 + math.sin(theta) * t2
        lines.append((centre, centre + radius * d, color))  # proxy α_p

    def _lines(self, lines: list) -> None:
        if not lines:
            return
        data = np.empty((2 * len(lines), 7), dtype=np.float32)
        for k, (a, b, c) in enumerate(lines[:MAX_LINE_VERTICES // 2]):
            data[2 * k, :3], data[2 * k, 3:] = a, c
            data[2 * k + 1, :3], data[2 * k + 1, 3:] = b, c
        n = min(len(lines), MAX_LINE_VERTICES // 2) * 2
        self.line_vbo.write(data[:n].tobytes())
        self.line_prog["u_vp"].write(_gl(self._vp))
        self.line_vao.render(moderngl.LINES, vertices=n)

    def release(self) -> None:
        for geom in self.geoms:
            geom.vao.release()
            geom.vbo.release()
        for t in self._textures.values():
            t.release()
        for vao in (self.sphere, self.shaft, self.head, self.line_vao):
            vao.release()
        for b in self._buffers + [self.line_vbo]:
            b.release()
        self.text.release()
        self.prog.release()
        self.line_prog.release()


def overlay_lines(frame: Frame, finger_names: list[str], status: str = "", help_line: str = "") -> list[str]:
    """The text overlay: timing line, one line per finger, status and key help."""
    rate = frame.scalar(S_RATE)
    nominal = frame.scalar(S_RATE_NOMINAL)
    mode = "real time" if frame.scalar(S_REALTIME) else "lockstep"
    rate_text = f"{rate:7.0f} Hz" if rate > 0 else f"{nominal:g} Hz"
    lines = [
        f"t {frame.t:7.3f} s  servo {rate_text} ({mode}, {nominal:g} Hz)",
        f"tick p50 {frame.scalar(S_P50_US):6.1f} us  p99 {frame.scalar(S_P99_US):6.1f} us  "
        f"faults {int(frame.scalar(S_FAULTS))}  misses {int(frame.scalar(S_MISSES))}",
    ]
    for i, f in enumerate(frame.fingers):
        name = finger_names[i] if i < len(finger_names) else f"finger {i + 1}"
        m = int(f[F_MODEL])
        kind = "point" if f[F_MODE] == POINT else f"soft {MODEL_NAMES[m] if 0 <= m < len(MODEL_NAMES) else ''}".strip()
        fmag = float(np.linalg.norm(f[F_FORCE:F_FORCE + 3]))
        text = f"{i + 1} {name:<6} {kind:<9} |F| {fmag:5.2f} N  P {f[F_NORMAL_FORCE]:5.2f} N"
        if f[F_MODE] != POINT:
            state = "-" if not f[F_TORSION_CONTACT] else ("SLIP" if f[F_SLIPPING] else "stick")
            text += (f"  a_p {math.degrees(f[F_ALPHA_P]):+7.3f} a_g {math.degrees(f[F_ALPHA_G]):+7.3f} deg"
                     f"  M {f[F_TORQUE] * 1000:+6.2f} N.mm {state}")
        text += f"  slips {int(f[F_SLIPS])}  E {f[F_ENERGY] * 1000:+.3f} mJ"
        lines.append(text)
    if status:
        lines.append(status)
    if help_line:
        lines.append(help_line)
    return lines
