"""Compile every Warp kernel module of the project for CUDA ahead of time (no GPU needed).

    python scripts/cuda_aot_check.py [--arch 90]

Warp's NVRTC builds PTX for the given architecture on a machine without a CUDA driver, so the
CUDA path of every kernel (rasterizer, precompute, shading variants, reference) is at least
compiled on the CPU-only machines. Imports every module of ``warp_sg``, ``raster`` and
``precompute``, instantiates the shading kernel variants a scene can select (all features on, and
each feature off in turn; the all-features variant for representative material-model sets: one
diffuse, one microfacet, Lafortune, measured, GGX, and a mix; an SG-mixture environment and the
gradient variant), and calls ``wp.compile_aot_module(..., arch=ARCH, use_ptx=True)`` on
each module that holds kernels. Exits 1 and names the module when one fails.
"""
from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
import tempfile
from dataclasses import fields, replace

import warp as wp


def project_modules() -> list[str]:
    names = []
    for pkg in ("warp_sg", "raster", "precompute"):
        mod = importlib.import_module(pkg)
        names.append(pkg)
        names += [m.name for m in pkgutil.walk_packages(mod.__path__, pkg + ".")]
    return names


def shading_variants():
    from warp_sg.brdf.registry import code_of
    from warp_sg.shading import kernel as S

    def codes(*names):
        return tuple(code_of(n) for n in names)

    full = S.Features(env_diffuse=S.ENV_SG, env_specular=S.ENV_PREFILTERED, lights=True, specular=True,
                      shadows=True, textures=True, normal_maps=True, fh_sigmoid=False, env_vis_vertex=True,
                      light_vis_vertex=True, env_visible_vertex=True, emission=True, occlusion=True, coat=True,
                      vertex_colors=True, cutouts=True, moving=True, bounce=True)
    off = {"env_diffuse": S.ENV_NONE, "env_specular": S.ENV_NONE, "lights": False, "specular": False,
           "shadows": False, "textures": False, "normal_maps": False, "fh_sigmoid": True,
           "env_vis_vertex": False, "light_vis_vertex": False, "env_visible_vertex": False, "models": codes("lambert"),
           "emission": False, "occlusion": False, "coat": False, "vertex_colors": False, "cutouts": False,
           "moving": False, "env_mixture": False, "grad": False, "bounce": False}
    variants = [full] + [replace(full, **{f.name: off[f.name]}) for f in fields(S.Features)]
    # an environment given as its SG mixture (ENV_MIXTURE), and the gradient variant (its adjoint,
    # warp_sg.shading.kernel_grad) of the features a fit uses
    mixture = replace(full, env_mixture=True, env_specular=S.ENV_MIXTURE)
    variants += [mixture, replace(mixture, grad=True, moving=False, coat=False, cutouts=False)]
    # material-model variants (brdf.kernel.material_variants): Oren–Nayar, Cook–Torrance, Lafortune,
    # measured, GGX, and Lambert + Blinn–Phong + Ward + Ashikhmin–Shirley
    variants += [replace(full, models=ms) for ms in (codes("oren_nayar"), codes("cook_torrance"), codes("lafortune"),
                                                     codes("measured"), codes("ggx"),
                                                     codes("lambert", "blinn_phong", "ward", "ashikhmin_shirley"))]
    # the per-vertex diffuse environment sum needs ρd = kd/π and no normal maps (shading.EVTX)
    variants += [replace(full, normal_maps=False, models=codes("lambert", "cook_torrance"))]
    return [S.shade_kernel(f) for f in variants]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--arch", type=int, default=90)
    ap.add_argument("--only", default="", help="comma-separated substrings: compile only the modules whose name "
                                                "contains one (e.g. reference_wp,shading); default all")
    a = ap.parse_args()
    only = [x for x in a.only.split(",") if x]
    wp.config.quiet = True
    wp.init()
    mods = []
    for name in project_modules():
        importlib.import_module(name)
        m = wp.get_module(name)
        if m.kernels or m.functions:
            mods.append(m)
    mods += [k.module for k in shading_variants()]
    if only:
        mods = [m for m in mods if any(x in m.name for x in only)]
    failed = []
    with tempfile.TemporaryDirectory() as out:
        for m in mods:
            if not m.kernels:
                continue
            try:
                wp.compile_aot_module(m, arch=a.arch, use_ptx=True, module_dir=out)
                print(f"ok    {m.name} ({len(m.kernels)} kernels)")
            except Exception as e:  # noqa: BLE001 - report every module, then fail
                failed.append(m.name)
                print(f"FAIL  {m.name}: {type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}")
    print(f"{len(mods) - len(failed)} modules compiled for sm_{a.arch}, {len(failed)} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
