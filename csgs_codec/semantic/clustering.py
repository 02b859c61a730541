"""Spherical k-means on unit semantic features, seeded so the same input always gives the same
clusters (k-means++ start from a fixed random generator, a fixed iteration budget)."""

from __future__ import annotations

import numpy as np

from csgs_codec.errors import InputError

#: Most clusters :func:`spherical_kmeans` accepts (guards against absurd requests).
MAX_CLUSTERS = 256
#: Points the centroids are fitted on; the rest are only assigned (keeps large scenes fast).
FIT_SAMPLE = 20_000
#: Rows per block when assigning points, so the (rows, k) score matrix stays small.
ASSIGN_BLOCK = 1 << 16


def unit_rows(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows of ``features`` scaled to unit length.

    Args:
        features: (N, S) float array.

    Returns:
        ((N, S) float64 unit rows, zero rows left at zero; (N,) bool, True where the row had a
        positive finite length).
    """
    values = np.asarray(features, dtype=np.float64)
    norms = np.linalg.norm(values, axis=1)
    valid = np.isfinite(norms) & (norms > 0)
    units = np.zeros_like(values)
    units[valid] = values[valid] / norms[valid, None]
    return units, valid


def assign_clusters(units: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    """(N,) int64 index of the centroid with the largest cosine to each unit row.

    Args:
        units: (N, S) unit rows; centroids: (k, S) unit rows.
    """
    out = np.empty(len(units), np.int64)
    for start in range(0, len(units), ASSIGN_BLOCK):
        block = units[start:start + ASSIGN_BLOCK]
        out[start:start + len(block)] = np.argmax(block @ centroids.T, axis=1)
    return out


def spherical_kmeans(units: np.ndarray, k: int, *, seed: int = 0, iterations: int = 50,
                     fit_sample: int = FIT_SAMPLE) -> tuple[np.ndarray, np.ndarray]:
    """Cluster unit vectors by cosine similarity.

    k-means++ picks the starting centroids (squared cosine distance ``1 - cos`` as the
    weight), then Lloyd iterations move each centroid to the normalised mean of its members
    until the assignment stops changing or ``iterations`` run out. Centroids are fitted on an
    even random sample of at most ``fit_sample`` rows; every row is then assigned.

    Args:
        units: (N, S) float unit rows (see :func:`unit_rows`), N >= 1.
        k: clusters wanted, 1..MAX_CLUSTERS; at most N are made.
        seed: seed of the random generator (sampling and k-means++).
        iterations: most Lloyd iterations.
        fit_sample: most rows the centroids are fitted on.

    Returns:
        ((k', S) float64 unit centroids with k' = min(k, N); (N,) int64 cluster of each row).

    Raises:
        InputError: k outside 1..MAX_CLUSTERS, or no rows.
    """
    if not isinstance(k, int | np.integer) or not 1 <= k <= MAX_CLUSTERS:
        raise InputError(f"cluster count must be an integer in 1..{MAX_CLUSTERS}, got {k!r}",
                         property="clusters")
    units = np.asarray(units, dtype=np.float64)
    if units.ndim != 2 or len(units) == 0:
        raise InputError("no features to cluster", property="semantic")
    rng = np.random.default_rng(seed)
    fit = units
    if len(units) > fit_sample:
        fit = units[np.sort(rng.choice(len(units), fit_sample, replace=False))]
    k = min(int(k), len(fit))
    centroids = _kmeans_plus_plus(fit, k, rng)
    assignment = None
    for _ in range(iterations):
        new_assignment = assign_clusters(fit, centroids)
        if assignment is not None and np.array_equal(new_assignment, assignment):
            break
        assignment = new_assignment
        sums = np.zeros_like(centroids)
        np.add.at(sums, assignment, fit)
        norms = np.linalg.norm(sums, axis=1)
        moved = norms > 0  # an emptied cluster keeps its old centroid
        centroids[moved] = sums[moved] / norms[moved, None]
    return centroids, assign_clusters(units, centroids)


def _kmeans_plus_plus(points: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """(k, S) starting centroids: the first uniform, each next drawn with probability
    proportional to its squared cosine distance to the nearest one chosen."""
    chosen = [int(rng.integers(len(points)))]
    distance = np.maximum(1.0 - points @ points[chosen[0]], 0.0) ** 2
    for _ in range(1, k):
        total = distance.sum()
        if total <= 0:  # every point coincides with a centroid: take unused rows in order
            unused = np.setdiff1d(np.arange(len(points)), chosen)
            chosen.append(int(unused[0]))
        else:
            chosen.append(int(rng.choice(len(points), p=distance / total)))
        distance = np.minimum(distance, np.maximum(1.0 - points @ points[chosen[-1]], 0.0) ** 2)
    return points[chosen].copy()
