"""Scene data classes, PLY input/output and validation."""

from csgs_codec.scene.gaussian_scene import SH_DEGREE_OF_REST, SH_REST_COUNTS, GaussianScene

__all__ = ["GaussianScene", "SH_REST_COUNTS", "SH_DEGREE_OF_REST"]
