"""What the joints of a skeleton are: names, sides, limb words, rig presets, hierarchy rules.

One place for the joint recognition that segmentation roles (:mod:`usdmotion.ops.segment.roles`),
body-segment landmarks (:mod:`usdmotion.anthropometry`) and automatic retargeting maps
(:mod:`usdmotion.ops.retarget.jointmap`) share:

* **Names.** :func:`strip_namespace` drops ``mixamorig:`` / ``group|`` prefixes;
  :func:`parse_side` splits a name into side and lower-case base
  (``mixamorig:LeftForeArm`` → ``("left", "forearm")``, ``lShldr`` → ``("left", "shldr")``,
  ``Knee.R`` → ``("right", "knee")``, ``CC_Base_L_Calf`` → ``("left", "calf")``);
  :func:`normalise_name` is the comparable key that joint maps match names by;
  :func:`safe_key` the one rig profiles and presets match by (``Bip01_L_Thigh`` as a DCC
  writes ``Bip01 L Thigh`` into USD).
* **Marks.** :func:`joint_kinds` / :func:`marked_joints`: the twist, root and helper bones
  a rig profile marks (no body points: joint maps leave them out and say why, bend angles
  skip them).
* **Limb words.** :data:`ELBOW_WORDS` and :data:`KNEE_WORDS`: base names of the middle
  joint of an arm and a leg (``forearm``, ``lowerarm``, ``radius``..., ``leg``, ``shin``,
  ``tibia``...); :data:`LIMB_WORDS` adds the other limb words a one-letter side prefix
  may stand before (``lhand``, ``rfemur``).
* **Rig profiles and presets** (data: ``usdmotion/data/rigs/*.json``, schema
  ``schemas/rigprofile.schema.json``): canonical body points (``hips``, ``l_forearm``...)
  → a rig's joint names. Joint maps recognise a profile through namespace-free names;
  the ``presets`` section of a profile names the exact-name preset (``cgspeed-mb``,
  ``daz``...) that segmentation roles and, with its ``landmarks``, body landmarks use.
* **Hierarchy rules**: ancestors, common ancestor, depth, the child with the longest
  bone, the nearest joint up / next joints down at a different rest position, the
  farthest leaf.

Everything here is topology-sized: small loops over joints, never over frames.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from types import MappingProxyType

import numpy as np

from usdmotion.motion import subtree_indices

SIDES = ("left", "right")

#: Base names (lower case, side and punctuation removed) of the middle joint of an arm.
ELBOW_WORDS = frozenset({"forearm", "elbow", "lowarm", "lowerarm", "armlower", "radius", "ulna", "forearmjnt"})
#: Base names of the middle joint of a leg.
KNEE_WORDS = frozenset({"leg", "knee", "lowleg", "lowerleg", "leglower", "shin", "tibia", "calf", "shank", "crus"})
#: Limb words after which a one-letter side prefix counts (``lhand``, ``Rforearm``).
LIMB_WORDS = ELBOW_WORDS | KNEE_WORDS | {"hand", "foot", "femur", "humerus", "thigh", "arm", "upleg", "shldr", "hip",
                                         "toe"}

#: The limbs found through their middle joint: ``(middle, upper, lower, tip, words of the middle)``.
LIMBS = (("elbow", "shoulder", "wrist", "hand_tip", ELBOW_WORDS), ("knee", "hip", "ankle", "toe_tip", KNEE_WORDS))

RIGS_FOLDER = Path(__file__).resolve().parent / "data" / "rigs"

# ------------------------------------------------------------------------------ names

_NAMESPACE = re.compile(r"[:|]")
_SIDE_WORD_FIRST = re.compile(r"^(left|right)(.+)$", re.IGNORECASE)
_SIDE_WORD_LAST = re.compile(r"^(.+?)(left|right)$", re.IGNORECASE)
_SIDE_LETTER_LAST = re.compile(r"^(.+?)[_.\- ]([lr])$", re.IGNORECASE)
_SIDE_LETTER_FIRST = re.compile(r"^([lr])(.+)$", re.IGNORECASE)
_WORD_BREAK = re.compile(r"^[A-Z_.\- ]")


def strip_namespace(name: str) -> str:
    """``"mixamorig:Hips"`` → ``"Hips"``, ``"rig|Hips"`` → ``"Hips"`` (the part after the last ``:``/``|``)."""
    return _NAMESPACE.split(name)[-1]


def base_name(name: str) -> str:
    """Lower case, letters and digits only: ``"Left_Fore-Arm"`` → ``"leftforearm"``."""
    return re.sub(r"[^a-z0-9]", "", name.lower())


def _letter_side(letter: str) -> str:
    return "left" if letter.lower() == "l" else "right"


def parse_side(name: str) -> tuple[str | None, str]:
    """``(side, base)`` of a joint name: ``"mixamorig:LeftForeArm"`` → ``("left", "forearm")``.

    ``side`` is ``"left"``, ``"right"`` or ``None``; ``base`` is :func:`base_name` of the
    rest. Tried in turn on the name without namespace: a leading or trailing ``left`` /
    ``right`` (any case, ``LeftArm``, ``arm_right``); a trailing ``l``/``r`` after a
    separator (``Knee.R``, ``LowerArm_L``); a leading ``l``/``r`` followed by a capital or
    a separator (``lShldr``, ``L_hand``) or by a limb word of :data:`LIMB_WORDS` (``rtibia``,
    ``lhand``, ``Lforearm``; capitals after the word are ignored, ``lhandIK``), so
    ``lowerback`` and ``leg`` stay side-less; last, one side word between separators
    inside the name, the base being what follows it (``CC_Base_L_Calf`` → ``("left",
    "calf")``, ``Bip01 R Forearm`` → ``("right", "forearm")``; not End Sites,
    ``Hand_L_End`` stays side-less as before).
    """
    name = strip_namespace(name)
    if m := _SIDE_WORD_FIRST.match(name):
        return m.group(1).lower(), base_name(m.group(2))
    if m := _SIDE_WORD_LAST.match(name):
        return m.group(2).lower(), base_name(m.group(1))
    if m := _SIDE_LETTER_LAST.match(name):
        return _letter_side(m.group(2)), base_name(m.group(1))
    if m := _SIDE_LETTER_FIRST.match(name):
        rest = m.group(2)
        if _WORD_BREAK.match(rest) or base_name(rest) in LIMB_WORDS or re.sub(r"[^a-z0-9]", "", rest) in LIMB_WORDS:
            return _letter_side(m.group(1)), base_name(rest)
    words = _SEPARATORS.split(name)
    sides = [k for k, w in enumerate(words[:-1]) if k > 0 and w.lower() in _SIDE_TOKENS]
    if len(sides) == 1 and words[-1].lower() != "end":  # a side word inside: CC_Base_L_Calf, Bip01 L Thigh
        k = sides[0]
        return _letter_side(words[k][0]), base_name("".join(words[k + 1:]))
    return None, base_name(name)


_TOKENS = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|[0-9]+")
_SIDE_TOKENS = {"left": "l", "l": "l", "right": "r", "r": "r"}
_SEPARATORS = re.compile(r"[_.\- ]+")


def normalise_name(name: str) -> str:
    """Comparable form of a joint name: no namespace, lower case, alphanumerics only, and
    a first or last word ``left``/``l``/``right``/``r`` moved to the front as ``l``/``r``
    (``LeftUpLeg``, ``upleg_L``, ``lUpLeg`` → ``lupleg``).

    Words are camel-case or separated runs, so a side counts only as a whole word
    (``Leftfoot`` stays ``leftfoot``): two rigs' names match when their keys are equal.
    """
    tokens = [t.lower() for t in _TOKENS.findall(strip_namespace(name))]
    side = ""
    for k in (0, -1):
        if len(tokens) > 1 and tokens[k] in _SIDE_TOKENS:
            side = _SIDE_TOKENS[tokens.pop(k)]
            break
    return side + "".join(tokens)


def split_side(key: str) -> tuple[str | None, str]:
    """``"left_hand_tip"`` → ``("left", "hand_tip")``; ``"chest"`` → ``(None, "chest")``."""
    side, _, part = key.partition("_")
    return (side, part) if side in SIDES else (None, key)


# ---------------------------------------------------------------------- rig profiles


@lru_cache(maxsize=1)
def rig_profiles() -> dict[str, dict]:
    """Built-in rig profiles by name.

    They are package data, not user input: ``tests/test_schemas.py`` validates every one
    against ``rigprofile.schema.json``, so reading them here needs no jsonschema (0.05 s of
    every command's start-up, since every BVH read checks its units through them).
    """
    out = {}
    for entry in sorted(RIGS_FOLDER.glob("*.json")):
        doc = json.loads(entry.read_text("utf-8"))
        out[doc["name"]] = doc
    return out


def names_by_key(names: Iterable[str], key: Callable[[str], str]) -> dict[str, str]:
    """``key(name)`` → name, the first name winning (``key``: :func:`strip_namespace`,
    :func:`normalise_name`...)."""
    table: dict[str, str] = {}
    for n in names:
        table.setdefault(key(n), n)
    return table


_UNSAFE = re.compile(r"[^0-9A-Za-z_]")


def safe_key(name: str) -> str:
    """``name`` with every character a USD identifier cannot hold made ``_``: how DCC tools
    write ``Bip01 L Thigh``, ``DEF-thigh.L`` as USD joint paths (``Bip01_L_Thigh``, ``DEF_thigh_L``).
    Rig profiles and presets match names by it."""
    return _UNSAFE.sub("_", name)


def _profile_key(name: str) -> str:
    return safe_key(strip_namespace(name))


def profile_joints(profile: dict, names: Iterable[str]) -> dict[str, str] | None:
    """Canonical point → joint name of ``names`` if the skeleton fits ``profile``, else ``None``.

    Names are compared without namespace and by :func:`safe_key`."""
    table = names_by_key(names, _profile_key)
    if not all(_has_any(table, s) for s in profile["signature"]):
        return None
    resolved = {}
    for point, candidates in profile["joints"].items():
        candidates = [candidates] if isinstance(candidates, str) else candidates
        hit = next((table[_profile_key(c)] for c in candidates if _profile_key(c) in table), None)
        if hit is not None:
            resolved[point] = hit
        elif point not in profile["optional"]:
            return None
    return resolved


def _has_any(table: Mapping[str, str], candidates: str | Sequence[str]) -> bool:
    return any(_profile_key(c) in table for c in ([candidates] if isinstance(candidates, str) else candidates))


def detect_profile(names: Iterable[str]) -> str | None:
    """Name of the built-in profile a skeleton fits (most points resolved), or ``None``.

    Profiles with ``"auto_map": false`` are left out: they are used only where named.
    ``"generic"`` profiles (names other rigs share, e.g. HumanIK's) count only when no
    other profile fits. Cached per skeleton (a library's takes share a few; matching every
    profile costs about 0.2 ms).
    """
    return _detect_profile(tuple(names))


@lru_cache(maxsize=256)
def _detect_profile(names: tuple[str, ...]) -> str | None:
    for generic in (False, True):
        best, best_count = None, 0
        for name, profile in rig_profiles().items():
            if not profile.get("auto_map", True) or profile.get("generic", False) != generic:
                continue
            resolved = profile_joints(profile, names)
            if resolved is not None and len(resolved) > best_count:
                best, best_count = name, len(resolved)
        if best is not None:
            return best
    return None


def rig_family(names: Iterable[str]) -> str | None:
    """The rig family to show for a skeleton: :func:`detect_profile`'s, else a profile used only
    where named (``"auto_map": false``, e.g. CMU ASF bone names) whose signature names are all
    there; ``None`` if neither. A label for people (library listings), never a joint map.
    Cached per skeleton, like :func:`detect_profile` (a library's takes share a few)."""
    return _rig_family(tuple(names))


@lru_cache(maxsize=256)
def _rig_family(names: tuple[str, ...]) -> str | None:
    found = _detect_profile(names)
    if found is not None:
        return found
    table = names_by_key(names, _profile_key)
    return next((name for name, profile in rig_profiles().items() if not profile.get("auto_map", True)
                 and all(_has_any(table, s) for s in profile["signature"])), None)


#: What a joint that is no body point of its rig's profile is (:func:`joint_kinds`).
JOINT_KINDS = ("twist", "floor root", "hips root", "helper")


def joint_kinds(profile: dict, names: Iterable[str]) -> dict[str, str]:
    """Joint name → kind (one of :data:`JOINT_KINDS`) for the joints of ``names`` that
    ``profile`` marks as twist segments, root bones or helpers (namespaces ignored); a joint
    the profile names as a body point (Biped's ``Bip01 HeadNub`` head top) is never marked."""
    names = list(names)
    twist = [re.compile(p) for p in profile.get("twist", ())]
    helpers = [re.compile(p) for p in profile.get("helpers", ())]
    roots = {_profile_key(k): v for k, v in profile.get("roots", {}).items()}
    body = set((profile_joints(profile, names) or {}).values())
    out = {}
    for name in names:
        bare = strip_namespace(name)
        if name in body:
            continue
        if _profile_key(name) in roots:
            out[name] = f"{roots[_profile_key(name)]} root"
        elif any(p.fullmatch(bare) for p in twist):
            out[name] = "twist"
        elif any(p.fullmatch(bare) for p in helpers):
            out[name] = "helper"
    return out


def marked_joints(names: Sequence[str]) -> dict[int, str]:
    """Joint index → kind (:data:`JOINT_KINDS`) of the joints that the rig profile a skeleton
    fits (:func:`detect_profile`) marks as twist segments, root bones or helpers; empty if none fits."""
    profile = detect_profile(names)
    if profile is None:
        return {}
    kinds = joint_kinds(rig_profiles()[profile], names)
    return {j: kinds[n] for j, n in enumerate(names) if n in kinds}


# --------------------------------------------------------------------------- presets

#: Canonical point of each segmentation role part (``left_elbow`` → ``l_forearm``).
ROLE_POINTS = {"root": "hips", "chest": "chest", "shoulder": "upper_arm", "elbow": "forearm", "wrist": "hand",
               "hip": "thigh", "knee": "shin", "ankle": "foot"}
#: Canonical point of each body-segment landmark part (``neck`` is the neck base, C7).
LANDMARK_POINTS = {"head_top": "head_top", "neck": "neck_base", "shoulder": "upper_arm", "elbow": "forearm",
                   "wrist": "hand", "hand_tip": "hand_tip", "hip": "thigh", "knee": "shin", "ankle": "foot",
                   "toe_tip": "toe_tip"}


@dataclass(frozen=True)
class RigPreset:
    """A rig's joints by exact name, for recognising roles or landmarks.

    Attributes:
        name: preset name (``cgspeed-mb``...).
        profile: the rig profile it comes from.
        points: canonical point → exact joint name (namespace included).
        signature: further exact names that must exist.
    """

    name: str
    profile: str
    points: Mapping[str, str]
    signature: tuple[str, ...]

    def joints(self, keys: Sequence[str], parts: Mapping[str, str]) -> dict[str, str]:
        """``key`` (``"root"``, ``"left_elbow"``...) → joint name, through ``parts`` (part → point)."""
        out = {}
        for key in keys:
            side, part = split_side(key)
            point = parts[part] if side is None else f"{side[0]}_{parts[part]}"
            out[key] = self.points[point]
        return out


def _first(candidates) -> str:
    return candidates if isinstance(candidates, str) else candidates[0]


@lru_cache(maxsize=2)
def rig_presets(kind: str) -> tuple[RigPreset, ...]:
    """The ``"roles"`` or ``"landmarks"`` presets, in the order they are tried.

    Every profile with ``presets`` has a role preset (its ``roles`` points over ``joints``, and
    its ``signature`` must exist too); one whose ``presets`` has ``landmarks`` also has a
    landmark preset (those points over ``joints``; it needs only its own joints).
    """
    if kind not in ("roles", "landmarks"):
        raise ValueError(f"kind must be 'roles' or 'landmarks', got {kind!r}")
    found = []
    for profile in rig_profiles().values():
        spec = profile.get("presets")
        if spec is None or (kind == "landmarks" and "landmarks" not in spec):
            continue
        points = {p: _first(c) for p, c in profile["joints"].items()}
        points.update(spec.get(kind, {}))  # the preset's own names of some points
        ns = spec.get("namespace", "")
        exact = MappingProxyType({p: ns + n for p, n in points.items()})
        signature = tuple(ns + n for n in spec["signature"]) if kind == "roles" else ()  # landmarks: none
        found.append((spec["order"], RigPreset(spec["name"], profile["name"], exact, signature)))
    return tuple(preset for _, preset in sorted(found, key=lambda item: item[0]))


def preset_names(kind: str) -> tuple[str, ...]:
    """Names of the ``kind`` presets, in the order they are tried."""
    return tuple(p.name for p in rig_presets(kind))


def preset_names_attribute(kind: str, module: str) -> Callable[[str], tuple[str, ...]]:
    """A module ``__getattr__`` that gives ``PRESET_NAMES`` (the ``kind`` preset names) on
    first use, so importing the module reads no rig profile."""
    def module_attribute(name: str) -> tuple[str, ...]:
        if name == "PRESET_NAMES":
            return preset_names(kind)
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return module_attribute


def preset_named(kind: str, name: str) -> RigPreset | None:
    """The ``kind`` preset called ``name``, or ``None``."""
    return next((p for p in rig_presets(kind) if p.name == name), None)


def fitting_preset(kind: str, names: Iterable[str], keys: Sequence[str],
                   parts: Mapping[str, str]) -> tuple[RigPreset, dict[str, str]] | None:
    """The first ``kind`` preset whose joints for ``keys`` and whose signature all exist
    in ``names`` (exact names, or the same :func:`safe_key`), with ``key → joint name`` of
    ``names``; ``None`` if none fits."""
    names = list(names)
    present = set(names)
    for preset in rig_presets(kind):
        joints = actual_names(preset.joints(keys, parts), names)
        signature = actual_names({n: n for n in preset.signature}, names)
        if set(joints.values()) | set(signature.values()) <= present:
            return preset, joints
    return None


def actual_names(wanted: Mapping[str, str], names: Iterable[str]) -> dict[str, str]:
    """``wanted`` (key → exact joint name of a preset) with each name replaced by the joint of
    ``names`` that has the same :func:`safe_key` (``Bip01_L_Thigh`` for ``Bip01 L Thigh``);
    names with no such joint stay as they are."""
    names = list(names)
    present = set(names)
    table = names_by_key(names, safe_key)
    return {k: n if n in present else table.get(safe_key(n), n) for k, n in wanted.items()}


# ------------------------------------------------------------------------- hierarchy


def ancestors(parents: np.ndarray, joint: int) -> list[int]:
    """``joint`` and its ancestors up to the root, nearest first."""
    chain = [int(joint)]
    while parents[chain[-1]] >= 0:
        chain.append(int(parents[chain[-1]]))
    return chain


def common_ancestor(parents: np.ndarray, a: int, b: int) -> int:
    """The lowest joint that is ``a`` or an ancestor of it and ``b`` or an ancestor of it."""
    above_a = set(ancestors(parents, a))
    return next(j for j in ancestors(parents, b) if j in above_a)


def depth(parents: np.ndarray, joint: int) -> int:
    """Number of links from the root to ``joint``."""
    return len(ancestors(parents, joint)) - 1


def children_map(parents: np.ndarray) -> dict[int, list[int]]:
    """Parent index → list of child indices (the root's parent is -1)."""
    out: dict[int, list[int]] = {}
    for j, p in enumerate(parents):
        out.setdefault(int(p), []).append(j)
    return out


def descendants(parents: np.ndarray, joint: int) -> list[int]:
    """Sorted indices of the joints below ``joint`` (not ``joint`` itself)."""
    return [int(j) for j in subtree_indices(parents, joint) if j != joint]


def longest_child(parents: np.ndarray, offsets: np.ndarray, joint: int) -> int | None:
    """The child of ``joint`` with the longest rest offset (the distal end of its bone)."""
    children = np.flatnonzero(parents == joint)
    if children.size == 0:
        return None
    lengths = np.linalg.norm(offsets[children], axis=1)
    return int(children[int(np.argmax(lengths))])


def rest_tolerance(rest: np.ndarray) -> float:
    """Distance below which two rest positions ``(J, 3)`` count as one (1e-6 of the extent)."""
    return 1e-6 * max(float(np.ptp(rest, axis=0).max()), 1e-12)


def _rest_distance(rest: np.ndarray, a: int, b: int) -> float:
    return float(np.linalg.norm(rest[a] - rest[b]))


def proximal_joint(parents: np.ndarray, rest: np.ndarray, joint: int, eps: float) -> int | None:
    """Nearest ancestor of ``joint`` at a different rest position (``None`` for the root)."""
    a = int(parents[joint])
    while a >= 0 and _rest_distance(rest, a, joint) <= eps:
        a = int(parents[a])
    return a if a >= 0 else None


def distal_joints(kids: dict[int, list[int]], rest: np.ndarray, joint: int, eps: float) -> list[int]:
    """The joints next down from ``joint`` at a different rest position (through zero-length links)."""
    frontier, found = list(kids.get(joint, [])), []
    while frontier:
        j = frontier.pop()
        if _rest_distance(rest, j, joint) > eps:
            found.append(j)
        else:
            frontier.extend(kids.get(j, []))
    return sorted(found)


def distal_joint(kids: dict[int, list[int]], rest: np.ndarray, joint: int, eps: float) -> int | None:
    """Next joint down the chain: of :func:`distal_joints`, the one with the longest bone."""
    found = distal_joints(kids, rest, joint, eps)
    return max(found, key=lambda j: _rest_distance(rest, j, joint)) if found else None


def farthest_leaf(parents: np.ndarray, kids: dict[int, list[int]], rest: np.ndarray, joint: int) -> int | None:
    """The leaf below ``joint`` farthest from it at rest (``None`` for a leaf)."""
    leaves = [j for j in descendants(parents, joint) if j not in kids]
    return max(leaves, key=lambda j: _rest_distance(rest, j, joint)) if leaves else None


def middle_joint_candidates(joint_names: Sequence[str], end_sites: np.ndarray,
                            parsed: Sequence[tuple[str | None, str]] | None = None,
                            ) -> Iterator[tuple[str, tuple[str, str, str, str], list[int]]]:
    """For each side and limb of :data:`LIMBS`: ``(side, (middle, upper, lower, tip), joints)``,
    ``joints`` being the joints (End Sites excepted) on that side whose base name is one of
    the limb's middle-joint words, in file order.

    ``parsed`` (:func:`parse_side` of every name) saves parsing the names again.
    """
    parsed = parsed if parsed is not None else [parse_side(n) for n in joint_names]
    for side in SIDES:
        for middle, upper, lower, tip, words in LIMBS:
            joints = [j for j, (s, b) in enumerate(parsed) if s == side and b in words and not end_sites[j]]
            yield side, (middle, upper, lower, tip), joints
