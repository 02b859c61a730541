"""Opening the scene a command is given: the one place that knows which file types are scenes."""

from __future__ import annotations

from pathlib import Path

from csgs_codec.errors import InputError, UnsupportedError

#: File suffixes accepted as scene input by render, compare and view.
SCENE_SUFFIXES = (".ply", ".csgs")
CSGS_MAGIC = b"\x89CSG\r\n\x1a\n"


ANCHOR_PROPERTY = b"f_anchor_feat_"
#: Commands that also take anchor scenes (AnchorScene) from a .csgs.
ANCHOR_COMMANDS = ("select",)
HEADER_PEEK = 1 << 16


def is_anchor_input(path: str | Path) -> bool:
    """True when ``path`` is a Scaffold-GS anchor scene: a checkpoint folder (or model root)
    or a PLY whose header has ``f_anchor_feat_*`` properties."""
    path = Path(path)
    if path.is_dir():
        if inria_output(path) is not None:
            return False
        return (path / "point_cloud.ply").is_file() or (path / "point_cloud").is_dir()
    return _is_anchor_ply(path)


def _is_anchor_ply(path: Path) -> bool:
    if not path.is_file():
        return False
    with open(path, "rb") as fh:
        head = fh.read(HEADER_PEEK)
    end = head.find(b"end_header")
    return head.startswith(b"ply") and ANCHOR_PROPERTY in head[: end if end >= 0 else None]


def inria_output(path: str | Path) -> tuple[Path, Path] | None:
    """(point cloud PLY, cameras.json) of an INRIA 3DGS output folder, or None.

    Such a folder holds ``cameras.json`` and ``point_cloud/iteration_N/point_cloud.ply`` for
    one or more N; the highest N is taken. A Scaffold-GS checkpoint has the same layout with
    an anchor PLY: it is not an INRIA output.
    """
    path = Path(path)
    if not path.is_dir() or not (path / "cameras.json").is_file():
        return None
    found = []
    for ply in path.glob("point_cloud/iteration_*/point_cloud.ply"):
        number = ply.parent.name[len("iteration_"):]
        if number.isdigit():
            found.append((int(number), ply))
    if not found:
        return None
    ply = max(found)[1]
    return None if _is_anchor_ply(ply) else (ply, path / "cameras.json")


def load_anchor_scene(path: str | Path):
    """Read the anchor scene in ``path``: a checkpoint folder with its MLPs, or a bare anchor
    PLY (then with its MLP files if they sit beside it)."""
    from csgs_codec.scene.scaffold_io import read_scaffold

    return read_scaffold(path, require_mlps=False)


def load_scene(path: str | Path, *, command: str, layers: str = "color,semantic"):
    """Read the scene in ``path`` for ``csgs <command>``: a 3DGS PLY, or a .csgs bitstream
    (recognised by its magic or its suffix) decoded with ``layers``: a GaussianScene, or for
    the commands in :data:`ANCHOR_COMMANDS` an AnchorScene when the file holds one.

    Raises:
        InputError: missing file, a folder, or a malformed PLY.
        FormatError: a malformed .csgs.
        UnsupportedError: a file type that is not a scene input of this command.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such file", file=path)
    if path.is_dir():
        raise InputError("is a directory", file=path)
    with open(path, "rb") as fh:
        is_csgs = fh.read(len(CSGS_MAGIC)) == CSGS_MAGIC
    suffix = path.suffix.lower()
    if is_csgs or suffix == ".csgs":
        from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file
        from csgs_codec.codec.decoder import Decoder

        if is_anchor_file(path):
            if command not in ANCHOR_COMMANDS:
                raise UnsupportedError(f"'csgs {command}' takes Gaussian scenes; this is an "
                                       "anchor scene (csgs decode writes it as a Scaffold-GS "
                                       "checkpoint)", file=path)
            return AnchorDecoder().decode(path, layers=layers)
        return Decoder().decode(path, layers=layers)
    if suffix not in SCENE_SUFFIXES:
        raise UnsupportedError(f"'{suffix or path.name}' files are not supported as input to "
                               f"'csgs {command}' (supported: {', '.join(SCENE_SUFFIXES)})",
                               file=path)
    from csgs_codec.scene.ply_io import read_ply

    return read_ply(path)
