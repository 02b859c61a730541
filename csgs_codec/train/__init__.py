"""Training inputs, loss terms and the semantic stage (torch): the foundation of the
CSGaussian training stages (docs/design.md, 'Training').

* :mod:`.views`: :class:`~.views.TrainingView`, an image with its camera and instance mask.
* :mod:`.datasets`: images + cameras from transforms.json, INRIA cameras.json or COLMAP, with
  optional masks and downscaling (:mod:`.image_files` reads the files); where no masks are
  given, :mod:`.segmentation` makes them with a classical graph segmenter.
* :mod:`.synthetic`: seeded scenes of labelled objects rendered into views with ground-truth
  masks, written as a transforms.json dataset.
* :mod:`.losses`: L1, SSIM and the stage-2 intra-mask smoothing and inter-mask contrastive
  losses; :mod:`.quantization`: uniform-noise quantization proxy, Gaussian rate proxy and the
  quality-aware weights.
* :mod:`.semantic_stage`: stages 2 and 3 on fixed geometry (per-anchor features from masks).
* Stage 1: :mod:`.anchor_model` (anchors on a voxel grid, their MLPs and offset masks),
  :mod:`.anchor_rate` (the rate estimate under an INR hyperprior and CARM),
  :mod:`.anchor_growth` (growing, pruning, view-frequency masking) and :mod:`.color_stage`
  (the loop); :mod:`.initial_points` finds the points anchors start from, and
  :mod:`.checkpoint` saves and resumes stage 1.
* :mod:`.pipeline`: all stages end to end, ending in a .csgs; :mod:`.evaluation` scores the
  result (held-out views, click mIoU).
"""
