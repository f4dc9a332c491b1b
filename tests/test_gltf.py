"""glTF 2.0 / GLB (issue 12): the writer checked by the Khronos glTF-Validator and by an
independent reading of the file, round trips through our reader, ``convert`` options, and
bad inputs (one line, exit 2, no output).

Independent checks:

* the Khronos glTF-Validator (npm ``gltf-validator``, pinned in ``tests/gltf_validator``,
  installed by ``scripts/setup.sh``), run once through node for every file written here;
* ``gltf_world_positions`` below reads a GLB with pygltflib only and composes node
  matrices with SciPy (no usdmotion code), so the file itself, not our reader, is checked
  against our FK: world position of joint j at frame i = ``mpu · R_up · FK``.
"""

from __future__ import annotations

import json
import shutil
import struct
import subprocess

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import REPO, shared_path
from usdmotion.cli import main
from usdmotion.io import read_motion, write_motion
from usdmotion.io.gltf import build_gltf, glb_bytes, write_gltf
from usdmotion.kinematics import joint_positions, skeleton_height
from usdmotion.ops.edit.timewarp import resample
from usdmotion.skin import INFLUENCES

VALIDATOR = REPO / "tests" / "gltf_validator"
ROUND_TRIP_TOL = 1e-5   # × height: float32 storage of rotations and translations
FILE_TOL = 1e-5         # × height: file (read independently) vs our FK

#: (id, shared file, units, up axis, first N frames) — diverse rigs, units and layouts
FILES = (
    ("cmu_cgspeed_walk", "cmu/cgspeed_12_01_walk.bvh", "asf", None, 240),
    ("daz_soccer_kick", "cmu/daz_10_01_soccer_kick.bvh", None, None, 200),
    ("bandai_position_channels", "bandai1/dataset-1_dash_normal_001.bvh", None, None, None),
    ("rokoko_60_joints", "other_rigs/ad_rokoko_jesse_dance.bvh", None, None, 120),
    ("mixamo_colon_names", "other_rigs/20tab_test_freebvh_mixamorig.bvh", None, None, 120),
    ("mixamo_6_channels_everywhere", "other_rigs/ad_mixamo_Boxing.bvh", None, None, 120),
    ("zup_inch_no_end_sites", "other_rigs/ad_cartwheel_clean.bvh", "in", "Z", 120),
    ("zup_inch_mixed_orders", "edge_cases/pybvh_bvh_example_mixed_orders_zup.bvh", "in", "Z", None),
    ("moving_joint_translations", "edge_cases/wspr_milad_blank_line_6ch_125fps.bvh", None, None, 150),
    ("metres_3dsmax", "cmu/max_131_01_start_walk_stop_scaled_metres.bvh", "m", None, 120),
)
MESH_IDS = ("cmu_cgspeed_walk", "mixamo_colon_names", "zup_inch_no_end_sites", "bandai_position_channels",
            "rokoko_60_joints", "daz_soccer_kick", "mixamo_6_channels_everywhere", "metres_3dsmax")


def load(case):
    _, relative, units, up_axis, frames = case
    motion = read_motion(shared_path(relative), units=units, up_axis=up_axis)
    return motion if frames is None else motion.sliced(0, frames)


def gltf_world_positions(path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """``(joint names, key times (F,), world positions (F, J, 3))`` of skin 0, read with
    pygltflib and SciPy only (frame i = key i of every channel, as the writer promises)."""
    import pygltflib

    gltf = pygltflib.GLTF2.load(str(path))
    blob = gltf.binary_blob()

    def accessor(index):
        a = gltf.accessors[index]
        view = gltf.bufferViews[a.bufferView]
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a.type]
        start = (view.byteOffset or 0) + (a.byteOffset or 0)
        return np.frombuffer(blob, "<f4", count=a.count * width, offset=start).reshape(a.count, width)

    joints = gltf.skins[0].joints
    animation = gltf.animations[0]
    times = accessor(animation.samplers[0].input)[:, 0]
    n = len(times)
    local = {}
    for k, node in enumerate(gltf.nodes):
        t = np.tile(node.translation or [0, 0, 0], (n, 1)).astype(float)
        q = np.tile(node.rotation or [0, 0, 0, 1], (n, 1)).astype(float)
        local[k] = [q, t]
    for channel in animation.channels:
        values = accessor(animation.samplers[channel.sampler].output).astype(float)
        local[channel.target.node][0 if channel.target.path == "rotation" else 1] = values
    parent = {c: k for k, node in enumerate(gltf.nodes) for c in node.children or []}
    world = {}

    def matrix(k):
        if k not in world:
            m = np.tile(np.eye(4), (n, 1, 1))
            m[:, :3, :3] = Rotation.from_quat(local[k][0]).as_matrix()  # SciPy quaternions are xyzw, as glTF
            m[:, :3, 3] = local[k][1]
            world[k] = m if k not in parent else matrix(parent[k]) @ m
        return world[k]

    positions = np.stack([matrix(j)[:, :3, 3] for j in joints], axis=1)
    return [gltf.nodes[j].name for j in joints], times, positions


def to_gltf_space(points, motion) -> np.ndarray:
    """File coordinates → glTF's metres, Y up (Z-up: ``(x, y, z) → (x, z, -y)``)."""
    p = np.asarray(points) * motion.meters_per_unit
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1) if motion.up_axis == "Z" else p


def validate(paths) -> dict:
    """Khronos glTF-Validator reports by path (skips where node or the package is missing)."""
    node = shutil.which("node")
    if node is None or not (VALIDATOR / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("the Khronos glTF-Validator is not installed (needs node/npm; run scripts/setup.sh)")
    out = subprocess.run([node, str(VALIDATOR / "validate.js"), *map(str, paths)], capture_output=True, text=True,
                         timeout=600, check=True)
    return {r["path"]: r for r in json.loads(out.stdout)}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """Every FILES case as GLB, and the MESH_IDS ones with --mesh too: {(id, mesh): (path, motion)}."""
    tmp = tmp_path_factory.mktemp("gltf")
    out = {}
    for case in FILES:
        motion = load(case)
        for mesh in (False, True) if case[0] in MESH_IDS else (False,):
            path = tmp / f"{case[0]}{'_mesh' if mesh else ''}.glb"
            write_motion(motion, path, mesh=mesh)
            out[case[0], mesh] = path, motion
    gltf = tmp / "cmu_cgspeed_walk.gltf"
    write_motion(out["cmu_cgspeed_walk", False][1], gltf)
    out["cmu_cgspeed_walk_json", False] = gltf, out["cmu_cgspeed_walk", False][1]
    return out


def test_khronos_validator_reports_no_errors_or_warnings(written):
    reports = validate([path for path, _ in written.values()])
    assert len(reports) >= 19
    for (case, mesh), (path, _) in written.items():
        report = reports[str(path)]
        assert report["errors"] == 0 and report["warnings"] == 0, (case, mesh, report["messages"][:5])
        infos = {(m["code"], m["pointer"]) for m in report["messages"]}
        # a skin no mesh uses is only an "info" (docs/gltf.md); with the body the skin is used
        assert infos <= ({("UNUSED_OBJECT", "/skins/0")} if not mesh else set()), (case, infos)


def test_file_positions_equal_our_fk(written):
    """Read independently (pygltflib + SciPy), every GLB's joints sit where our FK puts them."""
    for (case, mesh), (path, motion) in written.items():
        if path.suffix != ".glb":
            continue
        names, times, positions = gltf_world_positions(path)
        assert names == list(motion.joint_names)
        np.testing.assert_allclose(times, np.arange(motion.n_frames) / motion.fps, rtol=1e-6, atol=1e-6)
        expected = to_gltf_space(joint_positions(motion), motion)
        height = skeleton_height(motion) * motion.meters_per_unit
        error = np.abs(positions - expected).max() / height
        assert error <= FILE_TOL, (case, mesh, error)


def test_body_mesh_has_four_normalised_influences(written):
    import pygltflib

    path, motion = written["zup_inch_no_end_sites", True]
    gltf = pygltflib.GLTF2.load(str(path))
    primitive = gltf.meshes[0].primitives[0]
    blob = gltf.binary_blob()

    def read(index, dtype, width):
        a = gltf.accessors[index]
        view = gltf.bufferViews[a.bufferView]
        return np.frombuffer(blob, dtype, a.count * width, (view.byteOffset or 0) + (a.byteOffset or 0)).reshape(
            a.count, width)

    joints = read(primitive.attributes.JOINTS_0, np.uint8, INFLUENCES)
    weights = read(primitive.attributes.WEIGHTS_0, "<f4", INFLUENCES)
    positions = read(primitive.attributes.POSITION, "<f4", 3)
    assert gltf.nodes[-1].skin == 0 and gltf.nodes[-1].mesh == 0
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)
    assert joints.max() < motion.n_joints and (weights >= 0).all()
    # Y-up metres: the cartwheel rig (Z-up inches) stands along +Y at about human size
    extent = np.ptp(positions, axis=0)
    assert extent[1] == extent.max() and 1.0 < extent[1] < 2.5, extent


@pytest.mark.parametrize("case_id", ["cmu_cgspeed_walk", "zup_inch_no_end_sites", "bandai_position_channels",
                                     "mixamo_colon_names", "moving_joint_translations"])
def test_bvh_glb_bvh_round_trip(case_id, tmp_path, capsys):
    case = next(c for c in FILES if c[0] == case_id)
    source = shared_path(case[1])
    motion = load(case)
    options = [*(["--units", case[2]] if case[2] else []), *(["--up-axis", case[3]] if case[3] else [])]
    assert main(["convert", str(source), str(tmp_path / "a.glb"), *options]) == 0
    assert main(["convert", str(tmp_path / "a.glb"), str(tmp_path / "b.bvh")]) == 0
    back = read_motion(tmp_path / "b.bvh", units=case[2], up_axis=case[3])
    full = read_motion(source, units=case[2], up_axis=case[3])
    assert back.joint_names == full.joint_names and back.n_frames == full.n_frames
    assert np.array_equal(back.end_sites, full.end_sites) and back.channels == full.channels
    assert back.fps == pytest.approx(full.fps, rel=1e-12)
    error = np.abs(joint_positions(back) - joint_positions(full)).max() / skeleton_height(full)
    assert error <= ROUND_TRIP_TOL, error
    del motion


def test_usd_glb_usd_round_trip(shared_file, tmp_path, capsys):
    from pxr import Usd, UsdGeom, UsdSkel

    source = shared_file("other_rigs/ad_cartwheel_clean.bvh")
    assert main(["convert", str(source), str(tmp_path / "a.usdc"), "--units", "in", "--up-axis", "Z"]) == 0
    assert main(["convert", str(tmp_path / "a.usdc"), str(tmp_path / "b.glb")]) == 0
    assert main(["convert", str(tmp_path / "b.glb"), str(tmp_path / "c.usda")]) == 0

    def usd_world(path):  # usd-core's own joint world transforms, every time code
        stage = Usd.Stage.Open(str(path))
        skel = UsdSkel.Skeleton(stage.GetPrimAtPath(stage.GetDefaultPrim().GetPath().AppendChild("Skeleton")))
        query = UsdSkel.Cache().GetSkelQuery(skel)
        times = range(int(stage.GetEndTimeCode()) + 1)
        return (np.stack([np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(t)))[:, 3, :3] for t in times]),
                UsdGeom.GetStageMetersPerUnit(stage), UsdGeom.GetStageUpAxis(stage))

    a, mpu_a, up_a = usd_world(tmp_path / "a.usdc")
    c, mpu_c, up_c = usd_world(tmp_path / "c.usda")
    assert (mpu_a, up_a) == (mpu_c, up_c) and a.shape == c.shape
    height = np.ptp(a[0], axis=0).max()
    assert np.abs(a - c).max() / height <= ROUND_TRIP_TOL


def test_gltf_json_reads_like_glb(written):
    glb = read_motion(written["cmu_cgspeed_walk", False][0])
    gltf = read_motion(written["cmu_cgspeed_walk_json", False][0])
    assert np.array_equal(joint_positions(glb), joint_positions(gltf))


def test_fps_option_resamples_with_the_library(shared_file, tmp_path, capsys):
    source = shared_file("cmu/cgspeed_12_01_walk.bvh")
    assert main(["convert", str(source), str(tmp_path / "w30.glb"), "--units", "asf", "--fps", "30", "--mesh"]) == 0
    motion = read_motion(source, units="asf")
    expected = resample(motion, 30.0)
    names, times, positions = gltf_world_positions(tmp_path / "w30.glb")
    assert len(times) == expected.n_frames and times[1] == pytest.approx(1 / 30)
    height = skeleton_height(motion) * motion.meters_per_unit
    assert np.abs(positions - to_gltf_space(joint_positions(expected), motion)).max() / height <= FILE_TOL
    assert read_motion(tmp_path / "w30.glb").fps == 30.0
    assert (tmp_path / "w30.glb").stat().st_size < len(glb_bytes(motion, mesh=True))


def test_glb_bytes_is_what_write_gltf_writes(shared_file, tmp_path):
    motion = read_motion(shared_file("bandai1/dataset-1_run_normal_001.bvh"))
    write_gltf(motion, tmp_path / "run.glb")
    assert (tmp_path / "run.glb").read_bytes() == glb_bytes(motion, name="run")


# ------------------------------------------------------------------------ bad inputs


def _glb(document: dict | bytes, binary: bytes | None) -> bytes:
    """A GLB container from a JSON document (or raw bytes for the JSON chunk) and a binary chunk."""
    text = document if isinstance(document, bytes) else json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary is not None:
        binary += b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """A small valid GLB as (document dict, binary chunk)."""
    import pygltflib

    motion = read_motion(shared_path("bandai1/dataset-1_run_normal_001.bvh")).sliced(0, 6)
    gltf = pygltflib.GLTF2.load_from_bytes(glb_bytes(motion))
    return json.loads(gltf.gltf_to_json()), gltf.binary_blob()


def _bad_files(good) -> dict[str, tuple[bytes, str]]:
    document, binary = good
    data = _glb(document, binary)
    out = {
        "truncated": (data[:len(data) // 2], "truncated GLB"),
        "wrong_magic": (b"gLTf" + data[4:], "not a GLB file"),
        "json_not_json": (_glb(b'{"asset": {"version": "2.0"}, "nodes": [', binary), "not valid JSON"),
        "empty": (b"", "truncated GLB"),
    }
    short = json.loads(json.dumps(document))
    short["buffers"][0]["byteLength"] = len(binary) // 2
    out["short_buffer"] = (_glb(short, binary[:len(binary) // 2]), "needs bytes")
    nan = bytearray(binary)
    rotation = document["animations"][0]["samplers"][0]["output"]
    accessor = document["accessors"][rotation]
    at = document["bufferViews"][accessor["bufferView"]].get("byteOffset", 0) + accessor.get("byteOffset", 0) + 8
    nan[at:at + 4] = struct.pack("<f", float("nan"))
    out["nan_accessor"] = (_glb(document, bytes(nan)), "non-finite value")
    no_skin = json.loads(json.dumps(document))
    del no_skin["skins"]
    out["no_skin"] = (_glb(no_skin, binary), "no skin")
    no_animation = json.loads(json.dumps(document))
    del no_animation["animations"]
    out["no_animation"] = (_glb(no_animation, binary), "no animation")
    two = json.loads(json.dumps(document))
    two["skins"].append({"name": "Other", "joints": two["skins"][0]["joints"][1:5]})
    out["two_skins"] = (_glb(two, binary), "2 skins with different joints")
    morph = json.loads(json.dumps(document))
    del morph["skins"]
    morph["animations"][0]["channels"] = [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]
    morph["animations"][0]["samplers"] = morph["animations"][0]["samplers"][:1]
    out["morph_only"] = (_glb(morph, binary), "morph-target weights only")
    return out


@pytest.mark.parametrize("kind", ["truncated", "wrong_magic", "json_not_json", "empty", "short_buffer",
                                  "nan_accessor", "no_skin", "no_animation", "two_skins", "morph_only"])
def test_bad_glb_one_line_exit_2_no_output(good, kind, tmp_path, capsys):
    data, message = _bad_files(good)[kind]
    bad = tmp_path / f"{kind}.glb"
    bad.write_bytes(data)
    for output in ("out.bvh", "out.usda", "out.glb"):
        assert main(["convert", str(bad), str(tmp_path / output)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"usdmotion: error: {bad}: "), err
        assert message in err[0], err
        assert not (tmp_path / output).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [bad.name]


def test_two_skins_pick_one_with_an_option(good, tmp_path, capsys):
    document, binary = good
    two = json.loads(json.dumps(document))
    two["skins"].append({"name": "Other", "joints": two["skins"][0]["joints"][1:5]})
    path = tmp_path / "two.glb"
    path.write_bytes(_glb(two, binary))
    assert main(["convert", str(path), str(tmp_path / "a.bvh"), "--skeleton", "0"]) == 0
    assert main(["convert", str(path), str(tmp_path / "b.bvh"), "--skeleton", "1"]) == 0
    assert main(["info", str(path), "--skeleton", "Other"]) == 0  # every reading command, by name too
    assert read_motion(tmp_path / "b.bvh").n_joints == 4
    assert read_motion(tmp_path / "a.bvh").n_joints == read_motion(path, skeleton="0").n_joints > 4
    assert main(["convert", str(path), str(tmp_path / "c.bvh"), "--skeleton", "5"]) == 2
    assert "--skeleton 5: no such skin" in capsys.readouterr().err
    assert not (tmp_path / "c.bvh").exists()


@pytest.mark.parametrize(("extras", "warning"), [
    ({"endSites": [0]}, "endSites that are not leaf joints"),  # the root, which has children
    ({"endSites": [2**70]}, "malformed usdmotion metadata"),  # past int64
    ({"channels": ["Xrotation Nope"]}, "channel layout"),  # one layout for every joint, and no such channel
])
def test_a_glb_source_layout_is_distrusted_as_usd_custom_data_is(good, tmp_path, capsys, extras, warning):
    """A fuzz find: a GLB whose usdmotion extras marked a joint with children as an End Site
    converted to a BVH whose End Site held a JOINT, exit 0, a file that did not read back.
    The extras now go through the USD reader's check (``channels.trusted_layout``)."""
    from usdmotion.errors import UsdMotionWarning

    document, binary = good
    changed = json.loads(json.dumps(document))
    changed["skins"][0].setdefault("extras", {}).setdefault("usdmotion", {}).update(extras)
    path = tmp_path / "layout.glb"
    path.write_bytes(_glb(changed, binary))
    with pytest.warns(UsdMotionWarning, match=warning):
        motion = read_motion(path)
    assert main(["convert", str(path), str(tmp_path / "out.bvh")]) == 0
    back = read_motion(tmp_path / "out.bvh")
    assert back.n_joints == motion.n_joints
    assert np.allclose(joint_positions(back), joint_positions(motion), atol=1e-4 * skeleton_height(motion))


def test_build_gltf_names_every_joint_node(shared_file):
    motion = read_motion(shared_file("other_rigs/20tab_test_freebvh_mixamorig.bvh")).sliced(0, 3)
    gltf = build_gltf(motion)
    assert [gltf.nodes[j].name for j in gltf.skins[0].joints] == list(motion.joint_names)
    assert any(":" in n for n in motion.joint_names)


def _append(document: dict, binary: bytes, array: np.ndarray, kind: str) -> tuple[bytes, int]:
    """Append float32 ``array`` to the binary chunk as a new bufferView + accessor; returns its index."""
    data = np.ascontiguousarray(array, "<f4").tobytes()
    binary += b"\0" * (-len(binary) % 4)
    document["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
    accessor = {"bufferView": len(document["bufferViews"]) - 1, "componentType": 5126, "count": len(array),
                "type": kind}
    if kind == "SCALAR":
        accessor.update(min=[float(array.min())], max=[float(array.max())])
    document["accessors"].append(accessor)
    binary += data
    document["buffers"][0]["byteLength"] = len(binary)
    return binary, len(document["accessors"]) - 1


def test_reader_samples_step_cubic_and_sparse_keys(good, tmp_path):
    """Foreign files key channels differently: STEP and CUBICSPLINE samplers, and channels
    with fewer keys than the others (Blender drops constant keys) are sampled at the file's
    frames: keys give their values, a 2-key LINEAR channel is interpolated in between."""
    import pygltflib

    document, binary = good
    path = tmp_path / "base.glb"
    path.write_bytes(_glb(document, binary))
    base = read_motion(path)

    step = json.loads(json.dumps(document))
    for sampler in step["animations"][0]["samplers"]:
        sampler["interpolation"] = "STEP"
    (tmp_path / "step.glb").write_bytes(_glb(step, binary))
    np.testing.assert_allclose(joint_positions(read_motion(tmp_path / "step.glb")), joint_positions(base),
                               atol=1e-5)  # cm

    cubic, blob = json.loads(json.dumps(document)), binary
    gltf = pygltflib.GLTF2.load_from_bytes(_glb(document, binary))
    for sampler in cubic["animations"][0]["samplers"]:
        values = gltf_accessor(gltf, sampler["output"])
        tangents = np.zeros_like(values)
        keyed = np.stack([tangents, values, tangents], 1).reshape(-1, values.shape[1])
        blob, sampler["output"] = _append(cubic, blob, keyed, "VEC4" if values.shape[1] == 4 else "VEC3")
        sampler["interpolation"] = "CUBICSPLINE"
    (tmp_path / "cubic.glb").write_bytes(_glb(cubic, blob))
    np.testing.assert_allclose(joint_positions(read_motion(tmp_path / "cubic.glb")), joint_positions(base), atol=1e-5)

    sparse = json.loads(json.dumps(document))
    channel = next(c for c in sparse["animations"][0]["channels"] if c["target"]["path"] == "translation")
    sampler = sparse["animations"][0]["samplers"][channel["sampler"]]
    times = gltf_accessor(gltf, sampler["input"])[:, 0]
    values = gltf_accessor(gltf, sampler["output"])
    blob, sampler["input"] = _append(sparse, binary, times[[0, -1]], "SCALAR")
    blob, sampler["output"] = _append(sparse, blob, values[[0, -1]], "VEC3")
    (tmp_path / "sparse.glb").write_bytes(_glb(sparse, blob))
    motion = read_motion(tmp_path / "sparse.glb")
    assert motion.n_frames == base.n_frames
    u = (times - times[0]) / (times[-1] - times[0])
    expected = (values[0] + u[:, None] * (values[-1] - values[0])) / base.meters_per_unit  # back to the source's cm
    np.testing.assert_allclose(motion.root_translation, expected, rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(motion.rotations, base.rotations, atol=1e-12)


def gltf_accessor(gltf, index: int) -> np.ndarray:
    """A float accessor ``(count, width)`` of a pygltflib document (tightly packed views only)."""
    a = gltf.accessors[index]
    view = gltf.bufferViews[a.bufferView]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[a.type]
    start = (view.byteOffset or 0) + (a.byteOffset or 0)
    return np.frombuffer(gltf.binary_blob(), "<f4", a.count * width, start).reshape(a.count, width).astype(float)


def test_nodes_above_the_skeleton_are_folded_into_the_root(good, tmp_path):
    """Mixamo/FBX-converted files put the skeleton under an "Armature" node with a rotation
    and a 0.01 scale (centimetre joints): world positions must include that transform."""
    document, binary = good
    path = tmp_path / "base.glb"
    path.write_bytes(_glb(document, binary))
    base = read_motion(path)
    wrapped = json.loads(json.dumps(document))
    del wrapped["skins"][0]["extras"]  # a foreign file: read in glTF's metres, Y up
    (tmp_path / "plain.glb").write_bytes(_glb(wrapped, binary))
    plain = read_motion(tmp_path / "plain.glb")
    angle = 0.3
    wrapped["nodes"].append({"name": "Armature", "children": [0], "scale": [0.01, 0.01, 0.01],
                             "rotation": [0.0, float(np.sin(angle / 2)), 0.0, float(np.cos(angle / 2))],
                             "translation": [1.0, 0.0, 2.0]})
    wrapped["scenes"][0]["nodes"] = [len(wrapped["nodes"]) - 1]
    # the joints' own numbers become centimetres
    for node in wrapped["nodes"][:-1]:
        if "translation" in node:
            node["translation"] = [100 * v for v in node["translation"]]
    grown = bytearray(binary)
    for channel in wrapped["animations"][0]["channels"]:
        if channel["target"]["path"] == "translation":
            a = wrapped["accessors"][wrapped["animations"][0]["samplers"][channel["sampler"]]["output"]]
            start = wrapped["bufferViews"][a["bufferView"]].get("byteOffset", 0) + a.get("byteOffset", 0)
            values = np.frombuffer(binary, "<f4", a["count"] * 3, start) * 100
            grown[start:start + values.nbytes] = values.astype("<f4").tobytes()
    (tmp_path / "wrapped.glb").write_bytes(_glb(wrapped, bytes(grown)))
    motion = read_motion(tmp_path / "wrapped.glb")
    assert motion.meters_per_unit == 1.0 and plain.meters_per_unit == 1.0
    turn = Rotation.from_rotvec([0.0, angle, 0.0]).as_matrix()
    expected = joint_positions(plain) @ turn.T + [1.0, 0.0, 2.0]
    np.testing.assert_allclose(joint_positions(motion), expected, atol=1e-6 * skeleton_height(plain))
    assert np.abs(joint_positions(plain) - to_gltf_space(joint_positions(base), base)).max() < 1e-6


def test_mutated_documents_never_crash(good, tmp_path):
    """Random wrong values and deleted keys in the JSON (pygltflib checks no types), node
    cycles and absurd key times: every read either succeeds or raises one UsdMotionError."""
    import random

    from usdmotion.errors import UsdMotionError

    document, binary = good
    cycle = json.loads(json.dumps(document))
    cycle["nodes"][1].setdefault("children", []).append(0)
    huge = json.loads(json.dumps(document))
    times = huge["animations"][0]["samplers"][0]["input"]
    grown = bytearray(binary)
    a = huge["accessors"][times]
    start = huge["bufferViews"][a["bufferView"]].get("byteOffset", 0) + a.get("byteOffset", 0)
    grown[start + 4 * (a["count"] - 1):start + 4 * a["count"]] = struct.pack("<f", 1e9)
    huge["accessors"][times]["max"] = [1e9]
    cases = {"cycle": (cycle, binary, "cycle"), "huge": (huge, bytes(grown), "more than usdmotion reads")}
    for name, (doc, blob, message) in cases.items():
        (tmp_path / f"{name}.glb").write_bytes(_glb(doc, blob))
        with pytest.raises(UsdMotionError, match=message):
            read_motion(tmp_path / f"{name}.glb")

    def leaves(node, trail=()):
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for key, value in items:
            yield trail + (key,)
            yield from leaves(value, trail + (key,))

    paths = list(leaves(document))
    rnd = random.Random(12)
    values = [None, -1, 0, 1, 10 ** 9, 2.5, "x", [], {}, [1, 2], True]
    outcomes = {"read": 0, "error": 0}
    for trial in range(60):
        doc = json.loads(json.dumps(document))
        for _ in range(rnd.randint(1, 3)):
            *parent_keys, last = rnd.choice(paths)
            try:
                parent = doc
                for key in parent_keys:
                    parent = parent[key]
                if isinstance(parent, dict) and rnd.random() < 0.3:
                    del parent[last]
                else:
                    parent[last] = rnd.choice(values)
            except (KeyError, IndexError, TypeError):
                pass  # an earlier mutation removed the path
        path = tmp_path / "mutated.glb"
        path.write_bytes(_glb(doc, binary))
        try:
            read_motion(path)
            outcomes["read"] += 1
        except UsdMotionError as exc:
            assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
            outcomes["error"] += 1
    assert outcomes["error"] > 10 and sum(outcomes.values()) == 60, outcomes
