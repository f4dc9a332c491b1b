"""BVH reading: ``parse_bvh`` → ``BvhData`` → ``Motion`` (writing: :mod:`usdmotion.io.bvh_write`).

Conventions (see README "Conventions"):

* Channel values are degrees and file units; a joint's rotation is the product of its
  rotation channels in the order they are listed (``Zrotation Xrotation Yrotation`` →
  ``R = Rz @ Rx @ Ry``); missing rotation axes are zero.
* Root position: ``root_offset="add"`` (BVH specification, fairmotion, bvh11) puts the
  root at ``OFFSET + channels``; ``"replace"`` (Blender, pybvh, bvhio) at the channels
  alone (axes without a channel keep the OFFSET). Both agree when the OFFSET is zero.
  ``"auto"`` (default) picks ``"replace"`` when the channels evidently already contain
  the OFFSET (their mean along the OFFSET's largest axis is nearer the OFFSET than
  zero: every exporter with a non-zero root OFFSET in our corpus does this), else
  ``"add"``. The choice made is stored in ``Motion.root_offset``.
* Position channels on non-root joints *replace* the OFFSET (every exporter that writes
  them stores the full local translation; adding would double the bone).
* ``End Site`` blocks become leaf joints named ``<parent>_End`` with ``end_sites`` set.
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from usdmotion.channels import channel_columns, euler_columns, resolve_units, rotation_order
from usdmotion.constants import MAX_ABS_VALUE, MAX_FRAMES
from usdmotion.errors import BvhParseError, UsdMotionWarning
from usdmotion.io.bvh_header import BvhHeader, frame_rate, header_arrays, parse_header
from usdmotion.io.bvh_rows import line_of_row, parse_rows
from usdmotion.kinematics import fk_arrays
from usdmotion.motion import POSITION_CHANNELS, ROTATION_CHANNELS, Motion, RootOffset
from usdmotion.parallel import over_slices
from usdmotion.rotations import half_angles_to_quat

@dataclass(frozen=True)
class BvhData:
    """A parsed BVH file as plain arrays (no rotation math applied).

    Attributes:
        joint_names: ``J`` names (end sites named ``<parent>_End``).
        parents: ``(J,)`` parent indices, ``-1`` for the root.
        offsets: ``(J, 3)`` OFFSETs, file units.
        channels: per joint, its channel names in file order.
        end_sites: ``(J,)`` bool.
        frame_time: seconds per frame, as written.
        fps: frames per second (a standard rate when the frame time is its rounding,
            see :func:`usdmotion.io.bvh_header.frame_rate`).
        values: ``(F, C)`` channel values, degrees and file units.
        path: the file read, for messages.
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_sites: np.ndarray
    frame_time: float
    fps: float
    values: np.ndarray
    path: str | None = None


def _utf8_error(raw: bytes, start: int, path: str | None) -> BvhParseError:
    line = raw.count(b"\n", 0, start) + 1
    column = start - (raw.rfind(b"\n", 0, start) + 1) + 1
    return BvhParseError(path, f"not UTF-8 text (byte 0x{raw[start]:02x})", line, column)


def _decode_header(raw: bytes, path: str | None) -> str:
    """The header bytes as text (UTF-8, BOM dropped, ``\r\n``/``\r`` → ``\n``)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _utf8_error(raw, exc.start, path) from None
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise BvhParseError(path, "binary data (NUL byte), not a BVH text file", line)
    return text.replace("\r\n", "\n").replace("\r", "\n") if "\r" in text else text


_MOTION_LINE = re.compile(rb"^[ \t]*MOTION[ \t]*\r?$", re.IGNORECASE | re.MULTILINE)
_FRAMES_LINE = re.compile(rb"^\s*frames\s*[:=]?", re.IGNORECASE)
_FRAME_TIME_LINE = re.compile(rb"^\s*frame\s*time", re.IGNORECASE)


def _split_header(raw: bytes, path: str | None) -> tuple[bytes, memoryview]:
    """``(header bytes, motion-row bytes)``: rows start after the ``Frames:`` and
    ``Frame Time:`` lines (either order, blank lines allowed) that follow ``MOTION``."""
    if not raw or raw.isspace():  # no copy of a large buffer
        raise BvhParseError(path, "empty file", 1)
    motion = _MOTION_LINE.search(raw)
    if motion is None:
        return raw, b""
    pos = raw.find(b"\n", motion.end())
    pos = len(raw) if pos < 0 else pos + 1
    seen = set()
    while len(seen) < 2 and pos < len(raw):
        end = raw.find(b"\n", pos)
        end = len(raw) if end < 0 else end + 1
        line = raw[pos:end]
        if _FRAME_TIME_LINE.match(line):
            seen.add("time")
        elif _FRAMES_LINE.match(line):
            seen.add("frames")
        elif line.strip():
            pos = end  # keep it in the header: the header parser names this line
            break
        pos = end
    return raw[:pos], memoryview(raw)[pos:]  # the rows: no copy of a large file


def _unique_names(header: BvhHeader, path: str | None) -> tuple[str, ...]:
    names = list(header.joint_names)
    seen: dict[str, int] = {}
    renamed = []
    for j, name in enumerate(names):
        if name in seen:
            k = 2
            while f"{name}_{k}" in seen or f"{name}_{k}" in names:
                k += 1
            names[j] = f"{name}_{k}"
            renamed.append((header.name_tokens[j].line, name, names[j]))
        seen[names[j]] = j
    if renamed:
        line, old, new = renamed[0]
        warnings.warn(f"{path}:{line}: joint name {old!r} repeats; renamed to {new!r}"
                      + (f" (and {len(renamed) - 1} more)" if len(renamed) > 1 else ""),
                      UsdMotionWarning, stacklevel=3)
    return tuple(names)


def parse_bvh(text: str | bytes, path: str | os.PathLike | None = None, lenient: bool = False) -> BvhData:
    """Parse BVH text or bytes into :class:`BvhData`.

    Args:
        text: the whole file.
        path: used in error messages only.
        lenient: keep the complete motion rows when ``Frames:`` disagrees with the rows
            or rows have the wrong number of values (warns instead of raising).

    Raises:
        BvhParseError: malformed input, naming the file, line and column.
    """
    path = None if path is None else str(path)
    raw = text.encode("utf-8") if isinstance(text, str) else bytes(text)
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    head, data = _split_header(raw, path)
    header = parse_header(_decode_header(head, path), path)
    data_bytes = np.frombuffer(data, np.uint8)
    if data_bytes.size and data_bytes.max() > 127:
        start = len(head) + int(np.argmax(data_bytes > 127))
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise _utf8_error(raw, exc.start, path) from None
        line = raw.count(b"\n", 0, start) + 1
        raise BvhParseError(path, "non-ASCII character in the motion data", line,
                            start - (raw.rfind(b"\n", 0, start) + 1) + 1)
    n_channels = sum(len(c) for c in header.channels)
    rows = parse_rows(data, n_channels, header.data_line, path, lenient)
    values = rows.values
    n_rows = values.shape[0]
    if n_rows != header.n_frames:
        claim = f"Frames: {header.n_frames}" + (" (absurd)" if header.n_frames > MAX_FRAMES else "")
        message = f"{claim} but the file has {n_rows} complete motion rows"
        if not lenient:
            raise BvhParseError(path, message + " (use --lenient to keep the complete rows)",
                                header.frames_line)
        warnings.warn(f"{path}:{header.frames_line}: {message}; keeping {n_rows}", UsdMotionWarning,
                      stacklevel=2)
    if values.size and not -MAX_ABS_VALUE <= values.min() <= values.max() <= MAX_ABS_VALUE:  # NaN propagates
        row, col = (int(i) for i in np.argwhere(~(np.abs(values) <= MAX_ABS_VALUE))[0])
        line = line_of_row(bytes(data), row, header.data_line)
        if not np.isfinite(values[row, col]):
            raise BvhParseError(path, f"non-finite value ({values[row, col]}) in channel {col + 1} of the motion row",
                                line)
        raise BvhParseError(path, f"value beyond ±{MAX_ABS_VALUE:g} ({values[row, col]}) in channel {col + 1} of the "
                                  "motion row", line)
    parents, offsets = header_arrays(header)
    values.setflags(write=False)
    return BvhData(
        joint_names=_unique_names(header, path),
        parents=parents,
        offsets=offsets,
        channels=tuple(header.channels),
        end_sites=np.asarray(header.end_sites, dtype=bool),
        frame_time=header.frame_time,
        fps=frame_rate(header.frame_time_text),
        values=values,
        path=path,
    )


def rotations_from_channels(values: np.ndarray, channels: tuple[tuple[str, ...], ...]) -> np.ndarray:
    """Local rotations ``(F, J, 4)`` wxyz from channel values ``(F, C)`` in degrees.

    Joints sharing an Euler order are converted together (at most six groups).
    """
    n_frames, n_joints = values.shape[0], len(channels)
    columns = channel_columns(channels)
    rotations = np.zeros((n_frames, n_joints, 4))
    rotations[..., 0] = 1.0
    groups: dict[str, list[int]] = {}
    for j, names in enumerate(channels):
        if any(n in ROTATION_CHANNELS for n in names):
            groups.setdefault(rotation_order(names), []).append(j)
    half_per_degree = 0.5 * np.pi / 180.0
    for order, joints in groups.items():
        gather = np.stack([euler_columns(columns[j], order, -1) for j in joints])  # (G, 3), -1 = no channel
        missing = gather < 0
        safe = np.maximum(gather, 0)

        block = max(1, _BLOCK_ITEMS // len(joints))

        def convert(frames: slice, order=order, joints=joints, safe=safe, missing=missing, block=block) -> None:
            for start in range(frames.start, frames.stop, block):  # small temporaries, reused block to block
                part = slice(start, min(start + block, frames.stop))
                halves = []
                for axis in range(3):  # contiguous (F, G) planes of half angles in radians
                    plane = values[part][:, safe[:, axis]] * half_per_degree
                    if missing[:, axis].any():
                        plane[:, missing[:, axis]] = 0.0
                    halves.append(plane)
                rotations[part, joints] = half_angles_to_quat(*halves, order)

        over_slices(convert, n_frames, min_items=max(1, 40_000 // len(joints)))  # threads over slices of frames
    return rotations


#: Joint-frames converted at a time: the Euler → quaternion temporaries (about 20 arrays of
#: this many floats) stay in the allocator's free memory and the CPU caches from block to
#: block; 32,768 frames at a time cost twice the CPU time (a fresh page for every temporary:
#: ``benchmarks/startup.py``), and a long take's read peak held 160 MB of them.
_BLOCK_ITEMS = 16_000


def _positions(values: np.ndarray, columns: dict[str, int], base: np.ndarray, add: bool) -> np.ndarray:
    """``(F, 3)`` translation from a joint's position channels over ``base (3,)``."""
    out = np.broadcast_to(base, (values.shape[0], 3)).copy()
    for axis, name in enumerate(POSITION_CHANNELS):
        if name in columns:
            channel = values[:, columns[name]]
            out[:, axis] = base[axis] + channel if add else channel
    return out


def guess_root_offset(data: BvhData) -> RootOffset:
    """``"replace"`` if the root position channels already contain the root OFFSET, else ``"add"``.

    Looks along the OFFSET's largest axis: channel mean nearer the OFFSET than zero
    means the channels are absolute positions (adding would double them).
    """
    offset = data.offsets[0]
    columns = channel_columns(data.channels)[0]
    axis = int(np.argmax(np.abs(offset)))
    name = POSITION_CHANNELS[axis]
    if offset[axis] == 0.0 or name not in columns or data.values.shape[0] == 0:
        return "add"
    mean = float(np.mean(data.values[:, columns[name]]))
    return "replace" if abs(mean - offset[axis]) < abs(mean) else "add"


def world_like_position_joints(motion: Motion) -> list[int]:
    """Non-root joints whose position channels look like *world* positions.

    A joint is flagged when its per-frame translation is nearer the world position it
    would have with its OFFSET than the OFFSET itself (median over frames), and its
    parent frame actually moves (a static identity parent at the origin, like Bandai's
    ``joint_Root``, makes local and world the same thing).
    """
    if motion.joint_translations is None or motion.n_frames == 0:
        return []
    with_offsets = np.broadcast_to(motion.offsets, motion.joint_translations.shape).copy()
    with_offsets[:, 0] = motion.root_translation
    world_q, world_p = fk_arrays(motion.rotations, with_offsets, motion.parents)
    flagged = []
    moving = np.flatnonzero(np.abs(motion.joint_translations - motion.offsets).max(axis=(0, 2)) > 0)
    for j in moving[moving > 0]:
        values = motion.joint_translations[:, j]
        from_offset = np.median(np.linalg.norm(values - motion.offsets[j], axis=1))
        from_world = np.median(np.linalg.norm(values - world_p[:, j], axis=1))
        parent = motion.parents[j]
        parent_moves = (np.abs(world_p[:, parent]).max() > 1e-9
                        or np.abs(np.abs(world_q[:, parent, 0]) - 1.0).max() > 1e-9)
        if parent_moves and from_world < 0.5 * from_offset:
            flagged.append(int(j))
    return flagged


def motion_from_bvh(data: BvhData, root_offset: str = "auto", meters_per_unit: float = 0.01,
                    up_axis: str = "Y", ignore_joint_positions: bool = False) -> Motion:
    """Build a :class:`Motion` from parsed BVH arrays.

    Args:
        data: output of :func:`parse_bvh`.
        root_offset: ``"auto"``, ``"add"`` or ``"replace"`` (see module docstring).
        meters_per_unit: length of one file unit in metres (BVH does not store it).
        up_axis: ``"Y"`` or ``"Z"``, the file's vertical axis.
        ignore_joint_positions: use the OFFSETs of non-root joints even where they carry
            position channels (for files whose such channels hold world positions; a
            warning names them).
    """
    if root_offset not in ("auto", "add", "replace"):
        raise ValueError(f"root_offset must be 'auto', 'add' or 'replace', got {root_offset!r}")
    if root_offset == "auto":
        root_offset = guess_root_offset(data)
    values = data.values
    columns = channel_columns(data.channels)
    rotations = rotations_from_channels(values, data.channels)
    root_translation = _positions(values, columns[0], data.offsets[0], add=root_offset == "add")
    joint_translations = None
    moving = [j for j in range(1, len(data.channels)) if any(n in POSITION_CHANNELS for n in data.channels[j])]
    if moving:
        joint_translations = np.broadcast_to(data.offsets, (values.shape[0],) + data.offsets.shape).copy()
        for j in moving:
            joint_translations[:, j] = _positions(values, columns[j], data.offsets[j], add=False)
    for owned in (rotations, root_translation, joint_translations):
        if owned is not None:
            owned.setflags(write=False)  # handed over: Motion shares frozen arrays instead of copying
    motion = Motion(
        joint_names=data.joint_names,
        parents=data.parents,
        offsets=data.offsets,
        rotations=rotations,
        root_translation=root_translation,
        fps=data.fps,
        joint_translations=None if ignore_joint_positions else joint_translations,
        end_sites=data.end_sites,
        meters_per_unit=meters_per_unit,
        up_axis=up_axis,
        channels=data.channels,
        root_offset=root_offset,
        source_channels=values,
    )
    if not ignore_joint_positions:
        flagged = world_like_position_joints(motion)
        if flagged:
            names = ", ".join(repr(motion.joint_names[j]) for j in flagged[:4])
            warnings.warn(f"{data.path or '<input>'}: position channels of {names} look like world positions, "
                          "not offsets; the skeleton will look distorted (use --ignore-joint-positions)",
                          UsdMotionWarning, stacklevel=2)
    return motion


def read_bvh(path: str | os.PathLike, root_offset: str = "auto", units: str | float = "cm",
             up_axis: str = "Y", lenient: bool = False, ignore_joint_positions: bool = False) -> Motion:
    """Read a BVH file into a :class:`Motion` (see :func:`parse_bvh`, :func:`motion_from_bvh`)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise BvhParseError(path, f"cannot read: {exc.strerror or exc}") from None
    data = parse_bvh(raw, path, lenient=lenient)
    del raw  # the file's bytes are not needed once parsed (a long take's are as large as its floats)
    return motion_from_bvh(data, root_offset=root_offset, meters_per_unit=resolve_units(units), up_axis=up_axis,
                           ignore_joint_positions=ignore_joint_positions)
