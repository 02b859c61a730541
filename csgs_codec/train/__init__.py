"""Training inputs, loss terms and the semantic stage (torch): the foundation of the
CSGaussian training stages (DESIGN.md section 2).

* :mod:`.views`: :class:`~.views.TrainingView`, an image with its camera and instance mask.
* :mod:`.datasets`: images + cameras from transforms.json, INRIA cameras.json or COLMAP, with
  optional masks and downscaling (:mod:`.image_files` reads the files); where no masks are
  given, :mod:`.segmentation` makes them with a classical graph segmenter.
* :mod:`.synthetic`: seeded scenes of labelled objects rendered into views with ground-truth
  masks, written as a transforms.json dataset.
* :mod:`.losses`: L1, SSIM and the stage-2 intra-mask smoothing and inter-mask contrastive
  losses; :mod:`.quantization`: uniform-noise quantization proxy, Gaussian rate proxy and the
  quality-aware weights.
* :mod:`.semantic_stage`: stage 2 on fixed geometry (per-anchor features from masks).
"""
