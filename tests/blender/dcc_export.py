"""Run by Blender's Python (bpy 4.5): author an animated armature the way an artist does
and export it with Blender's own USD exporter; print one JSON document.

    python dcc_export.py OUT_DIR CASES_JSON

Each case: ``{"name", "units" (convert_scene_units), "scale", "rotation_deg" (XYZ Euler of
the armature object), "location", "mesh" (optional: a skinned body with an animated shape key)}``. Writes ``OUT_DIR/<name>.usda`` and reports, per
case, Blender's evaluated bone head positions in world space (metres, Blender Z-up)
for every frame: ``{"<name>": {"file", "fps", "frames", "heads": {bone: [[x, y, z], ...]}}}``.
"""

import json
import math
import sys
from pathlib import Path

import bpy
from mathutils import Euler

BONES = [  # name, parent, head, tail (armature space, metres, Z-up)
    ("Hips", None, (0, 0, 0.95), (0, 0, 1.05)),
    ("Spine", "Hips", (0, 0, 1.05), (0, 0, 1.35)),
    ("Head", "Spine", (0, 0, 1.35), (0, 0, 1.7)),
    ("LThigh", "Hips", (0.1, 0, 0.95), (0.1, 0, 0.5)),
    ("LShin", "LThigh", (0.1, 0, 0.5), (0.1, 0.02, 0.08)),
    ("RThigh", "Hips", (-0.1, 0, 0.95), (-0.1, 0, 0.5)),
    ("RShin", "RThigh", (-0.1, 0, 0.5), (-0.1, 0.02, 0.08)),
]
FRAMES = range(1, 13)


def build(case):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = 30
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    data = bpy.data.armatures.new("Armature")
    arm = bpy.data.objects.new("Armature", data)
    scene.collection.objects.link(arm)
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode="EDIT")
    for name, parent, head, tail in BONES:
        bone = data.edit_bones.new(name)
        bone.head, bone.tail = head, tail
        if parent:
            bone.parent = data.edit_bones[parent]
            bone.use_connect = False
    bpy.ops.object.mode_set(mode="OBJECT")
    arm.location = case["location"]
    arm.rotation_euler = Euler([math.radians(a) for a in case["rotation_deg"]], "XYZ")
    arm.scale = (case["scale"],) * 3
    for k, frame in enumerate(FRAMES):
        for b, pose in enumerate(arm.pose.bones):
            pose.rotation_mode = "XYZ"
            pose.rotation_euler = (0.5 * math.sin(0.4 * k + b), 0.3 * math.cos(0.3 * k + 2 * b), 0.2 * math.sin(k + b))
            pose.keyframe_insert("rotation_euler", frame=frame)
        root = arm.pose.bones["Hips"]
        root.location = (0.05 * k, 0.02 * math.sin(k), 0.1 * k)
        root.keyframe_insert("location", frame=frame)
    return arm


def add_skinned_body(arm):
    """A mesh of boxes along the bones, parented to ``arm`` with an Armature modifier, one
    vertex group per bone (blended near joints), and a 'Smile' shape key animated 0 → 1."""
    verts, faces, groups = [], [], []
    ring = [(-0.04, -0.04), (0.04, -0.04), (0.04, 0.04), (-0.04, 0.04)]  # counter-clockwise seen from +Z
    for b, (name, parent, head, tail) in enumerate(BONES):
        up = tail[2] >= head[2]
        for t in (0.0, 0.5, 1.0):
            c = [h + t * (e - h) for h, e in zip(head, tail)]
            base = len(verts)
            verts += [(c[0] + dx, c[1] + dy, c[2]) for dx, dy in ring]
            groups += [(name, parent, t)] * 4
            if t > 0:  # closed tube, faces wound outwards whichever way the bone points
                for i in range(4):
                    quad = (base - 4 + i, base - 4 + (i + 1) % 4, base + (i + 1) % 4, base + i)
                    faces.append(quad if up else quad[::-1])
    data = bpy.data.meshes.new("Body")
    data.from_pydata(verts, [], faces)
    body = bpy.data.objects.new("Body", data)
    bpy.context.scene.collection.objects.link(body)
    body.parent = arm
    body.modifiers.new("Armature", "ARMATURE").object = arm
    for name, *_ in BONES:
        body.vertex_groups.new(name=name)
    for v, (name, parent, t) in enumerate(groups):
        if parent and t == 0.0:
            body.vertex_groups[name].add([v], 0.6, "REPLACE")
            body.vertex_groups[parent].add([v], 0.4, "REPLACE")
        else:
            body.vertex_groups[name].add([v], 1.0, "REPLACE")
    body.shape_key_add(name="Basis")
    smile = body.shape_key_add(name="Smile")
    for point in smile.data[:8]:  # the first two rings
        point.co.z += 0.05
    for k, frame in enumerate(FRAMES):
        smile.value = k / (len(FRAMES) - 1)
        smile.keyframe_insert("value", frame=frame)
    return body


def heads(arm):
    out = {b.name: [] for b in arm.pose.bones}
    for frame in FRAMES:
        bpy.context.scene.frame_set(frame)
        world = arm.matrix_world
        for b in arm.pose.bones:
            out[b.name].append(list(world @ b.head))
    return out


def main():
    out_dir, cases = Path(sys.argv[-2]), json.loads(Path(sys.argv[-1]).read_text())
    report = {}
    for case in cases:
        arm = build(case)
        if case.get("mesh"):
            add_skinned_body(arm)
        path = out_dir / f"{case['name']}.usda"
        bpy.ops.wm.usd_export(filepath=str(path), export_animation=True, export_armatures=True,
                              convert_scene_units=case["units"], selected_objects_only=False)
        report[case["name"]] = {"file": str(path), "fps": 30, "frames": len(FRAMES), "heads": heads(arm)}
    print("JSON:" + json.dumps(report))


main()
