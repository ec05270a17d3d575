"""The one boundary between the papers' units (mm, N, N·mm) and the engine's SI units.

Everything inside softproxy is N, m, rad, s. Constants printed in the seeds are
written in their own units and pass through these functions exactly once.
"""

MM = 1e-3
"""One millimetre in metres."""


def mm(value_mm: float) -> float:
    """Length in mm -> m."""
    return value_mm * MM


def to_mm(value_m: float) -> float:
    """Length in m -> mm (for printing in the papers' units)."""
    return value_m / MM


def nmm(value_nmm: float) -> float:
    """Torque in N·mm -> N·m."""
    return value_nmm * MM


def to_nmm(value_nm: float) -> float:
    """Torque in N·m -> N·mm."""
    return value_nm / MM


def per_mm_power(coefficient: float, exponent: float) -> float:
    """Coefficient of a power law `c * x**exponent` with x in mm -> the same law with x in m."""
    return coefficient * MM ** (-exponent)
