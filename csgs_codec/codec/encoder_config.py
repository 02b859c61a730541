"""What decides the bytes an :class:`~csgs_codec.codec.encoder.Encoder` writes, in one frozen
value: the rate target, the coding tools, and the tiling.

The same config gives the same file on any machine and for any worker count; progress
reporting is not part of it (it changes nothing written).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal, get_args

from csgs_codec.codec.tiling import check_tile_size
from csgs_codec.decisions.color_prior_choice import DEFAULT_PRIOR_FIT, PriorFitPolicy
from csgs_codec.decisions.presets import (
    DEFAULT_QUALITY,
    DEFAULT_ROTATION_STEPS,
    ROTATION_STEPS,
    preset,
)
from csgs_codec.decisions.view_pruning import DEFAULT_BUDGET
from csgs_codec.errors import InputError

#: How each Gaussian's rotation step follows its decoded attributes (FORMAT §12.8).
RotationRule = Literal["footprint", "uniform"]
#: Whether the semantic layer is written when the scene has semantic channels or labels.
SemanticMode = Literal["auto", "none"]
SEMANTIC_MODES: tuple[str, ...] = get_args(SemanticMode)


@dataclass(frozen=True)
class EncoderConfig:
    """Everything that decides what an encoder writes (see :class:`Encoder` for each field's
    meaning, units and measured effect).

    Rate target (at most one of the three; none: quality 5):
        quality: preset 1 (smallest) .. 12 (near-lossless).
        target_psnr: the smallest encode reaching this foreground PSNR (dB) on probe views.
        lambda_: the encode minimising J = D + lambda * R.
        fast: shorter searches and no hyperprior fit.

    Tools:
        hyperprior, prior_fit, rotation_steps, step_allocation, semantic, prune_opacity,
        view_pruning, cameras (a tuple of cameras, or None), view_budget, refine.

    Tiling:
        tile_size, workers, ray, levels (of detail: 1 is the scene alone).

    Raises:
        InputError: a value out of range or of the wrong kind, naming the field.
    """

    quality: int | None = None
    target_psnr: float | None = None
    lambda_: float | None = None
    fast: bool = False
    hyperprior: bool = True
    prior_fit: PriorFitPolicy = DEFAULT_PRIOR_FIT
    rotation_steps: RotationRule = DEFAULT_ROTATION_STEPS
    step_allocation: bool | None = None
    semantic: SemanticMode = "auto"
    prune_opacity: float | None = None
    view_pruning: bool | None = None
    cameras: tuple | None = None
    view_budget: float = DEFAULT_BUDGET
    refine: int = 0
    tile_size: int | None = None
    workers: int = 1
    ray: str | None = None
    levels: int = 1

    def __post_init__(self) -> None:
        if self.lambda_ is not None and (self.quality is not None
                                         or self.target_psnr is not None):
            raise InputError("lambda excludes quality and target PSNR: give one of them",
                             property="lambda")
        preset(self.effective_quality)  # InputError for a quality no preset has
        if self.target_psnr is not None:
            from csgs_codec.decisions.rate_control import check_target

            check_target(self.target_psnr)
        if self.lambda_ is not None:
            from csgs_codec.decisions.rate_control import check_render_lambda

            check_render_lambda(self.lambda_)
            object.__setattr__(self, "lambda_", float(self.lambda_))
        if self.semantic not in SEMANTIC_MODES:
            raise InputError(f"semantic must be one of {SEMANTIC_MODES}, got "
                             f"{self.semantic!r}", property="semantic")
        if self.prune_opacity is not None and not 0.0 <= self.prune_opacity < 1.0:
            raise InputError(f"prune_opacity must be in [0, 1), got {self.prune_opacity}",
                             property="prune_opacity")
        if not isinstance(self.prior_fit, PriorFitPolicy):
            raise InputError(f"prior_fit must be a PriorFitPolicy, got {self.prior_fit!r}",
                             property="prior_fit")
        if not 0.0 <= self.view_budget <= 10.0:
            raise InputError(f"view budget must be in [0, 10], got {self.view_budget}",
                             property="view_budget")
        if self.rotation_steps not in ROTATION_STEPS:
            raise InputError(f"rotation steps must be one of {ROTATION_STEPS}, got "
                             f"{self.rotation_steps!r}", property="rotation_steps")
        if self.step_allocation not in (None, True, False):
            raise InputError(f"step_allocation must be None, True or False, got "
                             f"{self.step_allocation!r}", property="step_allocation")
        refine = self.refine
        if isinstance(refine, bool) or not isinstance(refine, int) or not 0 <= refine <= 100_000:
            raise InputError(f"refine must be a step count in [0, 100000], got {refine!r}",
                             property="refine")
        check_tile_size(self.tile_size)
        levels = self.levels
        if isinstance(levels, bool) or not isinstance(levels, int) or not 1 <= levels <= 16:
            raise InputError(f"levels must be an integer in 1..16, got {levels!r}",
                             property="levels")
        if levels > 1 and self.refine:
            raise InputError("refinement works on scenes of one tile: a file with levels "
                             "of detail has several", property="refine")
        workers = self.workers
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise InputError(f"workers must be an integer >= 1, got {workers!r}",
                             property="workers")
        if self.ray is not None and (not isinstance(self.ray, str) or not self.ray.strip()):
            raise InputError(f"ray must be a cluster address or 'local', got {self.ray!r}",
                             property="ray")
        object.__setattr__(self, "fast", bool(self.fast))
        if self.view_pruning not in (None, True, False):
            raise InputError(f"view_pruning must be None, True or False, got "
                             f"{self.view_pruning!r}", property="view_pruning")
        object.__setattr__(self, "view_budget", float(self.view_budget))
        if self.cameras is not None:
            object.__setattr__(self, "cameras", tuple(self.cameras))

    @property
    def prunes_views(self) -> bool:
        """Whether the encode leaves out what the views barely see: ``view_pruning``, or
        when it is None, whether cameras were given."""
        return self.cameras is not None if self.view_pruning is None else self.view_pruning

    @property
    def leaf_tile_size(self) -> int | None:
        """The tile size the scene is cut with: ``tile_size``, or with levels of detail
        and none given, :data:`~csgs_codec.codec.level_tree.LOD_TILE_SIZE`."""
        if self.tile_size is None and self.levels > 1:
            from csgs_codec.codec.level_tree import LOD_TILE_SIZE

            return LOD_TILE_SIZE
        return self.tile_size

    @property
    def fits_hyperprior(self) -> bool:
        """Whether the encode fits the color hyperprior: ``hyperprior``, except in fast
        mode."""
        return self.hyperprior and not self.fast

    @property
    def effective_quality(self) -> int:
        """The preset the encode starts from (5 when no quality is given)."""
        return DEFAULT_QUALITY if self.quality is None else self.quality

    @classmethod
    def field_names(cls) -> frozenset[str]:
        """The names :class:`Encoder` accepts as keywords."""
        return frozenset(f.name for f in fields(cls))
