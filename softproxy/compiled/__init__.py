"""The engine's kernels (numba): the one implementation of the servo tick.

`layout` holds the record dtypes of fingers and shapes (and the mesh tables' columns);
`tolerances` the geometric tolerances; `shapes`, `mesh` and `certificate` the proxy-vs-shape
queries (on a mesh: `triangle` one triangle, `box_tree` the tree's bounds, `tree_walk` its
walk, `patch` a hint slot's patch, `ball` the ball certificates); `godobject` the god-object solver; `finger` the coupling, the torsion law and the
tick over every finger; `native` MuJoCo's C step and a monotonic clock for kernels;
`dispatch` calls kernels from Python without numba's per-call type resolution; `cache`
keeps numba's on-disk cache in step with every file the kernels are built from. The classes
users see (`softproxy.finger`, `proxy`, `torsion`, `geometry`, `mesh`) are views onto the
records these kernels read and write. `NUMBA_DISABLE_JIT=1` runs the same source as Python.

Every kernel is compiled by `kernel.kernel`: numpy's error model (a division by zero, from a
NaN pose of a diverged simulation, say, gives Inf or NaN, which the device guard turns into
zero force and a counted fault, never an exception out of a tick), cached, one machine code
per argument types, and numba's Python wrapper only where Python calls.
"""

from softproxy.compiled.cache import drop_stale

drop_stale()  # before any kernel is loaded from numba's cache
