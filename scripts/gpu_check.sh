#!/usr/bin/env bash
# The prepared GPU check (issue #31): on a CUDA machine with torch and no network, run the
# `gpu` tests, time the training stages and check that the conformance vectors decode to
# their hashes there. Wheels it needs beyond the machine's own packages (constriction) are
# taken from .whl/ in the repository (see /work/.library/device/README.md). Writes into
# $OUT (default /tmp/gpu_check): gpu.txt, pytest_gpu.log, train_speed_cuda.json,
# segment_scale_cuda.json, check_vectors.log. Every step has its own time limit, so the
# script ends within about 10 minutes whatever hangs.
set -u
cd "$(dirname "$0")/.."
OUT=${OUT:-/tmp/gpu_check}
mkdir -p "$OUT"
if ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || exit 1
fi
shim=/tmp/csgs_shim   # cli/ installs as csgs_cli; here it is not installed
mkdir -p "$shim" && ln -sfn "$PWD/cli" "$shim/csgs_cli"
export PYTHONPATH="$PWD:$shim:/tmp/site${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.txt" 2>&1
python3 -c "import torch, numpy; print('torch', torch.__version__, 'numpy', numpy.__version__)" >> "$OUT/gpu.txt"
echo "== pytest -m gpu"
timeout 240 python3 -m pytest -q -p no:cacheprovider -o addopts="" -m gpu --durations=10 \
    tests/train/test_cuda.py tests/entropy/test_determinism.py \
    tests/determinism/test_check_vectors.py tests/render/test_raster_gsplat.py \
    > "$OUT/pytest_gpu.log" 2>&1
echo "pytest exit $?"; tail -5 "$OUT/pytest_gpu.log"
echo "== training speed"
timeout 150 python3 benchmarks/train_speed.py --device cuda --semantic-iterations 10 \
    --out "$OUT/train_speed_cuda.json" 2>&1 | tail -3
echo "== segment at scale"
timeout 150 python3 benchmarks/segment_scale.py --device cuda \
    --out "$OUT/segment_scale_cuda.json" 2>&1 | tail -3
echo "== conformance vectors"
timeout 120 python3 -m tests.determinism.check_vectors --cuda > "$OUT/check_vectors.log" 2>&1
echo "check_vectors exit $?"; tail -3 "$OUT/check_vectors.log"
