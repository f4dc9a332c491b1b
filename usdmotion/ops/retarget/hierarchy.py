"""Joint hierarchies for retargeting: the target ``Rig``, removing/adding joints, and
step 1 of the paper (bone lengths from the source motion).

Everything here is NumPy and topology-sized (loops over joints, never over frames).

Removing a joint re-parents its children onto its parent; its ``End Site`` leaves go
with it. The new offset of a re-parented joint is the rest-pose composition of the
removed chain (the sum of the OFFSETs on the way: rest rotations are the identity), so
the *direction* of the bone in the rest pose is kept; step 1 then sets its *length*.
An added joint (``NAME:PARENT:X,Y,Z[:CHILD,...]``) hangs under ``PARENT`` at the given
offset; the listed children of ``PARENT`` move under it with the offset subtracted, so
the rest pose is unchanged.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field

import numpy as np

from usdmotion.constants import MAX_ABS_VALUE
from usdmotion.errors import UsdMotionError
from usdmotion.motion import ROTATION_CHANNELS, Motion, validate_topology

DEFAULT_ROTATION_CHANNELS = ("Zrotation", "Xrotation", "Yrotation")
#: Relative length change below which step 1 leaves an offset untouched (rigid bones).
RIGID_LENGTH_TOL = 1e-9


class RetargetError(UsdMotionError):
    """A retargeting request cannot be carried out (bad joints, bad options, bad rig)."""


class UnitsMismatchError(RetargetError):
    """Source and target sizes differ so much that their units must disagree."""


@dataclass(frozen=True, eq=False)
class Rig:
    """A target skeleton without animation.

    Attributes:
        joint_names: ``J`` names, parents before children.
        parents: ``(J,)`` parent indices (root -1).
        offsets: ``(J, 3)`` rest translations in the parent frame, rig units.
        end_sites: ``(J,)`` bool, BVH End Site leaves.
        channels: BVH channel layout per joint, or ``None`` (default layout on write).
        meters_per_unit: length of one unit.
        up_axis: ``"Y"`` or ``"Z"``.
        root_offset: BVH root-offset convention to write with.
        animated: ``(J,)`` bool, non-root joints whose translation varies over the frames
            of the file the rig came from (e.g. Bandai ``Hips``); they keep position
            channels and may carry a per-frame translation.
        path: the file the rig came from (for messages), or ``None``.
    """

    joint_names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    end_sites: np.ndarray
    channels: tuple[tuple[str, ...], ...] | None
    meters_per_unit: float = 0.01
    up_axis: str = "Y"
    root_offset: str = "add"
    animated: np.ndarray = field(default=None)  # type: ignore[assignment]
    path: str | None = None

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=np.int64)
        ok, reason = validate_topology(parents)
        if not ok:
            raise RetargetError(f"{self.path or 'target'}: invalid joint hierarchy: {reason}")
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3))
        object.__setattr__(self, "end_sites", np.asarray(self.end_sites, dtype=bool))
        animated = np.zeros(len(parents), bool) if self.animated is None else np.asarray(self.animated, bool)
        object.__setattr__(self, "animated", animated)

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def index(self, name: str, what: str = "joint") -> int:
        """Index of ``name``; :class:`RetargetError` naming close matches if absent."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            hint = _did_you_mean(name, self.joint_names)
            raise RetargetError(f"{self.path or 'skeleton'}: no {what} named {name!r}{hint}") from None

    def is_ancestor(self) -> np.ndarray:
        """``(J, J)`` bool, ``[a, d]`` true when ``a`` is a strict ancestor of ``d``."""
        return ancestor_matrix(self.parents)


def _did_you_mean(name: str, names) -> str:
    close = difflib.get_close_matches(name, list(names), n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


def ancestor_matrix(parents: np.ndarray) -> np.ndarray:
    """``(J, J)`` bool: ``[a, d]`` is true when joint ``a`` is a strict ancestor of ``d``."""
    n = len(parents)
    anc = np.zeros((n, n), bool)
    for j in range(1, n):  # parents first: inherit the parent's ancestors
        p = parents[j]
        anc[:, j] = anc[:, p]
        anc[p, j] = True
    return anc


def with_ancestors(parents: np.ndarray, joints) -> np.ndarray:
    """``(K,)`` sorted: ``joints`` and every ancestor of them (a set closed under parents,
    whose forward kinematics needs no other joint)."""
    keep = np.zeros(len(parents), bool)
    keep[np.asarray(joints, np.int64)] = True
    keep |= ancestor_matrix(parents)[:, keep].any(axis=1)
    return np.flatnonzero(keep)


def restricted_parents(parents: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """``(K,)`` parents of the sub-skeleton of ``joints`` (sorted, closed under parents, e.g.
    :func:`with_ancestors`), as positions in ``joints`` (-1: a root): forward kinematics of
    ``q[:, joints]`` with them gives those joints' world transforms."""
    position = np.full(len(parents), -1)
    position[joints] = np.arange(len(joints))
    return np.where(parents[joints] >= 0, position[np.maximum(parents[joints], 0)], -1)


def rig_from_motion(motion: Motion, path: str | None = None) -> Rig:
    """The skeleton of a motion as a :class:`Rig` (its animation is dropped)."""
    animated = np.zeros(motion.n_joints, bool)
    if motion.joint_translations is not None and motion.n_frames:
        deviation = np.abs(motion.joint_translations - motion.offsets[None]).max(axis=(0, 2))
        scale = max(1.0, float(np.abs(motion.offsets).max(initial=0.0)))
        animated = deviation > 1e-6 * scale
        animated[0] = False
    return Rig(motion.joint_names, motion.parents, motion.offsets, motion.end_sites, motion.channels,
               motion.meters_per_unit, motion.up_axis, motion.root_offset, animated, path)


@dataclass(frozen=True)
class AddSpec:
    """A joint to add: ``name`` under ``parent`` at ``offset``, adopting ``children``."""

    name: str
    parent: str
    offset: tuple[float, float, float]
    children: tuple[str, ...] = ()


def parse_add(spec: str) -> AddSpec:
    """Parse ``NAME:PARENT:X,Y,Z[:CHILD,CHILD...]`` (offset in the rig's units)."""
    parts = spec.split(":")
    if len(parts) not in (3, 4) or not parts[0].strip() or not parts[1].strip():
        raise RetargetError(f"--add {spec!r}: expected NAME:PARENT:X,Y,Z[:CHILD,...]")
    try:
        offset = tuple(float(v) for v in parts[2].split(","))
    except ValueError:
        offset = ()
    if len(offset) != 3 or not np.all(np.abs(offset) <= MAX_ABS_VALUE):
        raise RetargetError(f"--add {spec!r}: the offset must be three finite numbers X,Y,Z within "
                            f"±{MAX_ABS_VALUE:g}")
    children = tuple(c.strip() for c in parts[3].split(",") if c.strip()) if len(parts) == 4 else ()
    return AddSpec(parts[0].strip(), parts[1].strip(), offset, children)  # type: ignore[arg-type]


@dataclass(frozen=True, eq=False)
class DerivedRig:
    """A rig made from another by removing/adding joints, with the provenance of each joint.

    Attributes:
        rig: the new rig.
        origin: ``(J_new,)`` index of each joint in the old rig, ``-1`` for added joints.
        compose: per new joint, the old joints whose local rotations multiply (top-down)
            into its new local rotation: the removed joints between its new parent and it,
            then itself. ``()`` for added joints.
        removed: names removed (End Sites of removed joints included).
        added: names added.
    """

    rig: Rig
    origin: np.ndarray
    compose: tuple[tuple[int, ...], ...]
    removed: tuple[str, ...]
    added: tuple[str, ...]


def derive_rig(rig: Rig, remove=(), add=()) -> DerivedRig:
    """Remove the joints named in ``remove``, then add the :class:`AddSpec` s in ``add``."""
    where = rig.path or "source"
    drop = np.zeros(rig.n_joints, bool)
    for name in remove:
        j = rig.index(name)
        if j == 0:
            raise RetargetError(f"{where}: cannot remove the root joint {name!r} (every hierarchy needs its root)")
        drop[j] = True
    for j in range(1, rig.n_joints):  # End Sites go with their joint
        if rig.end_sites[j] and drop[rig.parents[j]]:
            drop[j] = True
    keep = np.flatnonzero(~drop)
    new_index = -np.ones(rig.n_joints, np.int64)
    new_index[keep] = np.arange(len(keep))
    parents, offsets, compose = [], [], []
    for j in keep:
        chain = [int(j)]
        p = int(rig.parents[j])
        while p >= 0 and drop[p]:
            chain.insert(0, p)
            p = int(rig.parents[p])
        parents.append(-1 if p < 0 else int(new_index[p]))
        offsets.append(rig.offsets[chain].sum(axis=0) if p >= 0 else rig.offsets[j])
        compose.append(tuple(chain))
    names = [rig.joint_names[j] for j in keep]
    channels = None if rig.channels is None else [rig.channels[j] for j in keep]
    end_sites = list(rig.end_sites[keep])
    animated = list(rig.animated[keep])
    origin = [int(j) for j in keep]
    for spec in add:
        _insert_joint(spec, names, parents, offsets, channels, end_sites, animated, origin, compose, where)
    new = Rig(tuple(names), np.array(parents), np.array(offsets), np.array(end_sites),
              None if channels is None else tuple(channels), rig.meters_per_unit, rig.up_axis,
              rig.root_offset, np.array(animated), rig.path)
    removed = tuple(rig.joint_names[j] for j in np.flatnonzero(drop))
    return DerivedRig(new, np.array(origin, np.int64), tuple(compose), removed, tuple(s.name for s in add))


def _insert_joint(spec: AddSpec, names, parents, offsets, channels, end_sites, animated, origin, compose,
                  where: str) -> None:
    """Insert one added joint into the parallel lists (in place), keeping parents first."""
    if spec.name in names:
        raise RetargetError(f"--add {spec.name}: {where} already has a joint named {spec.name!r}")
    if spec.parent not in names:
        raise RetargetError(f"--add {spec.name}: no parent joint named {spec.parent!r} in {where}"
                            f"{_did_you_mean(spec.parent, names)}")
    parent = names.index(spec.parent)
    if end_sites[parent]:
        raise RetargetError(f"--add {spec.name}: {spec.parent!r} is an End Site and cannot have children")
    adopted = []
    for child in spec.children:
        if child not in names or parents[names.index(child)] != parent:
            raise RetargetError(f"--add {spec.name}: {child!r} is not a child of {spec.parent!r} in {where}")
        adopted.append(names.index(child))
    at = min(adopted) if adopted else len(names)
    shift = lambda i: i + 1 if i >= at else i  # noqa: E731
    for k in range(len(parents)):
        parents[k] = shift(parents[k]) if parents[k] >= 0 else -1
    offset = np.asarray(spec.offset, dtype=np.float64)
    for c in adopted:
        parents[c] = at  # indices of adopted children are shifted below
        offsets[c] = offsets[c] - offset
    names.insert(at, spec.name)
    parents.insert(at, parent if parent < at else parent + 1)
    offsets.insert(at, offset)
    end_sites.insert(at, False)
    animated.insert(at, False)
    origin.insert(at, -1)
    compose.insert(at, ())
    if channels is not None:
        parent_rot = tuple(c for c in channels[parent] if c in ROTATION_CHANNELS)
        channels.insert(at, parent_rot or DEFAULT_ROTATION_CHANNELS)


def mapped_chains(parents: np.ndarray, mapped: np.ndarray) -> list[tuple[int, list[int]]]:
    """For every mapped non-root joint with a mapped ancestor: ``(ancestor, chain)``.

    ``chain`` lists the joints from below the nearest mapped ancestor down to the joint
    (unmapped intermediate joints first). ``mapped`` is a ``(J,)`` bool array.
    """
    chains = []
    for j in np.flatnonzero(mapped):
        chain = [int(j)]
        p = int(parents[j])
        while p >= 0 and not mapped[p]:
            chain.insert(0, p)
            p = int(parents[p])
        if p >= 0:
            chains.append((p, chain))
    return chains


def source_bone_lengths(source_positions: np.ndarray, chains, source_of: np.ndarray) -> np.ndarray:
    """Mean over frames of the source distance of every chain ``(len(chains),)``."""
    if not chains:
        return np.zeros(0)
    top = np.array([source_of[a] for a, _ in chains])
    bottom = np.array([source_of[c[-1]] for _, c in chains])
    return np.linalg.norm(source_positions[:, bottom] - source_positions[:, top], axis=-1).mean(axis=0)


def adapt_offsets(offsets: np.ndarray, parents: np.ndarray, chains, lengths: np.ndarray,
                  other_scale: float = 1.0, fallback_directions: dict[int, np.ndarray] | None = None) -> np.ndarray:
    """Step 1: rescale offsets so every mapped chain has its mean source length.

    Each chain's offsets are scaled by ``length / ‖rest chain vector‖`` (direction kept);
    an unmapped joint shared by several chains takes the mean of their factors; joints on
    no chain (fingers, eyes, added leaves) are scaled by ``other_scale``. A chain whose
    rest vector is zero but whose source length is not gets the direction in
    ``fallback_directions[joint]`` (unit vector) when given, else stays zero.
    """
    offsets = np.array(offsets, dtype=np.float64)
    factor_sum = np.zeros(len(parents))
    factor_count = np.zeros(len(parents))
    replaced: dict[int, np.ndarray] = {}
    for (_, chain), length in zip(chains, lengths):
        rest = offsets[chain].sum(axis=0)
        norm = float(np.linalg.norm(rest))
        if norm <= 1e-12:
            direction = None if fallback_directions is None else fallback_directions.get(chain[-1])
            if direction is not None and len(chain) == 1 and length > 0:
                replaced[chain[-1]] = length * direction
            continue
        factor = 1.0 if abs(length - norm) <= RIGID_LENGTH_TOL * max(norm, 1.0) else length / norm
        factor_sum[chain] += factor
        factor_count[chain] += 1
    scale = np.where(factor_count > 0, factor_sum / np.maximum(factor_count, 1), other_scale)
    scale[0] = 1.0  # the root OFFSET is a position, not a bone
    out = offsets * scale[:, None]
    for j, value in replaced.items():
        out[j] = value
    return out
