"""Blender imports our UsdSkel files correctly (issue 2, must-show 3; issue 4, must-show 2).

Runs only where a Blender Python exists: ``$USDMOTION_BLENDER_PYTHON``, else
``<repo>/.venv-blender/bin/python`` (made by ``scripts/setup_blender.sh``; Blender 4.5 LTS
as the ``bpy`` module, numpy<2), and it can ``import bpy``. Elsewhere every test here
skips, saying why. bpy never enters the main venv.

All Blender work is ONE subprocess: ``tests/blender/usd_probe.py`` imports every file
written here with Blender's default import options and reports one JSON document.
The expectations are derived, not fitted:

* Units and axes. Blender's importer scales the SkelRoot object by ``metersPerUnit``
  (Blender units are metres) and, for a Y-up stage, rotates it +90° about X (Blender is
  Z-up), so a stage point ``p`` lands at ``mpu · C · p`` with ``C = Rx(+90°)``
  (stage +Y → Blender +Z, stage +Z → Blender −Y: both "front" conventions agree); for a
  Z-up stage ``C = I``. Both right-handed, so ``C`` is a proper rotation.
* Time. Blender reads time code ``t`` as frame ``t``; we write time codes ``0 … F-1``,
  so Blender frame ``f`` is our frame ``f`` and the range is ``0 … F-1``.
* End Sites. ``Motion`` keeps BVH End Sites as leaf joints ``<parent>_End``; the writer
  makes them UsdSkel joints, so they become bones: bone count = J = joints + end sites
  (Blender's own BVH importer, by contrast, turns End Sites into tails).
* Names. Bone names are the last element of our joint path tokens
  (``joint_path_tokens``); the original name of each bone is ``motion.joint_names``.
* Poses. The head of pose bone ``j`` (evaluated, world space) at frame ``f`` must equal
  ``mpu · C · joint_positions(motion)[f, j]`` (our FK, file units) within
  ``POSITION_TOL × height`` (height: :func:`skeleton_height` in metres). Blender keeps
  F-curves and matrices in float32, so ~1e-6 relative is the floor; 1e-5 leaves room
  for deep chains without hiding a wrong joint (a swapped axis or a missing frame moves
  joints by a sizeable fraction of the height).
* Skinned mesh. A mesh authored with pxr (SkelBindingAPI, ``primvars:skel:jointIndices``
  / ``jointWeights`` with elementSize 4, ``geomBindTransform``, ``skel:skeleton``) must
  come in with an Armature modifier on our armature, one vertex group per influencing
  bone carrying our weights, and deformed vertices equal to linear blend skinning from
  our FK (cross-checked against usd-core's ``ComputeSkinnedPoints``).
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, SHARED_DATA, shared_path
from usdmotion.io import read_motion, write_motion
from usdmotion.io.usd import joint_path_tokens, write_usd
from usdmotion.kinematics import compose_transforms, fk, fk_arrays, joint_positions, skeleton_height
from usdmotion.motion import Motion

pytestmark = pytest.mark.blender

BLENDER_ENV = "USDMOTION_BLENDER_PYTHON"
PROBE = REPO / "tests" / "blender" / "usd_probe.py"
POSITION_TOL = 1e-5   # × skeleton height (metres), bone heads and skinned vertices
WEIGHT_TOL = 1e-6     # Blender stores vertex weights as float32
MATRIX_TOL = 1e-6     # relative, object matrices
C_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # Rx(+90°)


@dataclasses.dataclass(frozen=True)
class Case:
    id: str
    source: str                # relative to the shared data, or "synthetic:<name>"
    ext: str
    units: str | None = None
    up_axis: str | None = None
    frames: int | None = None  # keep only the first N frames
    mesh: str | None = None    # None, "identity" or "offset" geomBindTransform (test boxes), "body" (usdmotion.skin)
    via_cli: bool = False


CASES = (
    Case("cmu_cgspeed_walk", "cmu/cgspeed_12_01_walk.bvh", ".usda"),
    Case("mixamo_colon_names", "other_rigs/20tab_test_freebvh_mixamorig.bvh", ".usdc", via_cli=True),
    Case("daz_soccer_kick", "cmu/daz_10_01_soccer_kick.bvh", ".usdz"),
    Case("bandai_position_channels", "bandai1/dataset-1_dash_normal_001.bvh", ".usda"),
    Case("zup_inch_cartwheel_no_end_sites", "other_rigs/ad_cartwheel_clean.bvh", ".usdc", units="in", up_axis="Z"),
    Case("zup_inch_mixed_orders", "edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh", ".usdz",
         units="in", up_axis="Z"),
    Case("metres_3dsmax", "cmu/max_131_01_start_walk_stop_scaled_metres.bvh", ".usdc", units="m"),
    Case("moving_joint_translations", "edge_cases/wspr_milad_blank_line_6ch_125fps.bvh", ".usda"),
    Case("tricky_names", "synthetic:names", ".usda"),
    Case("skinned_tricky_names", "synthetic:names", ".usda", mesh="identity"),
    Case("skinned_cmu_walk_geom_bind", "cmu/cgspeed_12_01_walk.bvh", ".usdz", frames=48, mesh="offset"),
    Case("body_mesh_cmu_walk", "cmu/cgspeed_12_01_walk.bvh", ".usdc", units="asf", frames=60, mesh="body"),
)
MESH_CASES = tuple(c for c in CASES if c.mesh)


# --------------------------------------------------------------------------- inputs


def names_bvh_text(n_frames: int = 24) -> str:
    """A small BVH whose names Blender rejects unless sanitised: ':' , spaces, a leading
    digit, and two names ('a:b', 'a_b') that collide after sanitising, under different
    parents, plus two siblings ('rig:Spine', 'rig_Spine') that collide the same way."""
    joints = [  # name, parent, offset, end-site offset
        ("rig:Hips", -1, (0, 90, 0), None),
        ("Left Leg", 0, (10, -5, 0), None),
        ("1st Knee", 1, (0, -40, 0), None),
        ("a:b", 2, (0, -40, 5), (0, 0, 10)),
        ("rig:Spine", 0, (0, 10, 0), None),
        ("a_b", 4, (0, 30, 0), (0, 15, 0)),
        ("rig_Spine", 0, (5, 10, 0), (8, 0, 0)),
    ]
    children = {j: [k for k, jt in enumerate(joints) if jt[1] == j] for j in range(len(joints))}

    def block(j: int, depth: int) -> list[str]:
        name, parent, offset, end = joints[j]
        pad = "  " * depth
        channels = "6 Xposition Yposition Zposition Zrotation Xrotation Yrotation" if parent < 0 else \
            "3 Zrotation Xrotation Yrotation"
        lines = [f"{pad}{'ROOT' if parent < 0 else 'JOINT'} {name}", f"{pad}{{",
                 f"{pad}  OFFSET {offset[0]} {offset[1]} {offset[2]}", f"{pad}  CHANNELS {channels}"]
        for k in children[j]:
            lines += block(k, depth + 1)
        if end is not None:
            lines += [f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET {end[0]} {end[1]} {end[2]}", f"{pad}  }}"]
        return lines + [f"{pad}}}"]

    t = np.linspace(0.0, 2.0 * np.pi, n_frames)[:, None]
    phase = np.arange(3 * len(joints))[None, :]
    angles = 35.0 * np.sin(t + 0.7 * phase)
    root_pos = np.concatenate([10 * np.sin(t), 2 * np.cos(2 * t), 30 * t / (2 * np.pi)], axis=1)
    rows = np.concatenate([root_pos, angles], axis=1)
    motion = "\n".join(" ".join(f"{v:.6f}" for v in row) for row in rows)
    return "\n".join(["HIERARCHY", *block(0, 0), "MOTION", f"Frames: {n_frames}", "Frame Time: 0.04", motion]) + "\n"


def source_motion(case: Case, tmp: Path) -> tuple[Path, Motion]:
    if case.source == "synthetic:names":
        src = tmp / "tricky_names.bvh"
        if not src.exists():
            src.write_text(names_bvh_text())
    else:
        src = SHARED_DATA / case.source
    motion = read_motion(src, units=case.units, up_axis=case.up_axis)
    if case.frames is not None:
        motion = motion.with_frames(motion.rotations[:case.frames], motion.root_translation[:case.frames],
                                    None if motion.joint_translations is None
                                    else motion.joint_translations[:case.frames])
    return src, motion


def bind_transforms(motion: Motion) -> np.ndarray:
    """World bind transforms ``(J, 4, 4)``: the rest pose (identity rotations, OFFSETs)."""
    identity = np.zeros((motion.n_joints, 4))
    identity[:, 0] = 1.0
    return compose_transforms(*fk_arrays(identity, motion.offsets, motion.parents))


@dataclasses.dataclass(frozen=True)
class SkinnedBoxes:
    """One box per bone (8 vertices at 20 % and 80 % of its length), 4 influences each."""

    points: np.ndarray          # (V, 3) in the mesh's own space (geomBindTransform⁻¹ · bind space)
    counts: np.ndarray          # (faces,)
    indices: np.ndarray         # (faces · 4,)
    joint_indices: np.ndarray   # (V, 4)
    joint_weights: np.ndarray   # (V, 4), rows sum to 1, no joint twice in a row
    geom_bind: np.ndarray       # (4, 4) column-vector geomBindTransform


def skinned_boxes(motion: Motion, geom_bind: np.ndarray) -> SkinnedBoxes:
    rest = bind_transforms(motion)[:, :3, 3]
    quad_faces = np.array([[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]])
    points, faces, joint_indices, joint_weights = [], [], [], []
    for j in range(1, motion.n_joints):
        p = int(motion.parents[j])
        head, tail = rest[p], rest[j]
        length = float(np.linalg.norm(tail - head))
        if length < 1e-6:
            continue
        axis = (tail - head) / length
        u = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(axis, u)
        radius = 0.15 * length
        base = len(points)
        for t in (0.2, 0.8):
            centre = head + t * (tail - head)
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                points.append(centre + radius * (su * u + sv * v))
                grand = int(motion.parents[p])
                influences = [p, j] + ([grand] if grand >= 0 else [])
                weights = [0.9 - 0.6 * t, 0.1 + 0.5 * t] + ([0.15] if grand >= 0 else [])
                pad = 4 - len(influences)
                joint_indices.append(influences + [0] * pad)                # zero weights pad
                joint_weights.append(list(np.array(weights) / sum(weights)) + [0.0] * pad)
        faces.append(quad_faces + base)
    points = np.array(points)
    homogeneous = np.concatenate([points, np.ones((len(points), 1))], axis=1)
    local = (np.linalg.inv(geom_bind) @ homogeneous.T).T[:, :3]
    faces = np.concatenate(faces)
    return SkinnedBoxes(points=local, counts=np.full(len(faces), 4), indices=faces.ravel(),
                        joint_indices=np.array(joint_indices), joint_weights=np.array(joint_weights),
                        geom_bind=geom_bind)


def offset_geom_bind() -> np.ndarray:
    """A non-identity geomBindTransform: 30° about Z, then a translation (column vectors)."""
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    g = np.eye(4)
    g[:2, :2] = [[c, -s], [s, c]]
    g[:3, 3] = [12.0, -3.0, 7.5]
    return g


def add_mesh(boxes: SkinnedBoxes):
    """``decorate`` hook for :func:`write_usd`: author the boxes as a skinned Mesh."""

    def decorate(stage, skeleton) -> None:
        from pxr import Gf, UsdGeom, UsdSkel, Vt

        mesh = UsdGeom.Mesh.Define(stage, skeleton.GetPath().GetParentPath().AppendChild("Body"))
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(boxes.points.astype(np.float32)))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(boxes.counts.astype(np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(boxes.indices.astype(np.int32)))
        binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
        binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
        indices = boxes.joint_indices.astype(np.int32).ravel()
        weights = boxes.joint_weights.astype(np.float32).ravel()
        binding.CreateJointIndicesPrimvar(False, 4).Set(Vt.IntArray.FromNumpy(indices))   # constant=False: vertex
        binding.CreateJointWeightsPrimvar(False, 4).Set(Vt.FloatArray.FromNumpy(weights))  # elementSize 4
        binding.CreateGeomBindTransformAttr(Gf.Matrix4d(boxes.geom_bind.T.tolist()))  # USD is row-vector

    return decorate


def lbs(motion: Motion, boxes: SkinnedBoxes, frames: list[int]) -> np.ndarray:
    """Linear blend skinning from our FK: ``Σ w · T_world_joint(f) · B⁻¹ · G · p`` (stage units)."""
    skin = fk(motion)[frames] @ np.linalg.inv(bind_transforms(motion))[None]           # (n, J, 4, 4)
    homogeneous = np.concatenate([boxes.points, np.ones((len(boxes.points), 1))], axis=1)
    bound = (boxes.geom_bind @ homogeneous.T).T                                          # (V, 4)
    per_influence = np.einsum("fvkab,vb->fvka", skin[:, boxes.joint_indices], bound)     # (n, V, 4, 4)
    return np.einsum("fvka,vk->fva", per_influence, boxes.joint_weights)[..., :3]


def usd_skinned_points(path: Path, frames: list[int]) -> np.ndarray:
    """usd-core's own skinning of the mesh (skeleton space = world here), ``(n, V, 3)``."""
    from pxr import Usd, UsdGeom, UsdSkel, Vt

    stage = Usd.Stage.Open(str(path))
    cache = UsdSkel.Cache()
    root = UsdSkel.Root(stage.GetDefaultPrim())
    cache.Populate(root, Usd.PrimDefaultPredicate)
    mesh_prim = next(p for p in Usd.PrimRange(root.GetPrim()) if p.IsA(UsdGeom.Mesh))
    skel = UsdSkel.BindingAPI(mesh_prim).GetInheritedSkeleton()
    skel_query = cache.GetSkelQuery(skel)
    skinning = cache.GetSkinningQuery(mesh_prim)
    out = []
    for f in frames:
        points = Vt.Vec3fArray(UsdGeom.Mesh(mesh_prim).GetPointsAttr().Get(f))
        assert skinning.ComputeSkinnedPoints(skel_query.ComputeSkinningTransforms(f), points, f)
        out.append(np.array(points, dtype=np.float64))
    return np.stack(out)


def sample_frames(n_frames: int) -> list[int]:
    return sorted({0, min(1, n_frames - 1), n_frames // 3, (2 * n_frames) // 3, n_frames - 1})


def stage_to_blender(motion: Motion) -> np.ndarray:
    """4×4 (column vectors) from stage coordinates to Blender world, derived as above."""
    m = np.eye(4)
    m[:3, :3] = motion.meters_per_unit * (C_YUP if motion.up_axis == "Y" else np.eye(3))
    return m


# --------------------------------------------------------------------------- Blender run


def blender_python() -> Path:
    """The Blender Python to use, or ``pytest.skip`` with the reason there is none."""
    configured = os.environ.get(BLENDER_ENV)
    python = Path(configured) if configured else REPO / ".venv-blender" / "bin" / "python"
    how = f"${BLENDER_ENV}" if configured else "the default (run scripts/setup_blender.sh to create it)"
    if not python.exists():
        pytest.skip(f"no Blender Python at {python} ({how}); set {BLENDER_ENV} to a Python that can import bpy")
    try:
        check = subprocess.run([str(python), "-c", "import bpy; print(bpy.app.version_string)"],
                               capture_output=True, text=True, timeout=180, env=clean_env())
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"cannot run {python}: {exc}")
    if check.returncode != 0:
        last = (check.stderr.strip().splitlines() or ["?"])[-1]
        pytest.skip(f"{python} cannot import bpy ({last}); run scripts/setup_blender.sh")
    return python


def clean_env() -> dict[str, str]:
    """The environment for Blender's Python: nothing of the main venv's import path."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}


@dataclasses.dataclass
class Written:
    case: Case
    path: Path
    motion: Motion
    frames: list[int]
    boxes: SkinnedBoxes | None = None


def write_case(case: Case, tmp: Path) -> Written:
    src, motion = source_motion(case, tmp)
    out = tmp / f"{case.id}{case.ext}"
    boxes = None
    if case.mesh == "body":  # the product's own volumetric body (usdmotion convert --mesh)
        from usdmotion.io.usd_mesh import body_decorator
        from usdmotion.skin import build_body

        body = build_body(motion)
        assert np.allclose(body.bind_transforms, bind_transforms(motion))  # CMU: bound in the rest pose
        triangles = np.asarray(body.faces)
        boxes = SkinnedBoxes(points=np.asarray(body.vertices), counts=np.full(len(triangles), 3),
                             indices=triangles.ravel(), joint_indices=np.asarray(body.joint_indices),
                             joint_weights=np.asarray(body.joint_weights), geom_bind=np.eye(4))
        write_usd(motion, out, decorate=body_decorator(body))
    elif case.mesh:
        boxes = skinned_boxes(motion, np.eye(4) if case.mesh == "identity" else offset_geom_bind())
        write_usd(motion, out, decorate=add_mesh(boxes))
    elif case.via_cli:
        from usdmotion.cli import main

        args = ["convert", str(src), str(out)]
        args += ["--units", case.units] if case.units else []
        args += ["--up-axis", case.up_axis] if case.up_axis else []
        assert main(args) == 0
    else:
        write_motion(motion, out)
    return Written(case, out, motion, sample_frames(motion.n_frames), boxes)


def invalid_joint_paths_stage(path: Path) -> None:
    """A negative control: raw, unsanitised ``mixamorig:`` joint paths (what we must not write)."""
    from pxr import Gf, Usd, UsdSkel, Vt

    stage = Usd.Stage.CreateNew(str(path))
    root = UsdSkel.Root.Define(stage, "/Rig")
    stage.SetDefaultPrim(root.GetPrim())
    skel = UsdSkel.Skeleton.Define(stage, "/Rig/Skeleton")
    skel.CreateJointsAttr(Vt.TokenArray(["mixamorig:Hips", "mixamorig:Hips/mixamorig:Spine"]))
    rest = Vt.Matrix4dArray([Gf.Matrix4d(1), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 10, 0))])
    skel.CreateRestTransformsAttr(rest)
    skel.CreateBindTransformsAttr(rest)
    stage.GetRootLayer().Save()


@pytest.fixture(scope="module")
def blender_run(tmp_path_factory):
    """Write every case, run the probe ONCE over all files; ``(written by id, report by path)``."""
    python = blender_python()
    tmp = tmp_path_factory.mktemp("blender")
    written = {c.id: write_case(c, tmp) for c in CASES
               if c.source.startswith("synthetic:") or (SHARED_DATA / c.source).is_file()}
    invalid = tmp / "invalid_joint_paths.usda"
    invalid_joint_paths_stage(invalid)
    garbage = tmp / "garbage.usda"
    garbage.write_text("this is not a USD layer\n")
    jobs = [{"path": str(w.path), "frames": w.frames} for w in written.values()]
    jobs += [{"path": str(p), "frames": [0]} for p in (invalid, garbage, tmp / "missing.usda")]
    manifest, out = tmp / "manifest.json", tmp / "report.json"
    manifest.write_text(json.dumps(jobs))
    run = subprocess.run([str(python), str(PROBE), "--manifest", str(manifest), "--out", str(out)],
                         capture_output=True, text=True, timeout=900, env=clean_env())
    assert run.returncode == 0 and out.is_file(), f"probe failed ({run.returncode}): {run.stderr[-2000:]}"
    report = json.loads(out.read_text())
    sys.stderr.write(f"[test_blender] Blender {report['blender']} imported {len(jobs)} files\n")
    return written, {entry["path"]: entry for entry in report["files"]}


def case_result(blender_run, case: Case) -> tuple[Written, dict]:
    if not case.source.startswith("synthetic:"):
        shared_path(case.source)  # skips with a reason when the shared file is missing
    written, by_path = blender_run
    w = written[case.id]
    entry = by_path[str(w.path)]
    assert entry["ok"], f"{case.id}: Blender import failed: {entry.get('error')}\n{entry.get('log', '')[-2000:]}"
    return w, entry


def the_armature(entry: dict) -> dict:
    assert len(entry["armatures"]) == 1, f"expected one armature, got {[a['name'] for a in entry['armatures']]}"
    return entry["armatures"][0]


def bone_names(motion: Motion) -> list[str]:
    return [t.rsplit("/", 1)[-1] for t in joint_path_tokens(motion.joint_names, motion.parents)]


# --------------------------------------------------------------------------- tests

ids = [c.id for c in CASES]


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_import_is_clean(blender_run, case):
    """The operator finishes, and Blender and its USD library print no warning or error."""
    _, entry = case_result(blender_run, case)
    assert entry["operator"] == ["FINISHED"]
    assert entry["warnings"] == [], "\n".join(entry["warnings"])


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_skeleton_keeps_every_joint(blender_run, case):
    """One armature; one bone per joint (End Sites included); names and hierarchy as ours."""
    w, entry = case_result(blender_run, case)
    arm = the_armature(entry)
    motion = w.motion
    expected = bone_names(motion)
    assert arm["n_bones"] == motion.n_joints, (
        f"{arm['n_bones']} bones for {motion.n_joints} joints ({int(motion.end_sites.sum())} end sites)")
    assert arm["bone_names"] == expected  # Blender keeps the UsdSkel joint order
    parents = dict(zip(arm["bone_names"], arm["bone_parents"]))
    for j, name in enumerate(expected):
        want = expected[motion.parents[j]] if motion.parents[j] >= 0 else None
        assert parents[name] == want, f"bone {name} ({motion.joint_names[j]!r}): parent {parents[name]}, want {want}"
    assert len(set(expected)) == motion.n_joints  # bone name ↔ original joint name is one-to-one


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_animation_range(blender_run, case):
    """Scene and action span frames 0 … F-1; every bone has location, quaternion and scale curves."""
    w, entry = case_result(blender_run, case)
    last = w.motion.n_frames - 1
    assert (entry["scene"]["frame_start"], entry["scene"]["frame_end"]) == (0, last)
    action = the_armature(entry)["action"]
    assert action is not None, "the armature has no action"
    assert action["frame_range"] == [0.0, float(last)]
    if action["n_fcurves"] is not None:
        assert action["n_fcurves"] == 10 * w.motion.n_joints  # 3 location + 4 quaternion + 3 scale


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_units_and_axes(blender_run, case):
    """The armature's world matrix is exactly metersPerUnit · C (derived, see module doc)."""
    w, entry = case_result(blender_run, case)
    expected = stage_to_blender(w.motion)
    for frame, pose in the_armature(entry)["poses"].items():
        got = np.array(pose["matrix_world"])
        np.testing.assert_allclose(got, expected, rtol=0, atol=MATRIX_TOL * w.motion.meters_per_unit,
                                   err_msg=f"frame {frame}")


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_rest_pose_is_our_bind_pose(blender_run, case):
    """Bone rest heads (armature space, stage units) are our rest-pose joint positions."""
    w, entry = case_result(blender_run, case)
    rest = bind_transforms(w.motion)[:, :3, 3]
    heads = np.array(the_armature(entry)["rest_heads"])
    height = skeleton_height(w.motion)
    np.testing.assert_allclose(heads, rest, rtol=0, atol=POSITION_TOL * height)


@pytest.mark.parametrize("case", CASES, ids=ids)
def test_pose_matches_our_fk(blender_run, case):
    """Evaluated world bone heads at sampled frames equal mpu · C · our FK (incl. the last frame)."""
    w, entry = case_result(blender_run, case)
    motion = w.motion
    poses = the_armature(entry)["poses"]
    assert sorted(int(f) for f in poses) == w.frames
    to_blender = stage_to_blender(motion)
    positions = joint_positions(motion)
    height_m = skeleton_height(motion) * motion.meters_per_unit
    worst = 0.0
    for f in w.frames:
        expected = positions[f] @ to_blender[:3, :3].T
        got = np.array(poses[str(f)]["world_heads"])
        error = np.linalg.norm(got - expected, axis=1)
        worst = max(worst, float(error.max()))
        bad = int(np.argmax(error))
        assert error.max() <= POSITION_TOL * height_m, (
            f"frame {f}: joint {motion.joint_names[bad]!r} is {error[bad]:.3g} m off "
            f"(tolerance {POSITION_TOL * height_m:.3g} m)")
    # The check has teeth: the joints really move between the sampled frames.
    spread = np.ptp(positions[w.frames], axis=0).max() * motion.meters_per_unit
    assert spread > 100 * POSITION_TOL * height_m or motion.n_frames < 3


@pytest.mark.parametrize("case", MESH_CASES, ids=[c.id for c in MESH_CASES])
def test_mesh_is_skinned(blender_run, case):
    """The mesh comes in bound: Armature modifier on our armature, our vertex groups and weights."""
    w, entry = case_result(blender_run, case)
    boxes = w.boxes
    assert len(entry["meshes"]) == 1, [m["name"] for m in entry["meshes"]]
    mesh = entry["meshes"][0]
    arm = the_armature(entry)
    assert mesh["n_vertices"] == len(boxes.points)
    assert mesh["n_faces"] == len(boxes.counts)
    assert [(m["type"], m["object"]) for m in mesh["modifiers"]] == [("ARMATURE", arm["name"])]
    names = bone_names(w.motion)
    used = sorted({names[j] for j, wt in zip(boxes.joint_indices.ravel(), boxes.joint_weights.ravel()) if wt > 0})
    assert sorted(mesh["vertex_groups"]) == used
    assert set(mesh["vertex_groups"]) <= set(arm["bone_names"])
    for v, got in zip(mesh["vertex_indices"], mesh["weights"]):
        want = {names[j]: wt for j, wt in zip(boxes.joint_indices[v], boxes.joint_weights[v]) if wt > 0}
        assert got.keys() == want.keys(), f"vertex {v}: groups {sorted(got)}, want {sorted(want)}"
        for name, wt in want.items():
            assert abs(got[name] - wt) <= WEIGHT_TOL, f"vertex {v}, group {name}: {got[name]} vs {wt}"


@pytest.mark.parametrize("case", MESH_CASES, ids=[c.id for c in MESH_CASES])
def test_mesh_deforms_like_our_skinning(blender_run, case):
    """Blender's deformed vertices (world) equal mpu · C · LBS(our FK), which equals usd-core's skinning."""
    w, entry = case_result(blender_run, case)
    motion, boxes = w.motion, w.boxes
    expected_stage = lbs(motion, boxes, w.frames)
    height = skeleton_height(motion)
    np.testing.assert_allclose(usd_skinned_points(w.path, w.frames), expected_stage, rtol=0,
                               atol=POSITION_TOL * height, err_msg="usd-core skinning differs from ours")
    mesh = entry["meshes"][0]
    to_blender = stage_to_blender(motion)[:3, :3]
    height_m = height * motion.meters_per_unit
    for k, f in enumerate(w.frames):
        expected = expected_stage[k][mesh["vertex_indices"]] @ to_blender.T
        got = np.array(mesh["poses"][str(f)]["world_vertices"])
        error = np.linalg.norm(got - expected, axis=1)
        assert error.max() <= POSITION_TOL * height_m, (
            f"frame {f}: vertex {mesh['vertex_indices'][int(np.argmax(error))]} is {error.max():.3g} m off")
    # The check has teeth: the skinned vertices move far from where they were bound.
    moved = np.linalg.norm(expected_stage - expected_stage[:1], axis=-1).max() * motion.meters_per_unit
    assert moved > 100 * POSITION_TOL * height_m


def test_invalid_joint_paths_are_caught(blender_run):
    """Negative control: Blender drops a skeleton with raw 'mixamorig:' joint paths (0 bones,
    a warning). The bone-count and warning checks above would catch our writer doing that."""
    _, by_path = blender_run
    entry = next(e for p, e in by_path.items() if p.endswith("invalid_joint_paths.usda"))
    assert entry["ok"]
    assert [a["n_bones"] for a in entry["armatures"]] in ([0], [])
    assert any("invalid or duplicated" in line for line in entry["warnings"]), entry["warnings"]


def test_probe_survives_bad_input(blender_run):
    """A non-USD file and a missing file give an error entry each; the run goes on."""
    _, by_path = blender_run
    garbage = next(e for p, e in by_path.items() if p.endswith("garbage.usda"))
    missing = next(e for p, e in by_path.items() if p.endswith("missing.usda"))
    assert not garbage["ok"] and "USD" in garbage["error"]
    assert not missing["ok"] and missing["error"] == "no such file"
