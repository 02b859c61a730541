"""The public namespace of ``csgs_codec``: visible to dir() and tools, every name resolves."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

import csgs_codec
from csgs_codec import CsgsError, FormatError, GaussianScene, InputError

PACKAGE = Path(csgs_codec.__file__).resolve().parent


def test_dir_lists_the_lazy_names_and_each_resolves():
    names = dir(csgs_codec)
    assert set(csgs_codec._LAZY) <= set(csgs_codec.__all__) == set(names)
    for name in ("Encoder", "Decoder", "read_ply", "GaussianScene", "CsgsError"):
        assert name in names
    for name in csgs_codec.__all__:
        assert getattr(csgs_codec, name) is not None, name


def test_importing_the_package_stays_light():
    code = "import sys, csgs_codec; dir(csgs_codec); print('torch' in sys.modules, " \
           "'csgs_codec.codec.encoder' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == ["False", "False"]


def test_error_classes_are_exported_in_their_hierarchy():
    assert issubclass(FormatError, CsgsError) and issubclass(InputError, CsgsError)
    assert csgs_codec.DataLossWarning.__mro__[1] is csgs_codec.CsgsWarning
    assert csgs_codec.FallbackWarning.__mro__[1] is csgs_codec.CsgsWarning


def test_the_package_is_marked_typed():
    assert (PACKAGE / "py.typed").is_file()


def test_scene_repr_summarises_instead_of_printing_arrays():
    n = 45_000
    scene = GaussianScene(positions=np.zeros((n, 3), np.float32),
                          sh_dc=np.zeros((n, 3), np.float32),
                          sh_rest=np.zeros((n, 8, 3), np.float32),
                          opacity=np.zeros(n, np.float32), scales=np.zeros((n, 3), np.float32),
                          rotations=np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
                          semantic=np.zeros((n, 6), np.float32),
                          semantic_names=tuple(f"sem_{i}" for i in range(6)))
    assert repr(scene) == "GaussianScene(45,000 Gaussians, SH degree 2, 6 semantic channels)"
