"""The files an MJCF model names, checked before MuJoCo opens any of them.

MuJoCo's loader opens whatever a `file` attribute names and reads it to the end: a FIFO
blocks it forever (inside C, where no signal handler runs until it returns), a directory or
a device (/dev/zero, /dev/stdin) fails late or never. `check_model_files(mjcf)` walks the
model's XML, its `<include>`s too (each checked before it is opened), and refuses, in one
line naming the XML file, the element and the path, any file an attribute names (`file`,
`fileright`, ... of meshes, height fields, textures, skins, models and includes) that
exists but is not a regular file. A file that does not exist is left for MuJoCo to name.

Where MuJoCo looks: an include relative to the main model's folder; an asset relative to
`<compiler meshdir/texturedir/assetdir>` (themselves relative to that folder) or the folder
itself. Every such candidate is checked, so a path that resolves anywhere MuJoCo may look is
covered whatever the compiler's precedence.
"""

from __future__ import annotations

import os
import stat
import xml.etree.ElementTree as ElementTree
from pathlib import Path

MAX_INCLUDE_DEPTH = 32
"""Nested includes followed at most (MuJoCo refuses a file that includes itself)."""
_DIRS = ("meshdir", "texturedir", "assetdir")


class ModelFileError(ValueError):
    """A file named by an MJCF that MuJoCo must not open; one line naming the XML file, the
    element and the path."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (a named pipe: MuJoCo would wait on it forever)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def _check(path: Path, where: str) -> bool:
    """ModelFileError if `path` exists and is no regular file; True if it is one."""
    try:
        info = os.stat(path)  # follows links: what MuJoCo would open
    except OSError:
        return False  # missing (or unreadable): MuJoCo names it
    if not stat.S_ISREG(info.st_mode):
        raise ModelFileError(f"{where} names {path}, which is {_kind(info.st_mode)}; a model file must be a "
                             f"regular file")
    return True


def _parse(path: Path) -> ElementTree.Element | None:
    try:
        return ElementTree.parse(path).getroot()
    except (ElementTree.ParseError, OSError, RecursionError, ValueError):
        return None  # MuJoCo parses it again and names what is wrong


def check_model_files(mjcf: str | Path) -> None:
    """ModelFileError unless every file `mjcf` names (through its includes too) that exists is
    a regular file (see the module docstring). The model file itself is checked first."""
    mjcf = Path(mjcf)
    _check(mjcf, "the scene")
    root_dir = mjcf.parent
    trees: list[tuple[Path, ElementTree.Element]] = []
    queue, seen = [(mjcf, 0)], set()
    while queue:  # the model and every include, each checked before it is opened
        path, depth = queue.pop()
        key = os.path.realpath(path)
        if key in seen or depth > MAX_INCLUDE_DEPTH:
            continue
        seen.add(key)
        root = _parse(path)
        if root is None:
            continue
        trees.append((path, root))
        for element in root.iter("include"):
            name = element.get("file")
            if name:
                target = root_dir / name
                if _check(target, f"{path}: <include file={name!r}>"):
                    queue.append((target, depth + 1))
    dirs = {root_dir}
    for _, root in trees:
        for element in root.iter("compiler"):
            for attribute in _DIRS:
                value = element.get(attribute)
                if value:
                    dirs.add(root_dir / value)
    for path, root in trees:
        for element in root.iter():
            if element.tag == "include":
                continue
            for attribute, value in element.attrib.items():
                if not attribute.startswith("file") or not value:
                    continue
                where = f"{path}: <{element.tag} {attribute}={value!r}>"
                for folder in sorted(dirs):
                    _check(folder / value, where)
