#!/usr/bin/env bash
# Download the wheels scripts/gpu_check.sh installs on a GPU machine that has no network:
# constriction (the range coder) and gsplat 1.5.3 with the pure-Python packages it imports
# (its CUDA kernels are compiled there from the sources inside its wheel). Python 3.12,
# manylinux x86_64, into .whl/ (ignored by git; carry it to the machine).
set -eu
cd "$(dirname "$0")/.."
mkdir -p .whl
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --platform manylinux2014_x86_64 --dest .whl \
    constriction==0.5.0 gsplat==1.5.3 jaxtyping wadler-lindig ninja rich markdown-it-py \
    mdurl pygments
ls .whl
