"""The renderer against Mitsuba 3 on the accuracy matrix (warp_sg.groundtruth.accuracy_matrix): scenes
written as users write them, per region (object, lit floor, shadow, silhouette band), against
references an independent path tracer rendered (tests/data/mitsuba, scripts/mitsuba_refs.py).

Two checks per scene: the issue's targets (object |bias| ≤ 3 %, lit floor ≤ 2 %, shadow ≤ 10 %,
silhouette ≤ 10 %, object rel. MSE ≤ 1 % diffuse / 3 % glossy; a shadow that nothing but the key
light lights is judged by its leak, see ``target_failures``), except the misses listed in
``accuracy_matrix.KNOWN_MISSES`` with their cause (docs/report/mitsuba_matrix.md); and the regression gate: no
region worse than tests/data/accuracy_baseline.json by more than one percentage point of bias or 20 %
of rel. MSE (the failure names the scene and the region). Improving a figure updates the baseline
(``python scripts/accuracy_matrix.py --write-baseline``) in the same commit."""
from __future__ import annotations

import json

import pytest

from warp_sg.groundtruth import accuracy_matrix as AM

#: scene → the target it misses and why (kept honest: a miss that disappears fails the test)
KNOWN_MISSES = AM.KNOWN_MISSES

GROUPS = AM.groups()


def test_every_case_has_a_stored_reference_with_its_manifest_entry():
    manifest = json.loads((AM.REFERENCES / "manifest.json").read_text())
    assert len(AM.CASES) >= 60
    for c in AM.CASES:
        assert AM.reference_path(c).is_file(), c.name
        entry = manifest[c.name]
        assert entry["material"] == AM.MATERIALS[c.material] and entry["light"] == c.light, c.name
        assert entry["spp"] >= 1024 and entry["mitsuba"].startswith("3."), c.name
        assert entry["max_depth"] == c.depth, c.name
    base = AM.load_baseline()
    assert set(base) == {c.name for c in AM.CASES}, "the baseline file covers exactly the matrix"


@pytest.fixture(scope="module")
def images(tmp_path_factory):
    cache = {}

    def get(group):
        if group not in cache:
            cases = GROUPS[group]
            if any(AM.needs_shared(c) for c in cases) and AM.shared_assets() is None:
                pytest.skip("shared/assets (the real HDRIs and the scanned head) is absent")
            cache[group] = AM.render_group(cases, tmp_path_factory.mktemp("matrix"))
        return cache[group]

    return get


@pytest.mark.slow
@pytest.mark.parametrize("group", list(GROUPS), ids=["-".join(str(x) for x in g[:3]) for g in GROUPS])
def test_matrix_scenes_meet_their_targets_and_no_region_is_worse_than_the_baseline(images, group):
    imgs = images(group)
    base = AM.load_baseline()
    worse, missed = [], []
    for c in GROUPS[group]:
        e = AM.errors(c, imgs[c.name])
        worse += AM.gate_failures(c, e, base)
        fails = AM.target_failures(c, e)
        if c.name in KNOWN_MISSES:
            assert fails, f"{c.name} now meets its targets: remove it from KNOWN_MISSES"
        else:
            missed += fails
    assert not worse, "\n".join(worse)
    assert not missed, "\n".join(missed)
