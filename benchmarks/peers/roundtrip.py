"""Round-trip checks for a peer: which decoded Gaussian is which original, and how far off.

Some peers keep the input order (compressed PLY, SPZ); SOG sorts by Morton code. A decoded
scene is matched to its original by index when the order is kept, else each decoded Gaussian
is paired with the original nearest in position (VTK's static point locator; VTK comes with
pyvista, a project dependency), which is not one-to-one where positions collide after
quantization: ``unique_match_fraction`` says how close it came.
"""

from __future__ import annotations

import numpy as np
from vtkmodules.util.numpy_support import numpy_to_vtk
from vtkmodules.vtkCommonCore import vtkPoints
from vtkmodules.vtkCommonDataModel import vtkPolyData, vtkStaticPointLocator

from csgs_codec.scene.gaussian_scene import GaussianScene

#: Degree-0 SH basis constant: rgb = 0.5 + SH_C0 * f_dc.
SH_C0 = 0.28209479177387814
#: Alpha below which the reference 3DGS rasterizer skips a Gaussian's contribution.
VISIBLE_ALPHA = 1.0 / 255.0


def match_to_original(original: GaussianScene, decoded: GaussianScene
                      ) -> tuple[np.ndarray, str]:
    """Index into ``original`` for each decoded Gaussian, and how it was found.

    Returns:
        ``((M,) int64 indices, "index" | "nearest_position")``: "index" when the counts agree
        and pairing row i with row i is, at the 99th percentile, no farther than 4x the
        nearest-neighbour distance (plus a 1e-9-extent floor); else the nearest original.
    """
    p_orig = original.positions.astype(np.float64)
    p_dec = decoded.positions.astype(np.float64)
    nearest = nearest_points(p_orig, p_dec)
    nearest_dist = np.linalg.norm(p_dec - p_orig[nearest], axis=1)
    if len(decoded) == len(original) and len(decoded) > 0:
        _, extent = original.robust_center_and_extent()
        by_index = np.linalg.norm(p_dec - p_orig, axis=1)
        if np.percentile(by_index, 99) <= 4 * np.percentile(nearest_dist, 99) + 1e-9 * extent:
            return np.arange(len(decoded), dtype=np.int64), "index"
    return nearest.astype(np.int64), "nearest_position"


def nearest_points(reference: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """(M,) int64 index of the ``reference`` point ((N, 3) float64) nearest each of the
    (M, 3) ``queries``; empty when either is empty."""
    if len(reference) == 0 or len(queries) == 0:
        return np.zeros(0, np.int64)
    points = vtkPoints()
    points.SetData(numpy_to_vtk(np.ascontiguousarray(reference, np.float64), deep=True))
    cloud = vtkPolyData()
    cloud.SetPoints(points)
    locator = vtkStaticPointLocator()
    locator.SetDataSet(cloud)
    locator.BuildLocator()
    closest = locator.FindClosestPoint
    return np.fromiter((closest(q) for q in queries.tolist()), np.int64, len(queries))


def _abs_stats(prefix: str, error: np.ndarray, unit: str) -> dict[str, float]:
    error = np.abs(np.asarray(error, np.float64)).ravel()
    if error.size == 0:
        return {}
    return {f"{prefix}_max_{unit}": float(error.max()),
            f"{prefix}_rms_{unit}": float(np.sqrt(np.mean(error**2))),
            f"{prefix}_mean_{unit}": float(error.mean())}


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.clip(x.astype(np.float64), -60, 60)))


def _rotation_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(M,) angle in degrees between the rotations of (M, 4) quaternions (sign-blind)."""
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    a = a / np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-30)
    b = b / np.maximum(np.linalg.norm(b, axis=1, keepdims=True), 1e-30)
    dot = np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0)
    return np.degrees(2.0 * np.arccos(dot))


def roundtrip_report(original: GaussianScene, decoded: GaussianScene) -> dict:
    """Counts and per-attribute error statistics of ``decoded`` against ``original``.

    Units in the keys: ``world`` (scene units), ``rel_extent`` (fraction of the robust
    extent), ``rgb01`` (degree-0 color 0.5 + SH_C0 * f_dc clipped to [0, 1]), ``coef`` (raw
    SH coefficient), ``alpha`` (sigmoid opacity), ``logscale`` (natural-log scale), ``deg``
    (rotation angle). Each has ``_max``, ``_rms`` and ``_mean`` of the absolute error.
    ``visible_only`` repeats them over the Gaussians whose original alpha is at least
    :data:`VISIBLE_ALPHA`.
    """
    index, method = match_to_original(original, decoded)
    n_in, n_out = len(original), len(decoded)
    report: dict = {
        "input_gaussians": n_in,
        "decoded_gaussians": n_out,
        "dropped_gaussians": n_in - n_out,
        "matched_by": method,
        "unique_match_fraction": float(np.unique(index).size / max(n_out, 1)),
        "sh_degree_in": original.sh_degree_stored,
        "sh_degree_out": decoded.sh_degree_stored,
    }
    if n_out == 0:
        return report
    o = original.subset(index)
    _, extent = original.robust_center_and_extent()
    report.update(attribute_errors(o, decoded, extent))
    # Peers may zero what cannot show (SOG blacks out Gaussians whose alpha rounds to 0), so
    # the errors are also given over the Gaussians a render can see.
    visible = _sigmoid(o.opacity) >= VISIBLE_ALPHA
    report["visible_gaussians"] = int(visible.sum())
    report["visible_only"] = attribute_errors(o.subset(visible), decoded.subset(visible), extent)
    return report


def attribute_errors(original: GaussianScene, decoded: GaussianScene, extent: float
                     ) -> dict[str, float]:
    """Error statistics of row-aligned scenes (same N), per attribute; see
    :func:`roundtrip_report` for the units. ``extent`` scales the ``rel_extent`` figures."""
    o = original
    report: dict[str, float] = {}
    if len(o) == 0:
        return report
    position_error = decoded.positions.astype(np.float64) - o.positions
    report.update(_abs_stats("position", position_error, "world"))
    report.update(_abs_stats("position", position_error / max(extent, 1e-30), "rel_extent"))
    rgb_dec = np.clip(0.5 + SH_C0 * decoded.sh_dc.astype(np.float64), 0, 1)
    rgb_orig = np.clip(0.5 + SH_C0 * o.sh_dc.astype(np.float64), 0, 1)
    report.update(_abs_stats("color", rgb_dec - rgb_orig, "rgb01"))
    report.update(_abs_stats("sh_dc", decoded.sh_dc.astype(np.float64) - o.sh_dc, "coef"))
    bands = min(decoded.sh_rest.shape[1], o.sh_rest.shape[1])
    if bands:
        rest_error = decoded.sh_rest[:, :bands].astype(np.float64) - o.sh_rest[:, :bands]
        report.update(_abs_stats("sh_rest", rest_error, "coef"))
    report.update(_abs_stats("opacity", _sigmoid(decoded.opacity) - _sigmoid(o.opacity),
                             "alpha"))
    report.update(_abs_stats("scale", decoded.scales.astype(np.float64) - o.scales, "logscale"))
    report.update(_abs_stats("rotation", _rotation_angle_deg(decoded.rotations, o.rotations),
                             "deg"))
    return report
