"""The standard 3DGS PLY property behind each channel of a scene attribute, for messages."""

from __future__ import annotations

_FIXED = {"positions": ("x", "y", "z"), "sh_dc": ("f_dc_0", "f_dc_1", "f_dc_2"),
          "opacity": ("opacity",), "scales": ("scale_0", "scale_1", "scale_2"),
          "rotations": ("rot_0", "rot_1", "rot_2", "rot_3")}


def ply_property(attribute: str, channel: int, *, sh_bands: int = 0,
                 semantic_names: tuple[str, ...] = ()) -> str:
    """The PLY property name of column ``channel`` of ``attribute`` as
    :meth:`GaussianScene.attributes` lays it out.

    ``sh_rest`` columns are band-major (column 3 b + c is band coefficient b of color c) and
    the PLY's ``f_rest_*`` color-major (INRIA order), so ``f_rest_{c * sh_bands + b}``.
    Unknown attributes are returned unchanged.
    """
    if attribute in _FIXED:
        return _FIXED[attribute][channel]
    if attribute == "sh_rest" and sh_bands:
        band, color = divmod(int(channel), 3)
        return f"f_rest_{color * sh_bands + band}"
    if attribute == "semantic" and channel < len(semantic_names):
        return semantic_names[channel]
    return attribute
