"""One training view: an image, the camera that took it, an optional instance mask and an
optional foreground mask."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csgs_codec.errors import InputError
from csgs_codec.scene.camera import Camera


@dataclass
class TrainingView:
    """An image with its camera and, when known, its instance mask.

    Attributes:
        image: (H, W, 3) float32 RGB in [0, 1], the stored pixel values divided by 255 (no
            gamma decoding: 3DGS trainers fit the rendered color to these values directly).
        camera: the pinhole camera, ``camera.width == W`` and ``camera.height == H``.
        mask: (H, W) int32 instance ids (any integers; equal ids mean one instance), or None.
        name: identifier, usually the image file name.
        foreground: (H, W) bool, True where the photo shows the object being trained (the
            image is then already composited over the background elsewhere; see
            :mod:`csgs_codec.train.foreground`), or None to train every pixel.
        oversegmented: the mask holds the built-in segmenter's over-segments rather than
            instances; the semantic stages first make them into objects
            (:mod:`csgs_codec.train.segment_objects`) when every view's is.
    """

    image: np.ndarray
    camera: Camera
    mask: np.ndarray | None = None
    name: str = ""
    foreground: np.ndarray | None = None
    oversegmented: bool = False

    @property
    def height(self) -> int:
        """Image height H in pixels."""
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        """Image width W in pixels."""
        return int(self.image.shape[1])

    def validate(self) -> None:
        """Check shapes and dtypes against each other.

        Raises:
            InputError: naming the view when the image, camera and mask do not agree.
        """
        image = self.image
        if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.float32:
            raise InputError(f"image must be (H, W, 3) float32, got {image.shape} {image.dtype}",
                             file=self.name or None, property="image")
        if (self.camera.width, self.camera.height) != (self.width, self.height):
            raise InputError(f"camera is {self.camera.width}x{self.camera.height} but the image "
                             f"is {self.width}x{self.height}", file=self.name or None,
                             property="camera")
        if self.mask is not None and (self.mask.shape != image.shape[:2]
                                      or self.mask.dtype != np.int32):
            raise InputError(f"mask must be (H, W) = {image.shape[:2]} int32, got "
                             f"{self.mask.shape} {self.mask.dtype}", file=self.name or None,
                             property="mask")
        if self.foreground is not None and (self.foreground.shape != image.shape[:2]
                                            or self.foreground.dtype != np.bool_):
            raise InputError(f"foreground must be (H, W) = {image.shape[:2]} bool, got "
                             f"{self.foreground.shape} {self.foreground.dtype}",
                             file=self.name or None, property="foreground")
