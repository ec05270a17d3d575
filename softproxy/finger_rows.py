"""`FingerRows`: the engine's table of fingers, and `Field`, the attributes that view it.

A finger is two records of a `FingerRows` table (`softproxy.compiled.layout`), as MuJoCo
keeps mjModel apart from mjData: its model (`FINGER_MODEL`: radius, friction, stiffness,
clamps, the torsion law — what a run holds constant) and its data (`FINGER_DATA`: the
god-object, coupling, torsion, counters and this tick's sample — what a tick changes), which
the compiled kernels read and write in place. `SoftFingerProxy`, `GodObject` and
`TorsionalFriction` hold no state of their own: their attributes are `Field`s reading and
writing a field (or one component of a vector field) of those records, so what a user reads
is always what the engine computed, with nothing to copy back and forth. A finger made alone
has a table of one; a `ServoLoop` moves its fingers into one table of its own (`gather`).
"""

from __future__ import annotations

import numpy as np

from softproxy.compiled.dispatch import EntryPoints
from softproxy.compiled.godobject import scratch
from softproxy.compiled.layout import FINGER_DATA, FINGER_MODEL, Fingers
from softproxy.geometry import ShapeSet


class FingerRows:
    """n fingers over one ShapeSet: `model` and `data` (recarrays of `FINGER_MODEL` and
    `FINGER_DATA`), `near` (each finger's broad-phase list of shape rows) and the kernels' scratch."""

    def __init__(self, shapes: ShapeSet | None, n: int) -> None:
        """`shapes` None: records that touch nothing (a torsion law on its own)."""
        self.shapes = shapes
        self.model = np.zeros(n, dtype=FINGER_MODEL).view(np.recarray)
        self.data = np.zeros(n, dtype=FINGER_DATA).view(np.recarray)
        self.data.contact_torsion = 1.0  # no material: the finger's own torsional law
        self.data.popped = -1  # inside no shape it popped through
        self.near = np.zeros((n, max(len(shapes or ()), 1)), dtype=np.int64)
        self.scratch = scratch()
        self.tables = Fingers(self.model, self.data, self.near, self.scratch)
        """What the kernels take (`softproxy.compiled.layout.Fingers`)."""
        # item access on a plain structured row is ~7x faster than on a recarray's
        self._plain = (self.model.view(np.ndarray), self.data.view(np.ndarray))
        self.run = EntryPoints()
        """`run(kernel, *args)`: the kernel through its entry point (numba's per-call dispatch of
        this table's record arrays would cost more than the kernel itself)."""

    def records(self, i: int) -> tuple:
        """Finger i's (model, data) as numpy structured scalars that read and write the table in place."""
        return self._plain[0][i], self._plain[1][i]

    @classmethod
    def gather(cls, views: list) -> "FingerRows":
        """One table holding the records of `views` (`RecordView`s over one ShapeSet: the
        caller checks that, as `ServoLoop` does), in order; each view is rebound to its new row."""
        table = cls(views[0]._rows.shapes, len(views))
        for i, v in enumerate(views):
            table.model[i] = v._rows.model[v._i]
            table.data[i] = v._rows.data[v._i]
            table.near[i] = v._rows.near[v._i]
            v._bind(table, i)
        return table


class RecordView:
    """A view onto finger `_i` of a `FingerRows` table `_rows`: its `Field`s read and write
    that finger's records (`_recs`: model, data), and `_bind` moves it to another."""

    def _bind(self, rows: FingerRows, i: int) -> None:
        self._rows, self._i, self._recs = rows, i, rows.records(i)


class Field:
    """An attribute that is field `name` of its object's finger (component `index` of a vector
    field), as `kind`; the field is looked up in FINGER_MODEL, then FINGER_DATA."""

    __slots__ = ("name", "index", "kind", "_which")

    def __init__(self, name: str | None = None, index: int | None = None, kind=float) -> None:
        self.name = name
        self.index = index
        self.kind = kind

    def __set_name__(self, owner, attr: str) -> None:
        if self.name is None:
            self.name = attr
        if self.name in FINGER_MODEL.names:
            self._which = 0
        elif self.name in FINGER_DATA.names:
            self._which = 1
        else:
            raise AttributeError(f"{owner.__name__}.{attr}: no finger field {self.name!r}")

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        value = obj._recs[self._which][self.name]
        return self.kind(value if self.index is None else value[self.index])

    def __set__(self, obj, value) -> None:
        if self.index is None:
            obj._recs[self._which][self.name] = value
        else:
            obj._recs[self._which][self.name][self.index] = value


def vector(name: str, size: int = 3) -> tuple[Field, ...]:
    """The components of vector field `name` as `size` float attributes: `fx, fy, fz =
    vector("force")` in a view's class body."""
    return tuple(Field(name, i) for i in range(size))
