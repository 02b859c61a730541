"""What would a per-Gaussian SH band count save? Empirical entropies of the coded SH bands.

    .venv/bin/python benchmarks/sh_band_skip.py SCENE.ply [...] [--qualities 3 5 7] [--out FILE]

For each scene and quality the default encoder codes the scene; in its reconstruction, band b
of Gaussian i is *empty* when every coefficient of the band decodes to its channel's most
common value (index 0 of the channel's lattice: the coefficient is below its step). Costs
are empirical (order-0, per channel) entropies of the decoded values, an ideal adaptive
coder's bits, not the codec's own tables:

- ``bits_now``: every Gaussian codes every band, N x sum_c H_c;
- ``bits_with_count``: a band count per Gaussian (the highest non-empty band, 0..3: N x
  H(count), the side information), then band b only for the Gaussians whose count >= b, each
  channel's entropy over those Gaussians alone.

``saving`` is 1 - bits_with_count / bits_now; ``file_share`` the SH bands' share of the
file's bytes (so the file would shrink by about saving x file_share).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402

from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402
from csgs_codec.scene.gaussian_scene import SH_REST_COUNTS  # noqa: E402


def entropy_bits(values: np.ndarray) -> float:
    """Order-0 entropy of ``values`` (1-D), in bits per value; 0 for fewer than two."""
    if values.size < 2:
        return 0.0
    _, counts = np.unique(values, return_counts=True)
    p = counts / counts.sum()
    return float(-(p * np.log2(p)).sum())


def band_costs(sh_rest: np.ndarray, degree: int) -> dict:
    """Bits of the SH bands of one reconstruction (N, K, 3), with and without band counts."""
    n = sh_rest.shape[0]
    bands, empty = [], []
    for band in range(1, degree + 1):
        lo, hi = SH_REST_COUNTS[band - 1], SH_REST_COUNTS[band]
        values = sh_rest[:, lo:hi, :].reshape(n, -1)
        modes = np.array([np.unique(col, return_counts=True)[0][
            np.argmax(np.unique(col, return_counts=True)[1])] for col in values.T])
        bands.append(values)
        empty.append(np.all(values == modes, axis=1))
    count = np.zeros(n, np.int64)
    for band, is_empty in enumerate(empty, start=1):
        count[~is_empty] = band
    now = sum(n * sum(entropy_bits(col) for col in values.T) for values in bands)
    with_count = n * entropy_bits(count)
    for band, values in enumerate(bands, start=1):
        coded = values[count >= band]
        with_count += coded.shape[0] * sum(entropy_bits(col) for col in coded.T)
    return {"bits_now": now, "bits_with_count": with_count,
            "saving": 1 - with_count / now if now else 0.0,
            "count_entropy_bits": entropy_bits(count),
            "empty_share_by_band": [float(e.mean()) for e in empty],
            "count_share": [float((count == c).mean()) for c in range(degree + 1)]}


def main() -> int:
    """Encode each scene at each quality and report the band-count estimate."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+")
    parser.add_argument("--qualities", type=int, nargs="+", default=[3, 5, 7])
    parser.add_argument("--out")
    args = parser.parse_args()
    rows = []
    for path in args.scenes:
        scene = read_ply(path)
        for quality in args.qualities:
            result = Encoder(quality=quality).encode_with_report(scene)
            rec = result.reconstruction
            degree = rec.sh_degree_in_use()
            if degree == 0:
                continue
            sh_bytes = sum(v for k, v in result.stream_bytes.items() if k.startswith("SHB"))
            row = {"scene": Path(path).name, "quality": quality, "gaussians": len(rec),
                   "bytes": len(result.data), "sh_band_bytes": sh_bytes,
                   "file_share": sh_bytes / len(result.data),
                   "sh_band_bits_coded": 8 * sh_bytes,
                   **band_costs(rec.sh_rest, degree)}
            rows.append(row)
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()},
                  file=sys.stderr)
    emit(document("sh_band_skip", rows, settings=vars(args)), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
