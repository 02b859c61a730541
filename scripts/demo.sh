#!/usr/bin/env bash
# The main job on the bundled sample scene: encode -> info -> decode -> compare, with
# before/after renders; then a short training run (all three stages) on a tiny synthetic
# scene. Usage: scripts/demo.sh VENV OUTDIR
set -euo pipefail
venv=${1:-.venv}
out=${2:-demo-output}
csgs="$venv/bin/csgs"
scene=samples/donut.ply
quality=${QUALITY:-6}
mkdir -p "$out"

echo "== the input: $scene"
"$csgs" info "$scene"

echo
echo "== encode at quality $quality"
"$csgs" encode "$scene" -o "$out/donut.csgs" --quality "$quality"

echo
echo "== what the bitstream holds"
"$csgs" info "$out/donut.csgs"

echo
echo "== decode the color layer"
"$csgs" decode "$out/donut.csgs" -o "$out/donut_decoded.ply"

echo
echo "== compare decoded with original (8 orbit views, 400x300, black background)"
"$csgs" compare "$scene" "$out/donut.csgs" --orbit 8 --size 400x300

echo
echo "== render before/after pictures"
"$csgs" render "$scene" --orbit 4 --size 400x300 -o "$out/original" --quiet
"$csgs" render "$out/donut.csgs" --orbit 4 --size 400x300 -o "$out/decoded" --quiet
echo "wrote $out/original/*.png and $out/decoded/*.png"

echo
echo "== train a tiny synthetic scene from images + instance masks (stages 1-3), then encode"
"$csgs" synthetic "$out/synthetic" --views 12 --size 64x48 --gaussians 200 --quiet
"$csgs" train "$out/synthetic" -o "$out/synthetic.csgs" --iterations 300 --anchors 150 \
    --features 16 --offsets 5 --semantic-iterations 60 --test-every 4
"$csgs" info "$out/synthetic.csgs"

echo
echo "== the trained anchor scene, rendered per view and baked into a standard SPZ file"
"$csgs" render "$out/synthetic.csgs" --orbit 4 --size 400x300 -o "$out/synthetic_views" --quiet
"$csgs" decode "$out/synthetic.csgs" -o "$out/synthetic.spz"
"$csgs" compare "$out/synthetic.csgs" "$out/synthetic.spz" --orbit 8 --size 400x300
echo "wrote $out/synthetic_views/*.png and $out/synthetic.spz"
