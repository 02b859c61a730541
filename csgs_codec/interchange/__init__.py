"""Scene files in and out: every format csgs reads or writes other than its own ``.csgs``.

Not to be confused with :mod:`csgs_codec.format`, the ``.csgs`` container. One module per
format (the INRIA 3DGS PLY in ``ply_*``, Scaffold-GS checkpoints in ``scaffold_io``,
``anchor_ply`` and ``scaffold_mlp_files``); each splat reader returns a
:class:`~csgs_codec.scene.gaussian_scene.GaussianScene` in the INRIA PLY conventions (raw
log-scales, opacity logits, SH DC coefficients, (w, x, y, z) quaternions, the file's own
axes) together with a :class:`SceneSource` saying what the file was. Public API:

- :func:`read_interchange`: any of these files, recognised by its content
  (:func:`csgs_codec.read_scene` reads ``.csgs`` too).
- :func:`write_scene`: a scene to ``.ply``, ``.splat``, ``.spz`` or ``.glb`` by extension.
- :func:`detect_format`: which format a file holds, from its first bytes.

Read: 3DGS PLY (any property order, e.g. Brush's alphabetical one), PlayCanvas compressed
PLY, antimatter15 ``.splat``, mkkellogg ``.ksplat`` (levels 0-2), Niantic SPZ (v2-v4, and
the unreleased v1 layout, untested), PlayCanvas SOG (v1 and v2, ``.sog`` zip or a folder
with ``meta.json``), glTF/GLB with ``KHR_gaussian_splatting``. SOG needs Pillow (the
``formats`` extra) and SPZ v4 needs zstandard (same extra).
"""

from __future__ import annotations

from csgs_codec.interchange.open import detect_format, read_interchange
from csgs_codec.interchange.source import SceneSource, warn_if_lossy
from csgs_codec.interchange.writers import WRITERS, write_scene

__all__ = ["SceneSource", "WRITERS", "detect_format", "read_interchange", "warn_if_lossy",
           "write_scene"]
