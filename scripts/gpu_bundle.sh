#!/usr/bin/env bash
# Wheels for the GPU machine, in parts that fit one device call each.
#
# The device tool's machine (docs/benchmarks.md "CUDA") has Python 3.12 with numpy, scipy, tqdm,
# matplotlib, Pillow and OpenCV, but no warp-lang, trimesh, OpenEXR or pydantic, and no network.
# They travel as wheels. warp-lang's wheel alone (~150 MB) is over one call's 64 MiB, so the
# wheels are tarred and split into 55 MiB parts, one folder each (.gpu/p1, .gpu/p2, ...; ignored by
# git), each carried by one call that stashes it on the (warm) machine; the last call assembles,
# installs into /tmp/site and runs the checks:
#
#   bash scripts/gpu_bundle.sh                          # here, with network
#   run(carry=[".gpu/p1"], command="mkdir -p /root/gpu_parts && cp .gpu/p1/* /root/gpu_parts/")
#   run(carry=[".gpu/p2"], command="cp .gpu/p2/* /root/gpu_parts/")    # … every part, back to back
#   run(command="bash scripts/gpu_check.sh --parts /root/gpu_parts $OUT", timeout_s=600)
#
# (The machine goes back 30 s after a call: make the calls back to back, or carry everything
# again.) Versions are the ones installed here, so the GPU run uses the code CI tests.
set -euo pipefail
cd "$(dirname "$0")/.."
PYV="${PYV:-3.12}"
PY="${PYTHON:-python3}"
rm -rf .gpu && mkdir -p .gpu/wheels
specs=$("$PY" - <<'PYEOF'
from importlib.metadata import version
for name in ("warp-lang", "trimesh", "OpenEXR", "pydantic", "pydantic-core", "annotated-types",
             "typing-inspection", "typing-extensions"):
    print(f"{name}=={version(name)}")
PYEOF
)
echo "wheels for Python $PYV: $(echo $specs | tr '\n' ' ')"
# shellcheck disable=SC2086
"$PY" -m pip download -q --no-deps --only-binary=:all: --python-version "$PYV" --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 \
    -d .gpu/wheels $specs
tar -C .gpu -cf - wheels | split -b 55m -d -a 1 - .gpu/part.
rm -rf .gpu/wheels
i=1
for p in .gpu/part.*; do
    mkdir -p ".gpu/p$i" && mv "$p" ".gpu/p$i/"
    i=$((i + 1))
done
du -sh .gpu/p* | sed 's/^/  /'
echo "carry each .gpu/pN in its own call (see the header of this script)"
