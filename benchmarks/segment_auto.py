"""`csgs segment` without user masks: click mIoU on scenes of separate real objects.

    python benchmarks/segment_auto.py [--scenes pair six] [--per-object 6000] [--views 24]
        [--size 320x240] [--variants builtin exact] [--mary-rose] [--out FILE]

Scenes. Real objects of ``../shared/data`` (the shared scenes and fruit_drops), each stood
up (+z, :func:`csgs_codec.scene.orbit.guess_up_axis`), scaled to a robust extent of 1
(2-98 percentile box diagonal), its SH rest bands dropped (orientation changes would need
them rotated; the segmenters see colour only), thinned to ``--per-object`` Gaussians (the
largest opacity x area first) and placed apart on a circle (neighbours' centres 2 units
apart), every Gaussian labelled by its object: ``pair`` = guitar and plant, ``six`` = biker,
donut, guitar, plant, playbot and fruit_drops.

Views. ``--views`` orbit views (``--size``, 30 degrees elevation) rendered with the project
rasterizer; 8 held-out orbit views at 20 degrees elevation, between the training azimuths,
are clicked.

Variants. ``builtin``: ``segment_scene`` on the views' built-in segmenter masks
(:func:`csgs_codec.train.segmentation.segment_image` of each rendered image, what ``csgs
segment`` does without ``--masks``; its time is counted); ``exact``: the views' exact label
masks (:func:`csgs_codec.train.synthetic.instance_mask`, 0 = background), the reference.
Each runs the defaults of ``csgs segment`` (:class:`SegmentSettings`). Scored: 3D click mIoU
(:func:`csgs_codec.semantic.evaluation.click_object_ious`, "instance" mode, the segmented
scene without its labels, each object's projected centre clicked in each held-out view,
IoU against the object's Gaussians), instances found, wall seconds, and the peak resident
memory of the process while the variant ran (VmHWM after resetting it through
/proc/self/clear_refs; it includes the process's scene, views and imports).

``--mary-rose`` adds the real capture (``../shared/data/captures/mary_rose``, 69 photos with
foreground masks and no instance masks): ``csgs train --resolution 384`` (minutes), then every
8th photo (the training split's held-out views) is clicked at its foreground mask's pixel
nearest the mask centroid, on the decoded .csgs, by ``csgs select``'s rule; the selected
anchors' Gaussians are rendered and the pixels where they carry more weight than the rest of
the scene and the background are compared with the photo's foreground mask (2D IoU).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from bench_common import REPO, SCENES, document, emit  # noqa: E402

DATA = REPO.parent / "shared" / "data"
#: The objects of each scene, by file.
SCENE_OBJECTS = {
    "pair": ("scenes/guitar.ply", "scenes/plant.ply"),
    "six": ("scenes/biker.ply", "scenes/donut.ply", "scenes/guitar.ply", "scenes/plant.ply",
            "scenes/playbot.ply", "real_sh3/fruit_drops.ply"),
}


def _rotation_to_z(up: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking the unit vector ``up`` to +z (Rodrigues)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(up, z)
    sine, cosine = np.linalg.norm(axis), float(np.dot(up, z))
    if sine < 1e-12:
        return np.eye(3) if cosine > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / sine
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sine * cross + (1 - cosine) * cross @ cross


def _quaternion(rotation: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z) of a (3, 3) rotation."""
    w = np.sqrt(max(0.0, 1 + np.trace(rotation))) / 2
    if w > 1e-6:
        return np.array([w, (rotation[2, 1] - rotation[1, 2]) / (4 * w),
                         (rotation[0, 2] - rotation[2, 0]) / (4 * w),
                         (rotation[1, 0] - rotation[0, 1]) / (4 * w)])
    i = int(np.argmax(np.diag(rotation)))
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.sqrt(max(0.0, 1 + rotation[i, i] - rotation[j, j] - rotation[k, k]))
    q = np.zeros(4)
    q[1 + i] = r / 2
    q[0] = (rotation[k, j] - rotation[j, k]) / (2 * r)
    q[1 + j] = (rotation[j, i] + rotation[i, j]) / (2 * r)
    q[1 + k] = (rotation[k, i] + rotation[i, k]) / (2 * r)
    return q


def _quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a * b for a (4,) and b (N, 4), (w, x, y, z)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b.T
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=1)


def prepared_object(path, per_object: int, centre_xy: np.ndarray, label: int):
    """One object of a benchmark scene (module notes), labelled ``label``."""
    from csgs_codec import read_scene
    from csgs_codec.scene.gaussian_scene import GaussianScene
    from csgs_codec.scene.orbit import guess_up_axis, robust_bounds

    scene = read_scene(path)
    area = np.exp(np.sort(scene.scales, axis=1)[:, 1:].sum(axis=1).astype(np.float64))
    score = area / (1 + np.exp(-scene.opacity.astype(np.float64)))
    keep = np.sort(np.argsort(-score, kind="stable")[:per_object])
    rotation = _rotation_to_z(guess_up_axis(scene))
    low, high = robust_bounds(scene)
    factor = 1.0 / float(np.linalg.norm(high - low))
    positions = (scene.positions[keep].astype(np.float64) - (low + high) / 2) @ rotation.T
    positions *= factor
    bottom = np.percentile(positions[:, 2], 2)
    positions += np.array([centre_xy[0], centre_xy[1], -bottom])
    rotations = _quaternion_product(_quaternion(rotation),
                                    scene.rotations[keep].astype(np.float64))
    return GaussianScene(positions=positions.astype(np.float32), sh_dc=scene.sh_dc[keep],
                         sh_rest=np.zeros((len(keep), 0, 3), np.float32),
                         opacity=scene.opacity[keep],
                         scales=(scene.scales[keep] + np.float32(np.log(factor))),
                         rotations=rotations.astype(np.float32),
                         labels=np.full(len(keep), label, np.int32))


def object_scene(name: str, per_object: int):
    """The labelled scene ``name`` of :data:`SCENE_OBJECTS` (labels 1..K)."""
    from csgs_codec.scene.gaussian_scene import GaussianScene

    files = SCENE_OBJECTS[name]
    count = len(files)
    radius = 1.0 / np.sin(np.pi / count) if count > 2 else 1.0
    parts = []
    for i, file in enumerate(files):
        angle = 2 * np.pi * i / count
        parts.append(prepared_object(DATA / file, per_object,
                                     radius * np.array([np.cos(angle), np.sin(angle)]), i + 1))
    return GaussianScene.concatenate(parts)


def peak_reset() -> None:
    """Reset this process's resident-memory high-water mark (Linux)."""
    with open("/proc/self/clear_refs", "w") as handle:
        handle.write("5")


def peak_mb() -> float:
    """This process's resident-memory high-water mark (VmHWM), MiB."""
    with open("/proc/self/status") as handle:
        for line in handle:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def run_variant(scene, views, held_out, variant: str) -> dict:
    """Segment ``scene`` (labels hidden) from ``views`` with ``variant``'s masks; scores."""
    from csgs_codec.semantic.evaluation import click_object_ious
    from csgs_codec.train.segment import SegmentSettings, segment_scene
    from csgs_codec.train.segmentation import segment_image
    from csgs_codec.train.synthetic import instance_mask
    from csgs_codec.train.views import TrainingView

    truth = scene.labels
    hidden = scene.subset(np.arange(len(scene)))
    hidden.labels = None
    peak_reset()
    began = time.perf_counter()
    masked = []
    for view in views:
        mask = (segment_image(view.image) if variant == "builtin"
                else instance_mask(scene, view.camera))
        masked.append(TrainingView(view.image, view.camera, mask, name=view.name,
                                   oversegmented=variant == "builtin"))
    masks_s = time.perf_counter() - began
    result = segment_scene(hidden, masked, SegmentSettings())
    seconds = time.perf_counter() - began
    peak = peak_mb()
    segmented = result.scene
    ious = {}
    for camera in held_out:
        for label, iou in click_object_ious(segmented, camera, truth).items():
            ious.setdefault(label, []).append(iou)
    per_object = {int(k): float(np.mean(v)) for k, v in ious.items()}
    return {"variant": variant, "instances": result.instances.count,
            "click_miou_3d": float(np.mean([iou for values in ious.values()
                                            for iou in values])),
            "object_miou_3d": per_object, "seconds": round(seconds, 2),
            "phase_seconds": {"masks": round(masks_s, 2),
                              **{k: round(v, 2) for k, v in result.seconds.items()}},
            "peak_rss_mb": round(peak, 1)}


def measure_scene(name: str, args) -> list[dict]:
    """Every variant on one scene."""
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras
    from csgs_codec.train.views import TrainingView

    width, height = (int(v) for v in args.size.split("x"))
    scene = object_scene(name, args.per_object)
    cameras = orbit_cameras(scene, args.views, width=width, height=height, up="+z",
                            elevation_deg=30.0, fill=1.4)
    views = [TrainingView(np.clip(render(scene, c).image, 0, 1).astype(np.float32), c,
                          name=c.name) for c in cameras]
    held = orbit_cameras(scene, 2 * 8, width=width, height=height, up="+z",
                         elevation_deg=20.0, fill=1.4)[1::2]
    rows = []
    for variant in args.variants:
        row = run_variant(scene, views, held, variant)
        row.update(scene=name, objects=len(SCENE_OBJECTS[name]), gaussians=len(scene),
                   views=args.views, size=args.size)
        print(f"{name} {variant}: click mIoU {row['click_miou_3d']:.3f}, "
              f"{row['instances']} instances, {row['seconds']:.1f} s, "
              f"peak {row['peak_rss_mb']:.0f} MiB", file=sys.stderr)
        rows.append(row)
    return rows


def main() -> int:
    """Parse arguments, run, print or write the JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["pair", "six"],
                        choices=sorted(SCENE_OBJECTS))
    parser.add_argument("--variants", nargs="+", default=["builtin", "exact"],
                        choices=("builtin", "exact"))
    parser.add_argument("--per-object", type=int, default=6000)
    parser.add_argument("--views", type=int, default=24)
    parser.add_argument("--size", default="320x240")
    parser.add_argument("--mary-rose", action="store_true",
                        help="also train mary_rose and click its held-out photos (minutes)")
    parser.add_argument("--notes", default="")
    parser.add_argument("--out")
    args = parser.parse_args()
    rows = []
    for name in args.scenes:
        rows.extend(measure_scene(name, args))
    if args.mary_rose:
        from segment_auto_capture import measure_mary_rose

        rows.append(measure_mary_rose())
    emit(document("segment_auto", rows, notes=args.notes, scenes_folder=str(SCENES)), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
