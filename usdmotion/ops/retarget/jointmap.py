"""Joint maps: which source joint drives each target joint, and with what loss weight.

A map comes from a JSON file (``schemas/jointmap.schema.json``), from two built-in rig
profiles (``usdmotion/data/rigs/*.json``: canonical body points → a rig's joint names,
so a map between any two known rigs is composed through the canonical names), or is
made automatically:

1. **same names**: target joints whose names exist in the source (same rig family), unless
   the two skeletons are recognised by different profiles: Mixamo and the cgspeed CMU rig
   share ``Neck``, ``LeftShoulder``, ``Spine1`` but not their meaning (cgspeed's ``Neck`` and
   ``LeftShoulder`` are zero-length helpers), and a Mixamo take mapped onto the CMU walk by
   name turned the CMU rig's ``Neck``/``Neck1`` a half turn in one frame (175°/178°);
2. **rig profiles**: both skeletons recognised by a profile's ``signature`` (profiles
   with ``"auto_map": false`` are used only where a map file names them);
3. **normalised names**: lower case, ``prefix:`` / ``group|`` namespaces and
   non-alphanumerics removed, ``left/right`` → ``l/r``.

Names and profiles are read by :mod:`usdmotion.skeleton_names`, which segmentation roles
and body landmarks share.

:func:`auto_map` reports what it could not map.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from usdmotion.errors import InputError
from usdmotion.schemas import schema
from usdmotion.skeleton_names import detect_profile, names_by_key, normalise_name, profile_joints, rig_profiles
from usdmotion.skeleton_names import strip_namespace  # noqa: F401 - its old import path


class JointMapError(InputError):
    """A joint map file is malformed or names joints the skeletons do not have."""


@dataclass(frozen=True)
class JointMap:
    """Target joint name → source joint name (``None``: not compared), plus weights.

    Attributes:
        pairs: target name → source name or ``None``.
        weights: target name → loss weight (missing: 1).
        how: where the map came from (for reports).
        path: the map file, or ``None``.
        auto: map target joints that ``pairs`` does not list automatically.
        profiles: ``(source_profile, target_profile)`` named by the file, or ``None``.
    """

    pairs: dict[str, str | None] = field(default_factory=dict)
    weights: dict[str, float] = field(default_factory=dict)
    how: str = "file"
    path: str | None = None
    auto: bool = False
    profiles: tuple[str, str] | None = None


# ----------------------------------------------------------------------------- files


def _validate(doc, schema_name: str, path) -> None:
    import jsonschema

    validator = jsonschema.Draft202012Validator(schema(schema_name))
    errors = sorted(validator.iter_errors(doc), key=lambda e: list(e.absolute_path))
    if errors:
        error = errors[0]
        where = "/".join(str(p) for p in error.absolute_path) or "top level"
        message = error.message if len(error.message) < 160 else error.message[:157] + "..."
        raise JointMapError(path, f"invalid joint map at {where}: {message}")


def load_joint_map(path: str | Path) -> JointMap:
    """Read and validate a joint map JSON file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise JointMapError(path, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise JointMapError(path, f"cannot read: {exc}") from None
    from usdmotion.schemas import _json_path, _non_finite, parse_text

    try:
        doc = parse_text(text, path)  # refuses NaN/Infinity, absurd nesting
    except InputError as exc:
        raise JointMapError(path, exc.message, exc.line, exc.column) from None
    bad = _non_finite(doc)  # 1e400 parses as inf
    if bad is not None:
        raise JointMapError(path, f"invalid joint map at {_json_path(bad)}: not a finite number")
    return joint_map_from_document(doc, path)


def joint_map_from_document(doc, path: str | Path | None = None) -> JointMap:
    """A parsed joint map document (``schemas/jointmap.schema.json``) checked and read;
    ``path`` names it in errors and the report."""
    _validate(doc, "jointmap", path)
    pairs: dict[str, str | None] = {}
    weights: dict[str, float] = {}
    for target, value in doc.get("joints", {}).items():
        if isinstance(value, dict):
            pairs[target] = value["source"]
            if "weight" in value:
                weights[target] = float(value["weight"])
        else:
            pairs[target] = value
    weights.update({k: float(v) for k, v in doc.get("weights", {}).items()})
    profiles = None
    if "source_profile" in doc or "target_profile" in doc:
        if not ("source_profile" in doc and "target_profile" in doc):
            raise JointMapError(path, "give both source_profile and target_profile")
        known = rig_profiles()
        for key in ("source_profile", "target_profile"):
            if doc[key] not in known:
                raise JointMapError(path, f"{key}: unknown rig profile {doc[key]!r} "
                                          f"(known: {', '.join(sorted(known))})")
        profiles = (doc["source_profile"], doc["target_profile"])
    auto = bool(doc.get("auto", False))
    return JointMap(pairs, weights, "file", None if path is None else str(path), auto, profiles)


# -------------------------------------------------------------------------- profiles
# rig_profiles, profile_joints, detect_profile, strip_namespace and normalise_name live in
# usdmotion.skeleton_names (shared with segmentation roles and body landmarks).


def profile_map(source_profile: str, target_profile: str, source_names, target_names) -> dict[str, str]:
    """Target name → source name through the canonical points of two profiles."""
    profiles = rig_profiles()
    src = profile_joints(profiles[source_profile], source_names) or {}
    tgt = profile_joints(profiles[target_profile], target_names) or {}
    return {tgt[p]: src[p] for p in tgt if p in src}


# -------------------------------------------------------------------------- auto map

def auto_map(source_names, target_names, target_end_sites=None) -> JointMap:
    """Map target joints to source joints automatically (see module docstring)."""
    source_names, target_names = list(source_names), list(target_names)
    ends = np.zeros(len(target_names), bool) if target_end_sites is None else np.asarray(target_end_sites, bool)
    real = [n for n, e in zip(target_names, ends) if not e]
    same = {n: n for n in target_names if n in set(source_names)}
    sp, tp = detect_profile(source_names), detect_profile(target_names)
    other_families = bool(sp and tp and sp != tp)  # shared names, other meanings (a zero-length helper)
    if real and sum(n in same for n in real) >= 0.6 * len(real) and not other_families:
        return JointMap(same, {}, "same names")
    if sp and tp:
        return JointMap(profile_map(sp, tp, source_names, target_names), {}, f"rig profiles {sp} -> {tp}",
                        profiles=(sp, tp))
    by_key = names_by_key(source_names, normalise_name)
    pairs = {n: by_key[normalise_name(n)] for n in target_names if normalise_name(n) in by_key}
    return JointMap(pairs, {}, "normalised names")


def resolve_map(joint_map: JointMap | None, source_names, target_names, target_end_sites=None,
                default: dict[str, str | None] | None = None) -> tuple[np.ndarray, np.ndarray, JointMap]:
    """Source index ``(J_t,)`` (-1: not compared) and weight ``(J_t,)`` per target joint.

    Precedence, lowest first: ``default`` (the identity of a rig derived from the source)
    or, without it, the automatic map (when there is no map file or it sets ``auto``);
    then the file's rig profiles; then the file's listed joints. Raises
    :class:`JointMapError` for names the skeletons do not have.
    """
    source_names, target_names = tuple(source_names), tuple(target_names)
    where = None if joint_map is None else joint_map.path
    pairs: dict[str, str | None] = {}
    how = []
    if default is not None:
        pairs.update(default)
        how.append("identity (target derived from the source)")
    elif joint_map is None or joint_map.auto:
        automatic = auto_map(source_names, target_names, target_end_sites)
        pairs.update(automatic.pairs)
        how.append(automatic.how)
    if joint_map is not None:
        _check_names(joint_map, source_names, target_names)
        if joint_map.profiles is not None:
            sp, tp = joint_map.profiles
            for profile, names, side in ((sp, source_names, "source"), (tp, target_names, "target")):
                if profile_joints(rig_profiles()[profile], names) is None:
                    raise JointMapError(where, f"the {side} skeleton does not fit rig profile {profile!r}")
            pairs.update(profile_map(sp, tp, source_names, target_names))
            how.append(f"rig profiles {sp} -> {tp}")
        pairs.update(joint_map.pairs)
        if joint_map.path:
            how.append(f"map file {joint_map.path}")
    source_index = {n: i for i, n in enumerate(source_names)}
    src = np.array([source_index[pairs[n]] if pairs.get(n) is not None else -1 for n in target_names], np.int64)
    weights = np.ones(len(target_names))
    if joint_map is not None:
        for name, w in joint_map.weights.items():
            if name not in target_names:
                raise JointMapError(where, f"weights: no target joint named {name!r}{_close(name, target_names)}")
            weights[target_names.index(name)] = w
    resolved = JointMap({n: pairs.get(n) for n in target_names}, {n: float(w) for n, w in zip(target_names, weights)},
                        " + ".join(how) or "empty", where)
    return src, weights, resolved


def _close(name: str, names) -> str:
    import difflib

    close = difflib.get_close_matches(name, list(names), n=3)
    return f" (did you mean {', '.join(close)}?)" if close else ""


def _check_names(joint_map: JointMap, source_names, target_names) -> None:
    for target, source in joint_map.pairs.items():
        if target not in target_names:
            raise JointMapError(joint_map.path,
                                f"joints: no target joint named {target!r}{_close(target, target_names)}")
        if source is not None and source not in source_names:
            raise JointMapError(joint_map.path, f"joints: {target!r} -> no source joint named {source!r}"
                                                f"{_close(source, source_names)}")


# -------------------------------------------------------------------------- unmapped

def unmapped_reasons(source_names, target_names, pairs: dict[str, str | None],
                     target_end_sites=None) -> dict[str, str]:
    """Target joint → why no source joint drives it, for every target joint ``pairs`` leaves unmapped.

    Reasons: ``"end site"``; a kind the target's rig profile marks (``"twist"``,
    ``"floor root"``, ``"hips root"``, ``"helper"``: :func:`usdmotion.skeleton_names.joint_kinds`);
    ``"no <point> in the source"`` for a body point of the target profile that the source
    rig lacks; ``"not a body point"`` (fingers, face...) for other joints of a recognised
    rig, and ``"no source joint of that name"`` where the target fits no profile.
    """
    from usdmotion.skeleton_names import joint_kinds

    target_names = list(target_names)
    ends = np.zeros(len(target_names), bool) if target_end_sites is None else np.asarray(target_end_sites, bool)
    tp, sp = detect_profile(target_names), detect_profile(source_names)
    profiles = rig_profiles()
    kinds = joint_kinds(profiles[tp], target_names) if tp else {}
    points = {v: k for k, v in (profile_joints(profiles[tp], target_names) or {}).items()} if tp else {}
    source_points = set(profile_joints(profiles[sp], source_names) or {}) if sp else set()
    out = {}
    for name, end in zip(target_names, ends):
        if pairs.get(name) is not None:
            continue
        if end:
            out[name] = "end site"
        elif name in kinds:
            out[name] = kinds[name]
        elif name in points:
            out[name] = f"no {points[name]} in the source" if points[name] not in source_points else "not mapped"
        else:
            out[name] = "not a body point" if tp else "no source joint of that name"
    return out
