"""Body segment parameters and centre of mass from joint positions.

Segment masses and centre-of-mass (COM) locations follow de Leva (1996), "Adjustments to
Zatsiorsky–Seluyanov's segment inertia parameters", J. Biomech. 29(9):1223–1230, Table 4,
using the segment definitions whose end points a BVH skeleton has:

=========  ====================================  =========  =========  ===========  ===========
segment    from → to (de Leva end points)          mass ♂ %   mass ♀ %   COM ♂ % ¹    COM ♀ % ¹
=========  ====================================  =========  =========  ===========  ===========
head       vertex → C7 (VERT → CERV)               6.94       6.68       50.02        48.41
trunk      C7 → mid hip joint centres (MIDH)       43.46      42.57      51.38        49.64
upper arm  shoulder → elbow joint centre           2.71       2.55       57.72        57.54
forearm    elbow → wrist joint centre              1.62       1.38       45.74        45.59
hand       wrist → middle finger tip (DAC3)        0.61       0.56       36.24        34.27
thigh      hip → knee joint centre                 14.16      14.78      40.95        36.12
shank      knee → ankle joint centre               4.33       4.81       43.95        43.52
foot       heel → toe tip (TTIP) ²                 1.37       1.29       44.15        40.14
=========  ====================================  =========  =========  ===========  ===========

¹ distance of the segment COM from the first end point, % of the segment length.
² BVH rigs have no heel: the foot runs from the ankle joint to the toe tip here, which
  moves the foot COM forward by a few centimetres (≈ 1 mm on the whole-body COM).

The end points ("landmarks") are found on a skeleton by a preset for the rigs of the
shared corpus (the ``presets`` of the rig profiles, :mod:`usdmotion.skeleton_names`),
else by name (the elbow and knee by name, the rest from the hierarchy:
shoulder/hip = the ancestor next to the elbow/knee, wrist/ankle = the next joint down,
finger/toe tip and vertex = the farthest leaf below the wrist/ankle/head), and any
landmark can be overridden. A custom segment table (e.g. for a 3-segment gymnast model)
replaces de Leva's entirely. Every segment COM is a fixed linear combination of joint
positions, so the model is a ``(S, J)`` weight matrix applied to all frames at once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from usdmotion.errors import InputError
from usdmotion.kinematics import rest_positions
from usdmotion.motion import Motion
from usdmotion.schemas import load_document
from usdmotion.skeleton_names import (LANDMARK_POINTS, SIDES, children_map, depth, distal_joint, farthest_leaf,
                                      fitting_preset, middle_joint_candidates, parse_side, preset_names_attribute,
                                      proximal_joint, rest_tolerance)
from usdmotion.skeleton_names import distal_joints  # noqa: F401 - its old import path

SEXES = ("male", "female")
_LIMB = ("shoulder", "elbow", "wrist", "hand_tip", "hip", "knee", "ankle", "toe_tip")
#: Every landmark name, in a fixed order.
LANDMARKS = ("head_top", "neck") + tuple(f"{s}_{p}" for s in SIDES for p in _LIMB)
_OPTIONAL = ("head_top", "left_hand_tip", "right_hand_tip", "left_toe_tip", "right_toe_tip")

# (segment, origin landmark, other landmark, mass % male, female, COM % male, female)
_DE_LEVA = (
    ("head", "head_top", "neck", 6.94, 6.68, 50.02, 48.41),
    ("trunk", "neck", "mid_hip", 43.46, 42.57, 51.38, 49.64),
    ("upper_arm", "shoulder", "elbow", 2.71, 2.55, 57.72, 57.54),
    ("forearm", "elbow", "wrist", 1.62, 1.38, 45.74, 45.59),
    ("hand", "wrist", "hand_tip", 0.61, 0.56, 36.24, 34.27),
    ("thigh", "hip", "knee", 14.16, 14.78, 40.95, 36.12),
    ("shank", "knee", "ankle", 4.33, 4.81, 43.95, 43.52),
    ("foot", "ankle", "toe_tip", 1.37, 1.29, 44.15, 40.14),
)

#: ``side_and_base(name)`` is :func:`usdmotion.skeleton_names.parse_side`:
#: ``("left"|"right"|None, base)``, ``LeftForeArm`` → ``("left", "forearm")``.
side_and_base = parse_side


#: ``PRESET_NAMES``: the landmark presets in the order they are tried (read from the rig profiles on first use).
__getattr__ = preset_names_attribute("landmarks", __name__)


@dataclass(frozen=True)
class BodyModel:
    """Segments as linear combinations of joint positions.

    Attributes:
        segment_names: ``S`` names (``left_thigh`` ...).
        mass_fractions: ``(S,)`` fraction of body mass, summing to 1.
        weights: ``(S, J)``: segment COM = ``weights @ joint_positions``.
        source: what the numbers come from (table, sex, how landmarks were found).
        landmarks: landmark → joint name (or ``mid(a, b)``) as used.
        notes: approximations made (missing landmarks...).
    """

    segment_names: tuple[str, ...]
    mass_fractions: np.ndarray
    weights: np.ndarray
    source: str
    landmarks: dict[str, str]
    notes: tuple[str, ...] = ()

    @property
    def com_weights(self) -> np.ndarray:
        """``(J,)`` whole-body COM = ``com_weights @ joint_positions``."""
        return self.mass_fractions @ self.weights

    def segment_coms(self, positions: np.ndarray) -> np.ndarray:
        """Segment COMs ``(..., S, 3)`` from joint positions ``(..., J, 3)``."""
        return np.einsum("sj,...jd->...sd", self.weights, positions)

    def com(self, positions: np.ndarray) -> np.ndarray:
        """Whole-body COM ``(..., 3)`` from joint positions ``(..., J, 3)``."""
        return np.einsum("j,...jd->...d", self.com_weights, positions)


# ------------------------------------------------------------------ landmark finding


def _guess(motion: Motion) -> dict[str, int | None]:
    """Landmark → joint index by name and hierarchy (``None`` where not found)."""
    parents = motion.parents
    rest = rest_positions(motion)
    eps = rest_tolerance(rest)
    kids = children_map(parents)
    parsed = [parse_side(n) for n in motion.joint_names]
    found: dict[str, int | None] = {name: None for name in LANDMARKS}
    for side, (middle, upper, lower, tip), candidates in middle_joint_candidates(motion.joint_names,
                                                                                 motion.end_sites, parsed):
        if not candidates:
            continue
        mid = min(candidates, key=lambda j: depth(parents, j))
        found[f"{side}_{middle}"] = mid
        found[f"{side}_{upper}"] = proximal_joint(parents, rest, mid, eps)
        down = distal_joint(kids, rest, mid, eps)
        found[f"{side}_{lower}"] = down
        if down is not None:
            found[f"{side}_{tip}"] = farthest_leaf(parents, kids, rest, down)
    necks = [j for j, (_, b) in enumerate(parsed) if "neck" in b and not motion.end_sites[j]]
    heads = [j for j, (_, b) in enumerate(parsed) if b.startswith("head") and not motion.end_sites[j]]
    if necks:
        found["neck"] = min(necks, key=lambda j: depth(parents, j))
    if heads:
        head = min(heads, key=lambda j: depth(parents, j))
        found["head_top"] = farthest_leaf(parents, kids, rest, head)
        if found["head_top"] is None:
            found["head_top"] = head
        if found["neck"] is None:
            found["neck"] = proximal_joint(parents, rest, head, eps)
    return found


def _preset(motion: Motion) -> tuple[str, dict[str, int]] | None:
    """``(preset name, landmark → joint index)`` of the first landmark preset that fits, else ``None``."""
    hit = fitting_preset("landmarks", motion.joint_names, LANDMARKS, LANDMARK_POINTS)
    if hit is None:
        return None
    index = {n: j for j, n in enumerate(motion.joint_names)}
    return hit[0].name, {k: index[v] for k, v in hit[1].items()}


def find_landmarks(motion: Motion, overrides: Mapping[str, str] | None = None,
                   source: str | None = None) -> tuple[dict[str, int | None], str]:
    """Landmark → joint index (``None`` where not found), and how they were found.

    ``overrides`` maps landmark names to joint names and wins over presets and guesses.

    Raises:
        InputError: an override names an unknown landmark or joint (``source`` names the file).
    """
    preset = _preset(motion)
    if preset is not None:
        found: dict[str, int | None] = dict(preset[1])
        how = f"preset {preset[0]}"
    else:
        found, how = _guess(motion), "guessed from joint names"
    for landmark, joint in (overrides or {}).items():
        if landmark not in LANDMARKS:
            raise InputError(source, f"/landmarks/{landmark}: unknown landmark (use {', '.join(LANDMARKS)})")
        try:
            found[landmark] = motion.joint_index(joint)
        except KeyError as exc:
            raise InputError(source, f"/landmarks/{landmark}: {exc.args[0]}") from None
        how += f", {landmark} overridden"
    return found, how


# ------------------------------------------------------------------ body models


def _one_hot(n: int, j: int) -> np.ndarray:
    w = np.zeros(n)
    w[j] = 1.0
    return w


def de_leva_model(motion: Motion, sex: str = "male", overrides: Mapping[str, str] | None = None,
                  source: str | None = None) -> BodyModel:
    """de Leva (1996) 14-segment model of ``motion``'s skeleton.

    Raises:
        InputError: a required landmark (neck, shoulders, elbows, wrists, hips, knees,
            ankles) cannot be found; the message lists them and how to name them.
    """
    if sex not in SEXES:
        raise ValueError(f"sex must be one of {', '.join(SEXES)}, got {sex!r}")
    found, how = find_landmarks(motion, overrides, source)
    missing = [k for k in LANDMARKS if found[k] is None and k not in _OPTIONAL]
    if missing:
        raise InputError(source, f"cannot find {', '.join(missing)} for the body-segment model ({how}); "
                                 "name them with --segments map.json ({\"landmarks\": {\"left_knee\": \"...\"}})")
    n = motion.n_joints
    notes = []
    points = {k: _one_hot(n, j) for k, j in found.items() if j is not None}
    used = {k: motion.joint_names[j] for k, j in found.items() if j is not None}
    points["mid_hip"] = 0.5 * (points["left_hip"] + points["right_hip"])
    used["mid_hip"] = f"mid({used['left_hip']}, {used['right_hip']})"
    fallback = {"head_top": "neck", "left_hand_tip": "left_wrist", "right_hand_tip": "right_wrist",
                "left_toe_tip": "left_ankle", "right_toe_tip": "right_ankle"}
    for landmark, instead in fallback.items():
        if landmark not in points:
            points[landmark] = points[instead]
            notes.append(f"no {landmark} joint: that segment's COM is placed at {used[instead]}")
    female = sex == "female"
    names, masses, rows = [], [], []
    for segment, origin, other, m_male, m_female, c_male, c_female in _DE_LEVA:
        mass, com = (m_female, c_female) if female else (m_male, c_male)
        sides = ("",) if segment in ("head", "trunk") else ("left_", "right_")
        for side in sides:
            o, e = points[side + origin if side else origin], points[side + other if side else other]
            names.append(side + segment)
            masses.append(mass / 100.0)
            rows.append((1.0 - com / 100.0) * o + (com / 100.0) * e)
    masses_arr = np.asarray(masses)
    return BodyModel(tuple(names), masses_arr / masses_arr.sum(), np.stack(rows),
                     f"de Leva 1996 ({sex}); landmarks: {how}", used, tuple(notes))


def custom_model(motion: Motion, segments: Sequence[Mapping], source: str | None = None) -> BodyModel:
    """A model from ``[{"name", "from", "to", "mass_fraction", "com_fraction"}, ...]``.

    Mass fractions are normalised to sum to 1; ``com_fraction`` is measured from ``from``.

    Raises:
        InputError: unknown joint, or mass fractions that do not sum to a positive number.
    """
    n = motion.n_joints
    names, masses, rows = [], [], []
    for k, seg in enumerate(segments):
        ends = []
        for key in ("from", "to"):
            try:
                ends.append(_one_hot(n, motion.joint_index(str(seg[key]))))
            except KeyError as exc:
                raise InputError(source, f"/segments/{k}/{key}: {exc.args[0]}") from None
        c = float(seg["com_fraction"])
        names.append(str(seg["name"]))
        masses.append(float(seg["mass_fraction"]))
        rows.append((1.0 - c) * ends[0] + c * ends[1])
    total = float(np.sum(masses)) if masses else 0.0
    if not total > 0:
        raise InputError(source, "/segments: mass fractions must sum to a positive number")
    notes = () if abs(total - 1.0) < 1e-6 else (f"mass fractions summed to {total:g}; normalised to 1",)
    used = {nm: f"{seg['from']} → {seg['to']}" for nm, seg in zip(names, segments)}
    return BodyModel(tuple(names), np.asarray(masses) / total, np.stack(rows), "custom segment table", used, notes)


def body_model(motion: Motion, sex: str = "male", segment_map: Mapping | None = None,
               source: str | None = None) -> BodyModel:
    """The body model for ``motion``: a custom table if ``segment_map`` has ``segments``,
    else de Leva (1996) with ``segment_map["landmarks"]`` as overrides."""
    segment_map = segment_map or {}
    sex = segment_map.get("sex", sex)
    if segment_map.get("segments"):
        return custom_model(motion, segment_map["segments"], source)
    return de_leva_model(motion, sex, segment_map.get("landmarks"), source)


def load_segment_map(path) -> dict:
    """Read and validate a segment map (JSON or YAML, ``schemas/body-segments.schema.json``)."""
    return load_document(path, "body-segments")
