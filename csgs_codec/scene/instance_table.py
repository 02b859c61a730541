"""Per-instance embeddings of a segmented scene, for open-vocabulary queries.

A segmented scene's Gaussians carry their instance's prototype as their semantic feature
(``csgs segment``), so an instance is named by its prototype row. The table pairs each
prototype with an embedding in a space the user chose (CLIP image embeddings of the masks,
say): a text embedding in the same space then picks the instance whose embedding is most
similar (:mod:`csgs_codec.semantic.query`). The .csgs carries the table in its semantic
codebook (``SEMC``, FORMAT §12.23), embeddings as binary16.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError

#: Largest magnitude of an embedding value: binary16's largest finite number, as the
#: format stores them (FORMAT §12.23); larger ones would decode as infinity.
MAX_EMBEDDING_VALUE = 65504.0
#: Longest embedding a table holds (CLIP's are 512 to 1,024 values).
MAX_EMBEDDING_DIM = 4096


@dataclass(frozen=True)
class InstanceTable:
    """K instances, each a prototype feature and an embedding.

    Attributes:
        prototypes: (K, S) float32 distinct semantic feature rows, one per instance.
        embeddings: (K, E) float32 embedding of each instance.
    """

    prototypes: np.ndarray
    embeddings: np.ndarray

    def validate(self, channels: int | None = None) -> None:
        """Check shapes and values; ``channels`` is the scene's semantic width S.

        Raises:
            InputError: shapes that disagree, non-finite values, repeated prototypes, an
                embedding longer than :data:`MAX_EMBEDDING_DIM` or a value binary16 cannot
                hold (:data:`MAX_EMBEDDING_VALUE`).
        """
        p, e = self.prototypes, self.embeddings
        if p.ndim != 2 or e.ndim != 2 or len(p) != len(e) or p.dtype != np.float32 \
                or e.dtype != np.float32:
            raise InputError(f"instance table needs (K, S) and (K, E) float32 arrays, got "
                             f"{p.shape} {p.dtype} and {e.shape} {e.dtype}",
                             property="instances")
        if channels is not None and p.shape[1] != channels:
            raise InputError(f"instance prototypes have {p.shape[1]} channels, the scene "
                             f"{channels}", property="instances")
        if not 1 <= e.shape[1] <= MAX_EMBEDDING_DIM:
            raise InputError(f"embeddings must have 1..{MAX_EMBEDDING_DIM} values, got "
                             f"{e.shape[1]}", property="instances")
        if not (np.isfinite(p).all() and np.isfinite(e).all()):
            raise InputError("instance table holds a value that is not finite",
                             property="instances")
        if e.size and float(np.abs(e).max()) > MAX_EMBEDDING_VALUE:
            row, col = np.unravel_index(int(np.argmax(np.abs(e))), e.shape)
            raise InputError(f"embedding value {e[row, col]:g} (instance {row}, value {col}) "
                             f"exceeds binary16's {MAX_EMBEDDING_VALUE:g}, the format's "
                             "storage (scale the embeddings down)", property="embeddings")
        if len(np.unique(p.view(np.uint32), axis=0)) != len(p):
            raise InputError("instance prototypes repeat", property="instances")

    def rows_of(self, features: np.ndarray) -> np.ndarray:
        """(N,) int64 row of the table whose prototype equals each feature row bit for bit,
        -1 where none does."""
        features = np.ascontiguousarray(features, np.float32)
        keys = {row.tobytes(): i for i, row in enumerate(self.prototypes)}
        if features.ndim != 2 or features.shape[1] != self.prototypes.shape[1]:
            return np.full(len(features), -1, np.int64)
        # Distinct rows first (few in a segmented scene), then one lookup per distinct row.
        distinct, inverse = np.unique(features.view(np.uint32), axis=0, return_inverse=True)
        found = np.array([keys.get(row.view(np.float32).tobytes(), -1) for row in distinct],
                         np.int64)
        return found[inverse.reshape(-1)]

    @staticmethod
    def union(tables: list[InstanceTable]) -> InstanceTable | None:
        """The instances of every table once (first occurrence of a prototype wins)."""
        tables = [t for t in tables if t is not None]
        if not tables:
            return None
        seen: dict[bytes, int] = {}
        prototypes, embeddings = [], []
        for table in tables:
            for prototype, embedding in zip(table.prototypes, table.embeddings):
                key = prototype.tobytes()
                if key not in seen:
                    seen[key] = len(prototypes)
                    prototypes.append(prototype)
                    embeddings.append(embedding)
        width = tables[0].embeddings.shape[1]
        return InstanceTable(np.asarray(prototypes, np.float32).reshape(len(prototypes), -1),
                             np.asarray(embeddings, np.float32).reshape(len(embeddings),
                                                                        width))
