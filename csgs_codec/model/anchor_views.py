"""Rendering any scene exactly: a standard scene as it is, an anchor scene per view.

An anchor scene's neural Gaussians depend on the camera (Scaffold-GS evaluates its heads for
each view), so a command that renders, compares or frames a scene asks this module for the
Gaussians of each camera instead of using the scene directly. The heads are built once per
scene.
"""

from __future__ import annotations

from csgs_codec.scene.anchor_scene import AnchorScene
from csgs_codec.scene.camera import Camera
from csgs_codec.scene.gaussian_scene import GaussianScene


class SceneViews:
    """The Gaussians of ``scene`` for any camera.

    Args:
        scene: a :class:`GaussianScene` (returned as it is for every camera) or an
            :class:`AnchorScene` with MLPs (its neural Gaussians for each camera, exactly as
            training renders them, with the mean appearance embedding).

    Raises:
        InputError: an invalid scene, or something that is neither kind.
        ModelError: an anchor scene without MLPs.
    """

    def __init__(self, scene: GaussianScene | AnchorScene) -> None:
        from csgs_codec.errors import InputError

        if not isinstance(scene, GaussianScene | AnchorScene):
            raise InputError(f"expected a GaussianScene or AnchorScene, got "
                             f"{type(scene).__name__}", property="scene")
        self.scene = scene
        self._decoder = None
        if isinstance(scene, AnchorScene):
            from csgs_codec.model.scaffold import ScaffoldDecoder

            self._decoder = ScaffoldDecoder(scene)

    @property
    def is_anchor_scene(self) -> bool:
        """True for an anchor scene (its Gaussians depend on the camera)."""
        return self._decoder is not None

    def gaussians(self, camera: Camera) -> GaussianScene:
        """The Gaussians to render for ``camera``."""
        if self._decoder is None:
            return self.scene
        return self._decoder.to_gaussians(camera)

    def framing(self) -> GaussianScene:
        """A view-independent stand-in for framing cameras (orbit views, spheres): the scene
        itself, or an anchor scene's Gaussians seen from its anchors' bounding-box centre."""
        if self._decoder is None:
            return self.scene
        return self._decoder.export_gaussians()


def scene_views(scene: GaussianScene | AnchorScene | SceneViews) -> SceneViews:
    """``scene`` as :class:`SceneViews` (itself when it already is one)."""
    return scene if isinstance(scene, SceneViews) else SceneViews(scene)
