"""The servo tick's fingers as compiled code (numba): `ServoLoop(..., compiled=True)`.

`layout` says where each number lives in the flat arrays; `shapes`, `godobject` and
`finger` are numba twins of `softproxy.geometry`, `softproxy.proxy` and `softproxy.finger`
(with `torsion` and the world's wrenches), kept equal to them to the last bit; `engine`
is the Python surface (`CompiledFingers`). numba is imported only when this package is.
"""
