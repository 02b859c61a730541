"""Measuring decoded scenes: image metrics (PSNR, SSIM, foreground masks; numpy in
:mod:`~csgs_codec.metrics.image`, differentiable SSIM in :mod:`~csgs_codec.metrics.ssim`),
render comparisons of two scenes over views (:mod:`~csgs_codec.metrics.comparison`) and
per-attribute errors (:mod:`~csgs_codec.metrics.attribute_errors`)."""
