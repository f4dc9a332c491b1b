"""Record what the joint-recognition code finds on every skeleton of the shared corpus.

The record is the behaviour that ``usdmotion.skeleton_names`` must keep: segmentation
roles (``ops.roles``), body landmarks (``anthropometry``), bend triples (``ops.analyse``)
and automatic retargeting maps (``ops.jointmap``) on every BVH file in ``../shared/data``,
the package's own example BVH, the shipped synthesis example and a few renamed variants
of corpus rigs (other naming conventions). ``tests/test_skeleton_names.py`` compares the
current code against ``tests/data/skeleton_names_golden.json``, which was written once
from the code *before* the three modules were unified (commit ``c37d9a9``) with::

    export USDMOTION_SHARED_DATA=$(realpath ../shared/data)
    mkdir /tmp/before && git archive c37d9a9 | tar -x -C /tmp/before && cp tests/skeleton_names_record.py /tmp/before/tests/
    cd /tmp/before && PYTHONPATH=$PWD python tests/skeleton_names_record.py /tmp/golden.json

(``/tmp/golden.json`` comes out byte-identical to the golden).

Only public functions and the private guessers the tests call (``roles._guess_roles``,
``anthropometry._guess`` and ``_preset``, kept under those names) are used, so the
record is the same whichever module implements them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: The rig profiles the record was made with (later profiles are checked elsewhere).
PROFILES = ("bandai", "cmu_cgspeed", "cmu_max", "daz", "mixamo", "rokoko")
#: The role presets the record was made with (later presets are checked in tests/test_rigs.py).
PRESETS = ("cgspeed-mb", "cgspeed-max", "daz", "bandai", "mixamo", "asf")
#: Source → target rigs whose automatic maps are kept in full (the rest as digests).
FULL_MAPS = (
    ("cmu/cgspeed_12_01_walk.bvh", "cmu/daz_10_01_soccer_kick.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "bandai1/dataset-1_walk_normal_001.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "other_rigs/20tab_test_freebvh_mixamorig.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "other_rigs/ad_mixamo_Boxing.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "other_rigs/ad_rokoko_jesse_dance.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "cmu/max_131_01_start_walk_stop.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "other_rigs/ad_cartwheel_clean.bvh"),
    ("cmu/cgspeed_12_01_walk.bvh", "edge_cases/bvhio_example.bvh"),
    ("cmu/max_131_01_start_walk_stop.bvh", "cmu/cgspeed_12_01_walk.bvh"),
    ("other_rigs/ad_karate_mawashigeri.bvh", "other_rigs/ad_cartwheel_clean.bvh"),
    ("other_rigs/ad_rokoko_jesse_dance.bvh", "other_rigs/ad_mixamo_Boxing.bvh"),
)
#: Name conventions applied to a corpus rig to make extra skeletons: (label, rig file, rename).
VARIANTS = (
    ("blender_suffix", "cmu/cgspeed_12_01_walk.bvh",
     lambda n: n[4:] + ".L" if n.startswith("Left") else n[5:] + ".R" if n.startswith("Right") else n),
    ("namespace_colon", "cmu/max_131_01_start_walk_stop.bvh", lambda n: "rig:" + n),
    ("namespace_pipe", "cmu/daz_10_01_soccer_kick.bvh", lambda n: "grp|" + n),
    ("upper_case_letter", "cmu/daz_10_01_soccer_kick.bvh",
     lambda n: n[0].upper() + n[1:].lower() if n[:1] in "lr" and len(n) > 2 else n),
    ("snake_case", "other_rigs/ad_rokoko_jesse_dance.bvh",
     lambda n: ("l_" + n[4:].lower()) if n.startswith("Left") else ("r_" + n[5:].lower()) if n.startswith("Right")
     else n.lower()),
)


def _motions(shared: Path):
    """``(label, Motion)`` for every skeleton the record covers (files in sorted order)."""
    from usdmotion.io import read_motion
    from usdmotion.synthesis import example_path, load_synthesis

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        corpus = {str(p.relative_to(shared)): read_motion(p) for p in sorted(shared.rglob("*.bvh"))}
        yield from corpus.items()
        yield "package:cmu_12_01_walk.bvh", read_motion(REPO / "usdmotion" / "data" / "cmu_12_01_walk.bvh")
        yield "package:giant_swing.json", load_synthesis(example_path("giant_swing"))
    for label, relative, rename in VARIANTS:
        if relative in corpus:
            m = corpus[relative]
            yield f"variant:{label}", dataclasses.replace(m, joint_names=tuple(rename(n) for n in m.joint_names))


def _names(motion, found):
    """Joint indices → names (``None`` stays), recursively through dicts."""
    if isinstance(found, dict):
        return {k: _names(motion, v) for k, v in found.items()}
    return None if found is None else motion.joint_names[int(found)]


def _attempt(call):
    """``call()``'s JSON value, or ``{"error": class name, "message": ...}`` if it raises."""
    try:
        return call()
    except Exception as exc:  # noqa: BLE001 - the record keeps the kind of error
        return {"error": type(exc).__name__, "message": str(exc)}


def record_skeleton(motion) -> dict:
    """Everything the three modules find on one skeleton."""
    from usdmotion import anthropometry as A
    from usdmotion.ops.analyse import measures as analyse
    from usdmotion.ops.segment import roles as R
    from usdmotion.ops.retarget.jointmap import detect_profile, profile_joints, rig_profiles

    def guessed_roles():
        found, missing = R._guess_roles(motion)
        return {"found": _names(motion, found), "missing": list(missing)}

    def landmarks():
        found, how = A.find_landmarks(motion, source="rig.bvh")
        return {"found": _names(motion, found), "how": how}

    def de_leva():
        model = A.de_leva_model(motion, source="rig.bvh")
        return {"landmarks": model.landmarks, "notes": list(model.notes), "source": model.source,
                "weights_sum": float(np.round(model.weights, 12).sum())}

    def preset_landmarks():
        hit = A._preset(motion)
        return None if hit is None else [hit[0], _names(motion, hit[1])]

    return {
        "joints": len(motion.joint_names),
        "roles": _attempt(lambda: _names(motion, R.find_roles(motion, source="rig.bvh"))),
        "roles_preset": R.match_preset(motion),
        "roles_forced": {p: _attempt(lambda p=p: _names(motion, R.find_roles(motion, preset=p, source="rig.bvh")))
                         for p in PRESETS},
        "roles_guessed": _attempt(guessed_roles),
        "landmarks": _attempt(landmarks),
        "landmarks_guessed": _attempt(lambda: _names(motion, A._guess(motion))),
        "landmarks_preset": _attempt(preset_landmarks),
        "de_leva": _attempt(de_leva),
        "bend_triples": [[motion.joint_names[int(j)] for j in row] for row in analyse.bend_triples(motion)],
        "profile": detect_profile(motion.joint_names),
        "profile_joints": {name: profile_joints(rig_profiles()[name], motion.joint_names) for name in PROFILES},
    }


def record_names(names) -> dict:
    """Per joint name: ``roles.parse_side``, ``anthropometry.side_and_base``, ``jointmap.normalise_name``."""
    from usdmotion.anthropometry import side_and_base
    from usdmotion.ops.retarget.jointmap import normalise_name
    from usdmotion.ops.segment.roles import parse_side

    return {n: {"parse_side": list(parse_side(n)), "side_and_base": list(side_and_base(n)),
                "normalise_name": normalise_name(n)} for n in sorted(set(names))}


def record_maps(skeletons: dict) -> dict:
    """``auto_map`` (as the retarget command calls it) between every two distinct skeletons.

    The maps of :data:`FULL_MAPS` are kept in full, the others as :func:`digest`.
    """
    from usdmotion.ops.retarget.jointmap import auto_map

    distinct: dict[tuple, str] = {}
    for label, m in skeletons.items():
        distinct.setdefault((m.joint_names, tuple(bool(e) for e in m.end_sites)), label)
    out = {}
    for src in distinct.values():
        for tgt in distinct.values():
            if src == tgt:
                continue
            t = skeletons[tgt]
            jmap = auto_map(skeletons[src].joint_names, t.joint_names, t.end_sites)
            out[f"{src} -> {tgt}"] = {"how": jmap.how, "profiles": list(jmap.profiles or []) or None,
                                      "pairs": jmap.pairs if (src, tgt) in FULL_MAPS else digest(jmap.pairs)}
    return out


def digest(pairs: dict) -> str:
    """Count and SHA-256 of a map (sorted JSON): ``"71 pairs, sha256 ab12..."``."""
    text = json.dumps(pairs, sort_keys=True, ensure_ascii=False)
    return f"{len(pairs)} pairs, sha256 {hashlib.sha256(text.encode()).hexdigest()[:16]}"


def skeletons_of(shared: Path) -> dict:
    """Label (path under ``shared``, ``package:...``, ``variant:...``) → Motion."""
    return dict(_motions(shared))


def record(shared: Path) -> dict:
    """The whole record (JSON-ready)."""
    skeletons = skeletons_of(shared)
    return {
        "skeletons": {label: record_skeleton(m) for label, m in skeletons.items()},
        "names": record_names(n for m in skeletons.values() for n in m.joint_names),
        "maps": record_maps(skeletons),
    }


def to_text(doc: dict) -> str:
    """JSON with one line per name, per map and per skeleton field (small, diff-friendly)."""
    def line(value) -> str:
        return json.dumps(value, sort_keys=True, ensure_ascii=False)

    def block(items: dict, indent: str, inner) -> str:
        rows = [f"{indent} {line(k)}: {inner(v)}" for k, v in sorted(items.items())]
        return "{\n" + ",\n".join(rows) + f"\n{indent}}}"

    def section(key: str, value: dict) -> str:
        if key == "skeletons":
            return block(value, " ", lambda fields: block(fields, "  ", line))
        return block(value, " ", line)

    return "{\n" + ",\n".join(f" {line(k)}: {section(k, v)}" for k, v in sorted(doc.items())) + "\n}\n"


def main(argv: list[str]) -> int:
    sys.path.insert(0, str(REPO / "tests"))
    from conftest import SHARED_DATA

    out = Path(argv[1]) if len(argv) > 1 else REPO / "tests" / "data" / "skeleton_names_golden.json"
    doc = record(SHARED_DATA)
    out.write_text(to_text(doc), encoding="utf-8")
    print(f"{out}: {len(doc['skeletons'])} skeletons, {len(doc['names'])} names, {len(doc['maps'])} maps")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))
