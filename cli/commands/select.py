"""``csgs select SCENE --view CAMERA --click X,Y [--mode M] [--threshold T] -o object.ply``:
the object under a pixel (its instance, or the Gaussians whose semantic feature matches the
one under the pixel), written as a PLY."""

from __future__ import annotations

import io
import re
import warnings
from pathlib import Path

from csgs_codec.errors import CsgsWarning, InputError

NAME = "select"
HELP = ("select the object under a pixel by its instance or semantic feature and write its "
        "Gaussians as a .ply")
DEFAULT_ORBIT_VIEWS = 16
DEFAULT_ORBIT_SIZE = (800, 600)


def add_arguments(parser) -> None:
    """Arguments of ``csgs select``."""
    from csgs_codec.semantic.clustering import MAX_CLUSTERS
    from csgs_codec.semantic.selection import DEFAULT_CLUSTERS, DEFAULT_THRESHOLD, MODES

    parser.add_argument("scene", help="a 3DGS .ply with semantic properties, or a .csgs "
                                      "(decoded with its semantic layer)")
    parser.add_argument("--view", required=True, metavar="CAMERA",
                        help="the view clicked in: 'orbit:I' (view I of the --orbit N views "
                             "'csgs render --orbit N' makes), or a cameras file as 'csgs "
                             "render --cameras' takes (cameras.json, transforms.json, COLMAP), "
                             "optionally followed by '#I' (camera index, 0 first) or '#NAME'")
    parser.add_argument("--click", required=True, metavar="X,Y",
                        help="pixel clicked: column X and row Y from the image's top left")
    parser.add_argument("--threshold", type=float, default=DEFAULT_THRESHOLD, metavar="T",
                        help="cosine similarity a Gaussian's feature needs with the clicked "
                             f"one, in [-1, 1] (default {DEFAULT_THRESHOLD})")
    parser.add_argument("--mode", choices=MODES, default="instance",
                        help="instance: the instance (label, or distinct feature as 'csgs "
                             "segment' writes) carrying the most weight at the pixel; cosine: "
                             "every Gaussian over the threshold; cluster: the k-means cluster "
                             "of the clicked feature (default instance)")
    parser.add_argument("--clusters", type=int, default=DEFAULT_CLUSTERS, metavar="K",
                        help=f"k of the k-means in cluster mode, 1..{MAX_CLUSTERS} (default "
                             f"{DEFAULT_CLUSTERS})")
    parser.add_argument("--orbit", type=int, default=DEFAULT_ORBIT_VIEWS, metavar="N",
                        help=f"views on the orbit for --view orbit:I (default "
                             f"{DEFAULT_ORBIT_VIEWS})")
    parser.add_argument("--size", metavar="WxH",
                        help="image size the click refers to; default: the camera's own, or "
                             f"{DEFAULT_ORBIT_SIZE[0]}x{DEFAULT_ORBIT_SIZE[1]} for an orbit")
    parser.add_argument("--up", metavar="AXIS",
                        help="orbit up axis: +x -x +y -y +z -z (default: guessed)")
    parser.add_argument("--backend", default="numba",
                        choices=("auto", "torch", "numba", "gsplat"),
                        help="rasterizer backend for the feature map (default numba)")
    parser.add_argument("--save-mask", metavar="NPY",
                        help="also write the (N,) bool selection mask, in the scene's order, "
                             "as a .npy file (for 'csgs view --select-mask')")
    parser.add_argument("-o", "--output", required=True, metavar="PLY",
                        help="output .ply with the selected Gaussians")


def run(args) -> int:
    """Select at the click and write the selected Gaussians; prints how many."""
    from csgs_cli.output_guard import refuse_overwriting_inputs
    from csgs_cli.scene_input import load_scene
    from csgs_codec.atomic_write import check_output
    from csgs_codec.interchange.ply_io import write_ply
    from csgs_codec.semantic.selection import click_selection, selected_gaussians

    x, y = parse_click(args.click)
    output = Path(args.output)
    if output.is_dir():
        raise InputError("output is a folder; give a .ply file name", file=output)
    refuse_overwriting_inputs([("-o", output), ("--save-mask", args.save_mask)],
                              [("the scene", args.scene), ("--view", view_file(args.view))])
    check_output(output, [args.scene])
    if args.save_mask:
        check_output(args.save_mask, [args.scene])
    scene = load_scene(args.scene, command=NAME, layers="color,semantic")
    camera = camera_from_view(args.view, scene, size=args.size, up=args.up,
                              orbit_views=args.orbit)
    result = click_selection(scene, camera, x, y, threshold=args.threshold, mode=args.mode,
                             clusters=args.clusters, backend=args.backend)
    if result.count == 0:
        warnings.warn("no Gaussian matched the clicked feature; try a lower --threshold",
                      CsgsWarning, stacklevel=2)
    write_ply(selected_gaussians(scene, result.mask, camera), output, [args.scene])
    if args.save_mask:
        write_mask(result.mask, args.save_mask)
    rule = (f"instance from {result.instance_source}" if result.mode == "instance"
            else f"{result.mode}, threshold {result.threshold:g}")
    print(f"selected {result.count:,} of {len(scene):,} Gaussians ({rule}, pixel "
          f"{result.pixel[0]},{result.pixel[1]} of "
          f"{camera.width}x{camera.height}); wrote {output}")
    return 0


def parse_click(text: str) -> tuple[float, float]:
    """(x, y) pixel coordinates from 'X,Y'.

    Raises:
        InputError: the text is not two comma-separated finite numbers.
    """
    number = r"\s*([-+]?(?:\d+(?:\.\d*)?|\.\d+))\s*"
    match = re.fullmatch(number + "," + number, text or "")
    if not match:
        raise InputError(f"click must look like 120,80 (pixel column, row), got {text!r}",
                         property="--click")
    return float(match[1]), float(match[2])


def camera_from_view(spec: str, scene, *, size: str | None = None, up: str | None = None,
                     orbit_views: int = DEFAULT_ORBIT_VIEWS):
    """The one camera ``spec`` names (see the ``--view`` help), resized to ``size`` ('WxH').

    Raises:
        InputError: a malformed spec, an index or name the cameras do not have, or a bad
            camera file.
    """
    from csgs_cli.view_options import parse_size
    from csgs_codec.scene.cameras_io import load_cameras, resize_camera

    wanted = parse_size(size) if size else None
    orbit = re.fullmatch(r"orbit:(\d{1,6})", spec.strip())
    if orbit:
        return _orbit_camera(scene, int(orbit[1]), orbit_views, wanted or DEFAULT_ORBIT_SIZE,
                             up)
    path, pick = view_file(spec), None
    if not Path(spec).exists() and "#" in spec:
        pick = spec.rpartition("#")[2]
    cameras = load_cameras(path)
    if not cameras:
        raise InputError("the cameras file holds no camera", file=path)
    camera = _pick_camera(cameras, pick, path)
    return resize_camera(camera, *wanted) if wanted else camera


def view_file(spec: str) -> Path | None:
    """The cameras file a --view spec reads (None for an orbit view)."""
    if re.fullmatch(r"orbit:(\d{1,6})", spec.strip()):
        return None
    path = Path(spec)
    if not path.exists() and "#" in spec:
        path = Path(spec.rpartition("#")[0])
    return path


def write_mask(mask, path: str | Path) -> None:
    """Write the (N,) bool ``mask`` as a .npy file, atomically."""
    import numpy as np

    from csgs_codec.atomic_write import write_atomically

    buffer = io.BytesIO()
    np.save(buffer, np.asarray(mask, dtype=bool), allow_pickle=False)
    write_atomically(path, buffer.getvalue())


def _orbit_camera(scene, index: int, views: int, size: tuple[int, int], up: str | None):
    from csgs_cli.view_options import check_orbit_views
    from csgs_codec.scene.gaussian_scene import GaussianScene
    from csgs_codec.scene.orbit import orbit_cameras

    check_orbit_views(views)
    if index >= views:
        raise InputError(f"orbit view {index} does not exist: the orbit has {views} views "
                         "(0 first)", property="--view")
    if not isinstance(scene, GaussianScene):
        from csgs_codec.model.scaffold import ScaffoldDecoder

        scene = ScaffoldDecoder(scene).export_gaussians()
    return orbit_cameras(scene, views, width=size[0], height=size[1], up=up)[index]


def _pick_camera(cameras: list, pick: str | None, path: Path):
    if pick is None:
        return cameras[0]
    if re.fullmatch(r"[0-9]{1,9}", pick):
        if int(pick) >= len(cameras):
            raise InputError(f"camera {pick} does not exist: the file holds {len(cameras)} "
                             "(0 first)", file=path, property="--view")
        return cameras[int(pick)]
    for camera in cameras:
        if camera.name == pick or Path(camera.name).stem == pick:
            return camera
    raise InputError(f"no camera named {pick!r}", file=path, property="--view")
