"""Refusing, before any work, an output that would replace one of the command's inputs
(issue #52, item 1).

Every command names all the files it reads and all the files it writes. An output that
resolves to an input -- the same name, a hard link or a symlink to it (same device and
inode), or a file an input folder's reader reads -- is refused with an InputError naming the
output's option and the input it would destroy. Two outputs that resolve to one file are
refused too (the second would replace the first).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from csgs_codec.errors import InputError

#: Files of an input folder looked at (a scene or camera folder holds a handful; a bound
#: keeps a wrong argument such as '/' from walking the disk).
MAX_FOLDER_FILES = 10_000
#: Folder levels below an input folder looked at (INRIA: point_cloud/iteration_N/x.ply).
MAX_FOLDER_DEPTH = 3
#: The kinds of file an input folder's readers read: scenes and cameras (.ply, .json, COLMAP
#: .bin/.txt), SOG images (.webp), Scaffold-GS MLPs (.pt, .pth), embeddings (.npy). Other
#: files in the folder (a .csgs written there by an earlier run, say) are no input.
FOLDER_INPUT_SUFFIXES = frozenset({".ply", ".json", ".bin", ".txt", ".webp", ".pt", ".pth",
                                   ".npy"})

Named = tuple[str, "str | os.PathLike | None"]


def refuse_overwriting_inputs(outputs: Iterable[Named], inputs: Iterable[Named]) -> None:
    """Raise InputError when an output would replace an input or another output.

    Args:
        outputs: (option, path) per file the command writes, e.g. ``("-o", "x.ply")``;
            None paths are skipped.
        inputs: (what, path) per file or folder the command reads, e.g.
            ``("--cameras", "cams.json")``; a folder stands for the files under it (up to
            :data:`MAX_FOLDER_DEPTH` levels) of the kinds in :data:`FOLDER_INPUT_SUFFIXES`.
            None paths and missing files are skipped.

    Raises:
        InputError: naming the output file and option, and the input it resolves to.
    """
    known = {}
    for what, path in inputs:
        if path is None:
            continue
        for file in _files_of(Path(path)):
            identity = _identity(file)
            if identity is not None:
                known.setdefault(identity, (what, file))
    seen: dict[str, str] = {}
    for option, path in outputs:
        if path is None:
            continue
        identity = _identity(Path(path))
        if identity is not None and identity in known:
            what, file = known[identity]
            raise InputError(f"is the input file {os.fspath(file)!r} ({what}); refusing to "
                             "overwrite it (choose another output)", file=path,
                             property=option)
        resolved = _resolved(path)
        if resolved in seen:
            raise InputError(f"is also the output of {seen[resolved]}; give each output its "
                             "own file", file=path, property=option)
        seen[resolved] = option


def _identity(path: Path) -> tuple[int, int] | None:
    """(device, inode) of the file ``path`` leads to, symlinks followed; None if none."""
    try:
        info = os.stat(path)
    except (OSError, ValueError):  # missing, a name too long, a NUL byte: nothing to protect
        return None
    return info.st_dev, info.st_ino


def _resolved(path) -> str:
    """The absolute, symlink-free spelling of ``path`` (for outputs not written yet)."""
    try:
        return os.path.realpath(path)
    except (OSError, ValueError):
        return os.path.abspath(path)


def _files_of(path: Path) -> list[Path]:
    """``path`` itself, and when it is a folder the files under it that readers read
    (bounded)."""
    try:
        is_dir = path.is_dir()
    except (OSError, ValueError):
        return []
    if not is_dir:
        return [path]
    files = [path]
    root_depth = len(path.parts)
    for folder, subfolders, names in os.walk(path):
        if len(Path(folder).parts) - root_depth >= MAX_FOLDER_DEPTH:
            subfolders.clear()
        files.extend(Path(folder) / name for name in names
                     if Path(name).suffix.lower() in FOLDER_INPUT_SUFFIXES)
        if len(files) > MAX_FOLDER_FILES:
            break
    return files
