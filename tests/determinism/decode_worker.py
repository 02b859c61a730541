"""One decoding run of a determinism check, in its own process.

    python -m tests.determinism.decode_worker --vectors DIR --torch MODE [--only PREFIX ...]

The caller sets the BLAS thread and kernel environment variables before this process loads
numpy. ``--torch`` is ``none`` (torch never imported), ``on`` / ``off`` (torch imported and
``torch.use_deterministic_algorithms`` set), or ``cuda`` (as ``on``, with CUDA initialised
and a tensor placed on the GPU). Prints one JSON object: the environment it ran in and the
digest of every case (or ``error: <class>: <message>`` when the decode raised).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

TORCH_MODES = ("none", "on", "off", "cuda")


def _prepare_torch(mode: str) -> dict:
    """Import and configure torch as ``mode`` asks; returns facts about it for the report."""
    if mode == "none":
        return {"torch": None}
    import torch

    torch.use_deterministic_algorithms(mode != "off")
    facts = {"torch": torch.__version__,
             "deterministic": torch.are_deterministic_algorithms_enabled(),
             "torch_threads": torch.get_num_threads()}
    if mode == "cuda":
        torch.cuda.init()
        probe = torch.ones(1024, device="cuda").sum().item()
        facts["cuda_device"] = torch.cuda.get_device_name(0)
        facts["cuda_probe"] = probe
    return facts


def blas_name() -> str:
    """The BLAS numpy was built with, as numpy names it (e.g. 'scipy-openblas'), lower case."""
    import numpy as np

    try:
        config = np.show_config(mode="dicts")
        return str(config["Build Dependencies"]["blas"]["name"]).lower()
    except (TypeError, KeyError):  # older numpy without mode="dicts"
        return "unknown"


def main() -> int:
    """Decode every case and print the environment and the digests as one JSON line."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vectors", type=Path, required=True)
    parser.add_argument("--torch", choices=TORCH_MODES, default="none")
    parser.add_argument("--only", nargs="*")
    args = parser.parse_args()

    facts = _prepare_torch(args.torch)
    from tests.determinism.vector_cases import vector_cases

    digests = {}
    start = time.perf_counter()
    for case in vector_cases(args.vectors, args.only):
        try:
            digests[case.id] = case.compute()
        except Exception as err:  # noqa: BLE001 - reported as a mismatch, never hidden
            digests[case.id] = f"error: {type(err).__name__}: {err}"
    facts.update({
        "blas": blas_name(),
        "threads": {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS",
                                                   "OPENBLAS_NUM_THREADS")},
        "openblas_coretype": os.environ.get("OPENBLAS_CORETYPE"),
        "torch_loaded": "torch" in sys.modules,
        "seconds": round(time.perf_counter() - start, 3),
    })
    print(json.dumps({"environment": facts, "digests": digests}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
