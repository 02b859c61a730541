"""The standard 3D Gaussian Splatting scene: one row per Gaussian, INRIA conventions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.instance_table import InstanceTable
from csgs_codec.scene.ply_names import ply_property

#: Number of SH rest coefficients per color channel for SH degree 0..3.
SH_REST_COUNTS = {0: 0, 1: 3, 2: 8, 3: 15}
#: Inverse of :data:`SH_REST_COUNTS`.
SH_DEGREE_OF_REST = {v: k for k, v in SH_REST_COUNTS.items()}


@dataclass
class GaussianScene:
    """A trained 3DGS scene as stored in an INRIA-layout PLY.

    All arrays have N rows, one per Gaussian, and hold raw (pre-activation) values:

    Attributes:
        positions: (N, 3) float32, world units.
        sh_dc: (N, 3) float32, degree-0 SH coefficient per color channel (RGB).
        sh_rest: (N, B, 3) float32, higher SH coefficients, B in {0, 3, 8, 15}
            (degree 0..3), coefficient-major then RGB.
        opacity: (N,) float32, opacity logits (opacity = sigmoid(value)).
        scales: (N, 3) float32, natural-log scales (world units after exp).
        rotations: (N, 4) float32, quaternions (w, x, y, z) as stored: not assumed normalized.
        semantic: optional (N, S) float32 per-Gaussian semantic feature.
        semantic_names: names of the S semantic channels (PLY property names).
        labels: optional (N,) int32 integer object/instance labels.
        instances: optional per-instance embeddings keyed by semantic feature row
            (:class:`~csgs_codec.scene.instance_table.InstanceTable`), for open-vocabulary
            queries of a segmented scene; carried by .csgs files, not by PLY.
    """

    positions: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray
    opacity: np.ndarray
    scales: np.ndarray
    rotations: np.ndarray
    semantic: np.ndarray | None = None
    semantic_names: tuple[str, ...] = field(default_factory=tuple)
    labels: np.ndarray | None = None
    instances: InstanceTable | None = None

    # ----------------------------------------------------------------- construction
    @classmethod
    def empty(cls, sh_degree: int = 0) -> GaussianScene:
        """A scene with no Gaussians whose stored SH degree is ``sh_degree`` (0..3)."""
        b = SH_REST_COUNTS[sh_degree]
        return cls(
            positions=np.zeros((0, 3), np.float32),
            sh_dc=np.zeros((0, 3), np.float32),
            sh_rest=np.zeros((0, b, 3), np.float32),
            opacity=np.zeros((0,), np.float32),
            scales=np.zeros((0, 3), np.float32),
            rotations=np.zeros((0, 4), np.float32),
        )

    @classmethod
    def concatenate(cls, scenes: list[GaussianScene]) -> GaussianScene:
        """One scene holding ``scenes``' Gaussians in order (same SH degree and layers)."""
        first = scenes[0]

        def join(name: str) -> np.ndarray:
            return np.concatenate([getattr(s, name) for s in scenes])

        return cls(positions=join("positions"), sh_dc=join("sh_dc"), sh_rest=join("sh_rest"),
                   opacity=join("opacity"), scales=join("scales"), rotations=join("rotations"),
                   semantic=None if first.semantic is None else join("semantic"),
                   semantic_names=first.semantic_names,
                   labels=None if first.labels is None else join("labels"),
                   instances=InstanceTable.union([s.instances for s in scenes]))

    # ----------------------------------------------------------------- basic facts
    def __repr__(self) -> str:
        """A one-line summary (counts, SH degree, layers), not the arrays."""
        parts = [f"{len(self):,} Gaussians", f"SH degree {self.sh_degree_stored}"]
        if self.semantic is not None:
            parts.append(f"{self.semantic.shape[1]} semantic channels")
        if self.labels is not None:
            parts.append("labels")
        return f"GaussianScene({', '.join(parts)})"

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def count(self) -> int:
        """Number of Gaussians N."""
        return len(self)

    @property
    def sh_degree_stored(self) -> int:
        """SH degree the arrays can hold (from B, the number of rest coefficients)."""
        return SH_DEGREE_OF_REST[int(self.sh_rest.shape[1])]

    def sh_degree_in_use(self) -> int:
        """Highest SH band that has any non-zero coefficient (0 if all rest bands are zero)."""
        for degree in range(self.sh_degree_stored, 0, -1):
            lo, hi = SH_REST_COUNTS[degree - 1], SH_REST_COUNTS[degree]
            if np.any(self.sh_rest[:, lo:hi, :] != 0):
                return degree
        return 0

    def zero_sh_bands(self) -> list[int]:
        """SH bands 1..stored degree whose every coefficient is exactly zero."""
        bands = []
        for degree in range(1, self.sh_degree_stored + 1):
            lo, hi = SH_REST_COUNTS[degree - 1], SH_REST_COUNTS[degree]
            if not np.any(self.sh_rest[:, lo:hi, :] != 0):
                bands.append(degree)
        return bands

    def attributes(self) -> dict[str, np.ndarray]:
        """The per-Gaussian float attributes as 2-D (N, C) arrays, keyed by attribute name."""
        n = len(self)
        out = {
            "positions": self.positions,
            "sh_dc": self.sh_dc,
            "sh_rest": self.sh_rest.reshape(n, self.sh_rest.shape[1] * 3),
            "opacity": self.opacity.reshape(n, 1),
            "scales": self.scales,
            "rotations": self.rotations,
        }
        if self.semantic is not None:
            out["semantic"] = self.semantic
        return out

    def constant_channels(self) -> dict[str, list[int]]:
        """Per attribute, the channel indices whose value is identical for every Gaussian.

        Channels of an empty scene are not reported as constant. NaN never counts as constant.
        """
        out: dict[str, list[int]] = {}
        if len(self) == 0:
            return out
        for name, values in self.attributes().items():
            if values.shape[1] == 0:
                continue
            same = np.all(values == values[:1], axis=0)
            idx = [int(i) for i in np.flatnonzero(same)]
            if idx:
                out[name] = idx
        return out

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(min, max) of the positions, each (3,) float64; zeros for an empty scene."""
        if len(self) == 0:
            return np.zeros(3), np.zeros(3)
        p = self.positions.astype(np.float64)
        return p.min(axis=0), p.max(axis=0)

    def robust_bounds(self, percentile: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) per-axis percentiles of the positions (floaters excluded), (3,) float64."""
        if len(self) == 0:
            return np.zeros(3), np.zeros(3)
        p = self.positions.astype(np.float64)
        return np.percentile(p, percentile, axis=0), np.percentile(p, 100 - percentile, axis=0)

    def robust_center_and_extent(self, percentile: float = 1.0) -> tuple[np.ndarray, float]:
        """Centre (3,) and extent (largest side of the percentile box), world units."""
        lo, hi = self.robust_bounds(percentile)
        return (lo + hi) / 2, float(np.max(hi - lo)) if len(self) else 0.0

    # ----------------------------------------------------------------- editing
    def subset(self, keep: np.ndarray) -> GaussianScene:
        """A new scene with the rows selected by ``keep`` (boolean mask (N,) or index array)."""
        return GaussianScene(
            positions=self.positions[keep],
            sh_dc=self.sh_dc[keep],
            sh_rest=self.sh_rest[keep],
            opacity=self.opacity[keep],
            scales=self.scales[keep],
            rotations=self.rotations[keep],
            semantic=None if self.semantic is None else self.semantic[keep],
            semantic_names=self.semantic_names,
            labels=None if self.labels is None else self.labels[keep],
            instances=self.instances,
        )

    def nonfinite_rows(self) -> np.ndarray:
        """Boolean (N,) mask of Gaussians with any NaN or infinite float attribute."""
        bad = np.zeros(len(self), dtype=bool)
        for values in self.attributes().values():
            if values.shape[1]:
                bad |= ~np.all(np.isfinite(values), axis=1)
        return bad

    def equals(self, other: GaussianScene) -> bool:
        """True when every array (and semantic names) match exactly, bit for bit."""
        if not isinstance(other, GaussianScene) or self.semantic_names != other.semantic_names:
            return False
        if (self.instances is None) != (other.instances is None) or (
                self.instances is not None and not (
                    np.array_equal(self.instances.prototypes, other.instances.prototypes)
                    and np.array_equal(self.instances.embeddings,
                                       other.instances.embeddings))):
            return False
        for name in ("positions", "sh_dc", "sh_rest", "opacity", "scales", "rotations",
                     "semantic", "labels"):
            a, b = getattr(self, name), getattr(other, name)
            if (a is None) != (b is None):
                return False
            if a is not None and (a.shape != b.shape or a.dtype != b.dtype
                                  or a.tobytes() != b.tobytes()):
                return False
        return True

    def ply_property(self, attribute: str, channel: int) -> str:
        """The PLY property of column ``channel`` of :meth:`attributes` ``[attribute]``
        (``sh_dc`` 1 -> ``f_dc_1``), the name errors give so users find it in their file."""
        return ply_property(attribute, channel, sh_bands=int(self.sh_rest.shape[1]),
                            semantic_names=self.semantic_names)

    # ----------------------------------------------------------------- checks
    def validate(self, source: str | None = None) -> None:
        """Check shapes, dtypes and finiteness.

        Raises:
            InputError: naming the property and, for values, the first bad Gaussian index.
        """
        n = len(self)
        expected = {
            "positions": ((n, 3), np.float32),
            "sh_dc": ((n, 3), np.float32),
            "opacity": ((n,), np.float32),
            "scales": ((n, 3), np.float32),
            "rotations": ((n, 4), np.float32),
        }
        if self.positions.ndim != 2 or self.positions.shape[1:] != (3,):
            raise InputError(f"expected shape (N, 3), got {self.positions.shape}",
                             file=source, property="positions")
        for name, (shape, dtype) in expected.items():
            arr = getattr(self, name)
            if arr.shape != shape:
                raise InputError(f"expected shape {shape}, got {arr.shape}", file=source,
                                 property=name)
            if arr.dtype != dtype:
                raise InputError(f"expected dtype {np.dtype(dtype)}, got {arr.dtype}",
                                 file=source, property=name)
        r = self.sh_rest
        if r.ndim != 3 or r.shape[0] != n or r.shape[2] != 3 or r.shape[1] not in SH_DEGREE_OF_REST:
            raise InputError(f"expected shape (N, B, 3) with B in {{0, 3, 8, 15}}, got {r.shape}",
                             file=source, property="sh_rest")
        if r.dtype != np.float32:
            raise InputError(f"expected dtype float32, got {r.dtype}", file=source,
                             property="sh_rest")
        if self.semantic is not None:
            s = self.semantic
            if s.ndim != 2 or s.shape[0] != n or s.dtype != np.float32:
                raise InputError(f"expected (N, S) float32, got {s.shape} {s.dtype}",
                                 file=source, property="semantic")
            if len(self.semantic_names) != s.shape[1]:
                raise InputError(f"{s.shape[1]} channels but {len(self.semantic_names)} names",
                                 file=source, property="semantic")
        if self.labels is not None:
            lab = self.labels
            if lab.shape != (n,) or lab.dtype != np.int32:
                raise InputError(f"expected (N,) int32, got {lab.shape} {lab.dtype}",
                                 file=source, property="labels")
        if self.instances is not None:
            if self.semantic is None:
                raise InputError("an instance table needs semantic features", file=source,
                                 property="instances")
            self.instances.validate(self.semantic.shape[1])
        for name, values in self.attributes().items():
            if values.shape[1] == 0:
                continue
            finite = np.isfinite(values)
            if not finite.all():
                row, col = np.argwhere(~finite)[0]
                raise InputError(f"non-finite value {values[row, col]} (attribute {name}, "
                                 f"channel {col})", file=source,
                                 property=self.ply_property(name, int(col)), index=int(row))
