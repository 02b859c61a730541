#!/usr/bin/env bash
# The prepared GPU check (issue #31): on a CUDA machine with torch and no network, build
# gsplat's kernels, run the `gpu` tests, time stage 1 through gsplat and through the torch
# reference (same run), at 512x384 and at 1920x1080 with about 500k Gaussian slots, and train
# and decode a synthetic scene with `csgs train --device cuda`. Wheels it needs beyond the
# machine's own packages come from .whl/ (scripts/fetch_gpu_wheels.sh fills it; carry it).
# Writes into $OUT (default /tmp/gpu_check): gpu.txt, gsplat_build.log, pytest_gpu.log,
# train_speed_cuda*.json (the 512x384 one with operators counted per step), gpu_util.csv,
# train_cli.log. Every step has its own time limit, so the script ends within about 9
# minutes whatever hangs. QUICK=1 leaves out the conformance
# vectors and the `csgs train` run (a shorter check of speed and the training path).
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
export PATH="/tmp/site/bin:$PATH" TORCH_EXTENSIONS_DIR=/tmp/torch_ext MAX_JOBS=16
csgs() { python3 -c "import sys; from csgs_cli.main import main; sys.exit(main())" "$@"; }
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.txt" 2>&1
python3 -c "import torch, numpy; print('torch', torch.__version__, 'numpy', numpy.__version__)" >> "$OUT/gpu.txt"
TORCH_CUDA_ARCH_LIST=$(python3 -c "import torch; print('%d.%d' % torch.cuda.get_device_capability())")
export TORCH_CUDA_ARCH_LIST
echo "== gsplat kernels (arch $TORCH_CUDA_ARCH_LIST)"
# Built in the foreground from a fixed folder: a background build from the project folder
# failed there before ("getcwd() failed ... Could not open output file").
mkdir -p /tmp/gsplat_build
(cd /tmp/gsplat_build && timeout 300 python3 -c "
import time; t = time.time()
from gsplat.cuda._backend import _C
print('gsplat kernels loaded:', _C is not None, 'in %.1f s' % (time.time() - t))") \
    > "$OUT/gsplat_build.log" 2>&1
echo "build exit $?"; tail -2 "$OUT/gsplat_build.log"
echo "== training speed"
echo "timestamp, utilization.gpu [%], memory.used [MiB]" > "$OUT/gpu_util.csv"
nvidia-smi --query-gpu=timestamp,utilization.gpu,memory.used --format=csv,noheader -lms 250 \
    >> "$OUT/gpu_util.csv" 2>/dev/null &
smi=$!
echo "-- stage 1, 512x384, ~20k slots, gsplat" >> "$OUT/gpu_util.csv"
timeout 100 python3 benchmarks/train_speed.py --device cuda --rasterizer gsplat --steps 200 \
    --semantic-iterations 40 --profile-steps 20 --profile-out "$OUT/profile_512x384.txt" \
    --count-ops 5 --out "$OUT/train_speed_cuda.json" 2>&1 | tail -1
echo "-- stage 1, 512x384, ~20k slots, gsplat, kept slots gathered" >> "$OUT/gpu_util.csv"
timeout 60 python3 benchmarks/train_speed.py --device cuda --rasterizer gsplat --steps 100 \
    --all-slots no --semantic-iterations 0 --out "$OUT/train_speed_cuda_kept.json" \
    2>&1 | tail -1
echo "-- stage 1, 1920x1080, ~500k slots, gsplat" >> "$OUT/gpu_util.csv"
timeout 120 python3 benchmarks/train_speed.py --device cuda --rasterizer gsplat \
    --size 1920x1080 --anchors 50000 --offsets 10 --gaussians-per-object 20000 --views 8 \
    --steps 60 --semantic-iterations 0 --profile-steps 10 \
    --profile-out "$OUT/profile_1920x1080.txt" --out "$OUT/train_speed_cuda_1080p.json" \
    2>&1 | tail -1
echo "-- stage 1, 512x384, ~20k slots, torch reference" >> "$OUT/gpu_util.csv"
timeout 60 python3 benchmarks/train_speed.py --device cuda --rasterizer torch --steps 20 \
    --semantic-iterations 0 --out "$OUT/train_speed_cuda_torch.json" 2>&1 | tail -1
echo "-- end" >> "$OUT/gpu_util.csv"
kill $smi 2>/dev/null
echo "== pytest -m gpu"
tests="tests/train/test_cuda.py tests/render/test_raster_gsplat.py"
[ "${QUICK:-0}" = 1 ] || tests="$tests tests/entropy/test_determinism.py tests/determinism/test_check_vectors.py"
timeout 200 python3 -m pytest -q -p no:cacheprovider -o addopts="" -m gpu --durations=12 \
    $tests > "$OUT/pytest_gpu.log" 2>&1
echo "pytest exit $?"; tail -3 "$OUT/pytest_gpu.log"
[ "${QUICK:-0}" = 1 ] && exit 0
echo "== csgs train --device cuda, then decode"
rm -rf /tmp/syn && csgs synthetic /tmp/syn --objects 4 --gaussians 1500 --views 16 \
    --size 512x384 -q > "$OUT/train_cli.log" 2>&1
timeout 120 bash -c "$(declare -f csgs); csgs train /tmp/syn -o /tmp/syn.csgs --device cuda \
    --iterations 2000 --points /tmp/syn/scene.ply -q" >> "$OUT/train_cli.log" 2>&1
echo "train exit $?" | tee -a "$OUT/train_cli.log"
csgs decode /tmp/syn.csgs -o /tmp/syn_decoded.ply -q >> "$OUT/train_cli.log" 2>&1
echo "decode exit $?" | tee -a "$OUT/train_cli.log"; tail -4 "$OUT/train_cli.log"
