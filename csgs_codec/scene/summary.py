"""Facts about a Gaussian scene that ``csgs info`` reports and a codec decides on."""

from __future__ import annotations

import numpy as np

from csgs_codec.scene.gaussian_scene import GaussianScene


def _floats(values: np.ndarray) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=np.float64).ravel()]


def summarize_scene(scene: GaussianScene, robust_percentile: float = 1.0) -> dict:
    """JSON-ready summary of ``scene``.

    Keys: ``gaussians``; ``sh_degree_stored`` and ``sh_degree_in_use``; ``zero_sh_bands``;
    ``bounding_box`` (min, max, world units); ``robust`` (centre and extent of the
    ``robust_percentile``..``100 - robust_percentile`` box, world units); ``attributes``
    (per attribute: channel count and per-channel min / max / mean of the raw stored values);
    ``constant_channels``; ``semantic_channels``; ``labels`` (distinct label count or None).
    """
    lo, hi = scene.bounding_box()
    centre, extent = scene.robust_center_and_extent(robust_percentile)
    attributes = {}
    for name, values in scene.attributes().items():
        entry = {"channels": int(values.shape[1])}
        if len(scene) and values.shape[1]:
            v = values.astype(np.float64)
            entry.update(min=_floats(v.min(axis=0)), max=_floats(v.max(axis=0)),
                         mean=_floats(v.mean(axis=0)))
        attributes[name] = entry
    return {
        "gaussians": len(scene),
        "sh_degree_stored": scene.sh_degree_stored,
        "sh_degree_in_use": scene.sh_degree_in_use(),
        "zero_sh_bands": scene.zero_sh_bands(),
        "bounding_box": {"min": _floats(lo), "max": _floats(hi)},
        "robust": {"percentile": robust_percentile, "centre": _floats(centre),
                   "extent": float(extent)},
        "attributes": attributes,
        "constant_channels": scene.constant_channels(),
        "semantic_channels": list(scene.semantic_names),
        "labels": None if scene.labels is None else int(np.unique(scene.labels).size),
    }
