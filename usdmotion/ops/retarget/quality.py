"""What a coach sees in a retargeted motion, as numbers (JSON-ready, float64 from the result).

* ``rms_cm``: joint-position RMS of the mapped joints to their (converted, scaled)
  source positions — the targets of the solve, root scaling included — in cm;
* ``rotation_steps``: per target joint the largest change of its local rotation between
  consecutive frames (degrees) against a limit: twice the largest step of the source
  joint it follows (relative to the source joint its nearest mapped ancestor follows:
  the composition of source joints the target lacks, see :func:`followed_rotations`),
  or for joints no source joint drives 30° per frame at 120 fps
  (scaled by the frame rate); never below :data:`STEP_FLOOR_DEG` at 120 fps (a joint the
  source barely moves may still be moved a little). ``flips`` lists the joints above it.
  Steps are counted from ``steps_from_frame``: 1 where the source starts with a frame it
  jumps from (cgspeed's synthetic T-pose, :func:`usdmotion.kinematics.first_frame_jumps`):
  the whole body jumps there, and the target's chains share that jump differently from the
  source's joints (CMU walk → DAZ: the hand 12°, the hip 14° at that one step), else 0;
* with contacts, ``feet`` (:func:`usdmotion.ops.contacts.foot_metrics` on the target's
  contact joints: skate cm/s, penetration and floating against the planted level) and
  ``floor`` (the lowest of all moved joints against the floor: max depth cm, frames deeper
  than :data:`BELOW_FLOOR_CM`).
"""

from __future__ import annotations

import numpy as np

from usdmotion.kinematics import first_frame_jumps, fk_arrays, local_translations
from usdmotion.motion import Motion
from usdmotion.rotations import quat_conjugate, quat_mul

#: Unmapped joints: at most this many degrees per frame at 120 fps.
UNMAPPED_STEP_DEG = 30.0
#: Smallest limit (degrees per frame at 120 fps) of a mapped joint's rotation step.
STEP_FLOOR_DEG = 1.0
#: Depth below the floor (cm) from which a frame counts as penetrating.
BELOW_FLOOR_CM = 0.1


def rotation_steps(rotations: np.ndarray) -> np.ndarray:
    """``(J,)`` largest angle (degrees) between consecutive frames' local rotations ``(F, J, 4)``."""
    if rotations.shape[0] < 2:
        return np.zeros(rotations.shape[1])
    dot = np.abs(np.sum(rotations[1:] * rotations[:-1], axis=-1)).clip(0.0, 1.0)
    return np.degrees(2 * np.arccos(dot)).max(axis=0)


def followed_rotations(source: Motion, setup) -> tuple[np.ndarray, np.ndarray]:
    """``(joints (K,), rotations (F, K, 4))``: the source rotation each mapped target joint
    follows — its source joint ``s``'s rotation relative to the source joint that the target
    joint's nearest mapped ancestor follows (``W_a⁻¹ · W_s``, world rotations of the source).

    A target joint's local rotation is relative to its target parent; where the source has
    joints between the two mapped joints that the target lacks (CMU's ``LowerBack`` between
    ``Hips`` and ``Spine`` on a Mixamo rig), the target joint carries their rotations too,
    and ``W_a⁻¹ · W_s`` is their composition. Where the chains match (the nearest mapped
    ancestor follows ``s``'s source parent) it is ``s``'s local rotation exactly; where the
    ancestor's source joint is not above ``s`` (or there is none), ``s``'s local rotation."""
    from usdmotion.kinematics import world_rotations_positions

    parents, source_of = setup.rig.parents, setup.source_of
    follows = (source_of >= 0) & (setup.weights > 0)
    joints = np.flatnonzero(follows)
    relative_to = np.full(len(joints), -1)
    for k, j in enumerate(joints):  # per joint of the rig, once per report (not per frame)
        a = parents[j]
        while a >= 0 and not follows[a]:
            a = parents[a]
        s, above = source_of[j], source.parents[source_of[j]]
        while above >= 0 and a >= 0 and above != source_of[a]:
            above = source.parents[above]
        if a >= 0 and above >= 0 and above != source.parents[s]:
            relative_to[k] = above
    rotations = source.rotations[:, source_of[joints]].copy()
    chained = relative_to >= 0
    if chained.any():
        world = world_rotations_positions(source)[0]
        rotations[:, chained] = quat_mul(quat_conjugate(world[:, relative_to[chained]]),
                                         world[:, source_of[joints[chained]]])
    return joints, rotations


def step_limits(source: Motion, setup, start: int = 0) -> np.ndarray:
    """``(J,)`` allowed step per target joint (degrees per frame, see the module docstring):
    twice the largest step of the rotation it follows (:func:`followed_rotations`) from
    frame ``start`` on."""
    per_frame = 120.0 / source.fps
    joints, followed = followed_rotations(source, setup)
    limit = np.full(setup.rig.n_joints, UNMAPPED_STEP_DEG * per_frame)
    limit[joints] = np.maximum(2.0 * rotation_steps(followed[start:]), STEP_FLOOR_DEG * per_frame)
    return limit


def quality(source: Motion, setup, motion: Motion, terms=None) -> dict:
    """The quality figures of ``motion`` (a result on ``setup``'s rig; see the module docstring)."""
    rig, mapped = setup.rig, setup.mapped
    world = fk_arrays(motion.rotations, local_translations(motion), rig.parents)[1]
    cm = motion.meters_per_unit * 100.0
    err = np.linalg.norm(world[:, mapped] - setup.targets[:, mapped], axis=-1)
    start = 1 if first_frame_jumps(source) else 0  # no step across a leading T-pose frame counts
    steps = rotation_steps(motion.rotations[start:])
    limits = step_limits(source, setup, start)
    live = ~rig.end_sites
    flips = {rig.joint_names[j]: {"step_deg": float(steps[j]), "limit_deg": float(limits[j])}
             for j in np.flatnonzero(live & (steps > limits))}
    out = {
        "rms_cm": float(np.sqrt(np.mean(err ** 2)) * cm),
        "rotation_steps": {rig.joint_names[j]: {"step_deg": round(float(steps[j]), 3),
                                                "limit_deg": round(float(limits[j]), 3)}
                           for j in np.flatnonzero(live)},
        "flips": flips,
        "steps_from_frame": start,
    }
    if terms is not None:
        from usdmotion.ops.contacts import foot_metrics

        out["feet"] = foot_metrics(world * motion.meters_per_unit, motion.fps, terms.target_contacts).as_dict()
        out["floor"] = floor_penetration(world, terms.floor, terms.up, cm)
    return out


#: A result whose joint-position RMS to the source exceeds this share of the target's size
#: gets a warning: across rigs it is 1–4 % (``benchmarks/retarget_contacts.py``: 0.6–6.2 cm on
#: 1.7–1.8 m figures); beyond a tenth, the map or the source is wrong.
FAR_SHARE = 0.1


def warn_if_far(setup, motion: Motion, rms: float, source_path: str | None) -> None:
    """Warn (:class:`~usdmotion.errors.UsdMotionWarning`) when the result ``motion`` lies far
    from the source: its joint-position RMS ``rms`` (target units) above :data:`FAR_SHARE` of
    the target's rest-pose size. A wrong map or a distorted source, never a result to use
    without a look."""
    import warnings

    from usdmotion.errors import UsdMotionWarning
    from usdmotion.kinematics import skeleton_height

    size = skeleton_height(motion)
    if size > 0 and rms > FAR_SHARE * size:
        real = int((~setup.rig.end_sites).sum())
        mapped = int((~setup.rig.end_sites[setup.mapped]).sum())
        warnings.warn(f"{source_path or 'source'}: the result lies far from the source: joint-position RMS "
                      f"{rms:.3g} units, {100 * rms / size:.0f} % of the target's size, with {mapped} of {real} target "
                      f"joints mapped ({setup.joint_map.how}); check the map (--map) and the source's warnings",
                      UsdMotionWarning, stacklevel=3)


def floor_penetration(world: np.ndarray, floor: float, up: int, cm: float) -> dict:
    """``max_depth_cm`` of any joint of ``world (F, J, 3)`` below ``floor`` and ``frames_below``
    (deeper than :data:`BELOW_FLOOR_CM`)."""
    depth = np.maximum(floor - world[..., up].min(axis=1), 0.0) * cm
    return {"max_depth_cm": float(depth.max()) if depth.size else 0.0,
            "frames_below": int(np.count_nonzero(depth > BELOW_FLOOR_CM))}


def contacts_summary(terms, root_scale: str) -> dict:
    """The contact setup of a solve, for the report."""
    tc = terms.target_contacts
    return {"joints": list(tc.joints), "parts": list(tc.parts), "contact_frames": np.asarray(tc.contact).sum(0).tolist(),
            "floor_m": float(tc.floor), "clearance_m": [float(c) for c in tc.clearance],
            "leg_ratio": float(terms.leg_ratio), "root_scale": root_scale, "dropped_source_joints": list(terms.dropped)}
