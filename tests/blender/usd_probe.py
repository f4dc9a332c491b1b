"""Import USD files into Blender (the ``bpy`` module) and report what Blender made of them.

Runs under Blender's Python, not under usdmotion's (bpy 4.5 needs numpy<2, usdmotion
numpy 2), so it imports nothing from usdmotion. One process handles many files, because
starting Blender is the slow part::

    .venv-blender/bin/python tests/blender/usd_probe.py a.usda b.usdz          # JSON on stdout
    .venv-blender/bin/python tests/blender/usd_probe.py --manifest m.json --out r.json

``m.json`` is ``[{"path": "a.usda", "frames": [0, 10, 20]}, ...]``; without frames (and
for positional paths) the scene's first, middle and last frames are sampled.

For each file: reset to an empty scene, ``bpy.ops.wm.usd_import`` with Blender's default
options (what a user gets from File › Import), then report

* ``log`` / ``warnings``: what Blender and its USD library printed during the import
  (file descriptors 1 and 2 are captured, so C-level warnings are included);
* ``scene``: frame_start / frame_end / fps as the import left them;
* ``armatures``: bone names, parents and rest heads (armature space), the action's frame
  range and F-curve count, and at every sampled frame the object's ``matrix_world`` (and
  its scale) and the evaluated head of every pose bone, in armature space *and* in world space;
* ``meshes``: vertex count, vertex groups, per-vertex weights, modifiers (type, target),
  parent, and the evaluated (deformed) world-space vertices at every sampled frame.

A file that fails never stops the run: its entry gets ``"ok": false`` and ``"error"``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import tempfile
import traceback

MAX_MESH_VERTICES = 20000  # vertices reported per mesh (a deterministic stride beyond that)


@contextlib.contextmanager
def captured_output(sink: list[str]):
    """Capture everything written to fd 1 and fd 2 (Python and C code alike) into ``sink``."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            tmp.seek(0)
            sink.append(tmp.read().decode("utf-8", "replace"))


def matrix_list(m) -> list[list[float]]:
    return [[float(x) for x in row] for row in m]


def vec(v) -> list[float]:
    return [float(v[0]), float(v[1]), float(v[2])]


def action_info(ob) -> dict | None:
    ad = ob.animation_data
    if ad is None or ad.action is None:
        return None
    action = ad.action
    n_fcurves = None
    with contextlib.suppress(Exception):  # legacy API; layered actions keep it in 4.x
        n_fcurves = len(action.fcurves)
    return {"name": action.name, "frame_range": [float(action.frame_range[0]), float(action.frame_range[1])],
            "n_fcurves": n_fcurves}


def armature_info(ob) -> dict:
    bones = ob.data.bones
    return {
        "name": ob.name,
        "parent": ob.parent.name if ob.parent else None,
        "n_bones": len(bones),
        "bone_names": [b.name for b in bones],
        "bone_parents": [b.parent.name if b.parent else None for b in bones],
        "rest_heads": [vec(b.head_local) for b in bones],
        "action": action_info(ob),
        "poses": {},
    }


def mesh_info(ob) -> dict:
    me = ob.data
    n = len(me.vertices)
    stride = max(1, -(-n // MAX_MESH_VERTICES))
    indices = list(range(0, n, stride))
    group_names = [g.name for g in ob.vertex_groups]
    weights = [{group_names[g.group]: float(g.weight) for g in me.vertices[i].groups if g.group < len(group_names)}
               for i in indices]
    return {
        "name": ob.name,
        "parent": ob.parent.name if ob.parent else None,
        "parent_type": ob.parent_type,
        "n_vertices": n,
        "n_faces": len(me.polygons),
        "vertex_groups": group_names,
        "modifiers": [{"type": m.type, "name": m.name,
                       "object": getattr(getattr(m, "object", None), "name", None)} for m in ob.modifiers],
        "vertex_indices": indices,
        "weights": weights,
        "rest_vertices": [vec(me.vertices[i].co) for i in indices],
        "poses": {},
    }


def sample_frames(scene, requested) -> list[int]:
    if requested:
        return sorted({int(f) for f in requested})
    start, end = int(scene.frame_start), int(scene.frame_end)
    return sorted({start, (start + end) // 2, end})


def record_frame(bpy, scene, frame: int, armatures: list, meshes: list) -> None:
    scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    for ob, info in armatures:
        ev = ob.evaluated_get(depsgraph)
        mw = ev.matrix_world
        heads = [pb.head.copy() for pb in ev.pose.bones]
        info["poses"][str(frame)] = {
            "matrix_world": matrix_list(mw),
            "scale": vec(mw.to_scale()),
            "heads": [vec(h) for h in heads],
            "world_heads": [vec(mw @ h) for h in heads],
        }
    for ob, info in meshes:
        ev = ob.evaluated_get(depsgraph)
        mw = ev.matrix_world
        me = ev.to_mesh()
        try:
            verts = [vec(mw @ me.vertices[i].co) for i in info["vertex_indices"] if i < len(me.vertices)]
        finally:
            ev.to_mesh_clear()
        info["poses"][str(frame)] = {"matrix_world": matrix_list(mw), "world_vertices": verts}


def probe(bpy, path: str, frames) -> dict:
    result: dict = {"path": path, "ok": False, "error": None, "log": "", "warnings": []}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not os.path.isfile(path):
        result["error"] = "no such file"
        return result
    log: list[str] = []
    try:
        with captured_output(log):
            status = bpy.ops.wm.usd_import(filepath=os.path.abspath(path))
        result["operator"] = sorted(status)
    except Exception as exc:  # an operator error report surfaces as RuntimeError
        result["error"] = f"{type(exc).__name__}: {exc}".strip()
    result["log"] = "".join(log)
    result["warnings"] = [line.strip() for line in result["log"].splitlines()
                          if any(w in line.lower() for w in ("warn", "error", "invalid"))]
    if result["error"]:
        return result

    scene = bpy.context.scene
    result["scene"] = {"frame_start": scene.frame_start, "frame_end": scene.frame_end,
                       "fps": scene.render.fps / scene.render.fps_base}
    result["objects"] = [{"name": ob.name, "type": ob.type, "parent": ob.parent.name if ob.parent else None}
                         for ob in scene.objects]
    armatures = [(ob, armature_info(ob)) for ob in scene.objects if ob.type == "ARMATURE"]
    meshes = [(ob, mesh_info(ob)) for ob in scene.objects if ob.type == "MESH"]
    result["frames"] = sample_frames(scene, frames)
    for frame in result["frames"]:
        record_frame(bpy, scene, frame, armatures, meshes)
    result["armatures"] = [info for _, info in armatures]
    result["meshes"] = [info for _, info in meshes]
    result["ok"] = True
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="*", help="USD files (frames: first, middle, last)")
    parser.add_argument("--manifest", help='JSON list of {"path": ..., "frames": [...]}')
    parser.add_argument("--out", help="write the JSON report here (default: stdout)")
    args = parser.parse_args(argv)

    jobs = [{"path": p, "frames": None} for p in args.paths]
    if args.manifest:
        with open(args.manifest, encoding="utf-8") as fh:
            jobs += [{"path": str(j["path"]), "frames": j.get("frames")} for j in json.load(fh)]

    report: dict = {"blender": None, "files": []}
    try:
        import bpy
    except Exception as exc:
        report["error"] = f"cannot import bpy: {exc}"
    else:
        report["blender"] = bpy.app.version_string
        for job in jobs:
            try:
                report["files"].append(probe(bpy, job["path"], job["frames"]))
            except Exception as exc:
                report["files"].append({"path": job["path"], "ok": False, "error": f"{type(exc).__name__}: {exc}",
                                        "traceback": traceback.format_exc()})
    text = json.dumps(report)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as fh:
            fh.write(text)
    else:
        print(text)
    return 0 if "error" not in report else 1


if __name__ == "__main__":
    sys.exit(main())
