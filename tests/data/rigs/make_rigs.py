"""Write the small test skeletons of tests/data/rigs/ (run: python tests/data/rigs/make_rigs.py).

One BVH per rig family of issue 17 with the family's real joint names (Character Creator /
iClone, Unreal mannequin, Blender Rigify deform bones, 3ds Max Biped, MotionBuilder HumanIK
with a ``Character1:`` namespace, SMPL), twist/roll bones, root and IK/helper bones, and
plausible adult offsets in cm (Y up, facing +Z, the character's left at +X). Two frames: the
rest pose and a small knee and elbow bend. Written by hand, no data from the internet.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

#: Body points, world cm; ``l_*`` mirrored to ``r_*``.
POINTS = {
    "floor": (0, 0, 0), "hips": (0, 95, 0), "spine": (0, 105, 0), "spine2": (0, 117, 0), "chest": (0, 130, 0),
    "neck": (0, 148, 0), "neck2": (0, 154, 0), "head": (0, 160, 0), "head_top": (0, 178, 0),
    "l_clav": (3, 143, 2), "l_upper": (17, 145, 0), "l_fore": (45, 145, 0), "l_hand": (70, 145, 0),
    "l_mid1": (79, 145, 0), "l_mid2": (83, 145, 0), "l_mid3": (86, 145, 0), "l_tip": (88, 145, 0),
    "l_thigh": (9, 92, 0), "l_shin": (9, 50, 1), "l_foot": (9, 9, -2), "l_toe": (9, 2, 12), "l_toe_tip": (9, 2, 19),
}
POINTS.update({"r" + k[1:]: (-x, y, z) for k, (x, y, z) in list(POINTS.items()) if k.startswith("l_")})


def at(key: str, side: str = "l") -> np.ndarray:
    return np.array(POINTS[key.replace("X_", f"{side}_")], float)


def lerp(a: str, b: str, t: float, side: str = "l") -> np.ndarray:
    return at(a, side) + t * (at(b, side) - at(a, side))


def mirrored(rows, sides=(("l", "L"), ("r", "R"))):
    """Rows ``(name, parent, position)`` with ``{S}`` / ``{s}`` / ``{Side}`` / ``X_`` per side."""
    out = []
    for s, S in sides:
        side_word = "Left" if s == "l" else "Right"
        for name, parent, pos in rows:
            fill = (lambda t: t.replace("{S}", S).replace("{s}", s).replace("{Side}", side_word)) if True else None
            p = pos(s) if callable(pos) else at(pos, s)
            out.append((fill(name), fill(parent) if parent else parent, p))
    return out


def bvh_text(rows) -> str:
    """BVH of rows ``(name, parent, world position)``; name ``"End"`` makes an End Site."""
    world = {}
    children: dict[str | None, list] = {}
    for name, parent, pos in rows:
        children.setdefault(parent, []).append((name, np.asarray(pos, float)))
    lines, channels = ["HIERARCHY"], []

    def emit(name, pos, parent_pos, depth, root=False):
        pad = "  " * depth
        off = pos - parent_pos
        if name == "End":
            lines.extend([f"{pad}End Site", f"{pad}{{", f"{pad}  OFFSET {off[0]:.4f} {off[1]:.4f} {off[2]:.4f}",
                          f"{pad}}}"])
            return
        lines.append(f"{pad}{'ROOT' if root else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {off[0]:.4f} {off[1]:.4f} {off[2]:.4f}")
        chans = ["Xposition", "Yposition", "Zposition"] if root else []
        chans += ["Zrotation", "Xrotation", "Yrotation"]
        lines.append(f"{pad}  CHANNELS {len(chans)} {' '.join(chans)}")
        channels.append((name, len(chans)))
        world[name] = pos
        for child, child_pos in children.get(name, []):
            emit(child, child_pos, pos, depth + 1)
        lines.append(f"{pad}}}")

    (root_name, root_pos), = children[None]
    emit(root_name, root_pos, np.zeros(3), 0, root=True)
    n = sum(c for _, c in channels)
    rest = np.zeros(n)
    bent = np.zeros(n)
    col = 0
    for name, count in channels:
        lower = name.lower()
        if any(w in lower for w in ("calf", "shin", "knee", "leftleg", "rightleg")) and "twist" not in lower \
                and "roll" not in lower and "share" not in lower and not lower.endswith(".001"):
            bent[col + count - 2] = 20.0  # X rotation: the knee bends
        if any(w in lower for w in ("forearm", "lowerarm", "elbow")) and "twist" not in lower and "roll" not in lower \
                and "share" not in lower and not lower.endswith(".001"):
            bent[col + count - 1] = 15.0  # Y rotation: the elbow bends
        col += count
    lines += ["MOTION", "Frames: 2", "Frame Time: 0.0333333"]
    lines += [" ".join(f"{v:.4f}" for v in row) for row in (rest, bent)]
    return "\n".join(lines) + "\n"


def character_creator():
    rows = [("RL_BoneRoot", None, "floor"), ("CC_Base_Hip", "RL_BoneRoot", "hips"),
            ("CC_Base_Pelvis", "CC_Base_Hip", at("hips") + (0, -2, 0)),
            ("CC_Base_Waist", "CC_Base_Hip", "spine"), ("CC_Base_Spine01", "CC_Base_Waist", "spine2"),
            ("CC_Base_Spine02", "CC_Base_Spine01", "chest"), ("CC_Base_NeckTwist01", "CC_Base_Spine02", "neck"),
            ("CC_Base_NeckTwist02", "CC_Base_NeckTwist01", "neck2"), ("CC_Base_Head", "CC_Base_NeckTwist02", "head"),
            ("End", "CC_Base_Head", "head_top")]
    rows += mirrored([
        ("CC_Base_{S}_Thigh", "CC_Base_Pelvis", "X_thigh"), ("CC_Base_{S}_Calf", "CC_Base_{S}_Thigh", "X_shin"),
        ("CC_Base_{S}_Foot", "CC_Base_{S}_Calf", "X_foot"), ("CC_Base_{S}_ToeBase", "CC_Base_{S}_Foot", "X_toe"),
        ("End", "CC_Base_{S}_ToeBase", "X_toe_tip"),
        ("CC_Base_{S}_CalfTwist01", "CC_Base_{S}_Calf", lambda s: lerp("X_shin", "X_foot", 1 / 3, s)),
        ("CC_Base_{S}_CalfTwist02", "CC_Base_{S}_Calf", lambda s: lerp("X_shin", "X_foot", 2 / 3, s)),
        ("CC_Base_{S}_KneeShareBone", "CC_Base_{S}_Calf", lambda s: at("X_shin", s) + (0, 0, 4)),
        ("CC_Base_{S}_ThighTwist01", "CC_Base_{S}_Thigh", lambda s: lerp("X_thigh", "X_shin", 1 / 3, s)),
        ("CC_Base_{S}_ThighTwist02", "CC_Base_{S}_Thigh", lambda s: lerp("X_thigh", "X_shin", 2 / 3, s)),
        ("CC_Base_{S}_Clavicle", "CC_Base_Spine02", "X_clav"), ("CC_Base_{S}_Upperarm", "CC_Base_{S}_Clavicle", "X_upper"),
        ("CC_Base_{S}_UpperarmTwist01", "CC_Base_{S}_Upperarm", lambda s: lerp("X_upper", "X_fore", 1 / 3, s)),
        ("CC_Base_{S}_UpperarmTwist02", "CC_Base_{S}_Upperarm", lambda s: lerp("X_upper", "X_fore", 2 / 3, s)),
        ("CC_Base_{S}_Forearm", "CC_Base_{S}_Upperarm", "X_fore"),
        ("CC_Base_{S}_ForearmTwist01", "CC_Base_{S}_Forearm", lambda s: lerp("X_fore", "X_hand", 1 / 3, s)),
        ("CC_Base_{S}_ForearmTwist02", "CC_Base_{S}_Forearm", lambda s: lerp("X_fore", "X_hand", 2 / 3, s)),
        ("CC_Base_{S}_ElbowShareBone", "CC_Base_{S}_Forearm", lambda s: at("X_fore", s) + (0, 0, -3)),
        ("CC_Base_{S}_Hand", "CC_Base_{S}_Forearm", "X_hand"), ("CC_Base_{S}_Mid1", "CC_Base_{S}_Hand", "X_mid1"),
        ("CC_Base_{S}_Mid2", "CC_Base_{S}_Mid1", "X_mid2"), ("CC_Base_{S}_Mid3", "CC_Base_{S}_Mid2", "X_mid3"),
        ("End", "CC_Base_{S}_Mid3", "X_tip"),
        ("CC_Base_{S}_RibsTwist", "CC_Base_Spine02", lambda s: lerp("chest", "X_clav", 0.5, s) + (0, -12, 6)),
    ])
    return rows


def unreal():
    rows = [("root", None, "floor"), ("pelvis", "root", "hips"), ("spine_01", "pelvis", "spine"),
            ("spine_02", "spine_01", "spine2"), ("spine_03", "spine_02", "chest"), ("neck_01", "spine_03", "neck"),
            ("head", "neck_01", "head"), ("End", "head", "head_top"),
            ("ik_foot_root", "root", "floor"), ("ik_hand_root", "root", "floor"),
            ("ik_hand_gun", "ik_hand_root", "r_hand")]
    rows += mirrored([
        ("thigh_{s}", "pelvis", "X_thigh"), ("calf_{s}", "thigh_{s}", "X_shin"), ("foot_{s}", "calf_{s}", "X_foot"),
        ("ball_{s}", "foot_{s}", "X_toe"), ("End", "ball_{s}", "X_toe_tip"),
        ("thigh_twist_01_{s}", "thigh_{s}", lambda s: lerp("X_thigh", "X_shin", 0.3, s)),
        ("calf_twist_01_{s}", "calf_{s}", lambda s: lerp("X_shin", "X_foot", 0.5, s)),
        ("clavicle_{s}", "spine_03", "X_clav"), ("upperarm_{s}", "clavicle_{s}", "X_upper"),
        ("upperarm_twist_01_{s}", "upperarm_{s}", lambda s: lerp("X_upper", "X_fore", 0.3, s)),
        ("lowerarm_{s}", "upperarm_{s}", "X_fore"),
        ("lowerarm_twist_01_{s}", "lowerarm_{s}", lambda s: lerp("X_fore", "X_hand", 0.6, s)),
        ("hand_{s}", "lowerarm_{s}", "X_hand"), ("middle_01_{s}", "hand_{s}", "X_mid1"),
        ("middle_02_{s}", "middle_01_{s}", "X_mid2"), ("middle_03_{s}", "middle_02_{s}", "X_mid3"),
        ("End", "middle_03_{s}", "X_tip"),
        ("ik_foot_{s}", "ik_foot_root", "X_foot"), ("ik_hand_{s}", "ik_hand_gun", "X_hand"),
    ])
    return rows


def rigify():
    rows = [("DEF-spine", None, "hips"), ("DEF-spine.001", "DEF-spine", "spine"),
            ("DEF-spine.002", "DEF-spine.001", "spine2"), ("DEF-spine.003", "DEF-spine.002", "chest"),
            ("DEF-spine.004", "DEF-spine.003", "neck"), ("DEF-spine.005", "DEF-spine.004", "neck2"),
            ("DEF-spine.006", "DEF-spine.005", "head"), ("End", "DEF-spine.006", "head_top")]
    rows += mirrored([
        ("DEF-pelvis.{S}", "DEF-spine", lambda s: lerp("hips", "X_thigh", 0.5, s) + (0, 3, 6)),
        ("DEF-thigh.{S}", "DEF-spine", "X_thigh"),
        ("DEF-thigh.{S}.001", "DEF-thigh.{S}", lambda s: lerp("X_thigh", "X_shin", 0.5, s)),
        ("DEF-shin.{S}", "DEF-thigh.{S}.001", "X_shin"),
        ("DEF-shin.{S}.001", "DEF-shin.{S}", lambda s: lerp("X_shin", "X_foot", 0.5, s)),
        ("DEF-foot.{S}", "DEF-shin.{S}.001", "X_foot"), ("DEF-toe.{S}", "DEF-foot.{S}", "X_toe"),
        ("End", "DEF-toe.{S}", "X_toe_tip"),
        ("DEF-shoulder.{S}", "DEF-spine.003", "X_clav"), ("DEF-upper_arm.{S}", "DEF-shoulder.{S}", "X_upper"),
        ("DEF-upper_arm.{S}.001", "DEF-upper_arm.{S}", lambda s: lerp("X_upper", "X_fore", 0.5, s)),
        ("DEF-forearm.{S}", "DEF-upper_arm.{S}.001", "X_fore"),
        ("DEF-forearm.{S}.001", "DEF-forearm.{S}", lambda s: lerp("X_fore", "X_hand", 0.5, s)),
        ("DEF-hand.{S}", "DEF-forearm.{S}.001", "X_hand"), ("DEF-f_middle.01.{S}", "DEF-hand.{S}", "X_mid1"),
        ("DEF-f_middle.02.{S}", "DEF-f_middle.01.{S}", "X_mid2"),
        ("DEF-f_middle.03.{S}", "DEF-f_middle.02.{S}", "X_mid3"), ("End", "DEF-f_middle.03.{S}", "X_tip"),
        ("DEF-breast.{S}", "DEF-spine.003", lambda s: at("chest") + (0, -6, 10) + (0.5 * at("X_clav", s)[0], 0, 0)),
    ])
    return rows


def biped():
    rows = [("Bip01", None, "hips"), ("Bip01 Footsteps", "Bip01", "floor"), ("Bip01 Pelvis", "Bip01", "hips"),
            ("Bip01 Spine", "Bip01 Pelvis", "spine"), ("Bip01 Spine1", "Bip01 Spine", "spine2"),
            ("Bip01 Spine2", "Bip01 Spine1", "chest"), ("Bip01 Neck", "Bip01 Spine2", "neck"),
            ("Bip01 Head", "Bip01 Neck", "head"), ("Bip01 HeadNub", "Bip01 Head", "head_top"),
            ("End", "Bip01 HeadNub", at("head_top") + (0, 1, 0))]
    rows += mirrored([
        ("Bip01 {S} Thigh", "Bip01 Spine", "X_thigh"),
        ("Bip01 {S} ThighTwist", "Bip01 {S} Thigh", lambda s: lerp("X_thigh", "X_shin", 0.4, s)),
        ("Bip01 {S} Calf", "Bip01 {S} Thigh", "X_shin"),
        ("Bip01 {S} CalfTwist", "Bip01 {S} Calf", lambda s: lerp("X_shin", "X_foot", 0.5, s)),
        ("Bip01 {S} Foot", "Bip01 {S} Calf", "X_foot"), ("Bip01 {S} Toe0", "Bip01 {S} Foot", "X_toe"),
        ("Bip01 {S} Toe0Nub", "Bip01 {S} Toe0", "X_toe_tip"),
        ("End", "Bip01 {S} Toe0Nub", lambda s: at("X_toe_tip", s) + (0, 0, 1)),
        ("Bip01 {S} Clavicle", "Bip01 Neck", "X_clav"), ("Bip01 {S} UpperArm", "Bip01 {S} Clavicle", "X_upper"),
        ("Bip01 {S} UpArmTwist", "Bip01 {S} UpperArm", lambda s: lerp("X_upper", "X_fore", 0.4, s)),
        ("Bip01 {S} Forearm", "Bip01 {S} UpperArm", "X_fore"),
        ("Bip01 {S} ForeTwist", "Bip01 {S} Forearm", lambda s: lerp("X_fore", "X_hand", 0.5, s)),
        ("Bip01 {S} Hand", "Bip01 {S} Forearm", "X_hand"), ("Bip01 {S} Finger2", "Bip01 {S} Hand", "X_mid1"),
        ("Bip01 {S} Finger21", "Bip01 {S} Finger2", "X_mid2"), ("Bip01 {S} Finger2Nub", "Bip01 {S} Finger21", "X_tip"),
        ("End", "Bip01 {S} Finger2Nub", lambda s: at("X_tip", s) + (0.5 if s == "l" else -0.5, 0, 0)),
    ])
    return rows


def humanik():
    ns = "Character1:"
    rows = [(ns + "Reference", None, "floor"), (ns + "Hips", ns + "Reference", "hips"), (ns + "Spine", ns + "Hips", "spine"),
            (ns + "Spine1", ns + "Spine", "spine2"), (ns + "Spine2", ns + "Spine1", "chest"),
            (ns + "Neck", ns + "Spine2", "neck"), (ns + "Head", ns + "Neck", "head"), ("End", ns + "Head", "head_top")]
    rows += mirrored([
        (ns + "{Side}UpLeg", ns + "Hips", "X_thigh"),
        (ns + "{Side}UpLegRoll", ns + "{Side}UpLeg", lambda s: lerp("X_thigh", "X_shin", 0.5, s)),
        (ns + "{Side}Leg", ns + "{Side}UpLeg", "X_shin"),
        (ns + "{Side}LegRoll", ns + "{Side}Leg", lambda s: lerp("X_shin", "X_foot", 0.5, s)),
        (ns + "{Side}Foot", ns + "{Side}Leg", "X_foot"), (ns + "{Side}ToeBase", ns + "{Side}Foot", "X_toe"),
        ("End", ns + "{Side}ToeBase", "X_toe_tip"),
        (ns + "{Side}Shoulder", ns + "Spine2", "X_clav"), (ns + "{Side}Arm", ns + "{Side}Shoulder", "X_upper"),
        (ns + "{Side}ArmRoll", ns + "{Side}Arm", lambda s: lerp("X_upper", "X_fore", 0.5, s)),
        (ns + "{Side}ForeArm", ns + "{Side}Arm", "X_fore"),
        (ns + "{Side}ForeArmRoll", ns + "{Side}ForeArm", lambda s: lerp("X_fore", "X_hand", 0.5, s)),
        (ns + "{Side}Hand", ns + "{Side}ForeArm", "X_hand"), (ns + "{Side}HandMiddle1", ns + "{Side}Hand", "X_mid1"),
        (ns + "{Side}HandMiddle2", ns + "{Side}HandMiddle1", "X_mid2"),
        (ns + "{Side}HandMiddle3", ns + "{Side}HandMiddle2", "X_mid3"), ("End", ns + "{Side}HandMiddle3", "X_tip"),
    ])
    return rows


def smpl():
    rows = [("Pelvis", None, "hips"), ("Spine1", "Pelvis", "spine"), ("Spine2", "Spine1", "spine2"),
            ("Spine3", "Spine2", "chest"), ("Neck", "Spine3", "neck"), ("Head", "Neck", "head"),
            ("End", "Head", "head_top")]
    rows += mirrored([
        ("{S}_Hip", "Pelvis", "X_thigh"), ("{S}_Knee", "{S}_Hip", "X_shin"), ("{S}_Ankle", "{S}_Knee", "X_foot"),
        ("{S}_Foot", "{S}_Ankle", "X_toe"), ("End", "{S}_Foot", "X_toe_tip"),
        ("{S}_Collar", "Spine3", "X_clav"), ("{S}_Shoulder", "{S}_Collar", "X_upper"),
        ("{S}_Elbow", "{S}_Shoulder", "X_fore"), ("{S}_Wrist", "{S}_Elbow", "X_hand"),
        ("{S}_Hand", "{S}_Wrist", "X_mid1"), ("End", "{S}_Hand", "X_tip"),
    ])
    return rows


RIGS = {"character_creator": character_creator, "unreal": unreal, "rigify": rigify, "biped": biped,
        "humanik": humanik, "smpl": smpl}


def main() -> None:
    for name, build in RIGS.items():
        rows = [(n, p, at(pos) if isinstance(pos, str) else np.asarray(pos, float)) for n, p, pos in build()]
        (HERE / f"{name}.bvh").write_text(bvh_text(rows), encoding="utf-8")


if __name__ == "__main__":
    main()
