"""One instance-id image per view from per-object binary masks (SAM's automatic mask
generator writes one such folder per image).

Layout read: ``SOURCE/<view stem>/<object>.<image suffix>``, one folder per view named after
its image's stem, one file per object in it; a pixel belongs to an object where its mask is
non-zero (0/255 grey, 0/1, palette or RGB alike; a mask of more than 0 and one other value
is refused). Other files (SAM's ``metadata.csv``) are ignored. Objects are numbered 1, 2,
... in natural file-name order (``2.png`` before ``10.png``); id 0 is a pixel no object
covers. Where objects overlap, the smaller object (fewer pixels) wins, since SAM's masks
nest parts inside wholes; of two the same size, the later one. Written: ``TARGET/<view
stem>.png``, 8-bit grey when every id is at most 255, else 16-bit (docs/masks.md).
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.train.image_files import IMAGE_SUFFIXES, read_mask
from csgs_codec.train.semantic_batch import MAX_MASKS_PER_VIEW

_SUFFIXES = frozenset(suffix.lower() for suffix in IMAGE_SUFFIXES)


@dataclass
class ViewObjects:
    """One view's per-object mask files: ``name`` (the view's stem, its folder's name) and
    ``files`` in id order (the first is id 1)."""

    name: str
    files: list[Path]


def find_object_masks(source: str | Path) -> list[ViewObjects]:
    """The views under ``source`` (layout in the module notes), sorted by name; folders
    without image files are skipped.

    Raises:
        InputError: ``source`` is not a folder, holds no view folder with masks, or a view
            has more objects than :data:`MAX_MASKS_PER_VIEW` (naming the folder).
    """
    source = Path(source)
    if not source.is_dir():
        raise InputError("per-object masks folder not found", file=source)
    views = []
    for folder in sorted((p for p in source.iterdir() if p.is_dir()), key=_natural_key):
        files = sorted((p for p in folder.iterdir()
                        if p.is_file() and p.suffix.lower() in _SUFFIXES), key=_natural_key)
        if len(files) > MAX_MASKS_PER_VIEW:
            raise InputError(f"{len(files):,} object masks, more than the "
                             f"{MAX_MASKS_PER_VIEW:,} a view may hold", file=folder)
        if files:
            views.append(ViewObjects(folder.name, files))
    if not views:
        raise InputError("no per-object masks: expected one folder per view holding one "
                         "image per object (e.g. masks_sam/frame_001/0.png)", file=source)
    return views


def combine_object_masks(files: list[Path]) -> np.ndarray:
    """(H, W) int32 ids from the object masks ``files`` (id k + 1 for ``files[k]``, 0 where
    none; overlaps as in the module notes).

    Raises:
        InputError: an unreadable mask, one that is not binary (0 and one other value), or
            one whose size differs from the first (naming both files and sizes).
    """
    first = _object(files[0], read_mask(files[0]))
    objects = [first]
    for path in files[1:]:
        mask = read_mask(path, size=(first.shape[1], first.shape[0]),
                         owner=f"the view's first object mask {files[0]}")
        objects.append(_object(path, mask))
    areas = [int(obj.sum()) for obj in objects]
    ids = np.zeros(first.shape, dtype=np.int32)
    # Paint largest first so smaller objects land on top; equal areas keep file order.
    for k in sorted(range(len(objects)), key=lambda k: (-areas[k], k)):
        ids[objects[k]] = k + 1
    return ids


def _object(path: Path, mask: np.ndarray) -> np.ndarray:
    """The (H, W) bool pixels of one object's mask (non-zero), refusing a mask of more than
    two values: a photo or an id image is no one object's mask."""
    values = np.unique(mask)
    if len(values) > 2 or (len(values) == 2 and values[0] != 0):
        raise InputError(f"not a binary object mask: {len(values)} distinct values "
                         f"{values[:4].tolist()}{'...' if len(values) > 4 else ''} (expected "
                         "0 and one other value)", file=path)
    return mask != 0


def id_png(ids: np.ndarray) -> bytes:
    """The PNG bytes of (H, W) ids in 0..65535: 8-bit grey when all fit, else 16-bit."""
    from PIL import Image

    if ids.size and (ids.min() < 0 or ids.max() > 65535):
        raise InputError("mask ids must be in 0..65535 to be written as PNG", property="ids")
    pixels = ids.astype(np.uint8 if ids.size == 0 or ids.max() < 256 else np.uint16)
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="PNG")
    return buffer.getvalue()


def _natural_key(path: Path) -> list:
    """Sort key comparing runs of digits by value (``2`` before ``10``)."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part)
            for part in re.split(r"(\d+)", path.name)]
