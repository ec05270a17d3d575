"""The 3-DOF god-object of one finger: a view onto its record, solved by the compiled kernel.

The solver (sweep, slide on up to three constraint planes, friction cone with a slip state,
the touched geom's frame carrying the proxy) is `softproxy.compiled.godobject`, whose
docstring describes it; `GodObject` here reads and writes its finger's records
(`softproxy.finger_rows`), usable alone or as part of a `SoftFingerProxy`. Units: m, N,
N/m, N·s/m.
"""

from __future__ import annotations

from softproxy.compiled import godobject as kernel
from softproxy.compiled.godobject import RESTICK_TIME
from softproxy.compiled.godobject import WORKSPACE_LIMIT  # noqa: F401 (the workspace a device position must lie in)
from softproxy.finger_rows import Field, FingerRows, RecordView, vector
from softproxy.geometry import Shape, ShapeSet
from softproxy.input_error import check_finite, must_be


class GodObject(RecordView):
    """Translational proxy of one finger. `update(x_d)` moves it; read the contact fields after.

    Fields after `update`: x, y, z (proxy centre, m); contact (bool); nx, ny, nz (unit
    contact normal, out of the object); shape (the touched Shape or None); depth (how far
    the device is inside the constraint, m); sticking (bool: static friction; False in
    contact is the slip state, dynamic friction); lx, ly, lz (the proxy in the touched
    geom's frame, m); planes (the constraint planes it rests on).

    `restick_time` (s): a slipping proxy that has not had to slide for this long sticks
    again; 0 re-tests the static cone every tick (the literature's cone as printed).
    """

    x, y, z = vector("pos")
    contact = Field(kind=bool)
    nx, ny, nz = vector("normal")
    depth = Field()
    sticking = Field(kind=bool)
    squeezed = Field(kind=bool)
    """Caught between a moving and a static shape with no room between them: the proxy rests on
    the static one (never pushed through it), and the moving one overlaps it."""
    squeeze_ticks = Field(kind=int)
    lx, ly, lz = vector("local")
    radius = Field()
    mu_s = Field()
    mu_d = Field()
    restick_time = Field("slide_restick")

    def __init__(self, shapes: list[Shape], radius: float, mu_s: float = 0.0, mu_d: float = 0.0,
                 position: tuple[float, float, float] = (0.0, 0.0, 0.0), restick_time: float = RESTICK_TIME) -> None:
        radius = check_finite("radius", radius, non_negative=True)  # m
        mu_s = check_finite("mu_s", mu_s, non_negative=True)
        mu_d = check_finite("mu_d", mu_d, non_negative=True)
        if mu_d > mu_s:
            raise must_be("mu_d", f"<= mu_s ({mu_s!r})", mu_d)
        restick_time = check_finite("restick_time", restick_time, non_negative=True)  # s
        shapes = ShapeSet.of(shapes)
        shapes.prepare(float(radius))  # nothing the queries need is built in the tick
        self._bind(FingerRows(shapes, 1), 0)
        self.radius = float(radius)
        self.mu_s = float(mu_s)
        self.mu_d = float(mu_d)
        self.restick_time = float(restick_time)
        self.reset(*position)

    @classmethod
    def view(cls, rows: FingerRows, i: int) -> "GodObject":
        """The god-object of finger i of a table (no state of its own)."""
        god = cls.__new__(cls)
        god._bind(rows, i)
        return god

    @property
    def shapes(self) -> ShapeSet:
        return self._rows.shapes

    @property
    def shape(self) -> Shape | None:
        """The touched shape, or None."""
        k = int(self._recs[1]["touched"])
        return self._rows.shapes[k] if k >= 0 else None

    @property
    def planes(self) -> list[tuple]:
        """The constraint planes it rests on: (nx, ny, nz, c (m), shape), at most three."""
        shapes = self._rows.shapes
        fd = self._recs[1]
        return [(*p[:4], shapes[int(p[4])]) for p in fd["planes"][:int(fd["nplanes"])].tolist()]

    @property
    def near(self) -> list[Shape]:
        """The shapes the last broad phase gathered."""
        shapes = self._rows.shapes
        return [shapes[k] for k in self._rows.near[self._i, :int(self._recs[1]["nnear"])].tolist()]

    def reset(self, x: float, y: float, z: float) -> None:
        """Put the proxy at (x, y, z) with no contact (pushed out of any shape it overlaps).
        ValueError for a position outside the workspace (±WORKSPACE_LIMIT m on each axis)."""
        r = self._rows
        s = r.shapes
        if not r.run(kernel.reset_row, s.tables, r.tables, self._i, float(x), float(y),
                     float(z)):
            raise ValueError(f"proxy position must lie within ±{WORKSPACE_LIMIT} m, got {(x, y, z)!r}")

    def update(self, xd: float, yd: float, zd: float, dt: float = 1e-3) -> bool:
        """Move the proxy toward the device position (m, world), a tick of dt s later (the
        re-stick time counts in it). False on NaN/Inf/garbage: the proxy then only follows
        its body (`follow`)."""
        r = self._rows
        s = r.shapes
        return r.run(kernel.update_row, s.tables, r.tables, self._i, float(xd), float(yd),
                     float(zd), float(dt))

    def follow(self) -> None:
        """Without a device sample: the proxy stays on the body it touches and out of anything
        that moved into it, so a skipped tick never leaves it inside a moving object."""
        r = self._rows
        s = r.shapes
        r.run(kernel.follow_row, s.tables, r.tables, self._i)
