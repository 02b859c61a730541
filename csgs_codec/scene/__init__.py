"""Scene data classes (Gaussian and anchor scenes, cameras) and their validation; files in
and out are :mod:`csgs_codec.interchange`'s, coding forms :mod:`csgs_codec.attributes`'."""

from csgs_codec.scene.gaussian_scene import SH_DEGREE_OF_REST, SH_REST_COUNTS, GaussianScene

__all__ = ["GaussianScene", "SH_REST_COUNTS", "SH_DEGREE_OF_REST"]
