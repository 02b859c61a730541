"""``csgs render SCENE [--cameras FILE | --orbit N] [--size WxH] -o DIR``: views to PNG files,
named after the cameras' images (``--cameras``) or ``orbit_NNN.png``."""

from __future__ import annotations

import re
from pathlib import Path

from csgs_codec.errors import InputError

NAME = "render"
HELP = "render a scene to PNG images from its cameras or from an orbit around it"


def add_arguments(parser) -> None:
    """Arguments of ``csgs render``."""
    from csgs_cli.view_options import add_view_arguments

    parser.add_argument("scene", help="a scene file, a .csgs, or an anchor scene (rendered "
                                      "exactly, per view)")
    add_view_arguments(parser)
    parser.add_argument("-o", "--output", required=True, metavar="DIR",
                        help="folder for the PNG images (created if missing): with "
                             "--cameras each view is named after its camera's image "
                             "(frame_001.jpg -> frame_001.png, subfolders kept), so 'csgs "
                             "segment --images DIR --cameras FILE' finds them; orbit views "
                             "are orbit_NNN.png")


def run(args) -> int:
    """Render every requested view of ``args.scene`` into ``args.output``."""
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_cli.view_options import cameras_from_args, progress
    from csgs_codec.model.anchor_views import SceneViews
    from csgs_codec.render.image_io import save_png
    from csgs_codec.render.rasterizer import render

    views = SceneViews(load_scene(args.scene, command=NAME))
    cameras = cameras_from_args(args, views.framing())
    output = Path(args.output)
    if output.exists() and not output.is_dir():
        raise InputError("output exists and is not a folder", file=output)
    names = image_file_names(cameras, own_names=bool(args.cameras))
    refuse_overwriting_inputs([("-o", output / name) for name in names],
                              [("the scene", args.scene), ("--cameras", args.cameras)]
                              + [("the cameras' images", file) for file in captured(args)])
    try:
        for folder in sorted({(output / name).parent for name in names}):
            folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create output folder: {exc.strerror or exc}",
                         file=output) from None
    for camera, name in progress(args, list(zip(cameras, names)), "rendering"):
        save_png(render(views.gaussians(camera), camera, backend=args.backend).image,
                 output / name)
    if not args.quiet:
        print(f"wrote {len(cameras)} image(s) of {cameras[0].width}x{cameras[0].height} "
              f"to {output}")
    return 0


def captured(args) -> list:
    """The photos the cameras file names, where they are found (renders under the cameras'
    own names must not replace them); none for an orbit or a file without its images."""
    if not args.cameras:
        return []
    from csgs_codec.train.datasets import dataset_files

    try:
        # every photo the cameras name, inside the dataset or not, is kept from being replaced
        return dataset_files(args.cameras, allow_outside_paths=True)
    except InputError:
        return []


def image_file_names(cameras, *, own_names: bool) -> list[str]:
    """One PNG path per camera, relative to the output folder.

    Orbit views (``own_names`` False) keep ``orbit_NNN.png``. Cameras from a file
    (``own_names`` True) are written under the image name the file gives (transforms.json
    ``file_path``, INRIA ``img_name``, COLMAP image name), its image suffix replaced by .png
    (or .png added), subfolders kept: what ``csgs segment --images DIR --cameras FILE`` looks
    for. A name that is absolute or climbs out (``..``) keeps only its file name, so nothing
    is written outside the folder. Names that repeat, or hold control characters, make
    every view ``NNN_<stem>.png`` instead (with a warning).
    """
    if own_names:
        names = [_own_name(camera.name) for camera in cameras]
        if None not in names and len(set(names)) == len(names):
            return names
        import warnings

        from csgs_codec.errors import CsgsWarning

        warnings.warn("the cameras' image names repeat or hold control characters: the views "
                      "are numbered NNN_<name>.png instead ('csgs segment' will not find them "
                      "by the cameras file)", CsgsWarning, stacklevel=2)
    return [_numbered_name(i, camera.name) for i, camera in enumerate(cameras)]


def _own_name(name: str) -> str | None:
    """``name`` as a safe relative .png path (see :func:`image_file_names`); None when it
    cannot be one."""
    from pathlib import PurePath

    from csgs_codec.train.image_files import IMAGE_SUFFIXES

    if not name or any(ord(c) < 32 or ord(c) == 127 for c in name):
        return None
    path = PurePath(name)
    if path.is_absolute() or ".." in path.parts:
        path = PurePath(path.name)
    if path.name in ("", ".", ".."):
        return None
    suffixes = {suffix.lower() for suffix in IMAGE_SUFFIXES}
    if path.suffix.lower() in suffixes:
        return path.with_suffix(".png").as_posix()
    return path.with_name(path.name + ".png").as_posix()


def _numbered_name(index: int, name: str) -> str:
    """``orbit_NNN.png`` for an orbit view, else ``NNN_<stem>.png`` (file-system safe)."""
    if name.startswith("orbit_"):
        return f"{name}.png"
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(name).stem).strip("._")
    return f"{index:03d}_{stem}.png" if stem else f"{index:03d}.png"
