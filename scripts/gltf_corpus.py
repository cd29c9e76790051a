"""Render every glTF file of a folder as a user would, and count what happens.

The corpus is the Khronos glTF-Validator's own test suite (Apache-2.0; the ``test/`` folder of
https://github.com/KhronosGroup/glTF-Validator: 372 ``.gltf``/``.glb`` files, malformed and valid,
each beside the validator's report ``FILE.report.json``); a few of them are committed in
``tests/data/gltf_validator/`` (``tests/test_gltf_spec.py``). Each file is rendered small by the
command line (``warp-sg render FILE -o OUT.png --width 24 --height 16 --no-shadows``) in the
worker of ``scripts/outcomes.py`` and sorted into rendered / refused / traceback / noise / hang /
kill; the validator's verdict (its report's ``numErrors``) splits the counts into files it finds
valid and invalid. The targets: no traceback, hang or kill; no message quoting an exception class;
every file the validator finds valid rendered, or refused only for having nothing to draw::

    python scripts/gltf_corpus.py /path/to/glTF-Validator/test [--json out.json] [--list refused]

Most of the validator's files hold no drawable mesh (they test one JSON rule each), so
``--add-quad`` runs a second pass on copies of them (in a temporary folder, beside their own
``.bin`` and image files) with one valid textured-free quad added — a mesh, a node in the
default scene, a base64 buffer: a file the validator finds valid stays valid and must now
render; every other file must still be refused in one line or render.

Exit status 0 when the targets are met, 1 otherwise.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from outcomes import Runner, summary

#: the refusals a valid file may get: it has nothing this renderer draws, or the specification
#: asks a loader to refuse it (a newer ``minVersion``, a required extension it does not implement)
NOTHING_TO_DRAW = ("no triangles", "nothing to draw", "asset.minVersion", "extensionsRequired")


def validator_errors(path: Path) -> int | None:
    rep = path.with_name(path.name + ".report.json")
    if not rep.is_file():
        return None
    return int(json.loads(rep.read_text())["issues"]["numErrors"])


QUAD = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
QUAD_INDICES = np.array([0, 2, 1, 0, 3, 2], np.uint16)


def with_quad(header: dict) -> dict:
    """``header`` with one more buffer (a data: URI), two accessors, a mesh and a node holding it,
    the node added to the default scene (or left a root where the file has no scenes)."""
    import base64

    h = json.loads(json.dumps(header))
    data = QUAD.tobytes() + QUAD_INDICES.tobytes()
    lists = {k: h.get(k) if isinstance(h.get(k), list) else [] for k in
             ("buffers", "bufferViews", "accessors", "meshes", "nodes")}
    b, v, a = len(lists["buffers"]), len(lists["bufferViews"]), len(lists["accessors"])
    lists["buffers"].append({"byteLength": len(data),
                             "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()})
    lists["bufferViews"] += [{"buffer": b, "byteOffset": 0, "byteLength": 48},
                             {"buffer": b, "byteOffset": 48, "byteLength": 12}]
    lists["accessors"] += [{"bufferView": v, "componentType": 5126, "count": 4, "type": "VEC3",
                            "min": [-1, 0, -1], "max": [1, 0, 1]},
                           {"bufferView": v + 1, "componentType": 5123, "count": 6, "type": "SCALAR"}]
    lists["meshes"].append({"primitives": [{"attributes": {"POSITION": a}, "indices": a + 1}]})
    lists["nodes"].append({"mesh": len(lists["meshes"]) - 1})
    h.update(lists)
    scenes = h.get("scenes")
    if isinstance(scenes, list) and scenes:
        k = h.get("scene", 0)
        if isinstance(k, int) and 0 <= k < len(scenes) and isinstance(scenes[k], dict):
            scenes[k].setdefault("nodes", []).append(len(lists["nodes"]) - 1)
    return h


def quad_copies(folder: Path, files: list) -> tuple[Path, list]:
    """Copies of the corpus with a quad added to every file whose JSON reads (see ``--add-quad``)."""
    import shutil
    import struct

    dest = Path(tempfile.mkdtemp(prefix="gltf_corpus_quad_")) / "test"
    shutil.copytree(folder, dest)
    out = []
    for f in files:
        g = dest / f.relative_to(folder)
        raw = f.read_bytes()
        try:
            if f.suffix.lower() == ".glb":
                n = struct.unpack_from("<I", raw, 12)[0]
                h = json.loads(raw[20:20 + n])
                text = json.dumps(with_quad(h)).encode()
                text += b" " * (-len(text) % 4)
                rest = raw[20 + n + (-n % 4):]
                body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
                g.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
            else:
                g.write_text(json.dumps(with_quad(json.loads(raw))))
        except Exception:  # noqa: BLE001 - a file whose JSON does not read stays as it is
            pass
        out.append(g)
    return dest, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--json", type=Path, help="write every outcome here")
    ap.add_argument("--list", default="", help="print the cases of these outcomes (comma-separated; 'all')")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per file (default 120)")
    ap.add_argument("--limit", type=int, default=0, help="only the first N files")
    ap.add_argument("--add-quad", action="store_true", help="run copies of the files with a quad added (see above)")
    a = ap.parse_args(argv)
    files = sorted(p for p in a.folder.rglob("*") if p.suffix.lower() in (".gltf", ".glb"))
    if a.limit:
        files = files[:a.limit]
    reports = {str(f.relative_to(a.folder)): validator_errors(f) for f in files}
    if a.add_quad:
        a.folder, files = quad_copies(a.folder, files)
    out = Path(tempfile.mkdtemp(prefix="gltf_corpus_")) / "out.png"
    runner = Runner()
    results, verdicts = [], {}
    try:
        for i, f in enumerate(files):
            name = str(f.relative_to(a.folder))
            argv_ = ["render", str(f), "-o", str(out), "--width", "24", "--height", "16", "--no-shadows",
                     "--no-progress"]
            o = runner.run(name, {"argv": argv_}, timeout=a.timeout, output=str(out))
            n = reports[name]
            verdicts[name] = "unknown" if n is None else ("valid" if n == 0 else "invalid")
            results.append(o)
            print(f"[{i + 1}/{len(files)}] {o.outcome:9s} {verdicts[name]:7s} {name}: "
                  f"{(o.error or '; '.join(o.warnings))[:160]}", flush=True)
    finally:
        runner.close()
    bad_valid = [o for o in results if verdicts[o.name] == "valid" and o.outcome != "rendered"
                 and not (o.outcome == "refused" and any(s in o.error for s in NOTHING_TO_DRAW))]
    print()
    for v in ("valid", "invalid", "unknown"):
        sub = [o for o in results if verdicts[o.name] == v]
        if sub:
            print(f"{v:8s} {summary(sub)}")
    print(f"all      {summary(results)}")
    print(f"valid files not rendered (other than nothing to draw): {len(bad_valid)}")
    warned = Counter(w for o in results for w in o.warnings)
    print(f"warning lines: {sum(warned.values())} ({len(warned)} distinct)")
    shown = set(a.list.split(",")) if a.list else set()
    for o in results:
        if "all" in shown or o.outcome in shown or (o.internal and "internal" in shown):
            print(f"  {o.outcome}: {o.name}: {o.error or o.noise[:3]}")
    for o in bad_valid:
        print(f"  valid but {o.outcome}: {o.name}: {o.error or o.noise[:3]}")
    if a.json:
        a.json.write_text(json.dumps({"verdicts": verdicts, "outcomes": [o.as_dict() for o in results]}, indent=1))
    s = summary(results)
    failed = s.get("traceback", 0) + s.get("hang", 0) + s.get("kill", 0) + s.get("noise", 0) + s["internal"] \
        + s["left_output"] + len(bad_valid)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
