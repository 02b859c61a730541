"""csgs: a codec for 3D Gaussian Splatting scenes with semantics (CSGaussian, WACV 2026).

The decode path (format, entropy, integer networks) imports numpy and constriction only;
torch is imported by the encoder's fitting and the training code alone.
"""

__version__ = "0.1.0"
