"""The immutable, array-only ``Motion`` and its topology checks.

Static topology (names, parents, offsets, channel layout) is kept apart from the
per-frame arrays. Every array is read-only; edits return a new ``Motion`` through
``dataclasses.replace`` or :meth:`Motion.with_frames`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from usdmotion.constants import (MAX_FPS, MAX_JOINT_DEPTH, MAX_JOINTS, MAX_METERS_PER_UNIT, MIN_FPS,
                                 MIN_METERS_PER_UNIT, UP_AXES)
from usdmotion.errors import TopologyError

RootOffset = Literal["add", "replace"]

POSITION_CHANNELS = ("Xposition", "Yposition", "Zposition")
ROTATION_CHANNELS = ("Xrotation", "Yrotation", "Zrotation")
CHANNEL_NAMES = POSITION_CHANNELS + ROTATION_CHANNELS


def validate_topology(parents: np.ndarray) -> tuple[bool, str]:
    """Check a parent-index array ``(J,)``: one root at 0, parents before children.

    Returns ``(ok, reason)``; ``reason`` is empty when ``ok``.
    """
    parents = np.asarray(parents)
    if parents.ndim != 1 or parents.size == 0:
        return False, "a skeleton needs at least one joint (parents must be a non-empty 1-D array)"
    if not np.issubdtype(parents.dtype, np.integer):
        return False, f"parent indices must be integers, got {parents.dtype}"
    if parents[0] != -1:
        return False, f"joint 0 must be the root (parent -1), has parent {parents[0]}"
    if parents.size > MAX_JOINTS:
        return False, f"{parents.size} joints; at most {MAX_JOINTS} are supported (far more than any real rig)"
    rest = parents[1:]
    if np.any(rest < 0):
        j = int(np.flatnonzero(rest < 0)[0]) + 1
        return False, f"joint {j} is a second root; only one root joint is supported"
    too_late = rest >= np.arange(1, parents.size)
    if np.any(too_late):
        j = int(np.flatnonzero(too_late)[0]) + 1
        return False, f"joint {j} has parent {parents[j]}, which does not come before it (cycle or bad order)"
    depth = joint_depths(parents)
    if depth.max() > MAX_JOINT_DEPTH:
        j = int(np.argmax(depth > MAX_JOINT_DEPTH))
        return False, (f"joint {j} is {int(depth[j])} levels deep; at most {MAX_JOINT_DEPTH} are supported "
                       "(far more than any real rig)")
    return True, ""


def joint_depths(parents: np.ndarray) -> np.ndarray:
    """Depth of every joint ``(J,)`` (root = 0), for a parent array with parents before children."""
    parents = np.asarray(parents, dtype=np.int64)
    depth = np.zeros(len(parents), dtype=np.int64)
    for j, p in enumerate(parents.tolist()):  # topology only, O(J)
        if j:
            depth[j] = depth[p] + 1
    return depth


def subtree_indices(parents: np.ndarray, joint: int) -> np.ndarray:
    """Sorted indices ``(K,)`` of ``joint`` and all its descendants (parents before children)."""
    inside = np.zeros(len(parents), bool)
    inside[joint] = True
    for j in range(joint + 1, len(parents)):  # parents come first: one pass
        if parents[j] >= 0 and inside[parents[j]]:
            inside[j] = True
    return np.flatnonzero(inside)


def _frozen(a, dtype, shape_tail: tuple[int, ...], name: str) -> np.ndarray:
    """A read-only array of ``dtype``. An array that is already read-only and owns its data
    (e.g. another Motion's) is shared, not copied: nothing can change it."""
    shareable = (isinstance(a, np.ndarray) and a.dtype == dtype and not a.flags.writeable
                 and a.base is None)
    a = a if shareable else np.array(a, dtype=dtype, copy=True)
    if a.shape[a.ndim - len(shape_tail):] != shape_tail or a.ndim < len(shape_tail):
        raise ValueError(f"{name} must have shape (..., {', '.join(map(str, shape_tail))}), got {a.shape}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Motion:
    """A skeleton and its animation, as arrays over frames ``F`` and joints ``J``.

    Attributes:
        joint_names: ``J`` unique names, in file order (parents before children).
        parents: ``(J,)`` int, parent index per joint, ``-1`` for the root (joint 0).
        offsets: ``(J, 3)`` rest translation of each joint in its parent's frame, file
            units. ``offsets[0]`` is the root's OFFSET from the file.
        rotations: ``(F, J, 4)`` local joint rotations, unit wxyz quaternions.
        root_translation: ``(F, 3)`` position of the root joint in the world, file units
            (the file's root position channels with the OFFSET added or not, see
            ``root_offset``).
        fps: frames per second (``1 / Frame Time``).
        joint_translations: ``(F, J, 3)`` local translations per frame, or ``None``.
            Present only when non-root joints carry position channels; column 0 (the
            root) is unused and holds ``offsets[0]``.
        end_sites: ``(J,)`` bool, joints that were BVH ``End Site`` blocks (leaves with no
            channels, named ``<parent>_End``).
        meters_per_unit: length of one file unit in metres (BVH stores no units).
        up_axis: ``"Y"`` or ``"Z"``.
        channels: per joint, the BVH channel names in file order (``()`` for end sites),
            so a BVH is written back with the layout it was read with; ``None`` = default.
        root_offset: ``"add"`` if the root OFFSET was added to the root position channels
            (BVH specification, fairmotion), ``"replace"`` if the channels replaced it
            (Blender, bvhio, pybvh).
        source_channels: ``(F, C)`` the channel values as read (degrees, file units), or
            ``None``. Only a hint for choosing among equivalent Euler triples on write.
        meshes: skinned meshes bound to this skeleton, read from a USD input
            (:class:`usdmotion.io.usd_skin.SkinnedMesh`, bound by joint *name*); kept by
            operations that keep the skeleton, written back by the USD writer, which
            leaves out (with a warning) any mesh whose joints are gone or changed.
        blend_shape_names: ``S`` blend shape names the weights refer to (a USD
            SkelAnimation's ``blendShapes``), ``()`` when none are animated.
        blend_shape_weights: ``(F, S)`` animated blend-shape weights, or ``None``. Sliced
            with the frames; resampled (linearly, as USD interpolates them) where an
            operation says which source frames its new frames come from
            (:meth:`with_frames` ``frame_times``).

    Arrays passed in are copied into read-only arrays, except arrays that are already
    read-only and own their data (another Motion's, or ones a reader hands over): those
    are shared, so ``dataclasses.replace`` does not copy unchanged frames.
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    rotations: np.ndarray
    root_translation: np.ndarray
    fps: float
    joint_translations: np.ndarray | None = None
    end_sites: np.ndarray | None = None
    meters_per_unit: float = 0.01
    up_axis: str = "Y"
    channels: tuple[tuple[str, ...], ...] | None = None
    root_offset: RootOffset = "add"
    source_channels: np.ndarray | None = field(default=None, repr=False)
    meshes: tuple = field(default=(), repr=False)
    blend_shape_names: tuple[str, ...] = ()
    blend_shape_weights: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        names = tuple(str(n) for n in self.joint_names)
        set_(self, "joint_names", names)
        parents = np.array(self.parents, copy=True)
        if parents.dtype.kind not in "iu":
            parents = parents.astype(np.int64)
        ok, reason = validate_topology(parents)
        if not ok:
            raise TopologyError(reason)
        parents = parents.astype(np.int32)
        parents.setflags(write=False)
        set_(self, "parents", parents)
        n_joints = parents.size
        if len(names) != n_joints:
            raise TopologyError(f"{len(names)} joint names for {n_joints} joints")
        if len(set(names)) != n_joints:
            dup = sorted({n for n in names if names.count(n) > 1})
            raise TopologyError(f"joint names must be unique, repeated: {', '.join(dup[:5])}")
        set_(self, "offsets", _frozen(self.offsets, np.float64, (n_joints, 3), "offsets"))
        rotations = _frozen(self.rotations, np.float64, (n_joints, 4), "rotations")
        if rotations.ndim != 3:
            raise ValueError(f"rotations must have shape (F, J, 4), got {rotations.shape}")
        set_(self, "rotations", rotations)
        n_frames = rotations.shape[0]
        set_(self, "root_translation", _frozen(self.root_translation, np.float64, (3,), "root_translation"))
        if self.root_translation.shape != (n_frames, 3):
            raise ValueError(f"root_translation must have shape ({n_frames}, 3), got {self.root_translation.shape}")
        if self.joint_translations is not None:
            jt = _frozen(self.joint_translations, np.float64, (n_joints, 3), "joint_translations")
            if jt.shape != (n_frames, n_joints, 3):
                raise ValueError(f"joint_translations must have shape ({n_frames}, {n_joints}, 3), got {jt.shape}")
            set_(self, "joint_translations", jt)
        end_sites = np.zeros(n_joints, bool) if self.end_sites is None else np.array(self.end_sites, bool)
        if end_sites.shape != (n_joints,):
            raise ValueError(f"end_sites must have shape ({n_joints},), got {end_sites.shape}")
        end_sites.setflags(write=False)
        set_(self, "end_sites", end_sites)
        if self.channels is not None:
            channels = tuple(tuple(str(c) for c in cs) for cs in self.channels)
            if len(channels) != n_joints:
                raise ValueError(f"channels lists {len(channels)} joints, the skeleton has {n_joints}")
            for j, cs in enumerate(channels):  # a layout no BVH reader could read back is not kept
                if len(set(cs)) != len(cs) or not set(cs) <= set(CHANNEL_NAMES):
                    raise ValueError(f"channels of joint {names[j]!r}: {' '.join(cs)!r} is not a BVH channel layout "
                                     f"(distinct names among {', '.join(CHANNEL_NAMES)})")
            set_(self, "channels", channels)
        if self.source_channels is not None:
            sc = self.source_channels  # shared like the other arrays when read-only and owning its data
            if not (isinstance(sc, np.ndarray) and sc.dtype == np.float64 and not sc.flags.writeable
                    and sc.base is None):
                sc = np.array(sc, dtype=np.float64)
            if sc.ndim != 2 or sc.shape[0] != n_frames:
                raise ValueError(f"source_channels must have shape ({n_frames}, C), got {sc.shape}; "
                                 "use Motion.with_frames() when the frame count changes")
            sc.setflags(write=False)
            set_(self, "source_channels", sc)
        self._check_blend_shape_weights(n_frames)
        if not (MIN_FPS <= self.fps <= MAX_FPS):
            raise ValueError(f"fps must be a number in {MIN_FPS:.3g}..{MAX_FPS:g} (one frame an hour to a "
                             f"megahertz), got {self.fps}")
        set_(self, "fps", float(self.fps))
        if not (MIN_METERS_PER_UNIT <= self.meters_per_unit <= MAX_METERS_PER_UNIT):
            raise ValueError(f"meters_per_unit must be in {MIN_METERS_PER_UNIT:g}..{MAX_METERS_PER_UNIT:g} "
                             f"(a micrometre to 1,000 km), got {self.meters_per_unit}")
        set_(self, "meters_per_unit", float(self.meters_per_unit))
        if self.up_axis not in UP_AXES:
            raise ValueError(f"up_axis must be one of {UP_AXES}, got {self.up_axis!r}")
        if self.root_offset not in ("add", "replace"):
            raise ValueError(f"root_offset must be 'add' or 'replace', got {self.root_offset!r}")

    def _check_blend_shape_weights(self, n_frames: int) -> None:
        names = tuple(str(n) for n in self.blend_shape_names)
        object.__setattr__(self, "blend_shape_names", names)
        if self.blend_shape_weights is None:
            return
        weights = _frozen(self.blend_shape_weights, np.float64, (len(names),), "blend_shape_weights")
        if weights.shape != (n_frames, len(names)):
            raise ValueError(f"blend_shape_weights must have shape ({n_frames}, {len(names)}), got {weights.shape}")
        object.__setattr__(self, "blend_shape_weights", weights)

    # ----------------------------------------------------------------- shape helpers
    @property
    def n_frames(self) -> int:
        """Number of frames ``F``."""
        return int(self.rotations.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints ``J`` (end sites included)."""
        return int(self.parents.shape[0])

    @property
    def frame_time(self) -> float:
        """Seconds per frame."""
        return 1.0 / self.fps

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return max(self.n_frames - 1, 0) / self.fps

    def joint_index(self, name: str) -> int:
        """Index of the joint called ``name``; ``KeyError`` listing close names if absent."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            import difflib

            close = difflib.get_close_matches(name, self.joint_names, n=3)
            hint = f" (did you mean {', '.join(close)}?)" if close else ""
            raise KeyError(f"no joint named {name!r}{hint}") from None

    def children(self, joint: int) -> np.ndarray:
        """Indices of the direct children of ``joint``."""
        return np.flatnonzero(self.parents == joint)

    def subtree(self, joint: int) -> np.ndarray:
        """Sorted indices of ``joint`` and all its descendants."""
        return subtree_indices(self.parents, joint)

    def with_frames(self, rotations: np.ndarray, root_translation: np.ndarray,
                    joint_translations: np.ndarray | None = None, fps: float | None = None,
                    frame_times: np.ndarray | None = None) -> Motion:
        """A copy with new per-frame data (any frame count, optionally a new fps).

        Drops ``source_channels`` (the Euler hint of the frames as read), which no longer
        describes the new frames. Blend-shape weights follow the frames: resampled
        linearly at ``frame_times`` (``(F',)`` fractional source frames of the new frames)
        when given, kept when the frame count is unchanged, else dropped with a warning.
        """
        return dataclasses.replace(
            self,
            rotations=rotations,
            root_translation=root_translation,
            joint_translations=joint_translations,
            fps=self.fps if fps is None else fps,
            source_channels=None,
            blend_shape_weights=self._weights_at(frame_times, len(rotations)),
        )

    def _weights_at(self, frame_times: np.ndarray | None, n_frames: int) -> np.ndarray | None:
        """The blend-shape weights of ``n_frames`` new frames (see :meth:`with_frames`)."""
        weights = self.blend_shape_weights
        if weights is None or (frame_times is None and n_frames == self.n_frames):
            return weights
        if frame_times is None or len(frame_times) != n_frames or self.n_frames == 0:
            import warnings

            from usdmotion.errors import UsdMotionWarning

            warnings.warn(f"the animated blend-shape weights ({', '.join(self.blend_shape_names[:3])}…) are left "
                          "out: this operation does not say which frames its new frames come from",
                          UsdMotionWarning, stacklevel=3)
            return None
        tau = np.clip(np.asarray(frame_times, np.float64), 0.0, self.n_frames - 1)
        i0 = np.minimum(np.floor(tau).astype(np.int64), max(self.n_frames - 2, 0))
        i1 = np.minimum(i0 + 1, self.n_frames - 1)
        t = (tau - i0)[:, None]
        return weights[i0] * (1.0 - t) + weights[i1] * t

    def sliced(self, start: int | None = None, stop: int | None = None) -> Motion:
        """Frames ``start:stop`` (Python slice, unchecked) as a new motion.

        Unlike :meth:`with_frames` it keeps ``source_channels`` for those frames, so a
        clip written as BVH repeats the input's numbers.
        """
        frames = slice(start, stop)
        return dataclasses.replace(
            self,
            rotations=self.rotations[frames],
            root_translation=self.root_translation[frames],
            joint_translations=None if self.joint_translations is None else self.joint_translations[frames],
            source_channels=None if self.source_channels is None else self.source_channels[frames],
            blend_shape_weights=None if self.blend_shape_weights is None else self.blend_shape_weights[frames],
        )
