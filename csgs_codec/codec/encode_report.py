"""What an encode returns besides the bytes (shared by the whole-scene and tiled encoders)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene


@dataclass
class EncodeReport:
    """What :meth:`Encoder.encode_with_report` returns.

    Attributes:
        data: the .csgs bytes.
        reconstruction: the scene the decoder will output (all layers written), in the
            decoder's order.
        order: (M,) int64: for each decoded Gaussian, the index of the Gaussian of the
            scene given to the encoder that it came from; Gaussians left out (``pruned``,
            ``view_pruned``) appear nowhere. The order is a deterministic function of the
            scene and the settings and is not stored in the bitstream.
        pruned: Gaussians removed by ``prune_opacity``.
        stream_bytes: chunk type -> payload bytes.
        seconds: encode wall time.
        view_pruned: Gaussians removed for contributing too little to the views (see
            :mod:`csgs_codec.decisions.view_pruning`); ``order`` skips them.
        views: the viewing distribution the pruning followed, or None when none ran.
        rate_control: the :class:`~csgs_codec.decisions.rate_control.RateControlReport` of a
            target-PSNR encode, the :class:`~csgs_codec.decisions.rate_control.LambdaReport`
            (chosen multiplier and cost J) of a lambda encode, else None.
        tiles: tiles in the file (1 without a tile index), every level's together.
        levels: levels of detail (1: the scene's own Gaussians only).
        allocation: the :class:`~csgs_codec.decisions.step_allocation.StepAllocation` the
            encoder chose for a quality encode, or None when it kept the preset's steps
            (allocation off, fast mode, a target or lambda search).
        sorted_axes: whether the Gaussians' axes were coded largest scale first
            (:mod:`csgs_codec.decisions.axis_order`; all but the few whose rotation the
            guard of :func:`~csgs_codec.attributes.attribute_forms.canonical_orientations`
            keeps); None for a tiled encode, where each tile decides for itself.
    """

    data: bytes
    reconstruction: GaussianScene
    order: np.ndarray
    pruned: int = 0
    stream_bytes: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0
    view_pruned: int = 0
    views: str | None = None
    rate_control: object | None = None
    tiles: int = 1
    levels: int = 1
    allocation: object | None = None
    sorted_axes: bool | None = None
