"""Reading 3DGS scenes from PLY files (binary either endianness, or ASCII).

The reader accepts any property order and any numeric property type, derives the SH degree from
the number of ``f_rest_*`` properties, keeps semantic properties (``ins_feat_*``, ``sem_*``,
``label``) and drops other unknown properties with one warning. It never allocates more than
the file can hold: element counts are checked against the file size before the body is read.
Nothing is read loosely: every ASCII row must hold one value per property, written as a PLY
number (C's strtod syntax, or nan/inf) that fits the property's type, every element must have
the rows its count declares (:mod:`csgs_codec.interchange.ply_ascii`), and the body must end where
the header's counts say (rows or bytes beyond them are an error, not ignored).
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csgs_codec.errors import CsgsWarning, DataLossWarning, InputError
from csgs_codec.interchange.ply_ascii import read_ascii_vertex_columns
from csgs_codec.interchange.ply_header import MAX_HEADER_BYTES, PlyElement, PlyHeader, parse_header
from csgs_codec.scene.gaussian_scene import SH_DEGREE_OF_REST, GaussianScene
from csgs_codec.untrusted import read_regular

REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
            "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
#: Standard properties that carry nothing csgs keeps (3DGS writes zero normals).
IGNORED = ("nx", "ny", "nz")
SEMANTIC_PREFIXES = ("ins_feat_", "sem_")
LABEL = "label"
_F_REST = re.compile(r"^f_rest_(\d+)$")


@dataclass
class PlyReport:
    """What reading a PLY found besides the scene.

    Attributes:
        format: the PLY format line's name.
        properties: the vertex properties in file order.
        dropped_properties: unknown properties that were not kept.
        nonfinite_dropped: Gaussians removed by ``sanitize=True`` for NaN/Inf values.
    """

    format: str
    properties: list[str]
    dropped_properties: list[str] = field(default_factory=list)
    nonfinite_dropped: int = 0


def read_ply(path: str | Path, *, sanitize: bool = False) -> GaussianScene:
    """Read a 3DGS PLY file into a :class:`GaussianScene`.

    Args:
        path: the PLY file.
        sanitize: drop Gaussians with NaN/Inf values (with a warning giving the count) instead
            of raising.

    Raises:
        InputError: unreadable or malformed file, missing property, wrong f_rest count, list
            properties, non-finite values (unless ``sanitize``); the message names the file,
            property and byte offset or index.
    """
    return read_ply_with_report(path, sanitize=sanitize)[0]


def read_ply_with_report(path: str | Path, *, sanitize: bool = False
                         ) -> tuple[GaussianScene, PlyReport]:
    """Like :func:`read_ply`, also returning a :class:`PlyReport`."""
    source = str(path)
    data = _read_file(path)
    return parse_ply_bytes(data, source=source, sanitize=sanitize)


def parse_ply_bytes(data: bytes, *, source: str | None = None, sanitize: bool = False
                    ) -> tuple[GaussianScene, PlyReport]:
    """Parse a whole PLY file held in ``data``; see :func:`read_ply` for the rules."""
    header, vertex, columns = read_vertex_columns(data, source)
    scene, report = _columns_to_scene(columns, vertex, header.format, source)
    bad = scene.nonfinite_rows()
    if bad.any():
        if not sanitize:
            scene.validate(source)  # raises, naming the property and first bad index
        scene = scene.subset(~bad)
        report.nonfinite_dropped = int(bad.sum())
        warnings.warn(f"{source}: dropped {report.nonfinite_dropped} Gaussians with NaN/Inf "
                      "values", DataLossWarning, stacklevel=3)
    scene.validate(source)
    return scene, report


def _read_file(path: str | Path) -> bytes:
    """The bytes of the regular file ``path`` (devices, FIFOs and directories refused)."""
    return read_regular(path)


# --------------------------------------------------------------------------- body
def read_vertex_columns(data: bytes, source: str | None = None
                        ) -> tuple[PlyHeader, PlyElement, dict[str, np.ndarray]]:
    """Parse a PLY held in ``data`` down to its vertex element's columns.

    Returns:
        (header, vertex element, {property name: (N,) array in the file's type}).

    Raises:
        InputError: malformed header, no vertex element, list properties in it, or a body
            shorter than the header declares (checked before anything is allocated).
    """
    header = parse_header(data[:MAX_HEADER_BYTES], source)
    vertex = header.element("vertex")
    if vertex is None:
        raise InputError("no 'vertex' element", file=source)
    if not vertex.properties:
        raise InputError("element 'vertex' has no properties", file=source)
    for prop in vertex.properties:
        if prop.type_code == "list":
            raise InputError("list properties are not supported in the vertex element",
                             file=source, property=prop.name)
    return header, vertex, _read_vertex_columns(data, header, vertex, source)


def _read_vertex_columns(data: bytes, header: PlyHeader, vertex: PlyElement,
                         source: str | None) -> dict[str, np.ndarray]:
    if header.byte_order is None:
        return read_ascii_vertex_columns(data, header, vertex, source)
    offset = header.header_bytes
    columns = None
    for el in header.elements:
        remaining = len(data) - offset
        if el.has_list:
            if columns is not None:
                return columns  # a list element after the vertices: its size is unknown
            raise InputError(f"element '{el.name}' has list properties; cannot locate the "
                             "vertex data behind it", file=source, offset=offset)
        needed = el.count * el.row_bytes
        if needed > remaining:
            raise InputError(f"element '{el.name}' declares {el.count} rows "
                             f"({needed} bytes) but only {remaining} bytes remain (truncated "
                             "body or wrong count)", file=source, offset=offset)
        if el is vertex:
            rows = np.frombuffer(data, dtype=el.dtype(header.byte_order), count=el.count,
                                 offset=offset)
            columns = {p.name: rows[p.name] for p in el.properties}
        offset += needed
    if offset < len(data):
        raise InputError(f"{len(data) - offset} bytes follow the last element the header "
                         "declares (a header count smaller than the body, or trailing data)",
                         file=source, offset=offset)
    return columns


# --------------------------------------------------------------------------- mapping
def unknown_properties(names: list[str]) -> list[str]:
    """The vertex properties among ``names`` that a scene does not keep (the reader drops
    them), in file order."""
    n_rest = sum(1 for n in names if _F_REST.match(n))
    known = set(REQUIRED) | set(IGNORED) | {LABEL} | {f"f_rest_{i}" for i in range(n_rest)}
    return [n for n in names if n not in known and not n.startswith(SEMANTIC_PREFIXES)]


def warn_unknown_properties(names: list[str], source: str | None, *,
                            stacklevel: int = 2) -> None:
    """One CsgsWarning naming the vertex properties of ``source`` that a scene does not keep
    (:func:`unknown_properties`), when there are any."""
    dropped = unknown_properties(names)
    if dropped:
        warnings.warn(f"{source}: ignoring unknown PLY properties: {', '.join(dropped)}",
                      CsgsWarning, stacklevel=stacklevel)


def _columns_to_scene(columns: dict[str, np.ndarray], vertex: PlyElement, fmt: str,
                      source: str | None, *,
                      warn_unknown: bool = True) -> tuple[GaussianScene, PlyReport]:
    names = [p.name for p in vertex.properties]
    for name in REQUIRED:
        if name not in columns:
            raise InputError("required property missing", file=source, property=name)
    rest_indices = sorted(int(m.group(1)) for n in names if (m := _F_REST.match(n)))
    n_rest = len(rest_indices)
    if n_rest % 3 or n_rest // 3 not in SH_DEGREE_OF_REST:
        raise InputError(f"{n_rest} f_rest properties; expected 0, 9, 24 or 45 (SH degree 0-3)",
                         file=source, property="f_rest_*")
    if rest_indices != list(range(n_rest)):
        missing = sorted(set(range(n_rest)) - set(rest_indices))
        raise InputError(f"f_rest properties are not numbered 0..{n_rest - 1}", file=source,
                         property=f"f_rest_{missing[0]}" if missing else "f_rest_*")
    semantic_names = tuple(n for n in names if n.startswith(SEMANTIC_PREFIXES))
    dropped = unknown_properties(names)
    if warn_unknown:
        warn_unknown_properties(names, source, stacklevel=5)

    def stack(keys: list[str]) -> np.ndarray:
        count = len(columns[REQUIRED[0]])
        if not keys:
            return np.zeros((count, 0), np.float32)
        return np.stack([_as_float32(columns[k]) for k in keys], axis=1)

    n = len(columns["x"])
    bands = n_rest // 3
    # INRIA stores f_rest channel-major: all of R's coefficients, then G's, then B's.
    f_rest = stack([f"f_rest_{i}" for i in range(n_rest)])
    sh_rest = np.ascontiguousarray(f_rest.reshape(n, 3, bands).transpose(0, 2, 1))
    scene = GaussianScene(
        positions=stack(["x", "y", "z"]),
        sh_dc=stack(["f_dc_0", "f_dc_1", "f_dc_2"]),
        sh_rest=sh_rest,
        opacity=np.ascontiguousarray(_as_float32(columns["opacity"])),
        scales=stack(["scale_0", "scale_1", "scale_2"]),
        rotations=stack(["rot_0", "rot_1", "rot_2", "rot_3"]),
        semantic=stack(list(semantic_names)) if semantic_names else None,
        semantic_names=semantic_names,
        labels=_labels(columns[LABEL], source) if LABEL in columns else None,
    )
    return scene, PlyReport(format=fmt, properties=names, dropped_properties=dropped)


def _as_float32(column: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        return column.astype(np.float32)  # native byte order; overflow becomes inf -> checked


def _labels(column: np.ndarray, source: str | None) -> np.ndarray:
    values = column.astype(np.float64)
    ok = (np.isfinite(values) & (values == np.round(values))
          & (values >= -(2**31)) & (values < 2**31))
    if not ok.all():
        first = int(np.flatnonzero(~ok)[0])
        raise InputError(f"label {values[first]} is not a 32-bit integer", file=source,
                         property=LABEL, index=first)
    return values.astype(np.int32)


def file_size(path: str | Path) -> int:
    """Size of ``path`` in bytes (for reports)."""
    return os.stat(path).st_size
