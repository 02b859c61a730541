"""Joint coding of a Gaussian's SH across colours: does a colour transform code the bands smaller?

    .venv/bin/python benchmarks/sh_colour_transform.py SCENE.ply [...] [--qualities 3 5 7]
        [--size 400x300] [--out FILE]

For each scene and quality the default encoder codes the scene; then the SH-rest streams
(bands 1-3) of its Gaussians, in the encoder's order, are written again by the codec's own
float-stream writer (no hyperprior, every mode including cross-channel prediction) at the
preset's step three ways: as they are (R, G, B per coefficient: ``rgb``), after a fixed
orthonormal colour transform (luma (1,1,1)/sqrt 3, (1,0,-1)/sqrt 2, (1,-2,1)/sqrt 6:
``opponent``), and after each band's own 3x3 principal axes over its coefficients
(``klt``, 9 floats per band of side information, counted). Orthonormal transforms keep the
squared error of uniform quantization, so each variant is scored by its SH bytes and by the
held-out foreground PSNR of the encode's reconstruction with its SH bands replaced by the
variant's (16 orbit views at 20 degrees + 12 at 45, none used by the encoder). Rows
``dc_rgb`` / ``dc_opponent`` do the same for the DC stream (its bytes in ``dc_bytes``, the
bands as the encode coded them); the encode may have coded DC with its hyperprior, so compare
the two rows with each other, not with the file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from derived_steps import HeldOut  # noqa: E402

from csgs_codec.attributes.float_stream import write_float_stream  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import PRESETS  # noqa: E402
from csgs_codec.format.primitives import ByteWriter  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS  # noqa: E402

OPPONENT = np.array([[1, 1, 1], [1, 0, -1], [1, -2, 1]], np.float64)
OPPONENT /= np.linalg.norm(OPPONENT, axis=1, keepdims=True)


def principal_axes(coefficients: np.ndarray) -> np.ndarray:
    """3x3 orthonormal rows: the principal axes of (M, 3) colour triples, largest first."""
    _, vectors = np.linalg.eigh(np.cov(coefficients.T.astype(np.float64)))
    return vectors[:, ::-1].T


def coded_bands(sh_rest: np.ndarray, degree: int, step: float, variant: str
                ) -> tuple[int, np.ndarray]:
    """(bytes, decoded (N, K, 3) SH rest) of the bands coded as ``variant``."""
    n = sh_rest.shape[0]
    decoded = np.zeros_like(sh_rest)
    total = 0
    for band in range(1, degree + 1):
        lo, hi = SH_REST_COUNTS[band - 1], SH_REST_COUNTS[band]
        block = sh_rest[:, lo:hi, :].astype(np.float64)
        if variant == "rgb":
            matrix = np.eye(3)
        elif variant == "opponent":
            matrix = OPPONENT
        else:
            matrix = principal_axes(block.reshape(-1, 3))
            total += 9 * 4
        turned = (block @ matrix.T).reshape(n, -1).astype(np.float32)
        out = ByteWriter()
        recon = write_float_stream(out, turned, step)
        total += len(out.getvalue())
        decoded[:, lo:hi, :] = (recon.reshape(n, hi - lo, 3).astype(np.float64)
                                @ matrix).astype(np.float32)
    return total, decoded


def main() -> int:
    """Encode, re-code the SH bands three ways, score."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--qualities", type=int, nargs="+", default=[3, 5, 7])
    parser.add_argument("--size", default="400x300")
    parser.add_argument("--out")
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    rows = []
    for path in args.scenes:
        scene = read_ply(path)
        held = HeldOut(scene, width, height)
        for quality in args.qualities:
            result = Encoder(quality=quality).encode_with_report(scene)
            original = scene.subset(result.order)
            degree = result.reconstruction.sh_degree_in_use()
            if degree == 0:
                continue
            for variant in ("rgb", "opponent", "klt"):
                nbytes, decoded = coded_bands(original.sh_rest, degree,
                                              PRESETS[quality].rest_step, variant)
                candidate = result.reconstruction.subset(np.arange(len(original)))
                candidate.sh_rest = decoded
                rows.append({"scene": Path(path).name, "quality": quality,
                             "variant": variant, "sh_band_bytes": nbytes,
                             "file_bytes": len(result.data),
                             "held_out_fg_psnr_db": held.psnr(candidate)})
                print(rows[-1], file=sys.stderr)
            for variant in ("rgb", "opponent"):
                matrix = np.eye(3) if variant == "rgb" else OPPONENT
                turned = (original.sh_dc.astype(np.float64) @ matrix.T).astype(np.float32)
                out = ByteWriter()
                recon = write_float_stream(out, turned, PRESETS[quality].dc_step)
                candidate = result.reconstruction.subset(np.arange(len(original)))
                candidate.sh_dc = (recon.astype(np.float64) @ matrix).astype(np.float32)
                rows.append({"scene": Path(path).name, "quality": quality,
                             "variant": f"dc_{variant}", "dc_bytes": len(out.getvalue()),
                             "file_bytes": len(result.data),
                             "held_out_fg_psnr_db": held.psnr(candidate)})
                print(rows[-1], file=sys.stderr)
    emit(document("sh_colour_transform", rows, settings=vars(args),
                  held_out_views=f"16 @20deg + 12 @45deg, {args.size}"), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
