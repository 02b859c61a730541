"""A binary 3DGS PLY read piece by piece: the vertex rows memory-mapped, never all loaded.

For scenes larger than memory: :meth:`MappedPly.positions` reads only the x, y, z columns
(block by block), and :meth:`MappedPly.scene` loads the rows of one tile. The rows convert
to a :class:`~csgs_codec.scene.gaussian_scene.GaussianScene` exactly as
:func:`~csgs_codec.interchange.ply_reader.read_ply` converts a whole file, so a scene encoded from
the map is the same as one encoded from ``read_ply``. ASCII PLY cannot be mapped.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_header import MAX_HEADER_BYTES, parse_header
from csgs_codec.interchange.ply_reader import _columns_to_scene
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.untrusted import open_regular

#: Rows read at a time by :meth:`MappedPly.positions`.
BLOCK_ROWS = 1 << 20


class MappedPly:
    """The vertex element of a binary PLY at ``path``, memory-mapped.

    Attributes:
        path: the file (str); count: vertex rows; properties: their names in file order.

    Raises:
        InputError: not a readable binary PLY, no vertex element, list properties before or
            in it, or a file size that differs from what the header declares.
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = str(path)
        with open_regular(path) as handle:
            try:
                head = handle.read(MAX_HEADER_BYTES)
                size = os.fstat(handle.fileno()).st_size
            except OSError as exc:
                raise InputError(f"cannot read: {exc.strerror or exc}", file=path) from None
            self._map(handle, head, size)

    def _map(self, handle, head: bytes, size: int) -> None:
        """Check the header in ``head`` against the file ``size`` and map the vertex rows of
        the open regular file ``handle``."""
        path = self.path
        header = parse_header(head, self.path)
        if header.byte_order is None:
            raise InputError("an ASCII PLY cannot be memory-mapped", file=path)
        vertex = header.element("vertex")
        if vertex is None:
            raise InputError("no 'vertex' element", file=path)
        if not vertex.properties:
            raise InputError("element 'vertex' has no properties", file=path)
        offset, end = header.header_bytes, header.header_bytes
        for el in header.elements:
            if el.has_list:
                raise InputError(f"element '{el.name}' has list properties", file=path)
            if el is vertex:
                offset = end
            end += el.count * el.row_bytes
        if end != size:
            raise InputError(f"the header declares {end} bytes, the file has {size} (truncated "
                             "body, wrong count or trailing data)", file=path,
                             offset=min(end, size))
        self.count = vertex.count
        self.properties = [p.name for p in vertex.properties]
        self._vertex = vertex
        self._format = header.format
        self._rows = np.memmap(handle, dtype=vertex.dtype(header.byte_order), mode="r",
                               offset=offset, shape=(vertex.count,)) if vertex.count else None

    def positions(self) -> np.ndarray:
        """(N, 3) float32 positions, read :data:`BLOCK_ROWS` rows at a time.

        Raises:
            InputError: a property x, y or z is missing, or a position is not finite.
        """
        for name in ("x", "y", "z"):
            if name not in self.properties:
                raise InputError("required property missing", file=self.path, property=name)
        out = np.empty((self.count, 3), np.float32)
        for start in range(0, self.count, BLOCK_ROWS):
            block = self._rows[start:start + BLOCK_ROWS]
            for axis, name in enumerate("xyz"):
                with np.errstate(over="ignore", invalid="ignore"):
                    out[start:start + len(block), axis] = block[name]
        bad = ~np.isfinite(out)
        if bad.any():
            row, axis = np.argwhere(bad)[0]
            raise InputError("position is not finite", file=self.path, property="xyz"[axis],
                             index=int(row))
        return out

    def scene(self, rows: np.ndarray) -> GaussianScene:
        """The Gaussians of ``rows`` ((M,) increasing int64 row numbers), as read_ply reads them.

        Raises:
            InputError: a missing property, or a non-finite value (its index is the file row).
        """
        rows = np.asarray(rows, np.int64)
        block = self._rows[rows] if self._rows is not None else None
        columns = {name: block[name] for name in self.properties}
        # Unknown properties are not said per block of rows (the tiled encoder says them
        # once). Not a catch_warnings block: that would silence other threads' warnings.
        scene, _ = _columns_to_scene(columns, self._vertex, self._format, self.path,
                                     warn_unknown=False)
        try:
            scene.validate(self.path)
        except InputError as err:
            if err.index is not None:
                err.index = int(rows[err.index])
                err.args = (str(err),)
            raise
        return scene


def read_ply_rows(path: str | Path, rows: np.ndarray) -> GaussianScene:
    """The Gaussians of ``rows`` of the binary PLY at ``path`` (see :class:`MappedPly`)."""
    return MappedPly(path).scene(rows)
