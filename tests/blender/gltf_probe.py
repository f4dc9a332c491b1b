"""Import GLBs with Blender's own glTF importer (and export one from a Blender-imported BVH);
report what Blender made of them, as JSON.

Runs under Blender's Python (``.venv-blender``), imports nothing from usdmotion. One process
handles every job, because starting Blender is the slow part::

    .venv-blender/bin/python tests/blender/gltf_probe.py --manifest m.json --out r.json

``m.json`` is a list of jobs:

* ``{"kind": "gltf", "path": "a.glb", "fps": 120.0, "frames": [0, 10, ...]}``: reset to an
  empty scene, set the scene rate to ``fps`` (Blender's importer turns glTF seconds into
  frames with it: time ``i / fps`` → frame ``i``), ``bpy.ops.import_scene.gltf`` with its
  default options (see ``_set_fps``), then record armatures and meshes at ``frames`` (``usd_probe`` helpers:
  bone names, evaluated world heads, deformed world vertices).
* ``{"kind": "bvh_export", "path": "a.bvh", "out": "b.glb", "frames": [...]}``: Blender's
  BVH importer (scene rate and range from the file), record the armature at ``frames``,
  then ``bpy.ops.export_scene.gltf`` (GLB, default options) to ``out``.

A job that fails never stops the run: its entry gets ``"ok": false`` and ``"error"``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from usd_probe import armature_info, captured_output, mesh_info, record_frame  # noqa: E402


def _set_fps(scene, fps: float) -> None:
    """Make Blender's glTF importer put time ``i / fps`` at frame ``i``. The importer (4.5,
    ``imp/animation_node.py``) converts with ``frame = t · render.fps · render.fps_base``
    (a product, where the scene rate is the quotient), so for a non-integer rate such as
    119.88 the base is ``fps / round(fps)``; for integer rates both readings agree."""
    whole = max(1, round(fps))
    scene.render.fps = whole
    scene.render.fps_base = fps / whole


def _record(bpy, scene, frames, result: dict) -> None:
    armatures = [(ob, armature_info(ob)) for ob in scene.objects if ob.type == "ARMATURE"]
    meshes = [(ob, mesh_info(ob)) for ob in scene.objects if ob.type == "MESH" and ob.vertex_groups]
    result["scene"] = {"frame_start": scene.frame_start, "frame_end": scene.frame_end,
                       "fps": scene.render.fps / scene.render.fps_base}
    result["frames"] = [int(f) for f in frames]
    for frame in result["frames"]:
        record_frame(bpy, scene, frame, armatures, meshes)
    result["armatures"] = [info for _, info in armatures]
    result["meshes"] = [info for _, info in meshes]


def probe(bpy, job: dict) -> dict:
    result: dict = {"path": job["path"], "kind": job["kind"], "ok": False, "error": None}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    log: list[str] = []
    with captured_output(log):
        if job["kind"] == "gltf":
            _set_fps(scene, float(job["fps"]))
            bpy.ops.import_scene.gltf(filepath=os.path.abspath(job["path"]))
        else:
            bpy.ops.import_anim.bvh(filepath=os.path.abspath(job["path"]), update_scene_fps=True,
                                    update_scene_duration=True)
    _record(bpy, scene, job["frames"], result)
    if job["kind"] == "bvh_export":
        with captured_output(log):
            bpy.ops.export_scene.gltf(filepath=os.path.abspath(job["out"]), export_format="GLB")
        result["exported"] = os.path.isfile(job["out"])
    result["log"] = "".join(log)[-4000:]
    result["ok"] = True
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--manifest", required=True)
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    with open(args.manifest, encoding="utf-8") as fh:
        jobs = json.load(fh)
    report: dict = {"blender": None, "files": []}
    try:
        import bpy
    except Exception as exc:
        report["error"] = f"cannot import bpy: {exc}"
    else:
        report["blender"] = bpy.app.version_string
        for job in jobs:
            try:
                report["files"].append(probe(bpy, job))
            except Exception as exc:
                report["files"].append({"path": job["path"], "kind": job["kind"], "ok": False,
                                        "error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()})
    with open(args.out, "w", encoding="utf-8") as fh:
        json.dump(report, fh)
    return 0 if "error" not in report else 1


if __name__ == "__main__":
    sys.exit(main())
