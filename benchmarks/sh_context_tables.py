"""Would SH tables chosen by the magnitude of a Gaussian's earlier coefficients pay? (issue 32)

    .venv/bin/python benchmarks/sh_context_tables.py SCENE.ply [...] [--qualities 6]
        [--cap 8] [--classes 8] [--out FILE]

A measurement for a format change not made: within an SH band chunk, channel c of Gaussian i
would be coded with the table of a *context class*, an integer function of the same
Gaussian's indices already decoded in that band, m_i = sum over channels j < c of
min(|k_j,i|, cap), cut into at most ``--classes`` classes at quantiles of m chosen per channel
(each threshold carried in the channel record, 2 bytes counted). The default encoder codes each
scene; its final SH band plans are captured as written, and each channel's coded size is
compared with what the same residuals would cost:

- ``frozen``: frozen Gaussian tables, one scale index per class (the codec's table cost,
  8 bits per class);
- ``histogram``: a frequency table per class (the codec's histogram cost, tables included);
- ``ideal``: the conditional order-0 entropy over the classes, no table cost at all (what an
  adaptive coder would approach on a scene far larger than these).

Each channel keeps the smallest of its current coding and the context codings
(``bits_context_real``), so the figure is an upper bound on what the change could save with
the codec's own table sources; a channel the color hyperprior codes is counted at its
planned cost without the hyperprior on both sides, so it adds nothing to the saving.
``saving_share_of_file`` is that saving over the file's bits.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_common import document, emit  # noqa: E402
from sh_band_skip import entropy_bits as bits_per_value  # noqa: E402

import csgs_codec.chunks.color_streams as color_streams  # noqa: E402
from csgs_codec.attributes.channel_coders import CODERS, TABLE_FROZEN  # noqa: E402
from csgs_codec.attributes.float_stream import predict  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.entropy.histogram import histogram_cost  # noqa: E402
from csgs_codec.interchange.ply_io import read_ply  # noqa: E402

#: Channels of each SH band stream (bands 1-3).
BAND_CHANNELS = (9, 15, 21)
#: Bytes a context threshold would take in a channel record (a varint of a small integer).
THRESHOLD_BITS = 16


def entropy_bits(values: np.ndarray) -> float:
    """Order-0 entropy of ``values`` (1-D) times their count: ideal bits, 0 for fewer than 2."""
    return values.size * bits_per_value(values)


def captured_band_plans(scene, quality: int) -> tuple[int, list]:
    """(file bytes, the StreamPlans of the SH band chunks as the default encoder writes them)."""
    plans = []
    original = color_streams.write_planned_stream

    def keep(out, plan, priors=None):
        if len(plan.channels) in BAND_CHANNELS:
            plans.append((plan, set(priors or {})))
        return original(out, plan, priors)

    color_streams.write_planned_stream = keep
    try:
        data = Encoder(quality).encode(scene)
    finally:
        color_streams.write_planned_stream = original
    return len(data), plans


def context_classes(earlier: np.ndarray, cap: int, classes: int) -> tuple[np.ndarray, int]:
    """((N,) class of each Gaussian, class count) from the (c, N) indices decoded before."""
    m = np.minimum(np.abs(earlier), cap).sum(axis=0)
    cuts = np.unique(np.quantile(m, np.linspace(0, 1, classes + 1)[1:-1], method="higher"))
    cuts = cuts[cuts > m.min()]
    return np.searchsorted(cuts, m, side="right"), len(cuts) + 1


def channel_costs(base: np.ndarray, cls: np.ndarray, count: int) -> dict:
    """Bits of ``base`` (N,) coded per class: frozen tables, histograms, ideal entropy."""
    members = [np.flatnonzero(cls == j) for j in range(count)]
    members = [rows for rows in members if rows.size]
    side = THRESHOLD_BITS * (count - 1)
    frozen, _ = CODERS[TABLE_FROZEN].cost(base, members)
    histogram = sum(histogram_cost(base[rows]) for rows in members) + side
    ideal = sum(entropy_bits(base[rows]) for rows in members)
    return {"frozen": frozen + side, "histogram": histogram, "ideal": ideal}


def measure(scene, name: str, quality: int, cap: int, classes: int) -> dict:
    """One row: the SH bands' bits now and with context classes (module notes)."""
    file_bytes, plans = captured_band_plans(scene, quality)
    n = scene.count
    now = real = frozen_only = ideal_now = ideal_context = 0.0
    for plan, prior_channels in plans:
        indices = np.zeros((len(plan.channels), plan.count), np.int64)
        for c, ch in enumerate(plan.channels):
            if ch.is_constant:
                continue
            k = ch.base if ch.coefs is None else ch.base + predict(indices[:c], ch.coefs,
                                                                    ch.bias)
            indices[c] = k
            now += ch.cost
            ideal_now += entropy_bits(ch.base)
            if c == 0 or c in prior_channels:
                real += ch.cost
                frozen_only += ch.cost
                ideal_context += entropy_bits(ch.base)
                continue
            costs = channel_costs(ch.base, *context_classes(indices[:c], cap, classes))
            real += min(ch.cost, costs["frozen"], costs["histogram"])
            frozen_only += min(ch.cost, costs["frozen"])
            ideal_context += costs["ideal"]
    return {"scene": name, "gaussians": n, "quality": quality, "cap": cap,
            "classes": classes, "file_bytes": file_bytes,
            "file_bits_per_gaussian": 8 * file_bytes / n,
            "sh_band_bits_per_gaussian": now / n,
            "bits_context_real": real / n, "bits_context_frozen_only": frozen_only / n,
            "ideal_order0": ideal_now / n, "ideal_context": ideal_context / n,
            "saving_bits_per_gaussian": (now - real) / n,
            "ideal_saving_bits_per_gaussian": (ideal_now - ideal_context) / n,
            "saving_share_of_file": (now - real) / (8 * file_bytes)}


def main(argv=None) -> int:
    """Measure each scene at each quality; JSON to stdout or ``--out``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="+", help="PLY files with SH bands")
    parser.add_argument("--qualities", nargs="+", type=int, default=[6])
    parser.add_argument("--cap", type=int, default=8, help="largest |index| counted")
    parser.add_argument("--classes", type=int, default=8, help="most context classes")
    parser.add_argument("--out", help="JSON file (default: stdout)")
    args = parser.parse_args(argv)
    rows = []
    for path in args.scenes:
        scene = read_ply(path)
        for quality in args.qualities:
            row = measure(scene, Path(path).stem, quality, args.cap, args.classes)
            print(f"{row['scene']} q{quality}: SH bands {row['sh_band_bits_per_gaussian']:.2f}"
                  f" -> {row['bits_context_real']:.2f} b/G (ideal "
                  f"{row['ideal_order0']:.2f} -> {row['ideal_context']:.2f})",
                  file=sys.stderr)
            rows.append(row)
    emit(document("sh_context_tables", rows, cap=args.cap, classes=args.classes), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
