"""glTF 2.0 writing: ``Motion`` (and optionally its skinned body) → ``.glb`` / ``.gltf``.

Layout written (pygltflib holds the container, NumPy the arrays)::

    scene 0: [joint node 0 (root), ..., "Body" mesh node]
    nodes 0 … J-1   one per joint, End Sites included, named as in the motion; rest TRS
                    (translation = OFFSET, no rotation), children as in the hierarchy
    node J          "Body" (``mesh=True`` only): mesh 0, skin 0
    skin 0          joints 0 … J-1, skeleton 0, inverseBindMatrices (J, 4×4)
    animation 0     per joint: rotation (LINEAR, F × xyzw); translation for the root and
                    for joints whose local translation changes; input times i / fps (s)

* Units and axes: glTF is metres and +Y up. Every length is multiplied by
  ``meters_per_unit``; a Z-up motion is turned by ``Rx(-90°)`` (``(x, y, z) → (x, z, -y)``)
  at the root (its rotation and translation), so world positions are
  ``mpu · R · joint_positions(motion)``.
* The mesh (``usdmotion.skin.build_body``, 4 influences per vertex, rows summing to 1) is
  in the same space; its inverse bind matrices are the body's bind transforms in glTF
  space, so glTF's skinning ``Σ w · jointWorld · inverseBind · v`` is
  :func:`usdmotion.skin.lbs`.
* ``skins[0].extras["usdmotion"]`` keeps what glTF has no place for (source units and up
  axis, End Site flags, BVH channel layout, root-offset convention, the exact fps), so
  :func:`usdmotion.io.gltf_read.read_gltf` restores the motion it came from.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError
from usdmotion.io.atomic import atomic_output
from usdmotion.io.gltf_read import EXTRAS_KEY, up_rotation
from usdmotion.kinematics import compose_transforms, local_translations, rest_pose
from usdmotion.motion import Motion
from usdmotion.rotations import quat_mul, quat_normalize, quat_rotate, quat_to_matrix, wxyz_to_xyzw

GLTF_EXTENSIONS = (".glb", ".gltf")
BODY_COLOR = (0.80, 0.62, 0.52, 1.0)  # linear RGBA, as the USD body's displayColor

_FLOAT, _UBYTE, _USHORT, _UINT = 5126, 5121, 5123, 5125
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963
_TYPES = {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


def gltf_frames(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local transforms in glTF space (metres, Y up).

    Returns:
        ``(rotations (F, J, 4) wxyz, translations (F, J, 3) m, rest_translations (J, 3) m)``;
        only the root's rotation and translation change besides the scale.
    """
    r = up_rotation(motion.up_axis)
    s = motion.meters_per_unit
    rotations = np.array(motion.rotations)
    rotations[:, 0] = quat_mul(r, rotations[:, 0])
    translations = local_translations(motion) * s
    translations[:, 0] = quat_rotate(r, translations[:, 0])
    rest = motion.offsets * s
    rest[0] = quat_rotate(r, rest[0])
    return rotations, translations, rest


def gltf_transforms(transforms: np.ndarray, meters_per_unit: float, up_axis: str) -> np.ndarray:
    """World transforms ``(..., 4, 4)`` (file units and axes) → glTF space: ``C · T · S⁻¹`` with
    ``C`` = scale × up rotation, ``S`` = scale (rotation turned, translation scaled and turned)."""
    r = up_rotation(up_axis)
    out = np.array(transforms, dtype=np.float64)
    rot = quat_to_matrix(r)
    out[..., :3, :3] = rot @ out[..., :3, :3]
    out[..., :3, 3] = (out[..., :3, 3] * meters_per_unit) @ rot.T
    return out


class _Blob:
    """The binary chunk under construction: aligned arrays, their bufferViews and accessors."""

    def __init__(self, gltf):
        self.gltf = gltf
        self.parts: list[bytes] = []
        self.size = 0

    def view(self, array: np.ndarray, target: int | None = None) -> int:
        import pygltflib

        data = np.ascontiguousarray(array).tobytes()
        pad = (-self.size) % 4
        if pad:
            self.parts.append(b"\0" * pad)
            self.size += pad
        self.gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=self.size, byteLength=len(data),
                                                          target=target))
        self.parts.append(data)
        self.size += len(data)
        return len(self.gltf.bufferViews) - 1

    def accessor(self, view: int, array: np.ndarray, offset: int = 0, bounds: bool = False) -> int:
        """Accessor of ``array`` ``(N, C)`` or ``(N,)`` stored at ``offset`` bytes in ``view``."""
        import pygltflib

        components = 1 if array.ndim == 1 else int(np.prod(array.shape[1:]))
        kind = {np.dtype(np.float32): _FLOAT, np.dtype(np.uint8): _UBYTE, np.dtype(np.uint16): _USHORT,
                np.dtype(np.uint32): _UINT}[array.dtype]
        flat = array.reshape(len(array), components)
        accessor = pygltflib.Accessor(bufferView=view, byteOffset=offset, componentType=kind, count=len(array),
                                      type=_TYPES[components])
        if bounds:
            cast = float if kind == _FLOAT else int
            accessor.min = [cast(v) for v in flat.min(axis=0)]
            accessor.max = [cast(v) for v in flat.max(axis=0)]
        self.gltf.accessors.append(accessor)
        return len(self.gltf.accessors) - 1

    def array(self, array: np.ndarray, target: int | None = None, bounds: bool = False) -> int:
        """One array in its own bufferView; returns the accessor index."""
        return self.accessor(self.view(array, target), array, bounds=bounds)

    def bytes(self) -> bytes:
        return b"".join(self.parts)


def _animated_translations(translations: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """Joints ``(K,)`` whose local translation needs a channel: the root, and any joint whose
    translation ``(F, J, 3)`` differs from its rest translation ``(J, 3)`` at some frame."""
    moving = np.any(translations != rest, axis=(0, 2))
    moving[0] = True
    return np.flatnonzero(moving)


def build_gltf(motion: Motion, *, mesh: bool = False, fps: float | None = None, body=None, name: str = "Motion"):
    """A ``pygltflib.GLTF2`` document for ``motion`` with its binary blob set.

    Args:
        motion: the motion (any units and up axis).
        mesh: add the skinned volumetric body (``usdmotion.skin.build_body``).
        fps: resample to this rate first (``usdmotion.ops.edit.timewarp.resample``); ``None``
            keeps the capture's rate.
        body: a ready :class:`usdmotion.skin.Body` for ``motion`` (implies ``mesh``).
        name: the scene's and skin's name.
    """
    import pygltflib

    if fps is not None and not np.isclose(fps, motion.fps, rtol=1e-12, atol=0.0):
        from usdmotion.ops.edit.timewarp import resample  # an fps change only

        motion = resample(motion, fps)
    if (mesh or body is not None) and body is None:
        from usdmotion.skin import build_body  # a mesh only

        body = build_body(motion)

    gltf = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0", generator="usdmotion"))
    blob = _Blob(gltf)
    rotations, translations, rest = gltf_frames(motion)
    n_joints, n_frames = motion.n_joints, motion.n_frames
    children = [[] for _ in range(n_joints)]
    for j, p in enumerate(motion.parents[1:].tolist(), start=1):
        children[p].append(j)
    for j in range(n_joints):
        gltf.nodes.append(pygltflib.Node(name=motion.joint_names[j], translation=[float(v) for v in rest[j]],
                                         children=children[j] or None))
    gltf.nodes[0].rotation = [float(v) for v in wxyz_to_xyzw(up_rotation(motion.up_axis))]
    if np.allclose(gltf.nodes[0].rotation, [0, 0, 0, 1]):
        gltf.nodes[0].rotation = None

    if body is None:
        bind_world = compose_transforms(*rest_pose(motion))
    else:
        bind_world = body.bind_transforms
    bind = gltf_transforms(bind_world, motion.meters_per_unit, motion.up_axis)
    inverse_bind = np.linalg.inv(bind)
    inverse_bind[:, 3] = (0.0, 0.0, 0.0, 1.0)  # exact affine last row (validator checks it)
    ibm = blob.array(np.swapaxes(inverse_bind, -1, -2).astype(np.float32))  # column-major
    extras = {
        "sourceMetersPerUnit": motion.meters_per_unit,
        "sourceUpAxis": motion.up_axis,
        "fps": motion.fps,
        "endSites": [int(j) for j in np.flatnonzero(motion.end_sites)],
        "rootOffset": motion.root_offset,
    }
    if motion.channels is not None:
        extras["channels"] = [" ".join(c) for c in motion.channels]
    gltf.skins.append(pygltflib.Skin(name=name, joints=list(range(n_joints)), skeleton=0, inverseBindMatrices=ibm,
                                     extras={EXTRAS_KEY: extras}))
    scene_nodes = [0]

    if body is not None:
        scene_nodes.append(_add_body(gltf, blob, body, motion))

    if n_frames:
        _add_animation(gltf, blob, motion, rotations, translations, rest, name)

    gltf.scenes.append(pygltflib.Scene(name=name, nodes=scene_nodes))
    gltf.scene = 0
    data = blob.bytes()
    gltf.buffers.append(pygltflib.Buffer(byteLength=len(data)))
    gltf.set_binary_blob(data)
    return gltf


def _add_body(gltf, blob: _Blob, body, motion: Motion) -> int:
    """Mesh, material and node of the skinned body; returns the node index."""
    import pygltflib

    r = up_rotation(motion.up_axis)
    vertices = (quat_rotate(r, body.vertices * motion.meters_per_unit)).astype(np.float32)
    normals = quat_rotate(r, body.normals).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    index_type = np.uint16 if len(vertices) < 65535 else np.uint32
    joint_type = np.uint8 if motion.n_joints <= 256 else np.uint16
    weights = body.joint_weights.astype(np.float32)
    weights[weights < 0] = 0
    joints = np.where(weights > 0, body.joint_indices, 0).astype(joint_type)
    weights /= weights.sum(axis=1, keepdims=True)
    attributes = pygltflib.Attributes(
        POSITION=blob.array(vertices, _ARRAY_BUFFER, bounds=True),
        NORMAL=blob.array(normals, _ARRAY_BUFFER),
        JOINTS_0=blob.array(joints, _ARRAY_BUFFER),
        WEIGHTS_0=blob.array(weights, _ARRAY_BUFFER),
    )
    indices = blob.array(body.faces.reshape(-1).astype(index_type), _ELEMENT_ARRAY_BUFFER)
    gltf.materials.append(pygltflib.Material(
        name="Skin", pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
            baseColorFactor=list(BODY_COLOR), metallicFactor=0.0, roughnessFactor=0.75)))
    gltf.meshes.append(pygltflib.Mesh(name="Body", primitives=[
        pygltflib.Primitive(attributes=attributes, indices=indices, material=0, mode=4)]))
    gltf.nodes.append(pygltflib.Node(name="Body", mesh=0, skin=0))
    return len(gltf.nodes) - 1


def _add_animation(gltf, blob: _Blob, motion: Motion, rotations: np.ndarray, translations: np.ndarray,
                   rest: np.ndarray, name: str) -> None:
    """One LINEAR sampler per animated joint property, all sharing the time accessor."""
    import pygltflib

    n_frames, n_joints = motion.n_frames, motion.n_joints
    times = (np.arange(n_frames) / motion.fps).astype(np.float32)
    time_accessor = blob.array(times, bounds=True)
    animation = pygltflib.Animation(name=name)
    # rotations: (J, F, 4) xyzw float32 in one view, one accessor per joint
    quats = quat_normalize(np.moveaxis(wxyz_to_xyzw(rotations), 1, 0)).astype(np.float32)
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    rot_view = blob.view(quats)
    moving = _animated_translations(translations, rest)
    trans = np.ascontiguousarray(np.moveaxis(translations[:, moving], 1, 0)).astype(np.float32)
    trans_view = blob.view(trans)
    for j in range(n_joints):
        out = blob.accessor(rot_view, quats[j], offset=j * n_frames * 16)
        animation.samplers.append(pygltflib.AnimationSampler(input=time_accessor, output=out,
                                                             interpolation="LINEAR"))
        animation.channels.append(pygltflib.AnimationChannel(
            sampler=len(animation.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=j, path="rotation")))
    for k, j in enumerate(moving.tolist()):
        out = blob.accessor(trans_view, trans[k], offset=k * n_frames * 12)
        animation.samplers.append(pygltflib.AnimationSampler(input=time_accessor, output=out,
                                                             interpolation="LINEAR"))
        animation.channels.append(pygltflib.AnimationChannel(
            sampler=len(animation.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=j, path="translation")))
    gltf.animations.append(animation)


def _plain(value):
    """JSON-ready form of a pygltflib object tree: ``None`` and empty lists / dicts left out
    (what pygltflib's own ``to_json`` does, without its deep copies: 3× faster here)."""
    if type(value).__module__.startswith("pygltflib"):  # its dataclasses and its Attributes class
        value = {k: v for k, v in vars(value).items() if not k.startswith("_")}
    if isinstance(value, dict):
        out = {k: _plain(v) for k, v in value.items() if v is not None}
        return {k: v for k, v in out.items() if not (isinstance(v, (list, dict)) and not v)}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _json_bytes(gltf) -> bytes:
    import json

    return json.dumps(_plain(gltf), separators=(",", ":"), allow_nan=False).encode("utf-8")


def pack_glb(json_chunk: bytes, binary_chunk: bytes) -> bytes:
    """A GLB container: 12-byte header, JSON chunk (space-padded), BIN chunk (zero-padded)."""
    import struct

    json_chunk += b" " * (-len(json_chunk) % 4)
    binary_chunk += b"\0" * (-len(binary_chunk) % 4)
    total = 12 + 8 + len(json_chunk) + (8 + len(binary_chunk) if binary_chunk else 0)
    parts = [b"glTF", struct.pack("<II", 2, total), struct.pack("<II", len(json_chunk), 0x4E4F534A), json_chunk]
    if binary_chunk:
        parts += [struct.pack("<II", len(binary_chunk), 0x004E4942), binary_chunk]
    return b"".join(parts)


def glb_bytes(motion: Motion, *, mesh: bool = False, fps: float | None = None, body=None,
              name: str = "Motion") -> bytes:
    """The motion as a binary glTF (GLB) document, in memory (e.g. for a web player).

    ``mesh`` adds the skinned body (``JOINTS_0``/``WEIGHTS_0``); ``fps`` resamples first
    (``None``: the capture's rate). See :func:`build_gltf`.
    """
    gltf = build_gltf(motion, mesh=mesh, fps=fps, body=body, name=name)
    return pack_glb(_json_bytes(gltf), gltf.binary_blob())


def write_gltf(motion: Motion, path: str | os.PathLike, *, mesh: bool = False, fps: float | None = None,
               body=None, name: str | None = None) -> Path:
    """Write ``motion`` as ``.glb`` (one binary file) or ``.gltf`` (JSON with the buffer
    embedded as a data URI), atomically.

    Args:
        motion: the motion.
        path: output file; the extension picks GLB or glTF JSON.
        mesh: add the skinned body.
        fps: resample to this rate first (``None``: the capture's rate).
        body: a ready body (implies ``mesh``).
        name: scene/skin/animation name (default: the file stem).
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in GLTF_EXTENSIONS:
        raise OutputError(f"{path}: unknown glTF extension {ext!r} (use .glb or .gltf)")
    name = name or path.stem.split(".")[0] or "Motion"
    if ext == ".glb":
        data = glb_bytes(motion, mesh=mesh, fps=fps, body=body, name=name)
    else:
        import base64

        gltf = build_gltf(motion, mesh=mesh, fps=fps, body=body, name=name)
        gltf.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(gltf.binary_blob()).decode()
        data = _json_bytes(gltf)
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)
    return path
