"""The servo tick's fingers as compiled code (numba): `ServoLoop(..., compiled=True)`.

`layout` says where each number lives in the flat arrays; `shapes`, `godobject` and
`finger` are numba twins of `softproxy.geometry`, `softproxy.proxy` and `softproxy.finger`
(with `torsion` and the world's wrenches), kept equal to them to the last bit; `engine`
is the Python surface (`CompiledFingers`); `cache` keeps numba's on-disk cache in step with
the sources. numba is imported only when this package is.
"""

from softproxy.compiled.cache import drop_stale

drop_stale()  # before any kernel is loaded from numba's cache
