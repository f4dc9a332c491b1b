"""glTF 2.0 reading: one skin and its skeletal animation (``.glb`` / ``.gltf``) → ``Motion``.

What Blender, Mixamo and online services export: a skin (joint nodes, a hierarchy) and an
animation of those nodes' rotation / translation. The reader

* checks the container itself (GLB header and chunks, JSON, buffer sizes, accessor ranges,
  finite values) and turns every problem into one :class:`~usdmotion.errors.InputError`;
* takes the joints of the skin (``skin=``, the CLI's ``--skeleton``, picks one of several),
  plus any node between them and their lowest common ancestor, parents before children;
  the transforms of the nodes above that root are folded into the root;
* samples every channel (LINEAR, STEP, CUBICSPLINE) at ``t0 + i / fps``, ``fps`` being the
  one usdmotion wrote (``skins[s].extras.usdmotion.fps``) or the median key spacing;
* returns metres, Y up, unless usdmotion wrote the file: then the source's units, up axis,
  End Sites, BVH channel layout and root-offset convention come back.
"""

from __future__ import annotations

import base64
import os
import struct
import warnings
from pathlib import Path

import numpy as np

from usdmotion.channels import trusted_layout
from usdmotion.errors import InputError, UsdMotionError, UsdMotionWarning
from usdmotion.motion import Motion
from usdmotion.rotations import (axis_angle_quat, matrix_to_quat, quat_conjugate, quat_mul, quat_normalize,
                                 quat_rotate, quat_slerp, xyzw_to_wxyz)
from usdmotion.schemas import parse_text

GLB_MAGIC = b"glTF"
EXTRAS_KEY = "usdmotion"  # skins[s].extras[EXTRAS_KEY]: what usdmotion keeps of the source (see io.gltf)
_JSON_CHUNK, _BIN_CHUNK = 0x4E4F534A, 0x004E4942
_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}


def up_rotation(up_axis: str) -> np.ndarray:
    """wxyz quaternion ``(4,)`` taking ``up_axis``-up coordinates to glTF's Y-up (``Rx(-90°)`` for Z)."""
    if up_axis == "Z":
        return axis_angle_quat("X", np.float64(-np.pi / 2))
    return np.array([1.0, 0.0, 0.0, 0.0])


def _glb_chunks(path: Path, data: bytes) -> tuple[bytes, bytes | None]:
    """``(json_bytes, bin_bytes or None)`` of a GLB file, with its header checked."""
    if len(data) < 12:
        raise InputError(path, f"truncated GLB: {len(data)} bytes, the header alone has 12")
    magic, version, length = struct.unpack_from("<4sII", data)
    if magic != GLB_MAGIC:
        raise InputError(path, f"not a GLB file (magic {magic!r}, expected b'glTF')")
    if version != 2:
        raise InputError(path, f"GLB version {version}; only glTF 2.0 is supported")
    if length > len(data):
        raise InputError(path, f"truncated GLB: the header says {length} bytes, the file has {len(data)}")
    chunks, at = [], 12
    while at < length:
        if at + 8 > length:
            raise InputError(path, f"truncated GLB: chunk header at byte {at} is cut off")
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise InputError(path, f"truncated GLB: chunk at byte {at} needs {size} bytes, {length - at - 8} are left")
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size + (-size % 4 if at + 8 + size < length else 0)
    if not chunks or chunks[0][0] != _JSON_CHUNK:
        raise InputError(path, "GLB without a JSON chunk first")
    binary = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == _BIN_CHUNK else None
    return chunks[0][1], binary


def _load(path: Path):
    """``(pygltflib.GLTF2, [buffer bytes, ...])`` with the container checked."""
    import pygltflib

    if not path.is_file():
        raise InputError(path, "no such file")
    data = path.read_bytes()
    binary = None
    if path.suffix.lower() == ".glb" or data[:4] == GLB_MAGIC:
        text, binary = _glb_chunks(path, data)
    else:
        text = data
    try:
        text = text.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(path, f"the glTF JSON is not UTF-8 text: {exc}") from None
    try:
        document = parse_text(text, path)  # bad syntax, NaN, absurd nesting: one line
    except InputError as exc:
        if binary is None and data[:4] != GLB_MAGIC:
            raise  # a .gltf: the line and column are the file's
        where = f" (line {exc.line}, column {exc.column} of the chunk)" if exc.line is not None else ""
        raise InputError(path, f"the GLB's JSON chunk: {exc.message}{where}") from None
    if not isinstance(document, dict):
        raise InputError(path, "the glTF JSON is not an object")
    version = str((document.get("asset") or {}).get("version", ""))
    if not version.startswith("2."):
        raise InputError(path, f"glTF version {version or '(missing)'}; only glTF 2.0 is supported")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gltf = pygltflib.GLTF2.from_dict(document)
    except Exception as exc:  # pygltflib/dataclasses_json: any malformed field  # noqa: BLE001
        raise InputError(path, f"malformed glTF JSON: {type(exc).__name__}: {exc}") from None
    return gltf, [_buffer(path, gltf, i, binary) for i in range(len(gltf.buffers or []))]


def _buffer(path: Path, gltf, index: int, binary: bytes | None) -> bytes:
    buffer = gltf.buffers[index]
    uri = buffer.uri
    if uri is None:
        if binary is None or index != 0:
            raise InputError(path, f"buffer {index} has no uri and there is no GLB binary chunk for it")
        data = binary
    elif uri.startswith("data:"):
        try:
            data = base64.b64decode(uri.split(",", 1)[1], validate=False)
        except (IndexError, ValueError) as exc:
            raise InputError(path, f"buffer {index}: bad data URI ({exc})") from None
    else:
        from urllib.parse import unquote

        external = path.parent / unquote(uri)
        if not external.is_file():
            raise InputError(path, f"buffer {index}: file {uri!r} not found beside the glTF")
        data = external.read_bytes()
    if buffer.byteLength is not None and len(data) < buffer.byteLength:
        raise InputError(path, f"buffer {index} is shorter ({len(data)} bytes) than its byteLength {buffer.byteLength}")
    return data


def _accessor(path: Path, gltf, buffers: list[bytes], index: int) -> np.ndarray:
    """Accessor ``index`` as float64 ``(count, components)``; checked for range and finiteness."""
    if index is None or not 0 <= index < len(gltf.accessors or []):
        raise InputError(path, f"accessor {index} does not exist")
    acc = gltf.accessors[index]
    if acc.sparse is not None:
        raise InputError(path, f"accessor {index} is sparse; sparse accessors are not supported")
    components = _COMPONENTS.get(acc.type)
    dtype = _DTYPES.get(acc.componentType)
    if components is None or dtype is None or acc.count is None or acc.count < 0:
        raise InputError(path, f"accessor {index}: unsupported type {acc.type}/{acc.componentType}")
    if acc.bufferView is None:
        return np.zeros((acc.count, components))
    if not 0 <= acc.bufferView < len(gltf.bufferViews or []):
        raise InputError(path, f"accessor {index}: bufferView {acc.bufferView} does not exist")
    view = gltf.bufferViews[acc.bufferView]
    if view.buffer is None or not 0 <= view.buffer < len(buffers):
        raise InputError(path, f"bufferView {acc.bufferView}: buffer {view.buffer} does not exist")
    item = np.dtype(dtype).itemsize
    element = item * components
    stride = view.byteStride or element
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    need = 0 if acc.count == 0 else (acc.count - 1) * stride + element
    view_end = (view.byteOffset or 0) + (view.byteLength or 0)
    data = buffers[view.buffer]
    if start + need > min(view_end, len(data)) or (acc.byteOffset or 0) + need > (view.byteLength or 0):
        raise InputError(path, f"accessor {index} needs bytes {start}…{start + need} of buffer {view.buffer}, "
                               f"which has {len(data)} (bufferView {acc.bufferView} ends at {view_end})")
    raw = np.frombuffer(data, np.uint8, count=need, offset=start) if need else np.zeros(0, np.uint8)
    if stride == element:
        values = raw.view(np.dtype(dtype).newbyteorder("<")).reshape(acc.count, components)
    else:
        rows = np.lib.stride_tricks.as_strided(raw, (acc.count, element), (stride, 1))
        values = np.ascontiguousarray(rows).view(np.dtype(dtype).newbyteorder("<")).reshape(acc.count, components)
    values = values.astype(np.float64)
    if acc.normalized and dtype is not np.float32:
        info = np.iinfo(dtype)
        values = np.maximum(values / info.max, -1.0)
    if not np.all(np.isfinite(values)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(values), axis=1))[0])
        raise InputError(path, f"accessor {index} has a non-finite value (NaN or infinity) at element {bad}")
    return values


# ------------------------------------------------------------------------ skeleton


def _parents(path: Path, gltf) -> np.ndarray:
    """Parent node of every node ``(N,)`` (-1: none); a node with two parents is an error."""
    parents = np.full(len(gltf.nodes or []), -1)
    for n, node in enumerate(gltf.nodes or []):
        children = node.children or []
        if not isinstance(children, list) or not all(type(c) is int for c in children):
            raise InputError(path, f"node {n}: children must be a list of node indices")
        for c in children:
            if not 0 <= c < len(parents):
                raise InputError(path, f"node {n} has a child {c} that does not exist")
            if parents[c] >= 0 or c == n:
                raise InputError(path, f"node {c} has two parents (or is its own child); glTF nodes form trees")
            parents[c] = n
    return parents


def _ancestors(path: Path, node: int, parents: np.ndarray) -> list[int]:
    """``[node, parent, …, scene root]``; a cycle is an error."""
    chain = [node]
    while parents[chain[-1]] >= 0:
        chain.append(int(parents[chain[-1]]))
        if len(chain) > len(parents):
            raise InputError(path, f"node {node}: its ancestors form a cycle")
    return chain


def _node_trs(path: Path, node) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(rotation wxyz (4,), translation (3,), scale (3,))`` of a node's static transform."""
    if node.matrix is not None and len(node.matrix) == 16:
        m = np.asarray(node.matrix, float).reshape(4, 4).T  # column-major in JSON
        scale = np.linalg.norm(m[:3, :3], axis=0)
        return matrix_to_quat(m[:3, :3] / np.where(scale > 0, scale, 1.0)), m[:3, 3], scale
    rotation = xyzw_to_wxyz(np.asarray(node.rotation if node.rotation is not None else [0, 0, 0, 1], float))
    translation = np.asarray(node.translation if node.translation is not None else [0, 0, 0], float)
    scale = np.asarray(node.scale if node.scale is not None else [1, 1, 1], float)
    if rotation.shape != (4,) or translation.shape != (3,) or scale.shape != (3,) or not (
            np.all(np.isfinite(rotation)) and np.all(np.isfinite(translation))):
        raise InputError(path, f"node {node.name!r} has a malformed transform")
    return quat_normalize(rotation), translation, scale


def _pick_skin(path: Path, gltf, skin: str | int | None) -> int:
    skins = gltf.skins or []
    if not skins:
        paths = {c.target.path for a in gltf.animations or [] for c in a.channels or [] if c.target is not None}
        if paths == {"weights"}:
            raise InputError(path, "no skin, and the animation drives morph-target weights only; usdmotion reads "
                                   "skeletal animation (a skin with joints and an animation of them)")
        raise InputError(path, "no skin in this glTF: usdmotion reads skeletal animation "
                               "(a skin with joints and an animation of them)")
    listing = ", ".join(f"{i} {s.name or '(unnamed)'!r} ({len(s.joints or [])} joints)" for i, s in enumerate(skins))
    if skin is not None:
        text = str(skin).strip()
        if text.isdigit() and 0 <= int(text) < len(skins):
            return int(text)
        named = [i for i, s in enumerate(skins) if s.name == text]
        if named:
            return named[0]
        raise InputError(path, f"--skeleton {text}: no such skin; the file has {listing}")
    distinct = {tuple(s.joints or []) for s in skins}
    if len(distinct) > 1:
        raise InputError(path, f"{len(skins)} skins with different joints ({listing}): choose one with "
                               "--skeleton INDEX|NAME")
    return 0


def _skeleton(path: Path, gltf, skin_index: int) -> tuple[list[int], np.ndarray]:
    """Joint nodes in parents-first order ``[node, ...]`` and their parent indices ``(J,)``."""
    node_parents = _parents(path, gltf)
    joints = gltf.skins[skin_index].joints or []
    if not joints or not isinstance(joints, list) or any(type(j) is not int or not 0 <= j < len(node_parents)
                                                         for j in joints):
        raise InputError(path, f"skin {skin_index} has no joints or names a node that does not exist")
    chains = [_ancestors(path, j, node_parents)[::-1] for j in joints]  # scene root … joint
    common = 0
    while all(len(c) > common for c in chains) and len({c[common] for c in chains}) == 1:
        common += 1
    if common == 0:
        raise InputError(path, f"skin {skin_index}: its joints are in separate node trees; one root is needed")
    keep = set()
    for c in chains:
        keep.update(c[common - 1:])
    root = chains[0][common - 1]
    order, stack = [], [root]
    while stack:  # depth-first, children in file order: parents come first
        n = stack.pop()
        order.append(n)
        stack.extend(c for c in reversed(gltf.nodes[n].children or []) if c in keep)
    position = {n: k for k, n in enumerate(order)}
    parents = np.array([-1] + [position[int(node_parents[n])] for n in order[1:]])
    return order, parents


def _names(gltf, order: list[int]) -> tuple[str, ...]:
    names, used = [], set()
    for n in order:
        base = gltf.nodes[n].name or f"joint{n}"
        name, k = base, 2
        while name in used:
            name, k = f"{base}_{k}", k + 1
        used.add(name)
        names.append(name)
    return tuple(names)


def _root_world(path: Path, gltf, root: int) -> tuple[np.ndarray, np.ndarray, float]:
    """World ``(rotation wxyz, translation, uniform scale)`` of the nodes above ``root``."""
    q, t, s = np.array([1.0, 0, 0, 0]), np.zeros(3), 1.0
    for n in _ancestors(path, root, _parents(path, gltf))[1:]:  # root's parent … scene root
        nq, nt, ns = _node_trs(path, gltf.nodes[n])
        if np.ptp(ns) > 1e-6 * max(abs(ns).max(), 1e-12):
            warnings.warn(f"{path}: node {gltf.nodes[n].name!r} above the skeleton has a non-uniform scale; "
                          "it is ignored", UsdMotionWarning, stacklevel=3)
        scale = float(np.mean(ns))
        q, t, s = quat_mul(nq, q), nt + scale * quat_rotate(nq, t), s * scale
    return q, t, s


# ----------------------------------------------------------------------- animation


def _pick_animation(path: Path, gltf, joint_nodes: set[int]) -> int:
    animations = gltf.animations or []
    if not animations:
        raise InputError(path, "no animation in this glTF: usdmotion reads skeletal animation")
    skeletal = [i for i, a in enumerate(animations)
                if any(c.target is not None and c.target.node in joint_nodes
                       and c.target.path in ("rotation", "translation", "scale") for c in a.channels or [])]
    if not skeletal:
        paths = {c.target.path for a in animations for c in a.channels or [] if c.target is not None}
        if paths == {"weights"}:
            raise InputError(path, "the animation drives morph-target weights only; usdmotion reads skeletal "
                                   "animation (joint rotations / translations)")
        raise InputError(path, "no animation of the skin's joints in this glTF")
    if len(skeletal) > 1:
        a = animations[skeletal[0]]
        warnings.warn(f"{path}: {len(skeletal)} animations; reading the first, {a.name or skeletal[0]!r}",
                      UsdMotionWarning, stacklevel=3)
    return skeletal[0]


def _sample(times: np.ndarray, keys: np.ndarray, values: np.ndarray, interpolation: str,
            rotation: bool, tolerance: float) -> np.ndarray:
    """One channel at ``times (F,)``: ``keys (K,)``, ``values (K, C)`` (``(3K, C)`` for CUBICSPLINE).

    A key within ``tolerance`` seconds of a time counts as reached (float32 key times are
    never exactly ``i / fps``; a STEP channel must not fall back to the previous key)."""
    if interpolation == "CUBICSPLINE":
        a, v, b = values[0::3], values[1::3], values[2::3]
    else:
        v = values
    if len(keys) == 1:
        out = np.repeat(v[:1], len(times), axis=0)
        return quat_normalize(out) if rotation else out
    i = np.clip(np.searchsorted(keys, times + tolerance, side="right") - 1, 0, len(keys) - 2)
    dt = keys[i + 1] - keys[i]
    u = np.clip((times - keys[i]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)[:, None]
    if interpolation == "STEP":
        out = np.where((times + tolerance >= keys[i + 1])[:, None], v[i + 1], v[i])
    elif interpolation == "CUBICSPLINE":
        u2, u3, d = u * u, u * u * u, dt[:, None]
        out = ((2 * u3 - 3 * u2 + 1) * v[i] + (u3 - 2 * u2 + u) * d * b[i]
               + (-2 * u3 + 3 * u2) * v[i + 1] + (u3 - u2) * d * a[i + 1])
    elif rotation:  # slerp only between keys: frames on a key (every frame, in most files) take it
        on_key = np.abs(times - keys[i]) <= tolerance
        on_next = ~on_key & (np.abs(times - keys[i + 1]) <= tolerance)
        out = np.where(on_next[:, None], v[i + 1], v[i])
        between = ~(on_key | on_next)
        if between.any():
            out[between] = quat_slerp(quat_normalize(v[i][between]), quat_normalize(v[i + 1][between]),
                                      u[between, 0])
    else:
        out = v[i] + u * (v[i + 1] - v[i])
    return quat_normalize(out) if rotation else out


MAX_SAMPLES = 50_000_000  # frames × joints read from one glTF animation (~1.6 GB of rotations)


def _frame_times(path: Path, keys: list[np.ndarray], fps: float | None, n_joints: int) -> tuple[np.ndarray, float]:
    """Frame times ``t0 + i / fps`` ``(F,)`` covering every channel's keys, and ``fps``."""
    start = min(float(k[0]) for k in keys)
    end = max(float(k[-1]) for k in keys)
    if fps is None:
        longest = max(keys, key=len)
        steps = np.diff(longest)
        if steps.size and steps.min() > 0 and np.ptp(steps) < 1e-3 * steps.mean():
            fps = (len(longest) - 1) / float(longest[-1] - longest[0])  # evenly sampled: the exact rate
        else:
            steps = np.concatenate([np.diff(k) for k in keys])
            steps = steps[steps > 1e-7]
            fps = 1.0 / float(np.median(steps)) if steps.size else 30.0
        if abs(fps - round(fps)) < 1e-6 * fps:
            fps = float(round(fps))
    count = (end - start) * fps + 1e-3
    if not np.isfinite(count) or (count + 1) * n_joints > MAX_SAMPLES:
        raise InputError(path, f"the animation spans {end - start:.6g} s at {fps:.6g} fps: {count:.3g} frames of "
                               f"{n_joints} joints, more than usdmotion reads ({MAX_SAMPLES:,} joint samples)")
    return start + np.arange(int(count) + 1) / fps, fps


def read_gltf(path: str | os.PathLike, skin: str | int | None = None) -> Motion:
    """Read the skin ``skin`` (index or name; default: the only one) of a glTF 2.0 file and
    its animation.

    Raises:
        InputError: unreadable container, no skin, several different skins and no
            ``skin``, no skeletal animation (or morph-target weights only), bad accessors,
            and any field of the wrong type (pygltflib does not check types: a string
            where an index belongs surfaces as a TypeError, reported as one line).
    """
    path = Path(path)
    try:
        return _read(path, skin)
    except UsdMotionError:
        raise
    except (TypeError, AttributeError, KeyError, IndexError, ValueError, OverflowError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise InputError(path, f"malformed glTF document ({type(exc).__name__}: {text})") from None


def _read(path: Path, skin: str | int | None) -> Motion:
    gltf, buffers = _load(path)
    skin_index = _pick_skin(path, gltf, skin)
    order, parents = _skeleton(path, gltf, skin_index)
    joint_of = {n: k for k, n in enumerate(order)}
    animation = gltf.animations[_pick_animation(path, gltf, set(order))]

    rest = [_node_trs(path, gltf.nodes[n]) for n in order]
    rest_q = np.stack([r[0] for r in rest])
    rest_t = np.stack([r[1] for r in rest])
    scales = np.stack([r[2] for r in rest])

    channels = []
    for c in animation.channels or []:
        if c.target is None or c.target.node not in joint_of or c.target.path not in ("rotation", "translation",
                                                                                     "scale"):
            continue
        if c.sampler is None or not 0 <= c.sampler < len(animation.samplers or []):
            raise InputError(path, f"animation channel on node {c.target.node} uses a sampler that does not exist")
        sampler = animation.samplers[c.sampler]
        keys = _accessor(path, gltf, buffers, sampler.input)[:, 0]
        values = _accessor(path, gltf, buffers, sampler.output)
        interpolation = sampler.interpolation or "LINEAR"
        width = {"rotation": 4, "translation": 3, "scale": 3}[c.target.path]
        expected = len(keys) * (3 if interpolation == "CUBICSPLINE" else 1)
        if not len(keys) or values.shape != (expected, width) or np.any(np.diff(keys) < 0):
            raise InputError(path, f"animation sampler {c.sampler}: {len(keys)} key times (increasing) and "
                                   f"{values.shape[0]} values of {values.shape[1]} for {c.target.path} do not match")
        if c.target.path == "rotation":
            values = xyzw_to_wxyz(values)
        channels.append((joint_of[c.target.node], c.target.path, keys, values, interpolation))
    if not any(path_ in ("rotation", "translation") for _, path_, *_ in channels):
        raise InputError(path, "the animation has no rotation or translation of the skin's joints")

    extras = (gltf.skins[skin_index].extras or {}).get(EXTRAS_KEY) if isinstance(
        gltf.skins[skin_index].extras, dict) else None
    extras = extras if isinstance(extras, dict) else {}
    fps = extras.get("fps")
    times, fps = _frame_times(path, [k for _, _, k, _, _ in channels],
                              float(fps) if isinstance(fps, (int, float)) and 0 < fps < 1e6 else None, len(order))
    n_frames, n_joints = len(times), len(order)
    rotations = np.broadcast_to(rest_q, (n_frames, n_joints, 4)).copy()
    translations = np.broadcast_to(rest_t, (n_frames, n_joints, 3)).copy()
    animated_scale = False
    for j, what, keys, values, interpolation in channels:  # one vectorised sampling per channel
        sampled = _sample(times, keys, values, interpolation, what == "rotation", 1e-3 / fps)
        if what == "rotation":
            rotations[:, j] = sampled
        elif what == "translation":
            translations[:, j] = sampled
        else:
            animated_scale |= bool(np.abs(sampled - 1.0).max(initial=0.0) > 1e-4)
    if animated_scale or np.abs(scales - 1.0).max(initial=0.0) > 1e-4:
        warnings.warn(f"{path}: joint scales are ignored", UsdMotionWarning, stacklevel=2)

    q0, t0, s0 = _root_world(path, gltf, order[0])
    rotations[:, 0] = quat_mul(q0, rotations[:, 0])
    translations[:, 0] = t0 + s0 * quat_rotate(q0, translations[:, 0])
    translations[:, 1:] *= s0
    offsets = rest_t * s0
    offsets[0] = t0 + s0 * quat_rotate(q0, rest_t[0])

    meters_per_unit, up_axis = 1.0, "Y"
    source_mpu, source_up = extras.get("sourceMetersPerUnit"), extras.get("sourceUpAxis")
    if isinstance(source_mpu, (int, float)) and source_mpu > 0 and source_up in ("Y", "Z"):
        back = quat_conjugate(up_rotation(source_up))  # glTF space → the source's axes and units
        rotations[:, 0] = quat_mul(back, rotations[:, 0])
        translations[:, 0] = quat_rotate(back, translations[:, 0])
        offsets[0] = quat_rotate(back, offsets[0])
        translations /= source_mpu
        offsets /= source_mpu
        meters_per_unit, up_axis = float(source_mpu), source_up

    moving = np.abs(translations[:, 1:] - offsets[1:]).max(initial=0.0) > 1e-6 * max(
        1.0, float(np.abs(offsets).max(initial=0.0)))
    end_sites, channel_layout = trusted_layout(extras, parents, path, f"skin {skin_index} extras")
    return Motion(
        joint_names=_names(gltf, order),
        parents=parents,
        offsets=offsets,
        rotations=rotations,
        root_translation=translations[:, 0],
        fps=fps,
        joint_translations=translations if moving else None,
        end_sites=end_sites,
        meters_per_unit=meters_per_unit,
        up_axis=up_axis,
        channels=channel_layout,
        root_offset="add" if extras.get("rootOffset") == "add" else "replace",
    )
