"""The one error format of bad input, and the finite-number check of the laws' arguments.

Every input mistake (a scene file, a HID profile, a [device] table, `FingerParams(...)`, an
argument of a fingertip or sensing law) is one line:

    [FILE: ]PATH must be REQUIREMENT, got VALUE[ (HINT)]

e.g. `scene.toml: finger[0].stiffness must be at least 10 N/m, got 2.0 (stiffness is in N/m:
2 N/mm is 2000 N/m)`. FILE is left out where there is none (a Python call), PATH is the
field's path in the file (`finger[0].tactile.cells`), HINT the likely fix where the bound
makes the mistake unambiguous. This module is the bottom layer of validation (it imports
nothing of softproxy): the laws check their arguments with it, and `softproxy.schema`, which
declares every input's fields, words its errors with it.
"""

from __future__ import annotations

import math
import operator


class InputError(ValueError):
    """Bad input: one line naming the file (where there is one), the field, what was wrong and the fix."""


class UnitWarning(UserWarning):
    """A value legal but implausible in its SI unit, as one typed in another would be (mm for m,
    degrees for rad): one line naming the field, the value and the likely unit. A warning, not
    an error: a research setup may mean it."""


PLAUSIBLE_REACH_M = 1.0
"""A device position farther than this from the device's origin on an axis (m) is likely in
mm: no desktop haptic device reaches a metre."""
PLAUSIBLE_TWIST_RAD = 2.0 * math.pi
"""A twist beyond ± a turn (rad) is likely in degrees."""


def implausible(path: str, value, unit: str, likely: str, *, source: str = "") -> UnitWarning:
    """The one-line warning `[source: ]path is value unit: likely?`."""
    where = f"{source}: " if source else ""
    return UnitWarning(f"{where}{path} is {value!r} {unit}: {likely}")


def must_be(path: str, requirement: str, value, *, source: str = "", hint: str = "") -> InputError:
    """The one-line error `[source: ]path must be requirement, got value[ (hint)]`."""
    where = f"{source}: " if source else ""
    fix = f" ({hint})" if hint else ""
    return InputError(f"{where}{path} must be {requirement}, got {value!r}{fix}")


def check_finite(name: str, value, *, positive: bool = False, non_negative: bool = False) -> float:
    """`value` as a finite float (> 0 or >= 0 if asked); InputError naming `name` otherwise."""
    if isinstance(value, (str, bytes)):  # float("5") would take a string for a number
        raise must_be(name, "a number", value)
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise must_be(name, "a number", value) from None
    except OverflowError:  # an integer past a float's range
        raise must_be(name, "finite", value) from None
    if not math.isfinite(number):
        raise must_be(name, "finite", value)
    if positive and number <= 0.0:
        raise must_be(name, "> 0", value)
    if non_negative and number < 0.0:
        raise must_be(name, ">= 0", value)
    return number


def check_count(name: str, value, minimum: int = 1) -> int:
    """`value` as an int >= minimum (an int or numpy integer, never a bool or 2.0); InputError otherwise."""
    try:
        number = None if isinstance(value, bool) else operator.index(value)
    except TypeError:
        number = None
    if number is None or number < minimum:
        raise must_be(name, f"an integer >= {minimum}", value)
    return number
