#!/usr/bin/env bash
# CUDA checks for a machine with a GPU (the device tool); about 5-8 minutes. Prints what it measures.
#   bash scripts/gpu_check.sh [OUT_DIR]
set -uo pipefail
cd "$(dirname "$0")/.."
OUT="${1:-out/gpu_check}"
mkdir -p "$OUT"
export WARP_SG_CACHE_DIR="${WARP_SG_CACHE_DIR:-$(mktemp -d)}"
rc=0
echo "== nvidia-smi"; nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv || true
echo "== CUDA-marked and device-parametrised tests"
python3 -m pytest -q -o addopts="" -k "cuda" tests 2>&1 | tail -15 || rc=1
echo "== CPU vs CUDA agreement (render, reference)"
python3 scripts/gpu_check.py agree || rc=1
echo "== warp-sg bench --device cuda"
warp-sg bench --device cuda -o "$OUT/bench_cuda.md" || rc=1
echo "== 1080p, ~1 M triangles, full shading"
python3 scripts/gpu_check.py fps || rc=1
exit $rc
