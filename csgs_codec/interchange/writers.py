"""Writing a scene in the format its file name asks for: ``.ply``, ``.splat``, ``.spz`` or
``.glb``, always atomically."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import DataLossWarning, UnsupportedError, require_type
from csgs_codec.scene.gaussian_scene import GaussianScene


def _ply(scene: GaussianScene) -> bytes:
    from csgs_codec.interchange.ply_writer import ply_bytes

    return ply_bytes(scene)


def _splat(scene: GaussianScene) -> bytes:
    from csgs_codec.interchange.splat import splat_bytes

    return splat_bytes(scene)


def _spz(scene: GaussianScene) -> bytes:
    from csgs_codec.interchange.spz import spz_bytes

    return spz_bytes(scene)


def _glb(scene: GaussianScene) -> bytes:
    from csgs_codec.interchange.gltf import glb_bytes

    return glb_bytes(scene)


#: Output suffix -> (format name, writer, carries semantic channels, carries SH rest bands).
WRITERS = {
    ".ply": ("3DGS PLY", _ply, True, True),
    ".splat": ("antimatter15 .splat", _splat, False, False),
    ".spz": ("Niantic SPZ v4", _spz, False, True),
    ".glb": ("glTF binary with KHR_gaussian_splatting", _glb, False, True),
}


def writer_for(path: str | os.PathLike):
    """The :data:`WRITERS` entry for ``path``'s suffix.

    Raises:
        UnsupportedError: a suffix csgs does not write, listing those it does.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in WRITERS:
        raise UnsupportedError(f"cannot write '{suffix or Path(path).name}' files (csgs "
                               f"writes {', '.join(WRITERS)})", file=path)
    return WRITERS[suffix]


def scene_bytes(scene: GaussianScene, suffix: str) -> bytes:
    """The scene encoded as the format of ``suffix`` (e.g. ``".spz"``), warning with a
    :class:`DataLossWarning` about what that format cannot carry."""
    require_type(scene, GaussianScene, "scene")
    name, write, semantic, sh = writer_for("x" + suffix)
    lost = []
    if not semantic and scene.semantic is not None:
        lost.append(f"{scene.semantic.shape[1]} semantic channels")
    if not semantic and scene.labels is not None:
        lost.append("labels")
    if not sh and scene.sh_degree_in_use() > 0:
        lost.append(f"SH bands 1-{scene.sh_degree_stored}")
    if lost:
        warnings.warn(f"{name} does not carry {', '.join(lost)}: dropped", DataLossWarning,
                      stacklevel=3)
    return write(scene)


def write_scene(scene: GaussianScene, path: str | os.PathLike, inputs=()) -> None:
    """Write ``scene`` to ``path`` in the format its suffix names (see :data:`WRITERS`),
    atomically; ``inputs`` are files ``path`` must not be.

    Raises:
        UnsupportedError: an unknown suffix.
        InputError: an invalid scene, or what the format cannot hold (e.g. SPZ positions
            beyond its 24-bit range).
    """
    write_atomically(path, scene_bytes(scene, Path(path).suffix.lower()), inputs)
