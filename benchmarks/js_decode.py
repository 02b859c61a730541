"""JavaScript receiver against the Python decoder: decode time of one encoded scene in Node
(csgs_codec/js) and in Python, measured in the same run, as a ratio.

    .venv/bin/python benchmarks/js_decode.py [--scene playbot.ply] [--quality 5]
        [--layers color] [--rounds 5] [--repeat 8] [--out FILE]

The scene is encoded once (default encoder settings of the quality); both decoders must give
the same arrays (SHA-256 of each) before anything is timed. Then, ``rounds`` times, Node
decodes the file ``repeat`` times in one process (tables loaded once, outside the timing;
the fastest run counts) and Python does the same in this process, alternating so both see
the same machine load. JS runs on two threads (its default, as the Python decoder's) and on
one. Rows report the fastest wall and CPU seconds of each, the first decode of a Node process
(before its JIT has warmed up), the medians over the rounds, the Node process's wall time
(start-up, table loading, ``repeat`` decodes and hashing) and the ratios JS / Python.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _js_receiver import node_executable, run_js, scene_hashes  # noqa: E402
from bench_common import FULL_PRECISION, SCENES, document, emit  # noqa: E402

from csgs_codec import Decoder, Encoder, read_ply  # noqa: E402
from csgs_codec.format import read_layers  # noqa: E402


def python_decode(data: bytes, layers: str, repeat: int, threads: int | None = None):
    """(fastest wall s, fastest CPU s, scene) of ``repeat`` Python decodes."""
    wall = cpu = float("inf")
    scene = None
    decoder = Decoder(threads=threads)
    for _ in range(repeat):
        start, start_cpu = time.perf_counter(), time.process_time()
        scene = decoder.decode(data, layers=layers)
        wall = min(wall, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    return wall, cpu, scene


def measure(path: Path, data: bytes, layers: str, rounds: int, repeat: int) -> dict:
    """Alternate JS (one and two threads) and Python decodes of ``path``; the timing fields
    of a row."""
    js = {1: [], 2: []}
    js_cpu, js_first, js_process, py_wall, py_cpu, py1_wall, pairs = ([] for _ in range(7))
    for _ in range(rounds):
        for threads in (1, 2):
            start = time.perf_counter()
            (result,) = run_js([path], layers=layers, repeat=repeat, threads=threads)
            if threads == 2:
                js_process.append(time.perf_counter() - start)
                js_cpu.append(result["decode_cpu_s"])
                js_first.append(result["first_decode_s"])
            js[threads].append(result["decode_s"])
        wall, cpu, _ = python_decode(data, layers, repeat)
        py_wall.append(wall)
        py_cpu.append(cpu)
        py1_wall.append(python_decode(data, layers, repeat, threads=1)[0])
        pairs.append({"js_decode_s": js[2][-1], "js_1thread_decode_s": js[1][-1],
                      "python_decode_s": wall})
    best = {"js_decode_s": min(js[2]), "js_1thread_decode_s": min(js[1]),
            "js_decode_cpu_s": min(js_cpu), "js_first_decode_s": min(js_first),
            "js_process_s": min(js_process), "python_decode_s": min(py_wall),
            "python_decode_cpu_s": min(py_cpu), "python_1thread_decode_s": min(py1_wall)}
    best["ratio_js_to_python"] = best["js_decode_s"] / best["python_decode_s"]
    best["ratio_js_1thread_to_python_1thread"] = (best["js_1thread_decode_s"]
                                                  / best["python_1thread_decode_s"])
    best["ratio_js_first_to_python"] = best["js_first_decode_s"] / best["python_decode_s"]
    best["ratio_js_process_to_python"] = best["js_process_s"] / best["python_decode_s"]
    # The machine is shared: the medians show what a typical round gave, beside the best.
    best["median_js_decode_s"] = statistics.median(js[2])
    best["median_js_1thread_decode_s"] = statistics.median(js[1])
    best["median_python_decode_s"] = statistics.median(py_wall)
    best["median_ratio_js_to_python"] = statistics.median(
        j / p for j, p in zip(js[2], py_wall))
    best["median_ratio_js_1thread_to_python"] = statistics.median(
        j / p for j, p in zip(js[1], py_wall))
    best["rounds"] = pairs
    return best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="playbot.ply", help="file under ../shared/data/scenes")
    parser.add_argument("--scene-path", type=Path, help="a PLY anywhere (overrides --scene)")
    parser.add_argument("--quality", type=int, default=5)
    parser.add_argument("--layers", default="color")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--repeat", type=int, default=8)
    parser.add_argument("--out")
    args = parser.parse_args(argv)
    if node_executable() is None:
        print("node is not on PATH: the JavaScript receiver cannot run", file=sys.stderr)
        return 2
    path = args.scene_path or SCENES / args.scene
    start = time.perf_counter()
    data = Encoder(quality=args.quality).encode(read_ply(path))
    encode_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as tmp:
        file = Path(tmp) / "scene.csgs"
        file.write_bytes(data)
        (js,) = run_js([file], layers=args.layers)
        scene = Decoder().decode(data, layers=args.layers)
        if not js["ok"] or js["arrays"] != scene_hashes(scene):
            print(f"the decoders disagree on {path.name}: {js}", file=sys.stderr)
            return 1
        chunks = [e.type for e in read_layers(data, layers={"color"}).toc]
        row = {"scene": path.stem, "full_precision_scene": path.stem in FULL_PRECISION,
               "quality": args.quality, "layers": args.layers, "gaussians": len(scene),
               "bytes": len(data), "color_hyperprior": "CHYP" in chunks, "chunks": chunks,
               "encode_s": encode_s, "arrays_equal": True,
               **measure(file, data, args.layers, args.rounds, args.repeat)}
    node = subprocess.run([node_executable(), "--version"], capture_output=True, text=True,
                          check=True).stdout.strip()
    emit(document("js_decode", [row], node=node, rounds=args.rounds, repeat=args.repeat),
         args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
