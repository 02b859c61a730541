"""Open-vocabulary queries: the instance whose embedding best matches a query embedding.

A segmented scene with an instance table (``csgs segment --mask-embeddings``, carried by the
.csgs semantic codebook) pairs each instance's prototype feature with an embedding in a space
the user chose (image embeddings of its masks, say CLIP's). A query embedding in the same
space (CLIP's text embedding of "the red chair") selects the instance with the largest
cosine similarity, and every Gaussian whose semantic feature is that instance's prototype.
Nothing here computes embeddings: they come with the scene and the query.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass(frozen=True)
class QueryResult:
    """The outcome of one query.

    Attributes:
        mask: (N,) bool, the Gaussians of the best-matching instance.
        instance: its row in ``scene.instances``.
        scores: (K,) float64 cosine similarity of each instance's embedding with the query
            (0 for an all-zero embedding).
        ranking: (K,) int64 instance rows, best first.
        rows: (N,) int64 each Gaussian's instance row (-1 for a feature not in the table).
    """

    mask: np.ndarray
    instance: int
    scores: np.ndarray
    ranking: np.ndarray
    rows: np.ndarray

    @property
    def count(self) -> int:
        """Number of Gaussians selected."""
        return int(np.count_nonzero(self.mask))


def query_instances(scene: GaussianScene, embedding: np.ndarray) -> QueryResult:
    """Select the instance of ``scene`` whose embedding best matches ``embedding`` (E,).

    Raises:
        InputError: a scene without an instance table, or a query that is not a finite,
            non-zero (E,) vector of the table's width.
    """
    table = getattr(scene, "instances", None)
    if table is None or scene.semantic is None:
        raise InputError("the scene has no instance embeddings to query (segment it with "
                         "mask embeddings and decode the semantic layer)",
                         property="instances")
    query = np.asarray(embedding, np.float64).reshape(-1)
    width = table.embeddings.shape[1]
    if query.shape != (width,) or not np.isfinite(query).all() or not np.any(query):
        raise InputError(f"the query must be a finite, non-zero vector of {width} values, got "
                         f"shape {np.asarray(embedding).shape}", property="embedding")
    # Cosine similarity ignores scale: bring the largest value to 1 first, so the norm of a
    # query of 1e300s does not overflow (inf, then NaN scores) nor one of 1e-310s underflow.
    query = query / np.max(np.abs(query))
    vectors = table.embeddings.astype(np.float64)
    norms = np.linalg.norm(vectors, axis=1)
    scores = np.where(norms > 0, vectors @ query / np.where(norms > 0, norms, 1.0), 0.0)
    scores /= np.linalg.norm(query)
    ranking = np.lexsort((np.arange(len(scores)), -scores))
    best = int(ranking[0])
    rows = table.rows_of(scene.semantic)
    return QueryResult(rows == best, best, scores, ranking, rows)
