#!/usr/bin/env bash
# CUDA checks for a machine with a GPU; about 5-8 minutes. Prints what it measures.
#   bash scripts/gpu_check.sh [--parts DIR] [OUT_DIR]
# --parts DIR: install the wheels of scripts/gpu_bundle.sh (its parts, stashed in DIR by earlier
# copies) into /tmp/site first, for a GPU machine without warp-lang, trimesh, OpenEXR or pydantic.
set -uo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--parts" ]; then
    mkdir -p /tmp/gpu_wheels
    cat "$2"/part.* | tar -xf - -C /tmp/gpu_wheels || { echo "cannot assemble the parts in $2"; exit 2; }
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
        /tmp/gpu_wheels/wheels/*.whl || exit 2
    export PYTHONPATH="/tmp/site:$PWD${PYTHONPATH:+:$PYTHONPATH}"
    shift 2
fi
export PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1
OUT="${1:-out/gpu_check}"
mkdir -p "$OUT"
export WARP_SG_CACHE_DIR="${WARP_SG_CACHE_DIR:-$(mktemp -d)}"
rc=0
echo "== nvidia-smi"; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv || true
echo "== CUDA-marked and device-parametrised tests"
# (modules whose optional imports are missing there, e.g. pyvista, are reported and skipped)
python3 -m pytest -q -o addopts="" -p no:cacheprovider --continue-on-collection-errors -k "cuda" tests 2>&1 \
    | tee "$OUT/pytest_cuda.log" | tail -15 || rc=1
echo "== CPU vs CUDA agreement (render, reference)"
python3 scripts/gpu_check.py agree || rc=1
echo "== warp-sg bench --device cuda"
python3 -m warp_sg.tools.cli bench --device cuda -o "$OUT/bench_cuda.md" || rc=1
echo "== 1080p, ~1 M triangles, full shading"
python3 scripts/gpu_check.py fps || rc=1
exit $rc
