#!/usr/bin/env bash
# The main job on the bundled sample scene. Grows with the codec: each step uses only what
# exists end to end. Usage: scripts/demo.sh VENV OUTDIR
set -euo pipefail
venv=${1:-.venv}
out=${2:-demo-output}
csgs="$venv/bin/csgs"
scene=samples/donut.ply
mkdir -p "$out"

echo "== csgs info $scene"
"$csgs" info "$scene"
