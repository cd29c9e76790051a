"""Registers, spills and stack of shading-kernel variants on sm_90, without a GPU.

    python scripts/kernel_registers.py [--arch 90]

Builds the CUDA PTX of the shading kernel (``warp_sg.shading.kernel.shade_kernel``) with Warp's NVRTC for
the features of ``examples/cook_torrance.toml`` (environment SG diffuse and prefiltered specular, a
light, SSDF shadows, per-vertex environment visibility) and of its all-Lambert version, each as the
generic all-model kernel and as the variant specialised to the scene's material models
(``brdf.kernel.material_variants``), and reports what ``ptxas -v`` allocates for each: registers per
thread, spill stores / loads and stack bytes. Needs ``ptxas`` on the PATH (CUDA toolkit). A
static figure, not a timing: fewer spills and less stack mean less local-memory traffic per
thread; the frame-time effect needs a GPU run.

NVRTC may write a newer PTX ISA version than the local ``ptxas`` accepts; the version line is
lowered to the one ``ptxas`` names in its error (the kernels use no newer instructions), and the
trailing NUL of NVRTC's output is dropped.
"""
from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import warp as wp


def ptxas_info(ptx: Path, arch: int) -> dict:
    text = ptx.read_text().replace("\0", "")
    for _ in range(2):
        fixed = ptx.with_suffix(".fixed.ptx")
        fixed.write_text(text)
        r = subprocess.run(["ptxas", f"-arch=sm_{arch}", "-v", str(fixed), "-o", "/dev/null"],
                           capture_output=True, text=True)
        log = r.stdout + r.stderr
        m = re.search(r"Unsupported \.version [\d.]+; current version is '([\d.]+)'", log)
        if not m:
            break
        text = re.sub(r"^\.version [\d.]+", f".version {m.group(1)}", text, count=1, flags=re.M)
    block = log[log.find("cuda_kernel_forward"):]
    grab = {"registers": r"Used (\d+) registers", "spill_stores": r"(\d+) bytes spill stores",
            "spill_loads": r"(\d+) bytes spill loads", "stack": r"(\d+) bytes stack frame"}
    out = {}
    for k, pat in grab.items():
        m = re.search(pat, block)
        if m is None:
            raise RuntimeError(f"ptxas gave no '{k}' for {ptx.name}:\n{log[-2000:]}")
        out[k] = int(m.group(1))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", type=int, default=90)
    a = ap.parse_args(argv)
    if shutil.which("ptxas") is None:
        print("ptxas not found on the PATH (install the CUDA toolkit)")
        return 1
    wp.config.quiet = True
    wp.init()
    from warp_sg.brdf.kernel.material_variants import ALL_MODELS
    from warp_sg.brdf.registry import code_of
    from warp_sg.shading import kernel as S

    ct = S.Features(env_diffuse=S.ENV_SG, env_specular=S.ENV_PREFILTERED, lights=True, specular=True, shadows=True,
                    env_vis_vertex=True, models=(code_of("lambert"), code_of("cook_torrance")))
    lam = replace(ct, specular=False, env_specular=S.ENV_NONE, models=(code_of("lambert"),))
    rows = [("cook_torrance", ct), ("cook_torrance, all Lambert", lam)]
    print("| scene features | kernel | models | registers | spill stores / loads B | stack B |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, f in rows:
            for kind, ff in (("specialised", f), ("generic", replace(f, models=tuple(sorted(ALL_MODELS))))):
                k = S.shade_kernel(ff)
                d = Path(tmp) / k.key
                d.mkdir()
                wp.compile_aot_module(k.module, arch=a.arch, use_ptx=True, module_dir=str(d))
                info = ptxas_info(next(d.glob("*.ptx")), a.arch)
                ms = ", ".join(map(str, ff.models)) if kind == "specialised" else "all"
                print(f"| {name} | {kind} | {ms} | {info['registers']} | {info['spill_stores']} / "
                      f"{info['spill_loads']} | {info['stack']} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
