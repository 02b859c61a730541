"""A quick look at a scene with pyvista: Gaussians as oriented ellipsoids or as points.

Each Gaussian is drawn with its DC color (0.5 + C0 * sh_dc, clipped), or with a color per
integer label when the scene has labels, or with its first three semantic channels mapped to
RGB when it has semantic features but no labels. Ellipsoids span ``sigma_scale`` standard
deviations along each axis of the Gaussian. The view is the first orbit camera
(:func:`~csgs_codec.scene.orbit.orbit_cameras`), so it is upright by the same rule as the
renders. Works offscreen (EGL or OSMesa builds of VTK) for screenshots.
"""

from __future__ import annotations

import math
import os
import sys
from pathlib import Path

import numpy as np

from csgs_codec.errors import InputError, UnsupportedError
from csgs_codec.scene.gaussian_scene import GaussianScene
from csgs_codec.scene.orbit import orbit_cameras

#: Real spherical-harmonic constant of band 0: color = 0.5 + SH_C0 * sh_dc.
SH_C0 = 0.28209479177387814
COLOR_MODES = ("auto", "dc", "label", "semantic")
#: Gaussians at or below this opacity are not drawn.
MIN_PREVIEW_OPACITY = 0.1
#: Brightness of unselected Gaussians when a selection is shown (a fraction of their color).
UNSELECTED_SHADE = 0.3


def dc_colors(scene: GaussianScene) -> np.ndarray:
    """(N, 3) float32 RGB in [0, 1] from the degree-0 SH coefficients."""
    return np.clip(0.5 + SH_C0 * scene.sh_dc.astype(np.float32), 0.0, 1.0)


def label_colors(labels: np.ndarray) -> np.ndarray:
    """(N, 3) float32 RGB: a distinct, saturated color per integer label (golden-ratio hues)."""
    labels = np.asarray(labels, dtype=np.int64)
    hue = np.mod(labels * 0.6180339887498949, 1.0)
    sector = hue * 6.0
    channels = [np.clip(np.abs(np.mod(sector + shift, 6.0) - 3.0) - 1.0, 0.0, 1.0)
                for shift in (0.0, 4.0, 2.0)]
    return (0.25 + 0.75 * np.stack(channels, axis=1)).astype(np.float32)


def semantic_colors(semantic: np.ndarray) -> np.ndarray:
    """(N, 3) float32 RGB: the first three semantic channels, each min-max scaled to [0, 1]."""
    values = np.zeros((len(semantic), 3), np.float64)
    channels = min(3, semantic.shape[1])
    values[:, :channels] = semantic[:, :channels]
    low, high = values.min(axis=0), values.max(axis=0)
    return ((values - low) / np.where(high > low, high - low, 1.0)).astype(np.float32)


def gaussian_colors(scene: GaussianScene, color_by: str = "auto") -> np.ndarray:
    """(N, 3) float32 RGB per Gaussian; ``color_by`` is one of :data:`COLOR_MODES`.

    "auto" uses labels when present, else DC color.
    """
    if color_by not in COLOR_MODES:
        raise InputError(f"color mode must be one of {', '.join(COLOR_MODES)}, got {color_by!r}",
                         property="color")
    if color_by == "auto":
        color_by = "label" if scene.labels is not None else "dc"
    if color_by == "label":
        if scene.labels is None:
            raise InputError("the scene has no labels to color by", property="labels")
        return label_colors(scene.labels)
    if color_by == "semantic":
        if scene.semantic is None:
            raise InputError("the scene has no semantic features to color by",
                             property="semantic")
        return semantic_colors(scene.semantic)
    return dc_colors(scene)


def highlight_selection(colors: np.ndarray, selection: np.ndarray) -> np.ndarray:
    """(N, 3) float32 RGB: ``colors`` where ``selection`` ((N,) bool) holds, a dim grey
    (:data:`UNSELECTED_SHADE` of the color's mean) elsewhere.

    Raises:
        InputError: ``selection`` is not an (N,) bool array.
    """
    selection = np.asarray(selection)
    if selection.dtype != np.bool_ or selection.shape != (len(colors),):
        raise InputError(f"selection mask must be ({len(colors)},) bool, got "
                         f"{selection.shape} {selection.dtype}", property="selection")
    grey = UNSELECTED_SHADE * colors.mean(axis=1, keepdims=True)
    return np.where(selection[:, None], colors, grey).astype(np.float32)


def preview_camera(scene: GaussianScene, window_size: tuple[int, int] = (800, 600),
                   up: str | np.ndarray | None = None):
    """The :class:`~csgs_codec.scene.camera.Camera` the preview looks from (the first orbit
    view at ``window_size``); pixel (x, y) of a screenshot is pixel (x, y) of its render."""
    width, height = window_size
    return orbit_cameras(scene, 1, width=width, height=height, up=up)[0]


def ellipsoid_mesh(positions: np.ndarray, log_scales: np.ndarray, quaternions: np.ndarray,
                   colors: np.ndarray, *, sigma_scale: float = 1.5, resolution: int = 8):
    """One pyvista PolyData of K ellipsoids with per-point "rgb" colors.

    Args:
        positions: (K, 3) centres, world units.
        log_scales: (K, 3) natural-log standard deviations along the Gaussian's axes.
        quaternions: (K, 4) rotations (w, x, y, z), normalised here.
        colors: (K, 3) RGB in [0, 1].
        sigma_scale: semi-axis length in standard deviations.
        resolution: sphere tessellation (longitude steps; latitude uses 3/4 of it).
    """
    import pyvista as pv

    template = pv.Sphere(radius=1.0, theta_resolution=resolution,
                         phi_resolution=max(4, resolution * 3 // 4)).triangulate()
    unit = np.asarray(template.points, dtype=np.float64)  # (V, 3)
    triangles = np.asarray(template.faces).reshape(-1, 4)[:, 1:]  # (F, 3)
    rotations = quaternion_matrices(quaternions)  # (K, 3, 3)
    axes = rotations * (sigma_scale * np.exp(log_scales.astype(np.float64)))[:, None, :]
    points = np.einsum("kij,vj->kvi", axes, unit) + positions[:, None, :].astype(np.float64)
    count, per = len(positions), len(unit)
    offsets = (np.arange(count) * per)[:, None, None]
    faces = np.concatenate([np.full((count, len(triangles), 1), 3),
                            triangles[None] + offsets], axis=2)
    mesh = pv.PolyData(points.reshape(-1, 3).astype(np.float32), faces.reshape(-1))
    mesh.point_data["rgb"] = (np.repeat(colors, per, axis=0) * 255).astype(np.uint8)
    return mesh


def quaternion_matrices(quaternions: np.ndarray) -> np.ndarray:
    """(K, 3, 3) float64 rotation matrices of (K, 4) quaternions (w, x, y, z), normalised."""
    q = np.asarray(quaternions, dtype=np.float64)
    q = q / np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-30)
    w, x, y, z = q.T
    return np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=1).reshape(-1, 3, 3)


def preview_plotter(scene: GaussianScene, *, mode: str = "ellipsoids", color_by: str = "auto",
                    window_size: tuple[int, int] = (800, 600), off_screen: bool = False,
                    up: str | np.ndarray | None = None, max_gaussians: int = 60_000,
                    selection: np.ndarray | None = None):
    """A pyvista Plotter showing ``scene``, looking from :func:`preview_camera`.

    Args:
        mode: "ellipsoids" or "points".
        color_by: see :func:`gaussian_colors`.
        window_size: (width, height) pixels.
        off_screen: render without a window (for screenshots).
        up: up direction for the view (see :func:`~csgs_codec.scene.orbit.parse_up`).
        max_gaussians: draw at most this many (an even stride through the visible ones).
        selection: optional (N,) bool mask; the rest are drawn dim grey
            (:func:`highlight_selection`).
    """
    import pyvista as pv

    if mode not in ("ellipsoids", "points"):
        raise InputError(f"preview mode must be 'ellipsoids' or 'points', got {mode!r}",
                         property="mode")
    colors = gaussian_colors(scene, color_by)
    if selection is not None:
        colors = highlight_selection(colors, selection)
    with np.errstate(over="ignore"):  # exp(-logit) is inf below -709: opacity 0
        opacity = 1.0 / (1.0 + np.exp(-scene.opacity.astype(np.float64)))
    shown = np.flatnonzero(opacity > MIN_PREVIEW_OPACITY)
    if len(shown) == 0:
        raise InputError("the scene has no Gaussians opaque enough to show")
    if len(shown) > max_gaussians:
        shown = shown[np.linspace(0, len(shown) - 1, max_gaussians).astype(np.int64)]
    width, height = window_size
    camera = preview_camera(scene, window_size, up)
    plotter = pv.Plotter(off_screen=off_screen, window_size=[width, height])
    plotter.set_background("black")
    if mode == "ellipsoids":
        mesh = ellipsoid_mesh(scene.positions[shown], scene.scales[shown],
                              scene.rotations[shown], colors[shown])
        plotter.add_mesh(mesh, scalars="rgb", rgb=True, ambient=0.45, diffuse=0.6,
                         specular=0.0, show_scalar_bar=False)
    else:
        cloud = pv.PolyData(scene.positions[shown].astype(np.float32))
        cloud.point_data["rgb"] = (colors[shown] * 255).astype(np.uint8)
        plotter.add_mesh(cloud, scalars="rgb", rgb=True, point_size=3.0,
                         render_points_as_spheres=True, show_scalar_bar=False)
    _place_camera(plotter, camera)
    return plotter


def save_screenshot(scene: GaussianScene, path: str | Path, **options) -> np.ndarray:
    """Render the preview offscreen to the PNG ``path``; returns the (H, W, 3) uint8 image.

    ``options`` are those of :func:`preview_plotter` except ``off_screen``.
    """
    from csgs_codec.render.image_io import save_png

    _prefer_headless_gl()
    plotter = preview_plotter(scene, off_screen=True, **options)
    try:
        image = np.asarray(plotter.screenshot(None, return_img=True))[..., :3]
    finally:
        plotter.close()
    save_png(image.astype(np.float32) / 255.0, path)
    return image


def show_window(scene: GaussianScene, **options) -> None:
    """Open an interactive preview window (blocks until it is closed)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise UnsupportedError("no display to open a window on; use --screenshot FILE to "
                               "render the preview to an image")
    preview_plotter(scene, off_screen=False, **options).show()


def _prefer_headless_gl() -> None:
    """Without a display, ask VTK for its EGL window first (it would otherwise try X first and
    print a warning before falling back). A choice already made in the environment stands."""
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"):
        return
    import ctypes.util

    if ctypes.util.find_library("EGL"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


def _place_camera(plotter, camera) -> None:
    """Point the VTK camera like ``camera`` (an OpenCV :class:`Camera`)."""
    rotation = camera.world_to_camera[:3, :3]
    position = camera.position
    forward, down = rotation[2], rotation[1]
    plotter.camera.position = tuple(position)
    plotter.camera.focal_point = tuple(position + forward)
    plotter.camera.up = tuple(-down)
    plotter.camera.view_angle = math.degrees(2 * math.atan(0.5 * camera.height / camera.fy))
    plotter.reset_camera_clipping_range()
