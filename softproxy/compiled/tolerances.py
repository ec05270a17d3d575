"""Geometric tolerances the kernels bake in (m, or cosines): one place for all of them."""

CONTACT_TOL = 1e-9
"""A sphere within this distance (m) of a surface touches it."""
GRAZE = 1e-9
"""A touching sphere moves *into* a surface only if the motion's inward component exceeds
this fraction of its length; below it the motion is tangent (rounding noise)."""
FACE_PARALLEL = 1.0 - 1e-12
"""A normal this aligned with a face's normal (cosine) is that face's."""
MAX_ADVANCE_STEPS = 32
"""Conservative-advancement iterations before a grazing sweep stops short (safe side)."""
