"""Step allocation benchmark: are the presets' ratios between attribute steps rate-distortion
balanced? A coordinate search over per-attribute step offsets, scored on render PSNR.

    .venv/bin/python benchmarks/allocation.py [--scenes donut plant biker playbot]
        [--quality 5] [--views 6] [--rounds 2] [--out FILE]

For each scene the uniform trade (bits per Gaussian per dB when every step moves together by
half an octave around the preset) sets the exchange rate; a candidate allocation is scored by
J = sum over scenes of (bits/G - exchange rate x foreground PSNR), lower is better, so a
negative change of J is the bits per Gaussian saved at equal PSNR. Each round tries every
attribute's step half an octave finer and coarser (position grid: one bit per axis more and
less) and keeps a move when it lowers J. Scores come from the encoder's own rate-control probe
(orbit views at 400x300, foreground PSNR against the original scene).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_common import SCENES, document, emit  # noqa: E402

from csgs_codec import read_ply  # noqa: E402
from csgs_codec.codec.encoder import Encoder  # noqa: E402
from csgs_codec.decisions.presets import Preset, preset, scaled_preset  # noqa: E402
from csgs_codec.decisions.rate_control import RenderProbe  # noqa: E402

STEP_FIELDS = ("dc_step", "rest_step", "opacity_step", "scale_step", "rotation_step")


def apply(base: Preset, offsets: dict[str, float]) -> Preset:
    """``base`` with each step times 2^offset and ``position_bits`` plus its offset."""
    changes = {name: getattr(base, name) * 2.0 ** offsets.get(name, 0.0) for name in STEP_FIELDS}
    changes["position_bits"] = base.position_bits + int(offsets.get("position_bits", 0))
    return dataclasses.replace(base, **changes)


class SceneScore:
    """Bits per Gaussian and probe PSNR of one scene under candidate presets."""

    def __init__(self, name: str, quality: int, views: int) -> None:
        self.name = name
        self.scene = read_ply(SCENES / f"{name}.ply")
        self.probe = RenderProbe(self.scene, views=views)
        self.encoder = Encoder(quality=quality)
        self.quality = quality
        self.sh = self.scene.sh_degree_in_use() > 0

    def measure(self, settings: Preset) -> tuple[float, float]:
        """(bits per Gaussian, foreground PSNR in dB) of the scene coded with ``settings``."""
        result = self.encoder._encode(self.scene, settings)
        return len(result.data) * 8 / len(self.scene), self.probe.psnr(result.reconstruction)

    def exchange_rate(self) -> float:
        """Bits per Gaussian per dB along the uniform trade around the preset."""
        from csgs_codec.decisions.presets import MULTIPLIERS

        m = MULTIPLIERS[self.quality]
        fine = self.measure(scaled_preset(m / 2**0.5))
        coarse = self.measure(scaled_preset(m * 2**0.5))
        return (fine[0] - coarse[0]) / max(fine[1] - coarse[1], 1e-6)


def main() -> int:
    """Run the search and write the JSON document."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=["donut", "plant", "biker", "playbot"])
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--views", type=int, default=6)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--out")
    args = parser.parse_args()
    began = time.perf_counter()
    scenes = [SceneScore(name, args.quality, args.views) for name in args.scenes]
    base = preset(args.quality)
    rates = {s.name: s.exchange_rate() for s in scenes}

    def score(offsets: dict[str, float]) -> tuple[float, dict]:
        rows, total = {}, 0.0
        for s in scenes:
            bits, psnr = s.measure(apply(base, offsets))
            rows[s.name] = {"bits_per_gaussian": bits, "psnr": psnr}
            total += bits - rates[s.name] * psnr
        return total, rows

    offsets: dict[str, float] = {}
    best, best_rows = score(offsets)
    start_score, start_rows = best, best_rows
    trials = []
    moves = [(name, d) for name in STEP_FIELDS for d in (-0.5, 0.5)]
    moves += [("position_bits", -1), ("position_bits", 1)]
    sh_in_use = any(s.sh for s in scenes)
    for round_index in range(args.rounds):
        improved = False
        for name, delta in moves:
            if name == "rest_step" and not sh_in_use:
                continue
            candidate = dict(offsets)
            candidate[name] = candidate.get(name, 0) + delta
            value, rows = score(candidate)
            trials.append({"round": round_index, "offsets": candidate, "j": value,
                           "scenes": rows})
            print(f"round {round_index} {name} {delta:+}: J {value - start_score:+.3f}",
                  file=sys.stderr, flush=True)
            if value < best - 1e-3:
                best, best_rows, offsets, improved = value, rows, candidate, True
        if not improved:
            break
    results = [{"scene": s.name, "exchange_rate_bits_per_db": rates[s.name],
                "preset": start_rows[s.name], "allocated": best_rows[s.name]}
               for s in scenes]
    emit(document("allocation", results, quality=args.quality, views=args.views,
                  offsets=offsets, j_change_bits_per_gaussian=best - start_score,
                  trials=trials, wall_s=round(time.perf_counter() - began, 1)), args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
