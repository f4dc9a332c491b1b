"""Joint recognition keeps its behaviour: roles, landmarks, bend triples and automatic
joint maps on every rig of the shared corpus equal the record made before
``ops/roles.py``, ``anthropometry.py`` and ``ops/jointmap.py`` shared one core
(``tests/data/skeleton_names_golden.json``; how it was made: ``tests/skeleton_names_record.py``)."""

from __future__ import annotations

import json

import pytest
from conftest import SHARED_DATA, TEST_DATA
from skeleton_names_record import record_maps, record_names, record_skeleton, skeletons_of

GOLDEN = json.loads((TEST_DATA / "skeleton_names_golden.json").read_text("utf-8"))


def plain(value):
    """``value`` as JSON reads it back (tuples → lists)."""
    return json.loads(json.dumps(value))


@pytest.fixture(scope="module")
def skeletons():
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found under {SHARED_DATA} (set USDMOTION_SHARED_DATA)")
    return skeletons_of(SHARED_DATA)


@pytest.mark.parametrize("label", sorted(GOLDEN["skeletons"]))
def test_recognition_on_every_rig_is_unchanged(skeletons, label):
    if label not in skeletons:
        pytest.skip(f"{label} not found under {SHARED_DATA}")
    assert plain(record_skeleton(skeletons[label])) == GOLDEN["skeletons"][label]


def test_name_parsing_is_unchanged():
    assert plain(record_names(GOLDEN["names"])) == GOLDEN["names"]


def test_automatic_joint_maps_are_unchanged(skeletons):
    maps = plain(record_maps(skeletons))
    expected = {k: v for k, v in GOLDEN["maps"].items() if all(s in skeletons for s in k.split(" -> "))}
    assert len(expected) > 0.9 * len(GOLDEN["maps"]), "most of the corpus is missing"
    assert {k: maps.get(k) for k in expected} == expected
