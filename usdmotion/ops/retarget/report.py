"""The retargeting report: losses, per-joint errors and bone-length changes (JSON-ready).

Every number is recomputed here with NumPy float64 forward kinematics from the motion
that is returned (not taken from the float32 solver), so the report describes the
output exactly.
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.ops.retarget.losses import frame_losses
from usdmotion.ops.retarget.problem import ADAM_ITERATIONS, LM_ITERATIONS
from usdmotion.ops.retarget.jax_runtime import device_description


def loss_stats(per_frame: np.ndarray, n_mapped: int) -> dict:
    """``total``, ``per_frame_mean``, ``per_frame_max`` (units²) and ``rms`` per joint (units)."""
    total = float(per_frame.sum())
    return {"total": total, "per_frame_mean": float(per_frame.mean()), "per_frame_max": float(per_frame.max()),
            "rms": float(np.sqrt(total / (len(per_frame) * max(n_mapped, 1))))}


def largest_rotation_changes(rotations: np.ndarray, names, count: int = 5) -> dict:
    """The ``count`` joints whose local rotation changes most between consecutive frames
    (degrees): twists the loss cannot see would show up here as ~180° flips."""
    if rotations.shape[0] < 2:
        return {}
    dot = np.abs(np.sum(rotations[1:] * rotations[:-1], axis=-1)).clip(0.0, 1.0)
    worst = np.degrees(2 * np.arccos(dot)).max(axis=0)
    return {names[j]: float(worst[j]) for j in np.argsort(-worst)[:count]}


def build(source: Motion, setup, motion: Motion, q0: np.ndarray, init_name: str, method: str,
          iterations: int | None, times: dict, source_path: str | None, target_path: str | None) -> dict:
    """The report of a finished retargeting (see ``docs/retarget.md``)."""
    rig, mapped, names = setup.rig, setup.mapped, setup.rig.joint_names
    args = (rig.parents, mapped, setup.targets, setup.weights)
    final_t = local_translations(motion)
    final = frame_losses(final_t, motion.rotations, *args)
    initial = frame_losses(setup.translations, q0, *args)
    loss = {"initial": loss_stats(initial, len(mapped)), "final": loss_stats(final, len(mapped))}
    if "copy" in setup.inits and setup.mode == "derived":
        copied = frame_losses(setup.translations, setup.inits["copy"], *args)
        loss["copied"] = loss_stats(copied, len(mapped))
        loss["final_over_copied"] = float(final.sum() / copied.sum()) if copied.sum() > 0 else 0.0
    loss["final_over_initial"] = float(final.sum() / initial.sum()) if initial.sum() > 0 else 0.0
    world = fk_arrays(motion.rotations, final_t, rig.parents)[1]
    err = np.linalg.norm(world[:, mapped] - setup.targets[:, mapped], axis=-1)
    before = np.linalg.norm(rig.offsets, axis=1)
    after = np.linalg.norm(setup.offsets, axis=1)
    bones = {names[j]: {"before": float(before[j]), "after": float(after[j]), "change": float(after[j] - before[j])}
             for j in range(1, rig.n_joints)}
    jmap = setup.joint_map
    used = set(setup.source_of[setup.source_of >= 0].tolist())
    return {
        "source": source_path,
        "target": target_path if setup.mode == "target" else "derived from the source",
        "method": method,
        "iterations": iterations if iterations is not None else (LM_ITERATIONS if method == "lm" else ADAM_ITERATIONS),
        "init": init_name,
        "dtype": "float32",
        "device": device_description(),
        "frames": int(source.n_frames),
        "fps": float(source.fps),
        "target_joints": int(rig.n_joints),
        "target_joints_without_end_sites": int((~rig.end_sites).sum()),
        "mapped_joints": int(len(mapped)),
        "optimised_rotations": [names[j] for j in setup.rot_joints],
        "optimised_translations": [names[j] for j in setup.trans_joints],
        "removed": list(setup.derived.removed) if setup.derived is not None else [],
        "added": list(setup.derived.added) if setup.derived is not None else [],
        "map": {
            "how": jmap.how,
            "pairs": {names[j]: source.joint_names[setup.source_of[j]] for j in mapped},
            "weights": {names[j]: float(setup.weights[j]) for j in mapped if setup.weights[j] != 1.0},
            "unmapped_target_joints": [n for j, n in enumerate(names) if j not in set(mapped.tolist())
                                       and not rig.end_sites[j]],
            "unmapped_why": _unmapped_why(source, rig, names, mapped) if setup.mode == "target" else {},
            "unused_source_joints": [n for j, n in enumerate(source.joint_names) if j not in used
                                     and not source.end_sites[j]],
        },
        "units": {"source_meters_per_unit": source.meters_per_unit, "target_meters_per_unit": rig.meters_per_unit,
                  "source_scale": setup.scale, "up_axis": f"{source.up_axis} -> {rig.up_axis}",
                  "loss": "target units squared", "errors": "target units"},
        "loss": loss,
        "per_joint_rms": {names[j]: float(np.sqrt(np.mean(err[:, k] ** 2))) for k, j in enumerate(mapped)},
        "per_joint_max": {names[j]: float(err[:, k].max()) for k, j in enumerate(mapped)},
        "bone_lengths": bones,
        "largest_rotation_change_deg": {"target": largest_rotation_changes(motion.rotations, names),
                                        "source": largest_rotation_changes(source.rotations, source.joint_names)},
        "time_s": dict(times),
        "frames_per_second_solve": float(source.n_frames / times["solve"]) if times["solve"] > 0 else None,
    }


def _unmapped_why(source: Motion, rig: Motion, names, mapped) -> dict[str, str]:
    """Unmapped target joint (End Sites left out) → why (``jointmap.unmapped_reasons``)."""
    from usdmotion.ops.retarget.jointmap import unmapped_reasons

    pairs = {names[j]: "mapped" for j in mapped}
    why = unmapped_reasons(source.joint_names, names, pairs, rig.end_sites)
    return {n: w for n, w in why.items() if w != "end site"}
