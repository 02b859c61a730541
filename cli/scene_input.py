"""Opening the scene a command is given: anchor scenes and INRIA output folders here, every
other file through :func:`csgs_codec.codec.files.read_scene`, which knows the file types."""

from __future__ import annotations

from pathlib import Path

from csgs_codec.errors import UnsupportedError
from csgs_codec.interchange.open import READABLE

ANCHOR_PROPERTY = b"f_anchor_feat_"
#: Commands that also take anchor scenes (AnchorScene): from a .csgs, an anchor PLY or a
#: Scaffold-GS checkpoint folder.
ANCHOR_COMMANDS = ("select", "render", "compare", "view")
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
    from csgs_codec.interchange.scaffold_io import read_scaffold

    return read_scaffold(path, require_mlps=False)


def load_scene(path: str | Path, *, command: str, layers: str = "color,semantic"):
    """Read the scene in ``path`` for ``csgs <command>``: any format
    :func:`csgs_codec.codec.files.read_scene` recognises by content (PLY, compressed PLY,
    .splat, .ksplat, SPZ, SOG, GLB), or a .csgs bitstream decoded with ``layers``: a
    GaussianScene, or for the commands in :data:`ANCHOR_COMMANDS` an AnchorScene when the
    .csgs holds one.

    Raises:
        InputError: missing file, a folder that is no SOG, or malformed input.
        FormatError: a malformed .csgs.
        UnsupportedError: a file type that is not a scene input of this command.
    """
    from csgs_codec.codec.files import read_scene
    from csgs_codec.interchange import detect_format

    path = Path(path)
    if command in ANCHOR_COMMANDS and is_anchor_input(path):
        scene = load_anchor_scene(path)
        if scene.mlps is None:
            raise UnsupportedError("the anchor scene has no Scaffold-GS MLPs beside it, so its "
                                   "Gaussians cannot be made", file=path)
        return scene
    try:
        kind = detect_format(path)
    except UnsupportedError:
        raise UnsupportedError(f"'{path.suffix or path.name}' files are not supported as input "
                               f"to 'csgs {command}' (supported: {READABLE}, .csgs)",
                               file=path) from None
    if kind == "csgs":
        from csgs_codec.codec.anchor_decoder import AnchorDecoder, is_anchor_file

        if is_anchor_file(path):
            if command not in ANCHOR_COMMANDS:
                raise UnsupportedError(f"'csgs {command}' takes Gaussian scenes; this is an "
                                       "anchor scene ('csgs decode' bakes it into a .ply, "
                                       ".spz, .glb or .splat)", file=path)
            return AnchorDecoder().decode(path, layers=layers)
    return read_scene(path, layers=layers)
