"""Writing scenes as standard INRIA-layout binary PLY files, atomically."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import InputError, require_type
from csgs_codec.scene.gaussian_scene import GaussianScene


def ply_bytes(scene: GaussianScene) -> bytes:
    """The scene as a binary little-endian PLY in the INRIA property order.

    The bytes are canonical: the same scene always gives the same bytes.
    Order: x y z nx ny nz f_dc_0..2 f_rest_* opacity scale_0..2 rot_0..3, then the semantic
    channels by name (float) and ``label`` (int) when present. Normals are written as zeros.
    """
    require_type(scene, GaussianScene, "scene")
    scene.validate()
    n = len(scene)
    bands = scene.sh_rest.shape[1]
    fields: list[tuple[str, np.ndarray]] = []
    for i, axis in enumerate("xyz"):
        fields.append((axis, scene.positions[:, i]))
    zeros = np.zeros(n, np.float32)
    fields += [("nx", zeros), ("ny", zeros), ("nz", zeros)]
    fields += [(f"f_dc_{i}", scene.sh_dc[:, i]) for i in range(3)]
    f_rest = scene.sh_rest.transpose(0, 2, 1).reshape(n, 3 * bands)
    fields += [(f"f_rest_{i}", f_rest[:, i]) for i in range(3 * bands)]
    fields.append(("opacity", scene.opacity))
    fields += [(f"scale_{i}", scene.scales[:, i]) for i in range(3)]
    fields += [(f"rot_{i}", scene.rotations[:, i]) for i in range(4)]
    if scene.semantic is not None:
        fields += [(name, scene.semantic[:, i]) for i, name in enumerate(scene.semantic_names)]
    # No comment line (e.g. a version): the bytes are a canonical function of the scene, so
    # conformance vectors can pin the SHA-256 of a decoded scene.
    return vertex_ply_bytes(n, fields, labels=scene.labels)


def vertex_ply_bytes(n: int, fields: list[tuple[str, np.ndarray]], *,
                     labels: np.ndarray | None = None, comment: str | None = None) -> bytes:
    """A binary little-endian PLY with one vertex element of ``n`` rows.

    Args:
        fields: (name, (n,) values) written as float properties, in this order.
        labels: optional (n,) integers written last as ``property int label``.
        comment: an optional header comment line.

    Raises:
        InputError: a property name that is not one word of printable ASCII, a name given
            twice, or a comment that is not one line of printable ASCII.
    """
    fields = list(fields)
    seen = set()
    for name, _ in fields + ([("label", None)] if labels is not None else []):
        check_property_name(name)
        if name in seen:
            raise InputError("property name given twice", property=name)
        seen.add(name)
    if comment is not None and not re.fullmatch(r"[ -~]*", comment):
        raise InputError(f"a PLY comment must be one line of printable ASCII, got {comment!r}",
                         property="comment")
    types = {name: "<f4" for name, _ in fields}
    if labels is not None:
        fields.append(("label", labels))
        types["label"] = "<i4"
    rows = np.empty(n, dtype=[(name, types[name]) for name, _ in fields])
    for name, column in fields:
        rows[name] = column
    lines = ["ply", "format binary_little_endian 1.0"]
    lines += [f"comment {comment}"] if comment else []
    lines.append(f"element vertex {n}")
    lines += [f"property {'int' if types[name] == '<i4' else 'float'} {name}"
              for name, _ in fields]
    lines.append("end_header\n")
    return "\n".join(lines).encode("ascii") + rows.tobytes()


def check_property_name(name) -> None:
    """InputError unless ``name`` can be a PLY property name: one word (1..255 characters)
    of printable ASCII, no spaces. A newline would end the header line and let the name
    write header lines of its own; other bytes do not encode."""
    if not isinstance(name, str) or not re.fullmatch(r"[!-~]{1,255}", name):
        raise InputError(f"a PLY property name must be one word of printable ASCII (no "
                         f"spaces), 1..255 characters, got {name!r}")


def write_ply(scene: GaussianScene, path: str | Path, inputs=()) -> None:
    """Write ``scene`` to ``path`` (see :func:`ply_bytes`) without ever leaving a partial file.

    The bytes go to a temporary file in the same folder, which then replaces ``path`` (or,
    for a symlink, its target); ``inputs`` are files ``path`` must not be.

    Raises:
        InputError: the scene is invalid, the folder cannot be written, or ``path`` is not a
            regular file or is one of ``inputs``.
    """
    write_atomically(path, ply_bytes(scene), inputs)
