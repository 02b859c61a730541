"""Dataset and output checks shared by the commands that train on a capture (``csgs train``,
``csgs segment``)."""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

from csgs_codec.errors import InputError


def downscale_for(data: str, resolution: int | None) -> float:
    """The factor that brings the dataset's longest image side down to ``resolution`` pixels
    (1 when None or already smaller).

    Raises:
        InputError: a resolution under 16 pixels, or no cameras in ``data``.
    """
    if resolution is None:
        return 1.0
    if resolution < 16:
        raise InputError(f"--resolution must be at least 16 pixels, got {resolution}",
                         property="resolution")
    from csgs_codec.scene.cameras_io import load_cameras
    from csgs_codec.train.datasets import find_camera_file

    cameras = load_cameras(find_camera_file(Path(data)))
    longest = max((max(c.width, c.height) for c in cameras), default=resolution)
    return max(1.0, longest / resolution)


def check_output_folder(output: Path) -> None:
    """InputError naming ``output`` when its folder is missing or not writable (checked
    before training, so hours of work are not lost at the end)."""
    import os

    folder = output.parent if str(output.parent) else Path(".")
    if not folder.is_dir():
        raise InputError("the output's folder does not exist", file=output)
    if not os.access(folder, os.W_OK):
        raise InputError("the output's folder is not writable", file=output)
    if output.is_dir():
        raise InputError("the output is a folder", file=output)


def add_builtin_segmenter_argument(parser) -> None:
    """``--builtin-segmenter``: accept the built-in segmenter's masks without the warning."""
    parser.add_argument("--builtin-segmenter", action="store_true",
                        help="when no instance masks are found, segment the images with the "
                             "built-in segmenter without warning (it is much weaker than "
                             "SAM-style masks; see docs/masks.md)")


def add_outside_paths_argument(parser) -> None:
    """``--allow-outside-paths``: read image paths that leave the dataset folder."""
    parser.add_argument("--allow-outside-paths", action="store_true",
                        help="read images whose path in the camera file is absolute or climbs "
                             "out of the dataset folder with '..' (refused by default; "
                             "docs/captures.md)")


@contextlib.contextmanager
def mask_fallback(args):
    """Within: the built-in segmenter's FallbackWarning is silent when ``args`` ask for it
    (``--builtin-segmenter``); otherwise it shows, even under ``--quiet``."""
    from csgs_codec.errors import FallbackWarning

    with warnings.catch_warnings():
        if args.builtin_segmenter:
            warnings.simplefilter("ignore", FallbackWarning)
        yield
