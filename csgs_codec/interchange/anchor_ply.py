"""The Scaffold-GS anchor PLY: one vertex per anchor, in the official trainer's layout.

Layout (github.com/city-super/Scaffold-GS, ``scene/gaussian_model.py``
``construct_list_of_attributes``, ``save_ply``, ``load_ply_sparse_gaussian``): binary
little-endian float32 with properties, in this order: ``x y z nx ny nz``,
``f_offset_0..3K-1`` (offsets stored transposed: ``f_offset_{c*K + k}`` is coordinate c of
offset k), ``f_anchor_feat_0..F-1``, ``opacity``, ``scale_0..5`` and ``rot_0..3``. ``opacity``
and ``rot_*`` are written but never read by the renderer. HAC (YihangChen-ee/HAC) adds
``f_mask_0..K-1`` (mask logits; an offset is kept when sigmoid(logit) > 0.01) between the
offsets and the features. csgs appends the semantic channels (``sem_*``) and ``label``.

Reading checks every count against the file size before allocating and names the file and
property in every error.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from csgs_codec import __version__
from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.interchange.ply_reader import read_vertex_columns
from csgs_codec.interchange.ply_writer import vertex_ply_bytes
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.untrusted import read_regular

#: Placeholder values the official trainer writes for the unused anchor opacity and rotation.
PLACEHOLDER_OPACITY = np.float32(np.log(0.1 / 0.9))
PLACEHOLDER_ROTATION = (1.0, 0.0, 0.0, 0.0)
#: HAC keeps an offset when sigmoid(mask logit) > 0.01, i.e. logit > log(0.01 / 0.99).
MASK_LOGIT_THRESHOLD = float(np.log(0.01 / 0.99))
#: Logits csgs writes for kept (HAC's initial value) and masked offsets.
MASK_KEPT_LOGIT, MASK_DROPPED_LOGIT = 1.0, -10.0
SEMANTIC_PREFIXES = ("sem_", "ins_feat_")
_NUMBERED = re.compile(r"^(f_offset|f_anchor_feat|f_mask|scale|rot)_(\d+)$")


# =========================================================================== reading
def read_anchor_ply(path: str | Path) -> AnchorScene:
    """Read an anchor PLY (see the module docstring) into an :class:`AnchorScene` (no MLPs).

    Semantic channels (``sem_*``, ``ins_feat_*``) and ``label`` are kept; ``nx ny nz
    opacity rot_*`` are ignored; other properties are dropped with a warning.

    Raises:
        InputError: naming the file and the property (and anchor index for bad values).
    """
    return parse_anchor_ply(read_bytes(path), source=str(path))


def parse_anchor_ply(data: bytes, *, source: str | None = None) -> AnchorScene:
    """Parse the bytes of an anchor PLY; see :func:`read_anchor_ply`."""
    _, vertex, columns = read_vertex_columns(data, source)
    return _columns_to_anchors(columns, [p.name for p in vertex.properties], source)


def _numbered(names: list[str], prefix: str, source: str | None) -> list[str]:
    """Properties ``prefix_0..n-1`` in index order; a gap is an error naming the missing one."""
    found = sorted(int(m.group(2)) for n in names
                   if (m := _NUMBERED.match(n)) and m.group(1) == prefix)
    missing = sorted(set(range(len(found))) - set(found))
    if missing:
        raise InputError(f"{prefix}_* properties are not numbered 0..{len(found) - 1}",
                         file=source, property=f"{prefix}_{missing[0]}")
    return [f"{prefix}_{i}" for i in range(len(found))]


def _columns_to_anchors(columns: dict[str, np.ndarray], names: list[str],
                        source: str | None) -> AnchorScene:
    for name in ("x", "y", "z"):
        if name not in columns:
            raise InputError("required property missing", file=source, property=name)
    offset_names = _numbered(names, "f_offset", source)
    feat_names = _numbered(names, "f_anchor_feat", source)
    scale_names = _numbered(names, "scale", source)
    mask_names = _numbered(names, "f_mask", source)
    if not offset_names or len(offset_names) % 3:
        raise InputError(f"{len(offset_names)} f_offset properties; expected 3 x K, K >= 1",
                         file=source, property="f_offset_0")
    k = len(offset_names) // 3
    if not feat_names:
        raise InputError("required property missing", file=source, property="f_anchor_feat_0")
    if len(scale_names) != 6:
        raise InputError(f"{len(scale_names)} scale properties; Scaffold-GS anchors have 6",
                         file=source, property=f"scale_{min(len(scale_names), 5)}")
    if mask_names and len(mask_names) != k:
        raise InputError(f"{len(mask_names)} f_mask properties for {k} offsets", file=source,
                         property="f_mask_0")
    semantic_names = tuple(n for n in names if n.startswith(SEMANTIC_PREFIXES))
    used = {"x", "y", "z", *offset_names, *feat_names, *scale_names, *mask_names,
            *semantic_names}
    ignored = {"nx", "ny", "nz", "opacity", "label"}
    dropped = [n for n in names if n not in used and n not in ignored
               and not re.fullmatch(r"rot_\d+", n)]
    if dropped:
        warnings.warn(f"{source}: ignoring unknown anchor PLY properties: {', '.join(dropped)}",
                      CsgsWarning, stacklevel=4)

    def stack(keys: list[str] | tuple[str, ...]) -> np.ndarray:
        out = np.empty((len(columns["x"]), len(keys)), np.float32)
        for i, key in enumerate(keys):
            with np.errstate(over="ignore", invalid="ignore"):
                out[:, i] = columns[key]
            bad = ~np.isfinite(out[:, i])
            if bad.any():
                raise InputError(f"non-finite value {columns[key][bad.argmax()]}", file=source,
                                 property=key, index=int(bad.argmax()))
        return out

    m = len(columns["x"])
    offsets = stack(offset_names).reshape(m, 3, k).transpose(0, 2, 1)
    if mask_names:
        offset_mask = stack(mask_names) > MASK_LOGIT_THRESHOLD
    else:
        offset_mask = np.ones((m, k), bool)
    labels = None
    if "label" in columns:
        values = columns["label"].astype(np.float64)
        ok = np.isfinite(values) & (values == np.round(values)) & (np.abs(values) < 2**31)
        if not ok.all():
            raise InputError("label is not a 32-bit integer", file=source, property="label",
                             index=int(np.flatnonzero(~ok)[0]))
        labels = values.astype(np.int32)
    return AnchorScene(
        positions=stack(["x", "y", "z"]), features=stack(feat_names),
        offsets=np.ascontiguousarray(offsets), scaling=stack(scale_names),
        offset_mask=offset_mask,
        semantic=stack(semantic_names) if semantic_names else None,
        semantic_names=semantic_names, labels=labels)


def read_bytes(path: str | Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path`` (at most ``limit``); InputError naming the
    file otherwise (see :func:`csgs_codec.untrusted.read_regular`)."""
    return read_regular(path, limit)


# =========================================================================== writing
def anchor_ply_bytes(scene: AnchorScene) -> bytes:
    """The anchors as a binary little-endian PLY in the official Scaffold-GS property order.

    ``f_mask_*`` (HAC's layout, logit 1.0 kept / -10.0 masked) is written only when some offset
    is masked, so an all-kept scene gives exactly the official Scaffold-GS layout. Semantic
    channels follow ``rot_3`` under their names, then ``label`` (int32).

    Raises:
        InputError: invalid scene or semantic names that would not read back as semantic.
    """
    scene.validate()
    m, k = len(scene), scene.n_offsets
    fields: list[tuple[str, np.ndarray]] = [(a, scene.positions[:, i])
                                            for i, a in enumerate("xyz")]
    zeros = np.zeros(m, np.float32)
    fields += [("nx", zeros), ("ny", zeros), ("nz", zeros)]
    stored = scene.offsets.transpose(0, 2, 1).reshape(m, 3 * k)
    fields += [(f"f_offset_{j}", stored[:, j]) for j in range(3 * k)]
    if not scene.offset_mask.all():
        logits = np.where(scene.offset_mask, MASK_KEPT_LOGIT, MASK_DROPPED_LOGIT)
        fields += [(f"f_mask_{j}", logits[:, j]) for j in range(k)]
    fields += [(f"f_anchor_feat_{j}", scene.features[:, j]) for j in range(scene.feat_dim)]
    fields.append(("opacity", np.full(m, PLACEHOLDER_OPACITY, np.float32)))
    fields += [(f"scale_{j}", scene.scaling[:, j]) for j in range(6)]
    fields += [(f"rot_{j}", np.full(m, v, np.float32)) for j, v in enumerate(PLACEHOLDER_ROTATION)]
    if scene.semantic is not None:
        for j, name in enumerate(scene.semantic_names):
            if not re.fullmatch(r"(sem_|ins_feat_)\w+", name) or name in dict(fields):
                raise InputError("semantic channel names must be sem_* or ins_feat_* and "
                                 "unique", property=name)
            fields.append((name, scene.semantic[:, j]))
    return vertex_ply_bytes(m, fields, labels=scene.labels,
                            comment=f"written by csgs {__version__} (Scaffold-GS anchors)")


def write_anchor_ply(scene: AnchorScene, path: str | Path, inputs=()) -> None:
    """Write the anchor PLY (see :func:`anchor_ply_bytes`) atomically; ``path`` must not be
    one of ``inputs`` (see :func:`csgs_codec.atomic_write.write_atomically`)."""
    write_atomically(path, anchor_ply_bytes(scene), inputs)
