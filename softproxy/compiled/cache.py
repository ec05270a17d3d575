"""Keeps numba's on-disk cache of the kernels in step with every file they are built from.

numba keys each cached kernel on its own source file alone, yet the kernels bake in
constants and compile in functions from other modules: change one of those and numba would
load a kernel built with the old value. So a digest of every file the kernels are built from
is stamped beside the cache, and a different digest drops the whole cache first. Those files
are found by construction, not listed: this package's modules and every `softproxy` module
they import, transitively (read from their import statements).
"""

from __future__ import annotations

import ast
import hashlib
from pathlib import Path

from softproxy.compiled.kernel import kernel


_PACKAGE = Path(__file__).resolve().parent
_ROOT = _PACKAGE.parent
STAMP = "softproxy-compiled.stamp"


def _imports(path: Path) -> set[Path]:
    """The files of the `softproxy` modules that `path` imports."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            if name == "softproxy" or name.startswith("softproxy."):
                parts = name.split(".")[1:]
                for candidate in (_ROOT.joinpath(*parts).with_suffix(".py"), _ROOT.joinpath(*parts, "__init__.py")):
                    if parts and candidate.is_file():
                        found.add(candidate)
    return found


def sources() -> list[Path]:
    """Every file the kernels are built from: this package and what it imports of `softproxy`."""
    todo = sorted(_PACKAGE.glob("*.py"))
    seen = set(todo)
    while todo:
        for path in _imports(todo.pop()):
            if path not in seen:
                seen.add(path)
                todo.append(path)
    return sorted(seen)


@kernel(entry=True)
def _probe():
    """A cached function of this package: where numba keeps the cache (in-tree or per user)."""
    return 0


def digest() -> str:
    """SHA-256 of every source the kernels are built from."""
    h = hashlib.sha256()
    for path in sources():
        h.update(str(path.relative_to(_ROOT)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def drop_stale() -> bool:
    """Delete the package's cached kernels if they were built from other sources; True if so."""
    if not hasattr(_probe, "_cache"):  # NUMBA_DISABLE_JIT=1: plain functions, nothing cached
        return False
    return renew(Path(_probe._cache.cache_path), STAMP, digest(), "*.nb[ic]")


def renew(where: Path, stamp_name: str, current: str, pattern: str) -> bool:
    """In numba's cache folder `where`: unless the stamp `stamp_name` holds `current` (a
    digest of the sources), delete the cached kernels matching `pattern` and stamp `current`;
    True if they were dropped."""
    stamp = where / stamp_name
    try:
        if stamp.read_text() == current:
            return False
    except OSError:
        pass
    for path in where.glob(pattern):
        path.unlink(missing_ok=True)
    try:
        where.mkdir(parents=True, exist_ok=True)
        stamp.write_text(current)
    except OSError:  # a read-only cache: numba will not save there either
        pass
    return True
