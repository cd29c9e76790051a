r"""The accuracy matrix: scenes written as users write them, checked against an independent renderer.

Each :class:`Case` is a scene file made by :func:`write_case`: a floor of two triangles (Lambert),
one object (an icosphere ``sphere``, warp-lang's Stanford ``bunny``, the scanned ``head`` of
``shared/assets/LeePerrySmith.glb``), one material of :data:`MATERIALS` (every model of the scene
format at low, medium and high roughness; GGX as a per-channel conductor, as a dielectric and
anisotropic; a measured MERL file) and one light (:data:`LIGHTS`: a sun-sky EXR written here, each
Poly Haven HDRI of ``shared/assets``, a point light, a directional light); ``pose`` moves a
``dynamic = true`` object with ``Renderer.set_object_transform`` after the precompute
(:data:`POSES`). ``scripts/mitsuba_refs.py`` renders every case with Mitsuba 3 into
``tests/data/mitsuba/`` (:func:`reference_path`, ``manifest.json``); the suite renders the cases with
the renderer and compares per region (:mod:`warp_sg.groundtruth.region_error`) with those
references and with the per-region figures of ``tests/data/accuracy_baseline.json`` (the regression
gate, :func:`gate_failures`).

Cases that share object, light and pose form a group (:func:`groups`): one renderer, its materials
switched with ``Renderer.set_material`` (no precompute between them).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warp_sg.scene.plain_scenes import (
    BUNNY_PLACEMENT,
    sun_direction,
    toml_table,
    warp_bunny,
    write_floor_obj,
    write_sphere_ply,
)
from warp_sg.scene.plain_scenes import MATERIALS as PLAIN_MATERIALS

#: gold as users write it: per-channel η and k (Johnson & Christy 1972 at 650, 550, 450 nm)
GOLD = {"eta": [0.143, 0.375, 1.442], "k": [3.983, 2.386, 1.603]}
COPPER = {"eta": [0.200, 0.924, 1.102], "k": [3.912, 2.452, 2.142]}

#: material name → ``[materials.object]`` table
MATERIALS: dict[str, dict] = {
    "lambert": PLAIN_MATERIALS["lambert"],
    "oren_nayar_0.3": {"model": "oren_nayar", "kd": [0.6, 0.5, 0.4], "sigma": 0.3},
    "oren_nayar_0.8": {"model": "oren_nayar", "kd": [0.6, 0.5, 0.4], "sigma": 0.8},
    "phong_8": {"model": "phong", "kd": [0.4, 0.3, 0.25], "ks": [0.3, 0.3, 0.3], "n": 8.0},
    "phong_60": {"model": "phong", "kd": [0.3, 0.2, 0.15], "ks": [0.4, 0.4, 0.4], "n": 60.0},
    "phong_400": {"model": "phong", "kd": [0.3, 0.2, 0.15], "ks": [0.3, 0.3, 0.3], "n": 400.0},
    "blinn_phong_10": {"model": "blinn_phong", "kd": [0.4, 0.3, 0.25], "ks": [0.3, 0.3, 0.3], "n": 10.0},
    "blinn_phong_50": {"model": "blinn_phong", "kd": [0.15, 0.15, 0.15], "ks": [0.6, 0.6, 0.6], "n": 50.0},
    "blinn_phong_500": {"model": "blinn_phong", "kd": [0.3, 0.2, 0.15], "ks": [0.2, 0.2, 0.2], "n": 500.0},
    "cook_torrance_0.1": {"model": "cook_torrance", "kd": [0.1, 0.1, 0.12], "ks": [0.8, 0.8, 0.8], "m": 0.1,
                          "fresnel": {"schlick": 0.9}},
    "cook_torrance_0.25": {"model": "cook_torrance", "kd": [0.2, 0.2, 0.25], "ks": [0.8, 0.8, 0.8], "m": 0.25,
                           "fresnel": {"schlick": 0.9}},
    "cook_torrance_0.5": {"model": "cook_torrance", "kd": [0.2, 0.2, 0.25], "ks": [0.8, 0.8, 0.8], "m": 0.5,
                          "fresnel": {"schlick": 0.9}},
    "torrance_sparrow_0.1": {"model": "torrance_sparrow", "kd": [0.1, 0.1, 0.1], "ks": [0.9, 0.9, 0.9], "m": 0.1,
                             "fresnel": COPPER},
    "torrance_sparrow_0.35": {"model": "torrance_sparrow", "kd": [0.2, 0.15, 0.1], "ks": [0.8, 0.8, 0.8],
                              "m": 0.35, "fresnel": {"eta": 1.5}},
    "ward_0.08": {"model": "ward", "kd": [0.2, 0.2, 0.2], "ks": [0.3, 0.3, 0.3], "alpha": 0.08},
    "ward_0.2": {"model": "ward", "kd": [0.3, 0.3, 0.3], "ks": [0.5, 0.5, 0.5], "alpha": 0.2},
    "ward_0.45": {"model": "ward", "kd": [0.3, 0.3, 0.3], "ks": [0.5, 0.5, 0.5], "alpha": 0.45},
    "ward_aniso": {"model": "ward", "kd": [0.2, 0.2, 0.2], "ks": [0.5, 0.5, 0.5], "alpha_x": 0.35, "alpha_y": 0.08},
    "ashikhmin_shirley_iso": {"model": "ashikhmin_shirley", "kd": [0.3, 0.25, 0.2], "ks": [0.6, 0.6, 0.6],
                              "nu": 200.0, "nv": 200.0, "fresnel": {"schlick": 0.5}},
    "ashikhmin_shirley_aniso": {"model": "ashikhmin_shirley", "kd": [0.2, 0.2, 0.25], "ks": [0.7, 0.7, 0.7],
                                "nu": 20.0, "nv": 400.0, "fresnel": {"schlick": 0.5}},
    "lafortune_mirror": {"model": "lafortune", "kd": [0.4, 0.3, 0.2], "ks": [1.0, 1.0, 1.0],
                         "lobes": [{"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 30.0}]},
    "lafortune_retro": {"model": "lafortune", "kd": [0.3, 0.3, 0.3], "ks": [1.0, 1.0, 1.0],
                        "lobes": [{"cx": -0.9, "cy": -0.9, "cz": 0.8, "n": 12.0},
                                  {"cx": 0.6, "cy": 0.6, "cz": 0.6, "n": 8.0}]},
    "ggx_gold_0.05": {"model": "ggx", "kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "alpha": 0.05, "fresnel": GOLD},
    "ggx_gold_0.3": {"model": "ggx", "kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "alpha": 0.3, "fresnel": GOLD},
    "ggx_gold_0.7": {"model": "ggx", "kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "alpha": 0.7, "fresnel": GOLD},
    "ggx_dielectric_0.1": {"model": "ggx", "kd": [0.5, 0.1, 0.08], "ks": [1.0, 1.0, 1.0], "alpha": 0.1,
                           "fresnel": {"eta": 1.5}},
    "ggx_dielectric_0.4": {"model": "ggx", "kd": [0.1, 0.3, 0.5], "ks": [1.0, 1.0, 1.0], "alpha": 0.4,
                           "fresnel": {"eta": 1.5}},
    "ggx_aniso": {"model": "ggx", "kd": [0.0, 0.0, 0.0], "ks": [1.0, 1.0, 1.0], "alpha_x": 0.4, "alpha_y": 0.1,
                  "fresnel": COPPER},
    "measured": {"model": "measured", "file": "measured.binary", "lobes": 2},
}
#: materials with a specular lobe (object rel. MSE target 3 %; diffuse 1 %)
DIFFUSE = ("lambert", "oren_nayar_0.3", "oren_nayar_0.8")

#: the sun-sky written to EXR (not plain_scenes' sky): 1024 × 512, a sun of the real sun's angular
#: radius (0.27°, less than a texel) and radiance 2e5 at 30° elevation, a halo and a blue gradient
SUNSKY = {"width": 1024, "height": 512, "elevation": 30.0, "azimuth": 40.0, "sun_radius": 0.00465,
          "sun_radiance": 2.0e5, "halo": 0.1, "sky_intensity": 0.8}
#: the same sky with the sun low and behind the object (backlit: grazing glints, the sun hidden by the object)
BACKLIT = {**SUNSKY, "elevation": 14.0, "azimuth": 155.0}
#: the Poly Haven HDRIs of shared/assets
HDRIS = ("venice_sunset_1k.hdr", "pedestrian_overpass_1k.hdr", "moonless_golf_1k.hdr", "blouberg_sunrise_2_1k.hdr",
         "spot1Lux.hdr")
LIGHTS = ("sunsky", "backlit", "point", "sun", *(f"hdr:{h}" for h in HDRIS))
#: Mitsuba's max_depth of the cases with interreflection (as warp_sg.groundtruth.reference's full depth)
FULL_DEPTH = 8
#: poses of a dynamic object: translations applied after the precompute
POSES = {0: (0.0, 0.0, 0.0), 1: (0.9, 0.0, 0.0), 2: (-0.7, 0.0, 0.6)}
#: scanned head placement: LeePerrySmith.glb's bounds are ±(4.28, 3.97, 2.59); 1 unit tall on the floor
HEAD_PLACEMENT = {"scale": 0.126, "translate": [0.0, 0.5, 0.0]}


@dataclass(frozen=True)
class Case:
    """One scene of the matrix (module docstring). ``name`` is unique; ``size`` the image side."""

    obj: str
    light: str
    material: str
    pose: int | None = None
    size: int = 64
    #: path segments of the reference (Mitsuba's max_depth): 2 = direct light, the paper's transport
    #: (the scene gets ``[render] bounces = 0``); FULL_DEPTH = with interreflection (default bounces)
    depth: int = 2

    @property
    def name(self) -> str:
        light = self.light.replace("hdr:", "").replace("_1k.hdr", "").replace(".hdr", "")
        pose = "" if self.pose is None else f"-pose{self.pose}"
        full = "" if self.depth == 2 else "-full"
        return f"{self.obj}-{light}-{self.material}{pose}{full}"

    @property
    def group(self) -> tuple:
        return self.obj, self.light, self.pose, self.size, self.depth

    @property
    def diffuse(self) -> bool:
        return self.material in DIFFUSE


def _cases() -> list[Case]:
    out = [Case("sphere", "sunsky", m) for m in MATERIALS]
    out += [Case("bunny", "sunsky", m) for m in ("lambert", "blinn_phong_50", "measured", "ggx_gold_0.3",
                                                 "ward_aniso", "cook_torrance_0.25")]
    out += [Case("sphere", "backlit", m) for m in ("ggx_gold_0.3", "cook_torrance_0.25", "lambert")]
    out += [Case("bunny", "backlit", m) for m in ("blinn_phong_50", "ggx_gold_0.3", "measured")]
    out += [Case("head", f"hdr:{h}", "lambert") for h in HDRIS]
    out += [Case("head", f"hdr:{h}", "ggx_gold_0.3") for h in ("pedestrian_overpass_1k.hdr", "venice_sunset_1k.hdr")]
    out += [Case("head", "sunsky", m) for m in ("lambert", "blinn_phong_50")]
    out += [Case("head", "point", "lambert")]
    out += [Case("sphere", "point", m) for m in ("lambert", "cook_torrance_0.25", "ward_0.2", "ggx_gold_0.3",
                                                 "blinn_phong_500")]
    out += [Case("sphere", "sun", m) for m in ("lambert", "blinn_phong_50", "ggx_dielectric_0.1")]
    out += [Case("sphere", "hdr:pedestrian_overpass_1k.hdr", m) for m in ("ggx_gold_0.05", "cook_torrance_0.25")]
    out += [Case("bunny", "hdr:venice_sunset_1k.hdr", m) for m in ("lambert", "blinn_phong_50")]
    out += [Case("bunny", "point", m) for m in ("lambert", "ggx_gold_0.3")]
    out += [Case("sphere", "sunsky", "lambert", pose=p) for p in POSES]
    out += [Case("sphere", "point", "lambert", pose=1)]
    # with interreflection, against Mitsuba at full depth (the renderer's default bounces)
    out += [Case("head", f"hdr:{h}", "lambert", depth=FULL_DEPTH)
            for h in ("moonless_golf_1k.hdr", "pedestrian_overpass_1k.hdr", "venice_sunset_1k.hdr")]
    out += [Case("head", "hdr:pedestrian_overpass_1k.hdr", "ggx_gold_0.3", depth=FULL_DEPTH)]
    out += [Case("bunny", "sunsky", m, depth=FULL_DEPTH) for m in ("lambert", "blinn_phong_50")]
    out += [Case("sphere", "point", "lambert", depth=FULL_DEPTH)]
    return out


#: every case, in a fixed order
CASES: list[Case] = _cases()
BY_NAME: dict[str, Case] = {c.name: c for c in CASES}


def groups(cases=None) -> dict[tuple, list[Case]]:
    """Cases by (object, light, pose, size, depth), in case order."""
    out: dict[tuple, list[Case]] = {}
    for c in CASES if cases is None else cases:
        out.setdefault(c.group, []).append(c)
    return out


def shared_assets() -> Path | None:
    """The shared inputs' folder: ``$WARP_SG_SHARED_ASSETS``, else ``shared/assets`` beside the
    repository or one of its parents; None when absent."""
    env = os.environ.get("WARP_SG_SHARED_ASSETS")
    if env:
        return Path(env) if Path(env).is_dir() else None
    root = Path(__file__).resolve().parents[2]
    for up in (root.parent, *root.parents):
        if (up / "shared" / "assets").is_dir():
            return up / "shared" / "assets"
    return None


def needs_shared(case: Case) -> bool:
    return case.obj == "head" or case.light.startswith("hdr:")


def write_sunsky(path: Path, s: dict = SUNSKY) -> Path:
    """The matrix's sun-sky EXR (:data:`SUNSKY`, or :data:`BACKLIT`)."""
    from warp_sg.core.image_io import save_image
    from warp_sg.scene.sky import procedural_sky

    sky = procedural_sky(s["width"], s["height"], sun_direction=tuple(sun_direction(s["elevation"], s["azimuth"])),
                         sun_angular_radius=s["sun_radius"], sun_intensity=s["sun_radiance"], halo=s["halo"],
                         sky_intensity=s["sky_intensity"])
    save_image(path, sky)
    return path


def write_measured(path: Path) -> Path:
    """The measured material's MERL file: a tabulated glossy plastic (GGX α = 0.15 with a dielectric's
    Fresnel over an orange diffuse base), the kind of table a gonioreflectometer gives."""
    from warp_sg.brdf import make_model, merl

    m = make_model("ggx", kd=[0.35, 0.12, 0.04], ks=[1.0, 1.0, 1.0], alpha=0.15, fresnel={"eta": 1.5})
    merl.write_merl(path, merl.tabulate(m))
    return path


def write_case(case: Case, folder) -> Path:
    """Write ``case``'s scene into ``folder`` and return its ``scene.toml`` (shared inputs by absolute
    path; FileNotFoundError when they are absent)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    shared = shared_assets() if needs_shared(case) else None
    if needs_shared(case) and shared is None:
        raise FileNotFoundError("shared/assets is absent")
    write_floor_obj(folder / "floor.obj")
    if case.obj == "sphere":
        ob = {"mesh": write_sphere_ply(folder / "sphere.ply").name}
    elif case.obj == "bunny":
        ob = {"mesh": warp_bunny().as_posix(), **BUNNY_PLACEMENT}
    elif case.obj == "head":
        ob = {"mesh": (shared / "LeePerrySmith.glb").as_posix(), **HEAD_PLACEMENT}
    else:
        raise ValueError(f"unknown object {case.obj!r}")
    ob = {**ob, "material": "object", "name": "object"}
    if case.pose is not None:
        ob["dynamic"] = True
    mat = dict(MATERIALS[case.material])
    if mat["model"] == "measured" and not (folder / mat["file"]).is_file():
        write_measured(folder / mat["file"])
    parts = [toml_table("camera", {"origin": [0.0, 2.2, 3.6], "target": [0.0, 0.35, 0.0], "fov": 40.0,
                               "width": case.size, "height": case.size}),
             toml_table("objects", ob, array=True),
             toml_table("objects", {"mesh": "floor.obj", "material": "floor", "name": "floor"}, array=True),
             toml_table("materials.object", mat), toml_table("materials.floor", PLAIN_MATERIALS["lambert"])]
    if case.light in ("sunsky", "backlit"):
        sky = f"{case.light}.exr"
        if not (folder / sky).is_file():
            write_sunsky(folder / sky, SUNSKY if case.light == "sunsky" else BACKLIT)
        parts.append(toml_table("lights", {"type": "environment", "file": sky}, array=True))
    elif case.light.startswith("hdr:"):
        parts.append(toml_table("lights", {"type": "environment", "file": (shared / case.light[4:]).as_posix()},
                            array=True))
    elif case.light == "point":
        parts.append(toml_table("lights", {"type": "point", "position": [1.6, 3.0, 1.4], "radius": 0.15,
                                       "intensity": [9.0, 9.0, 9.0]}, array=True))
    elif case.light == "sun":
        parts.append(toml_table("lights", {"type": "directional", "direction": sun_direction().tolist(),
                                       "radius": 0.03, "intensity": [3.0, 2.9, 2.7]}, array=True))
    else:
        raise ValueError(f"unknown light {case.light!r}")
    if case.depth == 2:  # the direct light of a max_depth = 2 reference
        parts.append(toml_table("render", {"bounces": 0}))
    path = folder / "scene.toml"
    path.write_text("".join(parts))
    return path


def pose_matrix(case: Case) -> np.ndarray | None:
    """The 4×4 motion of ``case``'s dynamic object (None: static)."""
    if case.pose is None:
        return None
    m = np.eye(4)
    m[:3, 3] = POSES[case.pose]
    return m


def load_case(case: Case, folder):
    """``(scene, path)``: the case's scene loaded, its dynamic object at the case's pose."""
    from warp_sg.scene import load_scene

    path = write_case(case, folder)
    scene = load_scene(path)
    m = pose_matrix(case)
    if m is not None:
        scene.objects[0].motion = m
    return scene, path


# --------------------------------------------------------------------------------------------
# stored references and the regression gate
# --------------------------------------------------------------------------------------------
DATA = Path(__file__).resolve().parents[2] / "tests" / "data"
REFERENCES = DATA / "mitsuba"
BASELINE = DATA / "accuracy_baseline.json"
REGIONS = ("object", "lit_floor", "shadow", "silhouette")
#: targets per region (|bias|), and object rel. MSE (diffuse, glossy)
TARGET_BIAS = {"object": 0.03, "lit_floor": 0.02, "shadow": 0.10, "silhouette": 0.10}
TARGET_OBJECT_REL_MSE = {True: 0.01, False: 0.03}
#: a shadow whose relative bias is over its target still passes when its mean error is at most this
#: fraction of the lit floor's mean (``leak``): the shadow of a lone light is near black, and a
#: relative bias of a near-black region says little (10 % of a shadow at 6 % of the lit floor is 0.6 %)
TARGET_SHADOW_LEAK = 0.01
#: a region is worse when its |bias| grew by more than this (absolute) or its rel. MSE by this factor
GATE_BIAS = 0.01
GATE_REL_MSE = 1.2


#: scenes that miss a target, and why (measured; tests/test_accuracy_matrix.py fails if one starts to meet it)
KNOWN_MISSES: dict[str, str] = {
    "bunny-venice_sunset-blinn_phong_50": (
        "glossy lobes that straddle the floor's horizon under a sunset whose brightest band lies just above "
        "it: the half-space cut (eq. 25-31) and the visible part's mean radiance read from ΓL one lobe "
        "(visible_lobe) take too little of that band. Against our reference (512 spp): -5.0 % with the "
        "floor, -0.8 % without it; reading the visible part as two lobes moved it to -4.7 % only"),
    "head-venice_sunset-ggx_gold_0.3": (
        "the same cut on a concave scan under the same sunset: with shadows off the object is +16 %, the "
        "lobes' visibility takes about 4.5 % too much (red, the sunset's band; our reference agrees with "
        "Mitsuba within 0.4 %)"),
    "head-pedestrian_overpass-ggx_gold_0.3-full": (
        "direct light -2.8 % (within the target) plus the glossy receivers' indirect light, gathered through "
        "32 fixed world lobes of sharpness 8 (warp_sg.shading.bounce), about 0.5 points short (64 lobes of "
        "sharpness 12: -4.1 %)"),
    "bunny-sunsky-blinn_phong_50-full": (
        "the glossy receivers' indirect light through the same fixed lobes: 32 of sharpness 8 (the warm frame "
        "with bounces 1.25x the frame without; 64 of sharpness 12 cost 1.55x, over the bound of 1.5x) give "
        "+3.1 % on the object where 64 gave +2.4 %: a per-receiver lobe set would remove the trade"),
}


def reference_path(case: Case) -> Path:
    return REFERENCES / f"{case.name}.npz"


def load_reference(case: Case) -> dict:
    """``{"image", "stderr", "masks": {region: bool (H, W)}, "spp"}`` of a stored reference."""
    with np.load(reference_path(case)) as z:
        h, w = z["image"].shape[:2]
        masks = {r: np.unpackbits(z[f"mask_{r}"])[: h * w].reshape(h, w).astype(bool) for r in REGIONS}
        return {"image": z["image"].astype(np.float32), "stderr": z["stderr"].astype(np.float32), "masks": masks,
                "spp": int(z["spp"])}


def save_reference(case: Case, image, stderr, masks: dict, spp: int) -> Path:
    """Store a reference (float16 image and standard error, packed region masks) atomically."""
    from warp_sg.core.files import atomic_output

    REFERENCES.mkdir(parents=True, exist_ok=True)
    path = reference_path(case)
    arrays = {"image": np.asarray(image, np.float16), "stderr": np.asarray(stderr, np.float16),
              "spp": np.int64(spp)}
    for r in REGIONS:
        arrays[f"mask_{r}"] = np.packbits(np.asarray(masks[r], bool).ravel())
    with atomic_output(path) as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return path


def errors(case: Case, image: np.ndarray, ref: dict | None = None) -> dict:
    """Per-region ``{"bias", "rel_mse", "pixels"}`` of ``image`` against the stored reference
    (rel. MSE net of the reference's own noise)."""
    from warp_sg.groundtruth.region_error import region_errors

    ref = load_reference(case) if ref is None else ref
    e = region_errors(np.asarray(image, np.float32), ref["image"], ref["masks"], stderr=ref["stderr"])
    out = {r: {"bias": float(e[r]["bias"]), "rel_mse": float(e[r]["rel_mse"]), "pixels": int(e[r]["pixels"])}
           for r in REGIONS if r in e and e[r]["pixels"] > 0}
    if "shadow" in out and "leak" in e["shadow"]:
        out["shadow"]["leak"] = float(e["shadow"]["leak"])
    return out


def target_failures(case: Case, errs: dict) -> list[str]:
    """The issue's targets that ``errs`` misses, one line each."""
    out = []
    for r, lim in TARGET_BIAS.items():
        if r in errs and errs[r]["pixels"] >= 20 and abs(errs[r]["bias"]) > lim:
            leak = errs[r].get("leak")
            if r == "shadow" and leak is not None and abs(leak) <= TARGET_SHADOW_LEAK:
                continue  # a dark shadow: its error is within 1 % of the lit floor's brightness
            out.append(f"{case.name} {r}: bias {errs[r]['bias']:+.1%} (target ±{lim:.0%})")
    lim = TARGET_OBJECT_REL_MSE[case.diffuse]
    if "object" in errs and errs["object"]["rel_mse"] > lim:
        out.append(f"{case.name} object: rel. MSE {errs['object']['rel_mse']:.4f} (target {lim})")
    return out


def load_baseline() -> dict:
    return json.loads(BASELINE.read_text()) if BASELINE.is_file() else {}


def gate_failures(case: Case, errs: dict, baseline: dict | None = None) -> list[str]:
    """Regions of ``case`` worse than the baseline file: |bias| up by more than one percentage point,
    or rel. MSE up by more than 20 % (and by more than 1e-4, below which the noise rules)."""
    base = (load_baseline() if baseline is None else baseline).get(case.name, {})
    out = []
    for r, b in base.items():
        if r not in errs:
            continue
        e = errs[r]
        if abs(e["bias"]) > abs(b["bias"]) + GATE_BIAS:
            out.append(f"{case.name} {r}: |bias| {abs(e['bias']):.2%} > baseline {abs(b['bias']):.2%} + 1 point")
        if e["rel_mse"] > GATE_REL_MSE * b["rel_mse"] and e["rel_mse"] - b["rel_mse"] > 1e-4:
            out.append(f"{case.name} {r}: rel. MSE {e['rel_mse']:.5f} > 1.2 × baseline {b['rel_mse']:.5f}")
    return out


def render_group(cases: list[Case], folder, device: str = "cpu") -> dict[str, np.ndarray]:
    """Our images of a group's cases: one renderer, the material switched between cases."""
    from warp_sg.renderer.renderer import Renderer

    out = {}
    r = None
    for c in cases:
        scene, _ = load_case(c, Path(folder) / c.name)
        if r is None:
            m = pose_matrix(c)
            if m is not None:
                scene.objects[0].motion = None  # built at rest, then moved: what a user's animation does
            r = Renderer(scene, device=device)
            if m is not None:
                r.set_object_transform("object", m)
        else:
            mat = scene.materials["object"]
            params = dict(mat.params)
            if "file" in params:  # relative to the case's scene file
                params["file"] = str(Path(scene.path).parent / params["file"])
            r.set_material("object", model=mat.model, **params)
        out[c.name] = r.render()
    return out


__all__ = ["Case", "CASES", "BY_NAME", "MATERIALS", "LIGHTS", "POSES", "groups", "write_case", "load_case",
           "pose_matrix", "shared_assets", "needs_shared", "reference_path", "load_reference", "save_reference",
           "errors", "target_failures", "gate_failures", "load_baseline", "render_group", "REGIONS", "TARGET_BIAS",
           "KNOWN_MISSES", "FULL_DEPTH"]
