"""Blender's own glTF importer and exporter against our GLBs (issue 12, must-show 2 and 3).

ONE Blender subprocess (``tests/blender/gltf_probe.py``) does every job here:

* imports each GLB we write (Blender's default import options, scene rate = the file's, so
  glTF time ``i / fps`` is Blender frame ``i``) and reports its bone heads and the
  deformed body vertices at 5 frames;
* imports a shared BVH with Blender's BVH importer and exports it as GLB with Blender's
  exporter (both default options), reporting Blender's bone heads first.

Expectations, derived not fitted: glTF is metres, Y up; Blender is metres, Z up, and its
importer turns glTF ``(x, y, z)`` into ``(x, -z, y)`` (``C = Rx(+90°)``), so bone ``j`` at
frame ``f`` sits at ``C · mpu · R_up · joint_positions(motion)[f, j]``, within
``1e-4 × height`` (Blender keeps poses in float32 and rebuilds bone-space matrices);
the body's deformed vertices equal :func:`usdmotion.skin.skin_frames` of our FK (the
same point set: nearest-vertex distances both ways, as Blender may reorder vertices) and
move away from the bind pose.
"""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import REPO, shared_path
from test_blender import C_YUP, blender_python, clean_env
from usdmotion.io import read_motion
from usdmotion.io.gltf import write_gltf
from usdmotion.kinematics import joint_positions, skeleton_height
from usdmotion.skin import build_body, skin_frames

pytestmark = pytest.mark.blender

PROBE = REPO / "tests" / "blender" / "gltf_probe.py"
POSITION_TOL = 1e-4  # × height (metres), Blender's import of our GLBs (measured ≤ 5e-7)
ROUND_TRIP_TOL = 1e-5  # × height, Blender's own export read back by us (measured 3.5e-7)

#: (id, shared file, units, up axis, first N frames, with the body mesh)
CASES = (
    ("cmu_walk_body", "cmu/cgspeed_12_01_walk.bvh", "asf", None, 240, True),
    ("mixamo_colon_names", "other_rigs/20tab_test_freebvh_mixamorig.bvh", None, None, 120, False),
    ("zup_inch_cartwheel_body", "other_rigs/ad_cartwheel_clean.bvh", "in", "Z", 120, True),
    ("bandai_position_channels", "bandai1/dataset-1_dash_normal_001.bvh", None, None, None, False),
    ("moving_joint_translations", "edge_cases/wspr_milad_blank_line_6ch_125fps.bvh", None, None, 150, False),
    ("daz_soccer_kick", "cmu/daz_10_01_soccer_kick.bvh", None, None, 200, False),
)
BLENDER_BVH = "cmu/cgspeed_12_01_walk.bvh"


def five_frames(n_frames: int) -> list[int]:
    return sorted({0, n_frames // 4, n_frames // 2, (3 * n_frames) // 4, n_frames - 1})


@pytest.fixture(scope="module")
def probed(tmp_path_factory):
    python = blender_python()
    tmp = tmp_path_factory.mktemp("gltf_blender")
    jobs, cases = [], {}
    for case_id, relative, units, up_axis, frames, mesh in CASES:
        motion = read_motion(shared_path(relative), units=units, up_axis=up_axis)
        motion = motion if frames is None else motion.sliced(0, frames)
        body = build_body(motion) if mesh else None
        path = tmp / f"{case_id}.glb"
        write_gltf(motion, path, body=body)
        cases[str(path)] = (case_id, motion, body)
        jobs.append({"kind": "gltf", "path": str(path), "fps": motion.fps, "frames": five_frames(motion.n_frames)})
    bvh = shared_path(BLENDER_BVH)
    exported = tmp / "blender_export.glb"
    n_frames = read_motion(bvh).n_frames
    jobs.append({"kind": "bvh_export", "path": str(bvh), "out": str(exported),
                 "frames": [f + 1 for f in five_frames(n_frames)]})  # Blender's BVH import starts at frame 1
    manifest, report = tmp / "manifest.json", tmp / "report.json"
    manifest.write_text(json.dumps(jobs))
    run = subprocess.run([str(python), str(PROBE), "--manifest", str(manifest), "--out", str(report)],
                         capture_output=True, text=True, timeout=900, env=clean_env())
    assert run.returncode == 0 and report.is_file(), run.stderr[-2000:]
    files = json.loads(report.read_text())["files"]
    return {f["path"]: f for f in files}, cases, exported


def to_blender(points, motion) -> np.ndarray:
    """File coordinates → Blender world: metres, Y-up glTF turned by ``C_YUP``."""
    p = np.asarray(points) * motion.meters_per_unit
    if motion.up_axis == "Z":
        p = np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)
    return p @ C_YUP.T


def test_blender_imports_bone_heads_at_our_fk(probed):
    files, cases, _ = probed
    for path, (case_id, motion, _) in cases.items():
        result = files[path]
        assert result["ok"], (case_id, result.get("error"), result.get("traceback"))
        (armature,) = result["armatures"]
        assert sorted(armature["bone_names"]) == sorted(motion.joint_names), case_id
        order = [motion.joint_index(n) for n in armature["bone_names"]]
        expected = to_blender(joint_positions(motion), motion)
        height = skeleton_height(motion) * motion.meters_per_unit
        assert len(result["frames"]) == 5
        worst = 0.0
        for frame in result["frames"]:
            heads = np.array(armature["poses"][str(frame)]["world_heads"])
            worst = max(worst, float(np.abs(heads - expected[frame, order]).max()) / height)
        assert worst <= POSITION_TOL, (case_id, worst)


def test_blender_deforms_the_body_as_our_skinning(probed):
    files, cases, _ = probed
    checked = 0
    for path, (case_id, motion, body) in cases.items():
        if body is None:
            continue
        (mesh,) = files[path]["meshes"]
        assert mesh["n_vertices"] == len(body.vertices) and len(mesh["vertex_groups"]) > 1, case_id
        assert any(m["type"] == "ARMATURE" for m in mesh["modifiers"]), case_id
        frames = files[path]["frames"]
        ours = to_blender(skin_frames(body, motion, np.array(frames)), motion)
        height = skeleton_height(motion) * motion.meters_per_unit
        shapes = []
        for k, frame in enumerate(frames):
            theirs = np.array(mesh["poses"][str(frame)]["world_vertices"])
            d_theirs, _ = cKDTree(ours[k]).query(theirs)
            d_ours, _ = cKDTree(theirs).query(ours[k][mesh["vertex_indices"]])
            assert max(d_theirs.max(), d_ours.max()) / height <= POSITION_TOL, (case_id, frame)
            shapes.append(np.linalg.norm(theirs - theirs.mean(axis=0), axis=1))  # rigid motion keeps these
        bent = np.ptp(np.array(shapes), axis=0).max() / height
        assert bent > 0.05, (case_id, bent)  # Blender's mesh really deforms, not only moves
        checked += 1
    assert checked == 2


def test_blender_exported_glb_reads_back_to_blenders_positions(probed):
    """Blender imports a BVH (its own importer) and exports GLB; we read that GLB and get
    Blender's bone heads back (glTF Y-up metres → Blender by ``C_YUP``)."""
    files, _, exported = probed
    result = files[str(shared_path(BLENDER_BVH))]
    assert result["ok"] and result["exported"], (result.get("error"), result.get("traceback"))
    (armature,) = result["armatures"]
    motion = read_motion(exported)
    assert motion.meters_per_unit == 1.0 and motion.up_axis == "Y"
    assert set(armature["bone_names"]) <= set(motion.joint_names)
    order = [motion.joint_index(n) for n in armature["bone_names"]]
    positions = joint_positions(motion) @ C_YUP.T
    height = skeleton_height(motion)
    assert motion.n_frames == read_motion(shared_path(BLENDER_BVH)).n_frames  # one key per BVH frame
    assert motion.fps == pytest.approx(result["scene"]["fps"], rel=1e-4)
    for frame in result["frames"]:  # Blender frame f = our frame f - frame_start
        heads = np.array(armature["poses"][str(frame)]["world_heads"])
        ours = positions[frame - result["scene"]["frame_start"], order]
        assert np.abs(heads - ours).max() / height <= ROUND_TRIP_TOL, frame
