"""Click selection: the Gaussians (or anchors) whose semantic feature matches the pixel clicked.

Three rules turn a click into a selection.

* ``"instance"`` (the default): every element belongs to one instance, and the click selects
  the instance that carries the most rendered weight at the clicked pixel (alpha * T of its
  Gaussians, summed), with all its elements. Instances are the scene's labels when it has
  them; else its features when they take at most :data:`MAX_INSTANCES` distinct values, at
  most one per :data:`MIN_INSTANCE_SIZE` elements (what ``csgs segment`` writes: one
  prototype per instance, coded exactly). The rule never compares a blended pixel feature
  with single Gaussians, which is what fails on real, translucent scenes (the pixel mixes the
  object with what lies behind it). A scene whose features are continuous (trained but not
  segmented) has no instances: the click then follows the cosine rule, as the browser page
  does (the result says ``mode="cosine"``); ``"cluster"`` groups such features first.

For the other two the semantic features are rendered into a feature map for the camera (the
same alpha compositing as color), the feature under the click is divided by the pixel's
accumulated opacity and normalised, and each element is scored by the cosine between its own
feature and that direction:

* ``"cosine"``: every element whose cosine is at least ``threshold``.
* ``"cluster"``: spherical k-means (fixed seed) groups the elements' unit features into
  ``clusters`` clusters; the selection is the cluster nearest the clicked feature together
  with every cluster whose centroid has cosine >= ``threshold`` with that cluster's centroid.
  The decision is per cluster, so an outlier feature follows its cluster; the merge undoes
  k-means splitting one object when ``clusters`` exceeds the number of objects.

Elements whose feature is all zero have no direction and are never selected.

The default threshold 0.9 (about 26 degrees) keeps objects whose feature directions differ by
more than that apart while tolerating the noise of trained features and of the codec's
semantic quantization.

For an :class:`AnchorScene` the elements are anchors: the anchors are decoded into the view's
neural Gaussians (each carries its anchor's semantic feature), those are rendered, and the
mask is over anchors; a selected anchor's Gaussians are selected with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.semantic.clustering import spherical_kmeans, unit_rows

#: Cosine similarity an element needs to be selected (both modes; see the module docstring).
DEFAULT_THRESHOLD = 0.9
#: Selection rules :func:`click_selection` knows; the first is the default.
MODES = ("instance", "cosine", "cluster")
#: Most distinct feature rows read as instances (more: the features are clustered).
MAX_INSTANCES = 255
#: Distinct feature rows are read as instances only when there are this many elements per
#: distinct row on average (trained continuous features are distinct almost everywhere).
MIN_INSTANCE_SIZE = 4
#: k of the k-means in "cluster" mode.
DEFAULT_CLUSTERS = 16
#: Seed of the k-means in "cluster" mode.
CLUSTER_SEED = 0
#: A click on a pixel whose accumulated opacity is below this hits nothing (the background).
MIN_CLICK_ALPHA = 0.05
#: Rasterizer backend used unless asked otherwise (fast CPU path).
DEFAULT_BACKEND = "numba"


@dataclass(frozen=True)
class ClickSelection:
    """The outcome of one click.

    Attributes:
        mask: (N,) bool, the selected Gaussians, or for an anchor scene the selected anchors.
        scores: (N,) float32 cosine similarity of each element's feature with the clicked
            feature (0 for an all-zero feature).
        clicked_feature: (S,) float32 unit semantic direction under the click.
        pixel: (column, row) of the pixel clicked.
        alpha: accumulated opacity at that pixel, in [0, 1).
        mode: "instance", "cosine" or "cluster".
        threshold: the cosine threshold used.
        clusters: (N,) int64 k-means cluster of each element in "cluster" mode (-1 for an
            all-zero feature), its instance in "instance" mode, else None.
        instance_source: in "instance" mode where instances came from: "labels" or
            "features"; else None.
    """

    mask: np.ndarray
    scores: np.ndarray
    clicked_feature: np.ndarray
    pixel: tuple[int, int]
    alpha: float
    mode: str
    threshold: float
    clusters: np.ndarray | None = None
    instance_source: str | None = None

    @property
    def count(self) -> int:
        """Number of elements selected."""
        return int(np.count_nonzero(self.mask))


@dataclass(frozen=True)
class FeatureMap:
    """A view's rendered semantic features, to click in as often as wanted.

    Attributes:
        camera: the view.
        features: (H, W, S) float32 accumulated features (alpha-weighted sums).
        alpha: (H, W) float32 accumulated opacity.
        elements: N, the Gaussians (or anchors) of the scene it was rendered from.
    """

    camera: Camera
    features: np.ndarray
    alpha: np.ndarray
    elements: int


def render_feature_map(scene: GaussianScene | AnchorScene, camera: Camera, *,
                       backend: str = DEFAULT_BACKEND) -> FeatureMap:
    """Render the scene's semantic features for ``camera`` (anchors: their view's Gaussians).

    Raises:
        InputError: the scene has no semantic features, or the camera is invalid.
        ModelError: an anchor scene without Scaffold-GS MLPs.
    """
    from csgs_codec.render.rasterizer import render  # torch: only when a view is rendered

    element_features(scene)
    gaussians = view_gaussians(scene, camera)
    out = render(gaussians, camera, features=gaussians.semantic, backend=backend)
    return FeatureMap(camera, out.features, out.alpha, len(scene))


def select_at_click(scene: GaussianScene | AnchorScene, camera: Camera, x: float, y: float,
                    *, threshold: float = DEFAULT_THRESHOLD, mode: str = "instance"
                    ) -> np.ndarray:
    """The (N,) bool mask of the Gaussians (anchors for an :class:`AnchorScene`) that match the
    semantic feature under pixel (x, y) of ``camera``; see :func:`click_selection`."""
    return click_selection(scene, camera, x, y, threshold=threshold, mode=mode).mask


def click_selection(scene: GaussianScene | AnchorScene, camera: Camera, x: float, y: float,
                    *, threshold: float = DEFAULT_THRESHOLD, mode: str = "instance",
                    clusters: int = DEFAULT_CLUSTERS, backend: str = DEFAULT_BACKEND,
                    feature_map: FeatureMap | None = None) -> ClickSelection:
    """Select what the click at pixel (x, y) lands on: its instance, or by semantic
    similarity.

    Args:
        scene: Gaussians with ``semantic`` (N, S) features, or anchors with (M, S) features.
        camera: the view clicked in; (x, y) are its pixel coordinates.
        x, y: pixel coordinates (column, row), pixel (i, j) spanning [i, i + 1) x [j, j + 1).
        threshold: cosine similarity in [-1, 1] (default :data:`DEFAULT_THRESHOLD`).
        mode: "instance" (default), "cosine" or "cluster" (see the module docstring).
        clusters: k of the k-means in "cluster" mode.
        backend: rasterizer backend for the feature map ("numba" by default).
        feature_map: this scene's :func:`render_feature_map` for ``camera``, to click again
            without rendering again; None renders it.

    Returns:
        :class:`ClickSelection`.

    Raises:
        InputError: no semantic features, a click outside the image or on the background
            (accumulated opacity below :data:`MIN_CLICK_ALPHA`), a zero feature under the
            click, or a bad threshold, mode or cluster count.
        ModelError: an anchor scene without Scaffold-GS MLPs (it cannot be rendered).
    """
    check_selection_rule(mode, threshold)
    if mode == "instance":
        selection = _instance_selection(scene, camera, x, y, threshold)
        if selection is not None:
            return selection
        mode = "cosine"  # continuous features have no instances (module notes)
    features = element_features(scene)
    column, row = click_pixel(camera, x, y)
    if feature_map is None:
        feature_map = render_feature_map(scene, camera, backend=backend)
    elif feature_map.camera is not camera or feature_map.elements != len(scene):
        raise InputError("the feature map was rendered for another camera or scene",
                         property="feature_map")
    direction, alpha = feature_under_pixel(feature_map, column, row)
    units, valid = unit_rows(features)
    scores = units @ direction
    assignment = None
    if mode == "cosine":
        mask = valid & (scores >= threshold)  # an all-zero feature has no direction
    else:
        mask, assignment = _cluster_selection(units, valid, direction, threshold, clusters)
    return ClickSelection(mask=mask, scores=scores.astype(np.float32),
                          clicked_feature=direction.astype(np.float32), pixel=(column, row),
                          alpha=alpha, mode=mode, threshold=float(threshold),
                          clusters=assignment)


def check_selection_rule(mode: str, threshold: float) -> None:
    """Check a selection mode and cosine threshold.

    Raises:
        InputError: ``mode`` is not in :data:`MODES` or ``threshold`` is not in [-1, 1].
    """
    if mode not in MODES:
        raise InputError(f"selection mode must be one of {', '.join(MODES)}, got {mode!r}",
                         property="mode")
    if (isinstance(threshold, bool) or not isinstance(threshold, int | float | np.floating)
            or not -1.0 <= threshold <= 1.0):
        raise InputError(f"threshold must be a cosine similarity in [-1, 1], got "
                         f"{threshold!r}", property="threshold")


def element_features(scene: GaussianScene | AnchorScene) -> np.ndarray:
    """(N, S) semantic features of the scene's selectable elements (Gaussians or anchors).

    Raises:
        InputError: the scene has no semantic features, or they are not (N, S) with S >= 1.
    """
    if not isinstance(scene, GaussianScene | AnchorScene):
        raise InputError(f"expected a GaussianScene or AnchorScene, got "
                         f"{type(scene).__name__}", property="scene")
    features = scene.semantic
    if features is None:
        raise InputError("the scene has no semantic features to select by (decode the "
                         "semantic layer: layers='color,semantic')", property="semantic")
    features = np.asarray(features)
    if features.ndim != 2 or features.shape[0] != len(scene) or features.shape[1] == 0:
        raise InputError(f"semantic features must be (N, S) with N = {len(scene)} and S >= 1, "
                         f"got {features.shape}", property="semantic")
    return features


def click_pixel(camera: Camera, x: float, y: float) -> tuple[int, int]:
    """(column, row) of the pixel containing image point (x, y).

    Raises:
        InputError: (x, y) is not finite or lies outside the camera's image.
    """
    try:
        fx, fy = float(x), float(y)
    except (TypeError, ValueError):
        raise InputError(f"click must be two numbers, got ({x!r}, {y!r})",
                         property="click") from None
    if not (math.isfinite(fx) and math.isfinite(fy)
            and 0 <= fx < camera.width and 0 <= fy < camera.height):
        raise InputError(f"click ({x}, {y}) is outside the {camera.width}x{camera.height} "
                         "image", property="click")
    return int(math.floor(fx)), int(math.floor(fy))


def feature_under_pixel(feature_map: FeatureMap, column: int, row: int
                        ) -> tuple[np.ndarray, float]:
    """The unit semantic feature at pixel (column, row) of a rendered feature map.

    Returns:
        ((S,) float64 unit feature, accumulated opacity at the pixel).

    Raises:
        InputError: the pixel's opacity is below :data:`MIN_CLICK_ALPHA` (nothing is under
            the click) or its feature is zero.
    """
    alpha = float(feature_map.alpha[row, column])
    if not alpha >= MIN_CLICK_ALPHA:
        raise InputError(f"nothing under the click at pixel ({column}, {row}): accumulated "
                         f"opacity {alpha:.3g} is below {MIN_CLICK_ALPHA}", property="click")
    feature = feature_map.features[row, column].astype(np.float64) / alpha
    norm = float(np.linalg.norm(feature))
    if not (math.isfinite(norm) and norm > 0):
        raise InputError(f"the semantic feature under the click at pixel ({column}, {row}) is "
                         "zero; there is no direction to match", property="semantic")
    return feature / norm, alpha


def view_gaussians(scene: GaussianScene | AnchorScene, camera: Camera) -> GaussianScene:
    """The Gaussians to render for ``camera``: the scene itself, or an anchor scene's neural
    Gaussians for that view (each with its anchor's semantic feature)."""
    if isinstance(scene, GaussianScene):
        return scene
    from csgs_codec.model.scaffold import ScaffoldDecoder

    return ScaffoldDecoder(scene).to_gaussians(camera)


def selected_gaussians(scene: GaussianScene | AnchorScene, mask: np.ndarray,
                       camera: Camera | None = None) -> GaussianScene:
    """The selected part of ``scene`` as a standard :class:`GaussianScene`.

    For an anchor scene, the selected anchors' neural Gaussians evaluated for ``camera`` (or
    the canonical export view when None).

    Raises:
        InputError: ``mask`` is not an (N,) bool array for this scene.
    """
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != (len(scene),):
        raise InputError(f"selection mask must be ({len(scene)},) bool, got {mask.shape} "
                         f"{mask.dtype}", property="mask")
    if isinstance(scene, GaussianScene):
        return scene.subset(mask)
    from csgs_codec.model.scaffold import ScaffoldDecoder

    decoder = ScaffoldDecoder(scene)
    origin = camera.position if camera is not None else decoder.scene_center()
    view = decoder.decode(origin)
    return view.gaussians.subset(mask[view.anchor_index])


def element_instances(scene: GaussianScene | AnchorScene
                      ) -> tuple[np.ndarray, str] | None:
    """The instance of every selectable element (see the module docstring, "instance").

    Returns:
        ((N,) int64 instance per element, "labels" or "features"), or None when the scene's
        features are continuous (no instances).

    Raises:
        InputError: the scene has neither labels nor semantic features.
    """
    if not isinstance(scene, GaussianScene | AnchorScene):
        raise InputError(f"expected a GaussianScene or AnchorScene, got "
                         f"{type(scene).__name__}", property="scene")
    labels = getattr(scene, "labels", None)
    if labels is not None:
        return np.asarray(labels, np.int64), "labels"
    if getattr(scene, "semantic", None) is None:
        raise InputError("the scene has no labels or semantic features to select by (decode "
                         "the semantic layer: layers='color,semantic')", property="semantic")
    features = element_features(scene)
    rows, inverse = np.unique(features, axis=0, return_inverse=True)
    if len(rows) <= MAX_INSTANCES and len(rows) * MIN_INSTANCE_SIZE <= len(features):
        return inverse.reshape(-1).astype(np.int64), "features"
    return None


def weights_at_pixel(gaussians: GaussianScene, camera: Camera, column: int, row: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Each Gaussian's compositing weight alpha * T at pixel (column, row), by the reference
    rasterizer's rule: ((P,) int64 Gaussians with weight, (P,) float64 weights)."""
    import dataclasses

    import torch

    from csgs_codec.render.composite_torch import composite_weights
    from csgs_codec.render.projection import project_gaussians
    from csgs_codec.render.rasterizer import scene_tensors
    from csgs_codec.render.tiles import depth_order

    # A 1 x 1 camera whose only pixel is the clicked one.
    pixel_camera = dataclasses.replace(camera, width=1, height=1, cx=camera.cx - column,
                                       cy=camera.cy - row)
    t = scene_tensors(gaussians)
    with torch.no_grad():
        projected = project_gaussians(t["means"], t["log_scales"], t["quats"],
                                      t["opacity_logits"], pixel_camera,
                                      near_plane=camera.near_plane)
        order = depth_order(projected.depths, projected.visible)
        _, index, weight = composite_weights(order, projected.means2d, projected.conics,
                                             projected.opacities, projected.extents, 1, 1)
    return index.cpu().numpy(), weight.double().cpu().numpy()


def _instance_selection(scene: GaussianScene | AnchorScene, camera: Camera, x: float,
                        y: float, threshold: float) -> ClickSelection | None:
    """"instance" mode (module notes); None when the scene has no instances."""
    found = element_instances(scene)
    if found is None:
        return None
    ids, source = found
    column, row = click_pixel(camera, x, y)
    if isinstance(scene, GaussianScene):
        gaussians, element = scene, np.arange(len(scene))
    else:
        from csgs_codec.model.scaffold import ScaffoldDecoder

        view = ScaffoldDecoder(scene).decode(camera.position)
        gaussians, element = view.gaussians, view.anchor_index
    index, weight = weights_at_pixel(gaussians, camera, column, row)
    alpha = float(weight.sum())
    if not alpha >= MIN_CLICK_ALPHA:
        raise InputError(f"nothing under the click at pixel ({column}, {row}): accumulated "
                         f"opacity {alpha:.3g} is below {MIN_CLICK_ALPHA}", property="click")
    values, inverse = np.unique(ids[element[index]], return_inverse=True)
    chosen = int(values[np.argmax(np.bincount(inverse, weights=weight))])
    mask = ids == chosen
    features = scene.semantic
    direction = np.zeros(0, np.float32)
    if features is not None and len(features):
        summed = (np.asarray(features, np.float64)[element[index]] * weight[:, None]).sum(0)
        norm = float(np.linalg.norm(summed))
        direction = (summed / norm if norm > 0 else summed).astype(np.float32)
    return ClickSelection(mask=mask, scores=mask.astype(np.float32), clicked_feature=direction,
                          pixel=(column, row), alpha=alpha, mode="instance",
                          threshold=float(threshold), clusters=ids,
                          instance_source=source)


def _cluster_selection(units: np.ndarray, valid: np.ndarray, direction: np.ndarray,
                       threshold: float, clusters: int) -> tuple[np.ndarray, np.ndarray]:
    """((N,) bool mask, (N,) int64 cluster per element) for "cluster" mode."""
    assignment = np.full(len(units), -1, np.int64)
    mask = np.zeros(len(units), bool)
    if not valid.any():
        return mask, assignment
    centroids, assignment[valid] = spherical_kmeans(units[valid], clusters, seed=CLUSTER_SEED)
    clicked = int(np.argmax(centroids @ direction))
    chosen = np.flatnonzero(centroids @ centroids[clicked] >= threshold)
    mask[valid] = np.isin(assignment[valid], np.union1d(chosen, [clicked]))
    return mask, assignment
