"""`FingerRows`: the engine's table of fingers, and `Field`, the attributes that view it.

Every finger's state — its god-object, coupling, torsion, counters — is one `FINGER` record
(`softproxy.compiled.layout`) of a `FingerRows` table, which the compiled kernels read and
write in place. `SoftFingerProxy`, `GodObject` and `TorsionalFriction` hold no state of their
own: their attributes are `Field`s reading and writing their record, so what a user reads is
always what the engine computed, with nothing to copy back and forth. A finger made alone
has a table of one; a `ServoLoop` moves its fingers into one table of its own (`gather`).
"""

from __future__ import annotations

import numpy as np

from softproxy.compiled.dispatch import EntryPoints
from softproxy.compiled.godobject import scratch
from softproxy.compiled.layout import FINGER
from softproxy.geometry import ShapeSet


class FingerRows:
    """n finger records over one ShapeSet: `F` (a recarray of `FINGER`), `near` (each finger's
    broad-phase list of shape rows) and the kernels' scratch."""

    def __init__(self, shapes: ShapeSet | None, n: int) -> None:
        """`shapes` None: records that touch nothing (a torsion law on its own)."""
        self.shapes = shapes
        self.F = np.zeros(n, dtype=FINGER).view(np.recarray)
        self.near = np.zeros((n, max(len(shapes or ()), 1)), dtype=np.int64)
        self.scratch = scratch()
        self._plain = self.F.view(np.ndarray)  # item access on a plain structured row is ~7x faster
        self.run = EntryPoints()
        """`run(kernel, *args)`: the kernel through its entry point (numba's per-call dispatch of
        this table's record arrays would cost more than the kernel itself)."""

    def record(self, i: int):
        """Row i as a numpy structured scalar that reads and writes the table in place."""
        return self._plain[i]

    @classmethod
    def gather(cls, views: list) -> "FingerRows":
        """One table holding the records of `views` (`RecordView`s over one ShapeSet: the
        caller checks that, as `ServoLoop` does), in order; each view is rebound to its new row."""
        table = cls(views[0]._rows.shapes, len(views))
        for i, v in enumerate(views):
            table.F[i] = v._rows.F[v._i]
            table.near[i] = v._rows.near[v._i]
            v._bind(table, i)
        return table


class RecordView:
    """A view onto record `_i` of a `FingerRows` table `_rows`: its `Field`s read and write
    that record (`_rec`), and `_bind` moves it to another."""

    def _bind(self, rows: FingerRows, i: int) -> None:
        self._rows, self._i, self._rec = rows, i, rows.record(i)


class Field:
    """An attribute that is field `name` of its object's record (`obj._rec`), as `kind`."""

    __slots__ = ("name", "kind")

    def __init__(self, name: str | None = None, kind=float) -> None:
        self.name = name
        self.kind = kind

    def __set_name__(self, owner, attr: str) -> None:
        if self.name is None:
            self.name = attr

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        return self.kind(obj._rec[self.name])

    def __set__(self, obj, value) -> None:
        obj._rec[self.name] = value
