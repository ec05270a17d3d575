"""Keeps numba's on-disk cache of the compiled tick in step with every file it is built from.

numba keys each cached kernel on its own source file alone, yet the kernels bake in
constants from `layout` and from the Python engine (tolerances, limits, iteration budgets):
change one of those and numba would load a kernel built with the old value. So a digest of
every such file is stamped beside the cache, and a different digest drops the cache first.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from numba import njit

_PACKAGE = Path(__file__).resolve().parent
SOURCES = sorted(_PACKAGE.glob("*.py")) + [_PACKAGE.parent / f"{name}.py" for name in
                                           ("geometry", "proxy", "finger", "fingertip", "mesh", "device_guard")]
"""The files the kernels are built from: this package and the modules they import constants from."""
KERNEL_MODULES = ("mesh", "shapes", "godobject", "finger", "cache", "certificate")
"""This package's modules with cached kernels (their files in the cache folder are dropped).
`softproxy.device_guard.guard_wrench` is cached beside its own module, and numba checks that
file itself; the kernels here that compiled it in are dropped through the digest (SOURCES)."""
STAMP = "softproxy-compiled.stamp"


@njit(cache=True)
def _probe():
    """A cached function of this package: where numba keeps the cache (in-tree or per user)."""
    return 0


def digest() -> str:
    """SHA-256 of every source the kernels are built from."""
    h = hashlib.sha256()
    for path in SOURCES:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def drop_stale() -> bool:
    """Delete the package's cached kernels if they were built from other sources; True if so."""
    if not hasattr(_probe, "_cache"):  # NUMBA_DISABLE_JIT=1: plain functions, nothing cached
        return False
    where = Path(_probe._cache.cache_path)
    stamp = where / STAMP
    current = digest()
    try:
        if stamp.read_text() == current:
            return False
    except OSError:
        pass
    for path in where.glob("*.nb[ic]"):
        if path.name.split(".", 1)[0] in KERNEL_MODULES:
            path.unlink(missing_ok=True)
    try:
        where.mkdir(parents=True, exist_ok=True)
        stamp.write_text(current)
    except OSError:  # a read-only cache: numba will not save there either
        pass
    return True
