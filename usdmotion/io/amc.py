"""Acclaim motion files (``.amc``, CMU mocap) on an ASF skeleton → :class:`Motion`.

``read_amc(path, skeleton)`` parses the AMC, checks it against the skeleton and builds a
motion in the layout of the widely used cgspeed BVH conversions of the CMU database:

* one joint per ASF bone, placed at the bone's *start*; the root's children at the root;
  the ``End`` site of a leaf bone at its end (``<bone>_End``);
* a joint's OFFSET is its parent bone's ``direction × length`` in the world rest frame,
  except that the children of a bone with several children (CMU: ``thorax`` → neck and
  clavicles, ``lwrist``/``rwrist`` → hand and thumb) start at that bone's start (OFFSET 0):
  cgspeed drops the length of such branching bones;
* the rotation of a bone relative to its parent is ``C @ M @ C⁻¹`` (``C`` the ASF ``axis``,
  ``M`` the AMC values), so the rest pose is the ASF pose with identity rotations;
* AMC frame numbers ``n0, n0+1, …`` become frames ``0, 1, …`` (no T-pose frame is added);
  the frame rate is 120 Hz (AMC does not store one; CMU captures at 120 Hz).

``layout="acclaim"`` keeps the branching bones' lengths (Acclaim forward kinematics:
every bone starts where its parent ends).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from usdmotion.channels import resolve_units
from usdmotion.errors import InputError
from usdmotion.io.asf import AsfSkeleton, read_asf
from usdmotion.motion import Motion
from usdmotion.rotations import euler_to_quat, quat_conjugate, quat_mul

AMC_FPS = 120.0
LAYOUTS = ("cgspeed", "acclaim")
ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
JOINT_CHANNELS = ("Zrotation", "Yrotation", "Xrotation")


class AmcParseError(InputError):
    """An AMC file is malformed or does not fit its skeleton; names the file and line."""


def _first_bad_number(rests: list[str]) -> tuple[int, str]:
    for i, rest in enumerate(rests):  # error path only
        for token in rest.split():
            try:
                float(token)
            except ValueError:
                return i, token
    return 0, ""


def parse_amc(text: str, skeleton: AsfSkeleton, path: str | os.PathLike | None = None) -> tuple[np.ndarray, bool]:
    """Parse AMC ``text`` against ``skeleton``.

    Returns ``(values (F, C), degrees)``: the channel values in skeleton order (bone by
    bone in ``skeleton.names`` order, each bone's ``dofs`` in ASF order; ``C`` = total
    DOFs), file units and angle units as written, and whether angles are in degrees.
    """
    path = None if path is None else str(path)
    lines = text.splitlines()
    numbers = np.array([i + 1 for i, s in enumerate(lines) if s.strip() and not s.lstrip().startswith("#")], np.int64)
    content = [lines[i - 1].strip() for i in numbers]
    if not content:
        raise AmcParseError(path, "empty AMC file (no frames)", max(len(lines), 1))
    is_frame = np.array([s.isdigit() for s in content])
    is_header = np.array([s.startswith(":") for s in content])
    first = int(np.argmax(is_frame)) if is_frame.any() else len(content)
    late = np.flatnonzero(is_header[first:])
    if late.size:
        raise AmcParseError(path, f"header line {content[first + late[0]]!r} after the first frame",
                            int(numbers[first + late[0]]))
    header = {s.split()[0].upper() for s in content[:first] if s.startswith(":")}
    strays = [i for i in range(first) if not is_header[i]]
    if strays:
        raise AmcParseError(path, f"{content[strays[0]].split()[0]!r} before the first frame number",
                            int(numbers[strays[0]]))
    if first == len(content):
        raise AmcParseError(path, "no frames (expected a frame number line such as '1')", int(numbers[-1]))
    degrees = True if ":DEGREES" in header else False if ":RADIANS" in header else skeleton.angles_in_degrees
    body_numbers, body = numbers[first:], content[first:]
    frame_rows = is_frame[first:]
    frame_values = np.array([int(s) for s, f in zip(body, frame_rows) if f], np.int64)
    expected = frame_values[0] + np.arange(frame_values.size)
    bad = np.flatnonzero(frame_values != expected)
    if bad.size:
        k = int(bad[0])
        raise AmcParseError(path, f"frame {frame_values[k]} follows frame {frame_values[k - 1]} (frames must be "
                            "numbered consecutively)", int(body_numbers[np.flatnonzero(frame_rows)[k]]))
    data_rows = np.flatnonzero(~frame_rows)
    frame_of_row = np.cumsum(frame_rows)[data_rows] - 1
    split = [body[i].split(None, 1) for i in data_rows]
    bone_index = {name: b for b, name in enumerate(skeleton.names)}
    n_dofs = np.array([len(d) for d in skeleton.dofs], np.int64)
    try:
        bones = np.array([bone_index[parts[0]] for parts in split], np.int64)
    except KeyError:
        k = next(i for i, parts in enumerate(split) if parts[0] not in bone_index)
        raise AmcParseError(path, f"bone {split[k][0]!r} is not in the skeleton {skeleton.path or ''}".rstrip(),
                            int(body_numbers[data_rows[k]])) from None
    rests = [parts[1] if len(parts) > 1 else "" for parts in split]
    counts = np.array([len(r.split()) for r in rests], np.int64)
    wrong = np.flatnonzero(counts != n_dofs[bones])
    if wrong.size:
        k = int(wrong[0])
        b = int(bones[k])
        dofs = " ".join(skeleton.dofs[b]) or "none"
        raise AmcParseError(path, f"{skeleton.names[b]} has {counts[k]} values, its DOFs are {dofs}",
                            int(body_numbers[data_rows[k]]))
    n_frames, n_bones = frame_values.size, len(skeleton.names)
    seen = np.zeros((n_frames, n_bones), np.int64)
    np.add.at(seen, (frame_of_row, bones), 1)
    twice = np.flatnonzero(seen[frame_of_row, bones] > 1)
    if twice.size:
        # the second occurrence of the first repeated (frame, bone)
        key = frame_of_row * n_bones + bones
        k = next(i for i in twice if np.count_nonzero(key[: i + 1] == key[i]) > 1)
        raise AmcParseError(path, f"{skeleton.names[bones[k]]} appears twice in frame {frame_values[frame_of_row[k]]}",
                            int(body_numbers[data_rows[k]]))
    needed = n_dofs > 0
    missing = np.argwhere((seen[:, needed] == 0))
    if missing.size:
        f, b = missing[0]
        name = np.array(skeleton.names)[needed][b]
        raise AmcParseError(path, f"frame {frame_values[f]} has no values for {name}",
                            int(body_numbers[np.flatnonzero(frame_rows)[f]]))
    try:
        flat = np.array(" ".join(rests).split(), dtype=np.float64)
    except ValueError:
        k, token = _first_bad_number(rests)
        raise AmcParseError(path, f"{token!r} is not a number", int(body_numbers[data_rows[k]])) from None
    if not np.all(np.isfinite(flat)):
        at = int(np.flatnonzero(~np.isfinite(flat))[0])
        k = int(np.searchsorted(np.cumsum(counts), at, side="right"))
        raise AmcParseError(path, "value is not finite", int(body_numbers[data_rows[k]]))
    starts = np.concatenate([[0], np.cumsum(n_dofs)[:-1]])
    row_of_value = np.repeat(np.arange(bones.size), counts)
    within = np.arange(flat.size) - np.repeat(np.cumsum(counts) - counts, counts)
    values = np.zeros((n_frames, int(n_dofs.sum())))
    values[frame_of_row[row_of_value], starts[bones[row_of_value]] + within] = flat
    return values, degrees


def _axis_quat(angles: np.ndarray, applied: str) -> np.ndarray:
    """Quaternions ``(..., 4)`` of rotations about X, Y, Z by ``angles (..., 3)`` (radians,
    indexed X, Y, Z) applied in the order ``applied`` (``"XYZ"`` → ``Rz @ Ry @ Rx``)."""
    order = applied[::-1]
    picked = np.stack([angles[..., "XYZ".index(a)] for a in order], axis=-1)
    return euler_to_quat(picked, order)


def _applied_order(dofs: tuple[str, ...]) -> str:
    axes = [d[1].upper() for d in dofs if d in ("rx", "ry", "rz")]
    return "".join(axes + [a for a in "XYZ" if a not in axes])


def _topology(skeleton: AsfSkeleton, layout: str):
    """Joint names, parents, offsets ``(J, 3)`` and bone index per joint (``-1`` for end sites)."""
    parents = skeleton.parents
    n_children = np.bincount(parents[1:], minlength=len(parents))
    bone_vectors = skeleton.directions * skeleton.lengths[:, None]
    if layout == "cgspeed":
        starts_at_end = n_children[parents[1:]] <= 1
    else:
        starts_at_end = np.ones(len(parents) - 1, bool)
    names, new_parents, offsets, bone_of = [], [], [], []
    joint_of_bone = np.zeros(len(parents), np.int64)
    for b in range(len(parents)):  # topology only, O(B)
        joint_of_bone[b] = len(names)
        names.append(skeleton.names[b])
        new_parents.append(-1 if b == 0 else int(joint_of_bone[parents[b]]))
        if b == 0:
            offsets.append(skeleton.root_position)
        else:
            offsets.append(bone_vectors[parents[b]] if starts_at_end[b - 1] else np.zeros(3))
        bone_of.append(b)
        if b > 0 and n_children[b] == 0:
            names.append(f"{skeleton.names[b]}_End")
            new_parents.append(int(joint_of_bone[b]))
            offsets.append(bone_vectors[b])
            bone_of.append(-1)
    return tuple(names), np.array(new_parents), np.array(offsets), np.array(bone_of)


def motion_from_amc(skeleton: AsfSkeleton, values: np.ndarray, degrees: bool = True, fps: float = AMC_FPS,
                    layout: str = "cgspeed", meters_per_unit: float | None = None) -> Motion:
    """Build a :class:`Motion` from AMC channel ``values (F, C)`` (see :func:`parse_amc`).

    ``meters_per_unit`` defaults to the skeleton's (``0.0254 / :units length``).
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    names, parents, offsets, bone_of = _topology(skeleton, layout)
    n_frames = values.shape[0]
    scale = np.pi / 180.0 if degrees else 1.0
    starts = np.concatenate([[0], np.cumsum([len(d) for d in skeleton.dofs])[:-1]])
    rotations = np.zeros((n_frames, len(names), 4))
    rotations[..., 0] = 1.0
    root_dofs = skeleton.dofs[0]
    translation = np.zeros((n_frames, 3))
    for k, axis in enumerate("xyz"):
        if f"t{axis}" in root_dofs:
            translation[:, k] = values[:, root_dofs.index(f"t{axis}")]
    for j in np.flatnonzero(bone_of >= 0):  # per bone, vectorised over frames (topology-sized loop)
        b = int(bone_of[j])
        dofs = skeleton.dofs[b]
        angles = np.zeros((n_frames, 3))
        for k, dof in enumerate(dofs):
            if dof.startswith("r"):
                angles[:, "xyz".index(dof[1])] = values[:, starts[b] + k] * scale
        c = _axis_quat(skeleton.axes[b], skeleton.axis_orders[b])  # axes are radians
        m = _axis_quat(angles, _applied_order(dofs))
        c_frames = np.broadcast_to(c, m.shape)
        rotations[:, j] = quat_mul(quat_mul(c_frames, m), quat_conjugate(c_frames))
    channels = tuple(() if b < 0 else ROOT_CHANNELS if b == 0 else JOINT_CHANNELS for b in bone_of)
    rotations.setflags(write=False)
    root_translation = skeleton.root_position + translation
    root_translation.setflags(write=False)
    return Motion(joint_names=names, parents=parents, offsets=offsets, rotations=rotations,
                  root_translation=root_translation, fps=fps, end_sites=bone_of < 0,
                  meters_per_unit=skeleton.meters_per_unit if meters_per_unit is None else meters_per_unit,
                  up_axis="Y", channels=channels, root_offset="add")


def find_skeleton(amc: Path) -> Path:
    """The ASF beside ``amc``: ``<stem>.asf``, else the subject's ``<subject>.asf`` (CMU
    ``86_01.amc`` → ``86.asf``), else the only ``.asf`` in the folder."""
    tried = [amc.with_suffix(".asf"), amc.with_name(amc.stem.split("_", 1)[0] + ".asf")]
    for candidate in tried:
        if candidate.is_file():
            return candidate
    others = sorted(amc.parent.glob("*.asf")) + sorted(amc.parent.glob("*.ASF"))
    if len(others) == 1:
        return others[0]
    looked = ", ".join(p.name for p in dict.fromkeys(tried))
    raise AmcParseError(amc, f"no skeleton: pass --skeleton FILE.asf (looked for {looked} beside it)")


def read_amc(path: str | os.PathLike, skeleton: str | os.PathLike | AsfSkeleton | None = None,
             layout: str = "cgspeed", units: str | float | None = None, fps: float = AMC_FPS) -> Motion:
    """Read an AMC file on an ASF skeleton (a path, a parsed skeleton, or ``None`` for
    the ``.asf`` beside it, see :func:`find_skeleton`) into a :class:`Motion`."""
    path = Path(path)
    if not isinstance(skeleton, AsfSkeleton):
        skeleton = read_asf(find_skeleton(path) if skeleton is None else skeleton)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise AmcParseError(path, f"cannot read: {exc.strerror or exc}") from None
    text = raw.decode("latin-1")
    if "\x00" in text:
        raise AmcParseError(path, "binary data, not an AMC text file", text[: text.index("\x00")].count("\n") + 1)
    values, degrees = parse_amc(text, skeleton, path)
    meters = None
    if units is not None:
        meters = resolve_units(units)
    return motion_from_amc(skeleton, values, degrees=degrees, fps=fps, layout=layout, meters_per_unit=meters)
