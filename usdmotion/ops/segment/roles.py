"""Body roles of a skeleton's joints: which joints are root, chest, shoulder, elbow, wrist, hip, knee, ankle.

The bone-angle feature of ALGORITHMS.md §3 needs eight limb bones (upper arm, forearm,
thigh, shank on each side) and the centre bone Root → Chest. Rigs name these joints in
many ways (``LeftForeArm``, ``LeftElbow``, ``lForeArm``, ``LowerArm_L``, ``lradius``,
``mixamorig:LeftForeArm``...), so roles are found in three steps:

1. **Presets** for the rigs in the shared corpus (cgspeed MotionBuilder/3dsMax/DAZ, Bandai
   Namco, Mixamo, CMU ASF names), used when every named joint exists: the ``presets`` of
   the rig profiles in ``usdmotion/data/rigs/`` (see :mod:`usdmotion.skeleton_names`).
2. **Guessing**: the *middle* joints of each limb (elbow, knee) are recognised by name
   (:func:`~usdmotion.skeleton_names.parse_side`: side prefix/suffix stripped:
   ``Left``/``Right``, ``L``/``R``, ``l``/``r``, ``_L``...);
   the rest follows from the hierarchy: the shoulder/hip is the elbow's/knee's parent, the
   wrist/ankle its child with the longest rest bone, the root the lowest common ancestor
   of the two hips, the chest that of the two shoulders.
3. **Overrides**: ``{"chest": "Spine2", ...}`` from the user win over both.

A rig whose roles cannot be found raises :class:`~usdmotion.errors.InputError` listing
what is missing and the joints that were looked at.
"""

from __future__ import annotations

from collections.abc import Mapping

from usdmotion.errors import InputError
from usdmotion.motion import Motion
from usdmotion.skeleton_names import (ROLE_POINTS, SIDES, actual_names, common_ancestor, fitting_preset, longest_child,
                                      middle_joint_candidates, preset_named, preset_names, preset_names_attribute)
from usdmotion.skeleton_names import parse_side  # noqa: F401 - its old import path

LIMB_ROLES = ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")
#: Every role, in a fixed order: ``root``, ``chest``, then ``left_shoulder`` ... ``right_ankle``.
ROLES = ("root", "chest") + tuple(f"{side}_{r}" for side in SIDES for r in LIMB_ROLES)
#: The eight limb bones ``(name, upper role, lower role)`` in feature order.
LIMB_BONES = tuple(
    (f"{side}_{bone}", f"{side}_{a}", f"{side}_{b}")
    for side in SIDES
    for bone, a, b in (("upper_arm", "shoulder", "elbow"), ("forearm", "elbow", "wrist"),
                       ("thigh", "hip", "knee"), ("shank", "knee", "ankle"))
)


#: ``PRESET_NAMES``: the role presets in the order they are tried (read from the rig profiles on first use).
__getattr__ = preset_names_attribute("roles", __name__)


def _preset_roles(motion: Motion, preset: str) -> dict[str, str]:
    """Role → joint name in role preset ``preset`` (whether or not ``motion`` has them; a joint
    whose name differs only where USD paths cannot hold a character counts as the same)."""
    return actual_names(preset_named("roles", preset).joints(ROLES, ROLE_POINTS), motion.joint_names)


def match_preset(motion: Motion) -> str | None:
    """Name of the first preset all of whose joints (and signature joints) exist in ``motion``, else ``None``."""
    hit = fitting_preset("roles", motion.joint_names, ROLES, ROLE_POINTS)
    return None if hit is None else hit[0].name


def _guess_roles(motion: Motion) -> tuple[dict[str, int], list[str]]:
    """Roles found by name and hierarchy (step 2), and the roles that could not be found."""
    found: dict[str, int] = {}
    missing: list[str] = []
    for side, (middle, upper, lower, _), hits in middle_joint_candidates(motion.joint_names, motion.end_sites):
        if not hits:
            missing.append(f"{side}_{middle}")
            continue
        j = hits[0]  # the first in file order is the one nearest the root
        found[f"{side}_{middle}"] = j
        found[f"{side}_{upper}"] = int(motion.parents[j])
        end = longest_child(motion.parents, motion.offsets, j)
        if end is None:
            missing.append(f"{side}_{lower}")
        else:
            found[f"{side}_{lower}"] = end
    for centre, limb in (("root", "hip"), ("chest", "shoulder")):  # where the legs / arms branch off
        if f"left_{limb}" in found and f"right_{limb}" in found:
            found[centre] = common_ancestor(motion.parents, found[f"left_{limb}"], found[f"right_{limb}"])
        else:
            missing.append(centre)
    return found, missing


def find_roles(motion: Motion, overrides: Mapping[str, str] | None = None, preset: str | None = None,
               source: str | None = None) -> dict[str, int]:
    """Joint index of every role in :data:`ROLES`.

    Args:
        motion: the skeleton.
        overrides: ``{role: joint name}`` that win over presets and guessing.
        preset: force a preset from :data:`PRESET_NAMES` (default: the first that fits,
            else name-based guessing).
        source: file name for error messages.

    Raises:
        InputError: an unknown role or joint in ``overrides``, an unknown preset, or roles
            that could not be found (the message lists them).
    """
    overrides = dict(overrides or {})
    bad_roles = sorted(set(overrides) - set(ROLES))
    if bad_roles:
        raise InputError(source, f"unknown role {bad_roles[0]!r} (roles: {', '.join(ROLES)})")
    if preset is not None and preset not in preset_names("roles"):
        raise InputError(source, f"unknown role preset {preset!r} (presets: {', '.join(preset_names('roles'))})")
    index = {n: j for j, n in enumerate(motion.joint_names)}
    chosen = preset or match_preset(motion)
    if chosen is not None:
        names = _preset_roles(motion, chosen)
        absent = [n for n in names.values() if n not in index]
        if absent:
            raise InputError(source, f"role preset {chosen!r} does not fit: no joint {absent[0]!r}")
        roles, missing = {r: index[n] for r, n in names.items()}, []
    else:
        roles, missing = _guess_roles(motion)
    for role, name in overrides.items():
        if name not in index:
            raise InputError(source, f"role {role}={name!r}: no such joint")
        roles[role] = index[name]
        if role in missing:
            missing.remove(role)
    if missing:
        raise InputError(source, f"cannot find the joints for role(s) {', '.join(missing)} among "
                                 f"{_sample(motion)}; name them with --role ROLE=JOINT")
    _check_bones(motion, roles, source)
    return {r: roles[r] for r in ROLES}


def _sample(motion: Motion, limit: int = 12) -> str:
    names = [n for n, e in zip(motion.joint_names, motion.end_sites) if not e]
    return ", ".join(names[:limit]) + (f" … ({len(names)} joints)" if len(names) > limit else "")


def _check_bones(motion: Motion, roles: Mapping[str, int], source: str | None) -> None:
    """Every bone of the feature must join two different joints."""
    for bone, a, b in LIMB_BONES + (("centre", "root", "chest"),):
        if roles[a] == roles[b]:
            raise InputError(source, f"the {bone} bone needs two different joints, {a} and {b} are both "
                                     f"{motion.joint_names[roles[a]]!r}")


def parse_role_overrides(items: list[str] | None) -> dict[str, str]:
    """``["chest=Spine2", "root=Hips"]`` → ``{"chest": "Spine2", "root": "Hips"}``."""
    out: dict[str, str] = {}
    for item in items or []:
        role, sep, name = item.partition("=")
        if not sep or not role.strip() or not name.strip():
            raise ValueError(f"--role {item!r}: expected ROLE=JOINT, e.g. chest=Spine2")
        out[role.strip()] = name.strip()
    return out
