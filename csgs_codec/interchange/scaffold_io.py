"""Reading and writing Scaffold-GS checkpoint folders in the official trainer's layout.

Layout (github.com/city-super/Scaffold-GS, ``scene/__init__.py`` ``Scene.save``):

    MODEL/point_cloud/iteration_N/point_cloud.ply     anchors (interchange/anchor_ply.py)
    MODEL/point_cloud/iteration_N/opacity_mlp.pt      traced heads, "split" mode
    MODEL/point_cloud/iteration_N/cov_mlp.pt          (interchange/scaffold_mlp_files.py)
    MODEL/point_cloud/iteration_N/color_mlp.pt
    MODEL/point_cloud/iteration_N/embedding_appearance.pt   when appearance_dim > 0

HAC (YihangChen-ee/HAC) checkpoints (``f_mask_*`` in the PLY, ``checkpoint.pth`` state dict)
read the same way.
"""

from __future__ import annotations

import re
from pathlib import Path

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import InputError
from csgs_codec.interchange.anchor_ply import anchor_ply_bytes, parse_anchor_ply, read_anchor_ply
from csgs_codec.interchange.scaffold_mlp_files import (
    APPEARANCE_FILE,
    HEAD_FILES,
    STATE_DICT_FILES,
    mlp_file_bytes,
    read_scaffold_mlps,
)
from csgs_codec.scene.anchor_scene import AnchorScene

PLY_NAME = "point_cloud.ply"

__all__ = ["PLY_NAME", "find_checkpoint_folder", "read_scaffold", "write_scaffold",
           "read_anchor_ply", "parse_anchor_ply", "anchor_ply_bytes", "read_scaffold_mlps"]


def find_checkpoint_folder(path: str | Path) -> Path:
    """The folder holding ``point_cloud.ply`` for ``path``.

    ``path`` may be that folder, the PLY inside it, or the model root (then the highest
    ``point_cloud/iteration_N`` is taken, as the official trainer does).

    Raises:
        InputError: when no such folder exists.
    """
    path = Path(path)
    if path.is_file():
        return path.parent
    if (path / PLY_NAME).is_file():
        return path
    iterations = []
    if (path / "point_cloud").is_dir():
        for child in (path / "point_cloud").iterdir():
            m = re.fullmatch(r"iteration_(\d+)", child.name)
            if m and (child / PLY_NAME).is_file():
                iterations.append((int(m.group(1)), child))
    if not iterations:
        raise InputError(f"no {PLY_NAME} here nor under point_cloud/iteration_*", file=path)
    return max(iterations)[1]


def read_scaffold(path: str | Path, *, require_mlps: bool = True) -> AnchorScene:
    """Read a Scaffold-GS (or HAC) checkpoint folder into an :class:`AnchorScene` with MLPs.

    Args:
        path: checkpoint folder, its ``point_cloud.ply``, or the model root.
        require_mlps: when False, a folder without MLP files gives a scene with ``mlps=None``.

    Raises:
        InputError: malformed PLY or MLP file, missing property or file, shapes that do not
            fit together; the message names the file and the property.
        UnsupportedError: a feature-bank checkpoint (``use_feat_bank``) or an MLP whose graph
            is not the standard Scaffold-GS head.
    """
    folder = find_checkpoint_folder(path)
    ply = folder / PLY_NAME if not Path(path).is_file() else Path(path)
    scene = read_anchor_ply(ply)
    scene.validate(str(ply))
    scene.mlps = read_scaffold_mlps(folder, required=require_mlps)
    if scene.mlps is not None:
        try:
            scene.mlps.validate(scene.feat_dim, scene.n_offsets)
        except InputError as exc:
            raise InputError(exc.message, file=_weights_file(folder, exc.property),
                             property=exc.property, index=exc.index) from None
    return scene


def _weights_file(folder: Path, prop: str | None) -> Path:
    """The file that holds the weights named ``prop`` (e.g. ``cov.w1``) in ``folder``."""
    head = (prop or "").split(".")[0]
    if (folder / HEAD_FILES["opacity"]).exists():
        if head == "appearance":
            return folder / APPEARANCE_FILE
        return folder / HEAD_FILES.get(head, HEAD_FILES["opacity"])
    for name in STATE_DICT_FILES:
        if (folder / name).exists():
            return folder / name
    return folder  # pragma: no cover - weights were read from one of the files above


def write_scaffold(scene: AnchorScene, folder: str | Path) -> Path:
    """Write ``scene`` as an official-layout checkpoint folder; returns the folder.

    Writes ``point_cloud.ply`` and the traced heads ``opacity_mlp.pt``, ``cov_mlp.pt``,
    ``color_mlp.pt`` (and ``embedding_appearance.pt`` with an appearance table), each file
    through a temporary file and a rename. The folder is created if missing.

    Raises:
        InputError: invalid scene, no MLPs, or an unwritable folder.
    """
    scene.validate()
    if scene.mlps is None:
        raise InputError("the scene has no MLP weights to write", property="mlps")
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create folder: {exc.strerror or exc}", file=folder) from None
    ply = anchor_ply_bytes(scene)
    files = mlp_file_bytes(scene.mlps)
    for name, data in files.items():
        write_atomically(folder / name, data)
    write_atomically(folder / PLY_NAME, ply)
    return folder
