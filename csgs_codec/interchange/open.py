"""Recognising a scene file's format by its content (the extension only where the content
cannot tell: ``.splat`` has no header) and reading the interchange formats."""

from __future__ import annotations

import os
from pathlib import Path

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.format import MAGIC as CSGS_MAGIC
from csgs_codec.interchange.source import SceneSource
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.untrusted import open_regular, read_regular

#: How many leading bytes :func:`detect_format` looks at.
SNIFF_BYTES = 64
#: Every format :func:`detect_format` can name.
FORMATS = ("csgs", "ply", "splat", "ksplat", "spz", "sog", "glb")
#: The readable formats as users know them, for messages and help.
READABLE = ("3DGS PLY, PlayCanvas compressed PLY, .splat, .ksplat, SPZ, SOG (.sog or a folder "
            "with meta.json), glTF .glb with KHR_gaussian_splatting")


def _head(path: Path) -> bytes:
    """The first :data:`SNIFF_BYTES` bytes of the regular file at ``path``."""
    with open_regular(path) as fh:
        try:
            return fh.read(SNIFF_BYTES)
        except OSError as exc:
            raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None


def detect_format(path: str | os.PathLike) -> str:
    """The format of the scene file or folder at ``path``: one of :data:`FORMATS` ("ply"
    covers the compressed PLY too, told apart when read).

    A folder is a SOG when it holds ``meta.json`` (so is a ``meta.json`` file). Files are
    recognised by their first bytes: the .csgs magic, ``ply`` (a compressed PLY is told
    apart when read), gzip or ``NGSP`` (SPZ), ``PK`` (a SOG zip), ``glTF``, the .ksplat
    version and header fields; a file with none of these is a ``.splat`` only when so
    named (that format has no header).

    Raises:
        InputError: a missing or empty file, a folder without ``meta.json``, a path that is
            no regular file (a device, FIFO or socket) or holds a NUL byte.
        UnsupportedError: bytes that are none of the formats.
    """
    from csgs_codec.interchange import ksplat, spz
    from csgs_codec.interchange.gltf import GLB_MAGIC
    from csgs_codec.interchange.sog import ZIP_MAGIC

    path = Path(path)
    if path.is_dir():
        if (path / "meta.json").is_file():
            return "sog"
        raise InputError("a folder without meta.json is no scene (a SOG folder holds "
                         "meta.json and its images)", file=path)
    if path.name == "meta.json":
        return "sog"
    head = _head(path)
    suffix = path.suffix.lower()
    if head.startswith(CSGS_MAGIC):
        return "csgs"
    if head.startswith(b"ply"):
        return "ply"
    if head.startswith(spz.GZIP_MAGIC) or head.startswith(spz.NGSP_MAGIC):
        return "spz"
    if head.startswith(ZIP_MAGIC):
        return "sog"
    if head.startswith(GLB_MAGIC):
        return "glb"
    if suffix == ".splat":
        return "splat"
    if ksplat.looks_like_ksplat(head):
        return "ksplat"
    if not head:
        raise InputError("empty file", file=path, offset=0)
    if suffix == ".gltf":
        raise UnsupportedError("a .gltf JSON file: csgs reads the binary .glb form", file=path)
    raise UnsupportedError(f"neither a .csgs bitstream (no .csgs magic) nor a scene file csgs "
                           f"reads ({READABLE})", file=path, offset=0)


def read_interchange(path: str | os.PathLike, *, sanitize: bool = False
                     ) -> tuple[GaussianScene, SceneSource]:
    """Read the scene in ``path`` in any format :func:`detect_format` names but ``.csgs``
    (that one is the codec's: :func:`csgs_codec.codec.files.read_scene_with_report` reads both).

    Args:
        path: a scene file, a SOG folder or its ``meta.json``.
        sanitize: PLY only: drop Gaussians with NaN/Inf values instead of failing.

    Returns:
        (scene in INRIA PLY conventions, what the file was).

    Raises:
        InputError: unreadable or malformed input, naming the file and byte offset,
            property or chunk.
        UnsupportedError: something well formed csgs does not read here (a ``.csgs``, SPZ SH
            degree 4, a missing optional package).
    """
    path = Path(path)
    kind = detect_format(path)
    source = str(path)
    if kind == "csgs":
        raise UnsupportedError("a .csgs bitstream: csgs_codec.read_scene (or Decoder) decodes "
                               "it", file=path)
    if kind == "sog":
        from csgs_codec.interchange.sog import read_sog

        scene, info = read_sog(path)
    elif kind == "ply":
        scene, info = _read_ply(path, sanitize)
    else:
        parse = _PARSERS[kind]()
        scene, info = parse(read_regular(path), source)
    scene.validate(source)
    return scene, info


def _read_ply(path: Path, sanitize: bool) -> tuple[GaussianScene, SceneSource]:
    from csgs_codec.interchange.compressed_ply import is_compressed_ply, parse_compressed_ply
    from csgs_codec.interchange.ply_header import MAX_HEADER_BYTES, parse_header
    from csgs_codec.interchange.ply_reader import parse_ply_bytes

    data = read_regular(path)
    header = parse_header(data[:MAX_HEADER_BYTES], str(path))
    if is_compressed_ply(header):
        return parse_compressed_ply(data, str(path))
    scene, report = parse_ply_bytes(data, source=str(path), sanitize=sanitize)
    details = {"ply_format": report.format, "ignored_properties": report.dropped_properties,
               "nonfinite_dropped": report.nonfinite_dropped}
    return scene, SceneSource("ply", "3DGS PLY", details=details)


def _splat():
    from csgs_codec.interchange.splat import parse_splat

    return parse_splat


def _ksplat():
    from csgs_codec.interchange.ksplat import parse_ksplat

    return parse_ksplat


def _spz():
    from csgs_codec.interchange.spz import parse_spz

    return parse_spz


def _glb():
    from csgs_codec.interchange.gltf import parse_glb

    return parse_glb


_PARSERS = {"splat": _splat, "ksplat": _ksplat, "spz": _spz, "glb": _glb}
