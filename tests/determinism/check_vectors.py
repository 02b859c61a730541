"""Check that this machine decodes the conformance vectors bit for bit as recorded.

    python -m tests.determinism.check_vectors [--vectors spec/vectors] [--threads 1 2 16]
        [--torch none on off] [--cuda] [--no-blas-variants] [--only PREFIX ...] [--json FILE]

Run it from the repository root (``tests`` is a package of the checkout, not installed).
Every valid read of every vector (see tests/determinism/vector_cases.py) is decoded in a
fresh subprocess for each configuration: OMP/MKL/OPENBLAS thread counts 1, 2 and all cores;
torch not imported, imported with ``torch.use_deterministic_algorithms(True)``, and with it
False (importing torch changes the process's BLAS and threading state even though the decoder
never uses torch); on x86-64 with numpy's OpenBLAS, also with OpenBLAS forced to its oldest
(Prescott, SSE3) kernels and to its Sandybridge, Haswell and SkylakeX kernels where the CPU
has AVX, AVX2 and AVX-512 (OPENBLAS_CORETYPE; the table names the kernel loaded); with ``--cuda``,
also with CUDA initialised. The SHA-256 of every output must equal the one the vector
records. Prints a table, and exits 1 on any mismatch, decode error or failed run.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.determinism.decode_worker import blas_name
from tests.determinism.vector_cases import vector_cases

REPO = Path(__file__).resolve().parents[2]
THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
WORKER_TIMEOUT_S = 900


@dataclass(frozen=True)
class Config:
    """One decoding environment: BLAS threads, torch mode, forced OpenBLAS kernel (or None)."""

    threads: int
    torch: str
    coretype: str | None = None

    @property
    def label(self) -> str:
        """e.g. 'threads=2 torch=on blas=default'."""
        return f"threads={self.threads} torch={self.torch} blas={self.coretype or 'default'}"

    def environment(self) -> dict[str, str]:
        """os.environ with this configuration's variables set (and others of ours cleared)."""
        env = dict(os.environ)
        env.update({name: str(self.threads) for name in THREAD_VARIABLES})
        env.pop("OPENBLAS_CORETYPE", None)
        env["OPENBLAS_VERBOSE"] = "2"  # OpenBLAS names the kernel it loads on stderr
        if self.coretype:
            env["OPENBLAS_CORETYPE"] = self.coretype
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
        return env


@dataclass
class RunResult:
    """What one configuration produced: digests by case id, its environment, or a failure."""

    config: Config
    digests: dict[str, str]
    environment: dict
    failure: str | None = None


def blas_variants() -> list[str]:
    """OpenBLAS kernels that can be forced safely on this CPU (empty off x86-64, or when numpy
    does not use OpenBLAS)."""
    if platform.machine().lower() not in ("x86_64", "amd64") or "openblas" not in blas_name():
        return []
    variants = ["Prescott"]
    try:
        flags = set(Path("/proc/cpuinfo").read_text().split())
    except OSError:
        return variants
    for flag, kernel in (("avx", "Sandybridge"), ("avx2", "Haswell"), ("avx512f", "SkylakeX")):
        if flag in flags:
            variants.append(kernel)
    return variants


def default_configs(threads: list[int], torch_modes: list[str], cuda: bool,
                    with_blas_variants: bool) -> list[Config]:
    """Every thread count with every torch mode, plus the BLAS-kernel and CUDA variants."""
    if importlib.util.find_spec("torch") is None:
        torch_modes = [m for m in torch_modes if m == "none"]
    configs = [Config(t, m) for t in threads for m in torch_modes]
    if with_blas_variants:
        configs += [Config(threads[0], "none", kind) for kind in blas_variants()]
    if cuda:
        configs += [Config(t, "cuda") for t in threads[:2]]
    return configs


def run_config(config: Config, vectors: Path, only: list[str] | None) -> RunResult:
    """Decode every case in a subprocess configured as ``config``."""
    command = [sys.executable, "-m", "tests.determinism.decode_worker", "--vectors",
               str(vectors), "--torch", config.torch]
    if only:
        command += ["--only", *only]
    try:
        done = subprocess.run(command, cwd=REPO, env=config.environment(), capture_output=True,
                              text=True, timeout=WORKER_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return RunResult(config, {}, {}, f"timed out after {WORKER_TIMEOUT_S} s")
    if done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
        return RunResult(config, {}, {}, f"exit {done.returncode}: {' | '.join(tail)}")
    report = json.loads(done.stdout.strip().splitlines()[-1])
    cores = [line.split(":", 1)[1].strip() for line in done.stderr.splitlines()
             if line.startswith("Core:")]
    report["environment"]["blas_core"] = cores[0] if cores else None
    return RunResult(config, report["digests"], report["environment"])


def compare(expected: dict[str, str], result: RunResult) -> list[tuple[str, str, str]]:
    """(case id, expected, got) for every case whose digest differs or is missing."""
    return [(case_id, want, result.digests.get(case_id, "missing"))
            for case_id, want in expected.items() if result.digests.get(case_id) != want]


def format_table(expected: dict[str, str], results: list[RunResult]) -> str:
    """One row per configuration: cases, matches, differences, seconds, BLAS, torch state."""
    lines = [f"{'configuration':<40} {'cases':>5} {'match':>5} {'differ':>6} {'s':>7}  "
             f"{'blas (kernel)':<28} torch"]
    for result in results:
        if result.failure:
            lines.append(f"{result.config.label:<40} FAILED: {result.failure}")
            continue
        bad = len(compare(expected, result))
        env = result.environment
        blas = f"{env.get('blas', '?')} ({env.get('blas_core') or '?'})"
        torch_state = ("not imported" if not env.get("torch_loaded") else
                       f"{env.get('torch')} deterministic={env.get('deterministic')}")
        lines.append(f"{result.config.label:<40} {len(expected):>5} {len(expected) - bad:>5} "
                     f"{bad:>6} {env.get('seconds', 0):>7.2f}  {blas:<28} "
                     f"{torch_state}")
    return "\n".join(lines)


def check(vectors: Path, configs: list[Config], only: list[str] | None = None,
          echo=print) -> tuple[bool, list[RunResult]]:
    """Run every configuration; returns (all identical to the record, the runs)."""
    expected = {case.id: case.expected for case in vector_cases(vectors, only)}
    if not expected:
        echo(f"no valid vectors found under {vectors}")
        return False, []
    results = []
    for config in configs:
        echo(f"decoding {len(expected)} cases with {config.label} ...")
        results.append(run_config(config, vectors, only))
    echo(format_table(expected, results))
    ok = True
    for result in results:
        if result.failure:
            ok = False
            continue
        for case_id, want, got in compare(expected, result):
            ok = False
            echo(f"MISMATCH {result.config.label}: {case_id}: expected {want}, got {got}")
    echo("all outputs identical to the recorded hashes" if ok else "determinism check FAILED")
    return ok, results


def main(argv: list[str] | None = None) -> int:
    """Command-line entry point; exit status 0 when every output matches."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vectors", type=Path, default=REPO / "spec" / "vectors")
    parser.add_argument("--threads", type=int, nargs="*",
                        default=sorted({1, 2, os.cpu_count() or 1}))
    parser.add_argument("--torch", nargs="*", default=["none", "on", "off"],
                        choices=["none", "on", "off"])
    parser.add_argument("--cuda", action="store_true", help="also decode with CUDA initialised")
    parser.add_argument("--no-blas-variants", action="store_true",
                        help="skip the runs with forced OpenBLAS kernels")
    parser.add_argument("--only", nargs="*", help="case id prefixes, e.g. entropy scenes/semantic")
    parser.add_argument("--json", type=Path, help="also write the runs as JSON here")
    args = parser.parse_args(argv)

    configs = default_configs(args.threads, args.torch, args.cuda, not args.no_blas_variants)
    ok, results = check(args.vectors.resolve(), configs, args.only)
    if args.json:
        args.json.write_text(json.dumps([
            {"config": r.config.label, "failure": r.failure, "environment": r.environment,
             "digests": r.digests} for r in results], indent=2) + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
