"""Body roles of a skeleton's joints: which joints are root, chest, shoulder, elbow, wrist, hip, knee, ankle.

The bone-angle feature of ALGORITHMS.md §3 needs eight limb bones (upper arm, forearm,
thigh, shank on each side) and the centre bone Root → Chest. Rigs name these joints in
many ways (``LeftForeArm``, ``LeftElbow``, ``lForeArm``, ``LowerArm_L``, ``lradius``,
``mixamorig:LeftForeArm``...), so roles are found in three steps:

1. **Presets** for the rigs in the shared corpus (cgspeed MotionBuilder/3dsMax/DAZ, Bandai
   Namco, Mixamo, CMU ASF names), used when every named joint exists.
2. **Guessing**: the *middle* joints of each limb (elbow, knee) are recognised by name
   (side prefix/suffix stripped: ``Left``/``Right``, ``L``/``R``, ``l``/``r``, ``_L``...);
   the rest follows from the hierarchy: the shoulder/hip is the elbow's/knee's parent, the
   wrist/ankle its child with the longest rest bone, the root the lowest common ancestor
   of the two hips, the chest that of the two shoulders.
3. **Overrides**: ``{"chest": "Spine2", ...}`` from the user win over both.

A rig whose roles cannot be found raises :class:`~usdmotion.errors.InputError` listing
what is missing and the joints that were looked at.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

from usdmotion.errors import InputError
from usdmotion.motion import Motion

SIDES = ("left", "right")
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

# Joint names of the rigs in the shared corpus; "{L}"/"{R}" are filled per side.
_PRESETS: dict[str, dict[str, str]] = {
    "cgspeed-mb": {"root": "Hips", "chest": "Spine1", "shoulder": "{S}Arm", "elbow": "{S}ForeArm",
                   "wrist": "{S}Hand", "hip": "{S}UpLeg", "knee": "{S}Leg", "ankle": "{S}Foot"},
    "cgspeed-max": {"root": "Hips", "chest": "Chest2", "shoulder": "{S}Shoulder", "elbow": "{S}Elbow",
                    "wrist": "{S}Wrist", "hip": "{S}Hip", "knee": "{S}Knee", "ankle": "{S}Ankle"},
    "daz": {"root": "hip", "chest": "chest", "shoulder": "{s}Shldr", "elbow": "{s}ForeArm",
            "wrist": "{s}Hand", "hip": "{s}Thigh", "knee": "{s}Shin", "ankle": "{s}Foot"},
    "bandai": {"root": "Hips", "chest": "Chest", "shoulder": "UpperArm_{X}", "elbow": "LowerArm_{X}",
               "wrist": "Hand_{X}", "hip": "UpperLeg_{X}", "knee": "LowerLeg_{X}", "ankle": "Foot_{X}"},
    "mixamo": {"root": "mixamorig:Hips", "chest": "mixamorig:Spine2", "shoulder": "mixamorig:{S}Arm",
               "elbow": "mixamorig:{S}ForeArm", "wrist": "mixamorig:{S}Hand", "hip": "mixamorig:{S}UpLeg",
               "knee": "mixamorig:{S}Leg", "ankle": "mixamorig:{S}Foot"},
    "asf": {"root": "pelvis", "chest": "thorax", "shoulder": "{s}humerus", "elbow": "{s}radius",
            "wrist": "{s}hand", "hip": "{s}femur", "knee": "{s}tibia", "ankle": "{s}foot"},
}
PRESET_NAMES = tuple(_PRESETS)
# Further joints that identify each preset's rig, so a look-alike rig falls back to guessing.
_SIGNATURES: dict[str, tuple[str, ...]] = {
    "cgspeed-mb": ("LHipJoint", "RHipJoint", "LowerBack", "Neck1"),
    "cgspeed-max": ("LHipJoint", "RHipJoint", "lowerback", "lowerneck"),
    "daz": ("abdomen", "lButtock", "rButtock"),
    "bandai": ("joint_Root", "Shoulder_L", "Shoulder_R"),
    "mixamo": ("mixamorig:Spine1", "mixamorig:LeftShoulder"),
    "asf": ("lclavicle", "rclavicle"),
}

# Base names (lower case, side and punctuation removed) of the middle joint of a limb.
_ELBOW_NAMES = frozenset({"forearm", "elbow", "lowarm", "lowerarm", "armlower", "radius", "ulna", "forearmjnt"})
_KNEE_NAMES = frozenset({"leg", "knee", "lowleg", "lowerleg", "leglower", "shin", "tibia", "calf", "shank", "crus"})
_SIDE_WORD = re.compile(r"^(left|right)(.+)$|^(.+?)(left|right)$", re.IGNORECASE)
_SIDE_SUFFIX = re.compile(r"^(.+?)[_.\- ]([lr])$", re.IGNORECASE)
_SIDE_LETTER = re.compile(r"^([lr])[_.\- ]?(.+)$", re.IGNORECASE)


def _base(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def parse_side(name: str) -> tuple[str | None, str]:
    """``(side, base)`` of a joint name: ``"mixamorig:LeftForeArm"`` → ``("left", "forearm")``.

    ``side`` is ``None`` when the name carries none. A single-letter prefix (``lThigh``,
    ``rradius``) counts only when the rest is a known limb name, so ``lowerback`` stays
    side-less.
    """
    name = re.split(r"[:|]", name)[-1]
    m = _SIDE_WORD.match(name)
    if m:
        word, rest = (m.group(1), m.group(2)) if m.group(1) else (m.group(4), m.group(3))
        return word.lower(), _base(rest)
    m = _SIDE_SUFFIX.match(name)
    if m:
        return ("left" if m.group(2).lower() == "l" else "right"), _base(m.group(1))
    m = _SIDE_LETTER.match(name)
    if m and _base(m.group(2)) in _ELBOW_NAMES | _KNEE_NAMES:
        return ("left" if m.group(1).lower() == "l" else "right"), _base(m.group(2))
    return None, _base(name)


def _preset_roles(motion: Motion, preset: str) -> dict[str, str]:
    table = _PRESETS[preset]
    roles = {"root": table["root"], "chest": table["chest"]}
    for side in SIDES:
        fill = {"S": side.capitalize(), "s": side[0], "X": side[0].upper()}
        for role in LIMB_ROLES:
            roles[f"{side}_{role}"] = table[role].format(**fill)
    return roles


def match_preset(motion: Motion) -> str | None:
    """Name of the first preset all of whose joints exist in ``motion``, else ``None``."""
    names = set(motion.joint_names)
    for preset in _PRESETS:
        if set(_preset_roles(motion, preset).values()) | set(_SIGNATURES[preset]) <= names:
            return preset
    return None


def _ancestors(parents: np.ndarray, j: int) -> list[int]:
    chain = [j]
    while parents[chain[-1]] >= 0:
        chain.append(int(parents[chain[-1]]))
    return chain


def _common_ancestor(parents: np.ndarray, a: int, b: int) -> int:
    above_a = set(_ancestors(parents, a))
    return next(j for j in _ancestors(parents, b) if j in above_a)


def _limb_end(motion: Motion, joint: int) -> int | None:
    """The child of ``joint`` with the longest rest offset (the distal end of its bone)."""
    children = motion.children(joint)
    if children.size == 0:
        return None
    lengths = np.linalg.norm(motion.offsets[children], axis=1)
    return int(children[int(np.argmax(lengths))])


def _guess_roles(motion: Motion) -> tuple[dict[str, int], list[str]]:
    found: dict[str, int] = {}
    missing: list[str] = []
    parsed = [parse_side(n) for n in motion.joint_names]
    for side in SIDES:
        for middle, vocabulary, upper, lower in (("elbow", _ELBOW_NAMES, "shoulder", "wrist"),
                                                  ("knee", _KNEE_NAMES, "hip", "ankle")):
            hits = [j for j, (s, b) in enumerate(parsed) if s == side and b in vocabulary
                    and not motion.end_sites[j]]
            if not hits:
                missing.append(f"{side}_{middle}")
                continue
            j = hits[0]  # the first in file order is the one nearest the root
            found[f"{side}_{middle}"] = j
            found[f"{side}_{upper}"] = int(motion.parents[j])
            end = _limb_end(motion, j)
            if end is None:
                missing.append(f"{side}_{lower}")
            else:
                found[f"{side}_{lower}"] = end
    if "left_hip" in found and "right_hip" in found:
        found["root"] = _common_ancestor(motion.parents, found["left_hip"], found["right_hip"])
    else:
        missing.append("root")
    if "left_shoulder" in found and "right_shoulder" in found:
        found["chest"] = _common_ancestor(motion.parents, found["left_shoulder"], found["right_shoulder"])
    else:
        missing.append("chest")
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
    if preset is not None and preset not in _PRESETS:
        raise InputError(source, f"unknown role preset {preset!r} (presets: {', '.join(PRESET_NAMES)})")
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
