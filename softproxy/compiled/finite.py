"""Whether a kernel's number is usable: one test for NaN and ±Inf, for every kernel."""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel


@kernel
def finite(v):
    """True for a number that is neither NaN nor ±Inf (a sum of several tests them all: NaN
    or an infinity in any term carries through)."""
    return v == v and v != math.inf and v != -math.inf
