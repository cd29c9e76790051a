#!/usr/bin/env bash
# Wheels for a machine with a GPU but no network access, in parts of at most 55 MiB.
#
# Such a machine may have Python 3.12 with numpy, scipy, tqdm, matplotlib, Pillow and OpenCV but
# no warp-lang, trimesh, OpenEXR or pydantic (docs/benchmarks.md "CUDA on a machine with a GPU").
# They travel as wheels: tarred and split into 55 MiB parts, one folder each (.gpu/p1, .gpu/p2, ...;
# ignored by git), which can be copied one at a time into one folder on that machine; there
#
#   bash scripts/gpu_check.sh --parts DIR OUT_DIR
#
# assembles them, installs into /tmp/site and runs the checks. Versions are the ones installed
# here, so the GPU run uses the code CI tests.
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
