"""Retargeting: move a motion onto another joint hierarchy, keeping global joint
positions as close as possible to the original (ALGORITHMS.md §1).

Pipeline (``retarget``):

1. **Target rig** — from a BVH/USD file, or derived from the source by removing joints
   (children re-parented to the parent) and adding joints (:mod:`usdmotion.ops.retarget.hierarchy`).
2. **Joint map** — which source joint each target joint is compared with
   (:mod:`usdmotion.ops.retarget.jointmap`). Across rigs the source positions are first brought
   into the target's frame: up axis converted, then scaled (``scale="units"``: the
   unit ratio, physical size kept; ``"auto"``: to the target's size; or a number).
3. **Step 1, offsets** — each mapped bone's length = the mean over frames of the source
   distance between the joint and its nearest mapped ancestor. Direction: the target
   rig's (rigs from files), or for rigs derived from the source the mean direction of
   the source bone in its new parent's frame (``directions="mean"``, default) or the
   rest-pose composition (``"rest"``, the paper's "direction kept").
4. **Step 2, rotations** — initial guess (copied/composed source rotations or "aim each
   bone at its source direction"), then :mod:`usdmotion.ops.retarget.solve` (LM by
   default, the paper's Adam as reference) over all frames at once.

The loss compares, per frame, the world positions of the mapped target joints with the
(converted, scaled) world positions of their source joints, in target units squared.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from usdmotion.channels import rotation_order
from usdmotion.kinematics import fk_arrays, world_rotations_positions
from usdmotion.motion import POSITION_CHANNELS, Motion
from usdmotion.ops.retarget.hierarchy import (Rig, RetargetError, adapt_offsets, ancestor_matrix,
                                     derive_rig, mapped_chains, rig_from_motion, source_bone_lengths, with_ancestors)
from usdmotion.ops.retarget import quality as retarget_quality
from usdmotion.ops.retarget import report as retarget_report
from usdmotion.ops.retarget.contact_terms import ROOT_SCALES, contact_terms, solved_ankle_levels
from usdmotion.ops.retarget.jointmap import JointMap, resolve_map
from usdmotion.ops.retarget.contact_phase import CONTACT_ITERATIONS, body_weight, contact_phase
from usdmotion.ops.retarget.leg_ik import fk_of, legs_of, place_legs
from usdmotion.ops.retarget.losses import frame_losses
from usdmotion.ops.retarget.problem import Problem
from usdmotion.ops.retarget.aim import aim_init, aim_single_points, identity_quats as _identity
from usdmotion.ops.retarget.rotation_terms import smooth_scale
from usdmotion.ops.retarget.scale import source_scale
from usdmotion.ops.retarget.solve import solve
from usdmotion.ops.retarget.unmapped import continuous_hemisphere, unmapped_rules
from usdmotion.progress import Progress
from usdmotion.rotations import quat_conjugate, quat_mul, quat_rotate

METHODS = ("lm", "adam")
#: Default weight (rigs from files) of the pull of every optimised joint's world rotation
#: towards the continuous initial guess: a radian weighs this share of the squared
#: distances the joint moves (see :func:`smooth_scale`); small enough to leave what the
#: positions determine alone (RMS +0.x %), large enough to hold what they barely determine.
PRIOR = 0.01


@dataclass(frozen=True)
class RetargetResult:
    """The retargeted motion and a JSON-ready report (see :func:`retarget`)."""

    motion: Motion
    report: dict = field(repr=False)


@dataclass(eq=False)
class Setup:
    """A retargeting problem in arrays (NumPy, float64). Built by :func:`prepare`."""

    rig: Rig                    # target rig (offsets as given / rest-composed)
    offsets: np.ndarray         # (J, 3) after step 1
    source_of: np.ndarray       # (J,) source joint per target joint, -1 = not compared
    weights: np.ndarray         # (J,)
    targets: np.ndarray         # (F, J, 3) source positions per target joint (target frame & units); 0 if unmapped
    translations: np.ndarray    # (F, J, 3) local translations (root: world) before solving
    rot_joints: np.ndarray      # joints whose rotation is optimised
    trans_joints: np.ndarray    # joints whose translation is optimised
    anchor: int                 # joint whose translation carries the world position
    top: int                    # deepest joint above (or at) every mapped joint
    inits: dict                 # name -> (F, J, 4) initial local rotations
    scale: float
    joint_map: JointMap
    derived: object | None      # DerivedRig when the target was derived from the source
    mode: str                   # "derived" or "target"

    @property
    def mapped(self) -> np.ndarray:
        return np.flatnonzero((self.source_of >= 0) & (self.weights > 0))


def _up_rotation(source_up: str, target_up: str) -> np.ndarray | None:
    """Quaternion taking source-frame vectors to the target frame (±90° about X), or None."""
    if source_up == target_up:
        return None
    half = np.sqrt(0.5)
    return np.array([half, half, 0.0, 0.0]) if target_up == "Z" else np.array([half, -half, 0.0, 0.0])


# ------------------------------------------------------------------------- setup


def _target(source: Motion, target: Motion | None, remove, add, target_path, source_path):
    if target is None:
        derived = derive_rig(rig_from_motion(source, source_path or "source"), remove, add)
        return derived.rig, derived, "derived"
    derived = derive_rig(rig_from_motion(target, target_path or "target"), remove, add) if (remove or add) else None
    return (derived.rig if derived else rig_from_motion(target, target_path or "target")), derived, "target"


def _chain_sizes(rig: Rig, mapped_mask: np.ndarray, source_of: np.ndarray, positions: np.ndarray):
    chains = mapped_chains(rig.parents, mapped_mask)
    lengths = source_bone_lengths(positions, chains, source_of)
    rest = np.array([np.linalg.norm(rig.offsets[c].sum(axis=0)) for _, c in chains]) if chains else np.zeros(0)
    return chains, lengths, rest


def prepare(source: Motion, target: Motion | None = None, *, remove=(), add=(), joint_map: JointMap | None = None,
            lengths: str = "source", directions: str = "auto", scale="units", local: bool = False,
            target_path: str | None = None, source_path: str | None = None) -> Setup:
    """Build the arrays of a retargeting problem (steps 1 and the initial guesses)."""
    if lengths not in ("source", "target"):
        raise RetargetError(f"lengths must be 'source' or 'target', got {lengths!r}")
    if directions not in ("auto", "mean", "rest"):
        raise RetargetError(f"directions must be 'auto', 'mean' or 'rest', got {directions!r}")
    rig, derived, mode = _target(source, target, remove, add, target_path, source_path)
    if mode == "derived":
        default = {rig.joint_names[j]: (source.joint_names[o] if o >= 0 else None)
                   for j, o in enumerate(derived.origin)}
        source_of, weights, jmap = resolve_map(joint_map, source.joint_names, rig.joint_names, rig.end_sites, default)
    else:
        if directions == "mean":
            raise RetargetError("--directions mean needs a target derived from the source (--remove/--add); "
                                "a target rig keeps its own bone directions")
        source_of, weights, jmap = resolve_map(joint_map, source.joint_names, rig.joint_names, rig.end_sites)
    mapped_mask = (source_of >= 0) & (weights > 0)
    if mapped_mask.sum() < 2:
        raise RetargetError(f"only {int(mapped_mask.sum())} target joint(s) could be matched with source joints "
                            f"({jmap.how}); write a joint map (docs/retarget.md) and pass --map")
    world_q_src, positions = world_rotations_positions(source)
    up = _up_rotation(source.up_axis, rig.up_axis)
    if up is not None:
        positions = quat_rotate(up, positions)
        world_q_src = quat_mul(up, world_q_src)
    units = source.meters_per_unit / rig.meters_per_unit
    chains, src_len, rest_len = _chain_sizes(rig, mapped_mask, source_of, positions)
    ratio = float(rest_len.sum() / (units * src_len.sum())) if src_len.sum() > 0 and rest_len.sum() > 0 else 1.0
    s = source_scale(scale, mode, units, ratio, source.meters_per_unit, rig)
    positions = positions * s
    src_len = src_len * s
    targets = np.zeros((source.n_frames, rig.n_joints, 3))
    targets[:, mapped_mask] = positions[:, source_of[mapped_mask]]
    # step 1: offsets
    offsets = rig.offsets.copy()
    if lengths == "source":
        fallback = None
        use_mean = mode == "derived" and directions in ("auto", "mean")
        if mode == "derived":
            fallback = _mean_directions(derived, chains, source_of, positions, world_q_src, only_changed=not use_mean)
            if use_mean:
                for j, direction in fallback.items():
                    if not rig.animated[j]:  # joints with per-frame translations keep their OFFSET
                        offsets[j] = direction * np.linalg.norm(offsets[j])
        other = 1.0 if mode == "derived" else float(src_len.sum() / rest_len.sum()) if rest_len.sum() > 0 else 1.0
        fixed = [k for k, (_, chain) in enumerate(chains) if rig.animated[chain[-1]]]  # per-frame translations
        keep = [k for k in range(len(chains)) if k not in fixed]
        offsets = adapt_offsets(offsets, rig.parents, [chains[k] for k in keep], src_len[keep], other_scale=other,
                                fallback_directions=fallback)
    roles = _roles(rig, mapped_mask, mode, derived, offsets, local)
    translations = _translations(source, rig, derived, mode, offsets, positions, world_q_src, roles, targets)
    setup = Setup(rig, offsets, source_of, weights, targets, translations, roles["rot"], roles["trans"],
                  roles["anchor"], roles["top"], {}, s, jmap, derived, mode)
    setup.inits = _initial_guesses(source, setup, up)
    return setup


def _mean_directions(derived, chains, source_of, positions, world_q_src, only_changed: bool) -> dict:
    """Unit mean direction, in the new parent's source frame, of every re-parented bone."""
    out = {}
    for a, chain in chains:
        j = chain[-1]
        if len(chain) != 1 or len(derived.compose[j]) < 2:
            continue  # bones with an unchanged parent keep their rest direction
        bone = positions[:, source_of[j]] - positions[:, source_of[a]]
        v = quat_rotate(quat_conjugate(world_q_src[:, source_of[a]]), bone)
        mean = v.mean(axis=0)
        norm = np.linalg.norm(mean)
        if norm > 1e-12 and (not only_changed or np.linalg.norm(derived.rig.offsets[j]) <= 1e-12):
            out[j] = mean / norm
    return out


def _roles(rig: Rig, mapped_mask, mode, derived, offsets, local) -> dict:
    """Which joints are optimised (rotation / translation) and which carries the position."""
    anc = ancestor_matrix(rig.parents)
    mapped = np.flatnonzero(mapped_mask)
    above_all = (anc | np.eye(rig.n_joints, dtype=bool))[:, mapped].all(axis=1)
    top = int(np.flatnonzero(above_all).max())  # deepest common ancestor-or-self (parents come first)
    carriers = np.flatnonzero(anc[:, top]) if mode == "target" else np.zeros(0, np.int64)
    # a rotation is optimised when it moves a mapped joint: one below it at a distance
    # (a zero-offset End Site sitting on the joint does not count)
    rest = fk_arrays(_identity((rig.n_joints,)), offsets, rig.parents)[1]
    far = np.linalg.norm(rest[None, mapped] - rest[:, None], axis=-1) > 1e-9 * max(1.0, float(np.abs(offsets).max()))
    movable = (anc[:, mapped] & far).any(axis=1) & ~rig.end_sites
    movable[carriers] = False
    if local and mode == "derived":
        movable &= _local_joints(rig, derived, offsets, anc)
    trans = np.zeros(0, np.int64)
    anchor = 0
    if mode == "target":
        has_position = rig.channels is not None and any(c in POSITION_CHANNELS for c in rig.channels[top])
        anchor = int(top) if top == 0 or has_position or rig.animated[top] else 0
        trans = np.array([anchor])
    return {"rot": np.flatnonzero(movable), "trans": trans, "anchor": anchor, "carriers": carriers, "top": int(top),
            "mapped": mapped}


def _local_joints(rig: Rig, derived, offsets, anc) -> np.ndarray:
    """Local mode: ancestors-or-self of the parents of changed joints, and their children."""
    changed = np.array([len(c) != 1 for c in derived.compose])
    changed |= np.linalg.norm(offsets - rig.offsets, axis=1) > 1e-9 * max(1.0, float(np.abs(rig.offsets).max()))
    changed[0] = False
    parents = rig.parents[changed]
    core = np.zeros(rig.n_joints, bool)
    core[parents] = True
    core |= anc[:, parents].any(axis=1)
    out = core.copy()
    out[1:] |= core[rig.parents[1:]]
    return out


def _translations(source, rig, derived, mode, offsets, positions, world_q_src, roles, targets) -> np.ndarray:
    """Local translations ``(F, J, 3)`` (root: world position) before solving.

    Derived rigs: the source root trajectory, and the exact relative position for joints
    whose position channels move. Rigs from files: the anchor is placed so the top mapped
    joint sits on its target (the joints above it keep identity rotations).
    """
    t = np.broadcast_to(offsets, (source.n_frames,) + offsets.shape).copy()
    if mode == "derived":
        t[:, 0] = positions[:, derived.origin[0]]
        for j in np.flatnonzero(rig.animated):
            p = rig.parents[j]
            o, op = derived.origin[j], derived.origin[p]
            t[:, j] = quat_rotate(quat_conjugate(world_q_src[:, op]), positions[:, o] - positions[:, op])
    else:
        rest = fk_arrays(_identity((rig.n_joints,)), offsets, rig.parents)[1]
        top, anchor = roles["top"], roles["anchor"]
        mapped = roles["mapped"]
        if top in mapped:
            place = targets[:, top] - rest[top]
        else:  # an unmapped common ancestor: match the centroids, ignoring rotation
            place = targets[:, mapped].mean(axis=1) - rest[mapped].mean(axis=0)
        t[:, anchor] = offsets[anchor] + place
    return t


# ----------------------------------------------------------------- initial guesses


def _initial_guesses(source: Motion, setup: Setup, up) -> dict:
    rig = setup.rig
    inits = {}
    copied = _identity((source.n_frames, rig.n_joints))
    origin = setup.derived.origin if setup.mode == "derived" else setup.source_of
    has = origin >= 0
    copied[:, has] = source.rotations[:, origin[has]]
    if setup.mode == "derived":
        inits["copy"] = copied
        composed = _identity((source.n_frames, rig.n_joints))
        for j, chain in enumerate(setup.derived.compose):
            if chain:
                q = source.rotations[:, chain[0]]
                for c in chain[1:]:
                    q = quat_mul(q, source.rotations[:, c])
                composed[:, j] = q
        inits["compose"] = composed
    else:
        if up is not None:
            copied[:, setup.anchor] = quat_mul(up, copied[:, setup.anchor])
        inits["copy"] = copied
    inits["aim"] = aim_init(setup, copied)
    return inits


# ------------------------------------------------------------------------ retarget


def _choose_init(setup: Setup, init: str, method: str) -> str:
    if init != "auto":
        if init not in setup.inits:
            choices = ", ".join(["auto", *setup.inits])
            raise RetargetError(f"init {init!r} is not available here (choose from {choices})")
        return init
    if setup.mode == "derived":
        return "copy" if method == "adam" else "compose"
    losses = {name: float(frame_losses(setup.translations, q, setup.rig.parents, setup.mapped, setup.targets,
                                       setup.weights).sum()) for name, q in setup.inits.items()}
    return min(losses, key=losses.get)  # one choice for the whole take keeps twists continuous


def _problem(setup: Setup, smooth: float = 0.0, prior: float = 0.0):
    channels = setup.rig.channels
    orders = tuple(rotation_order(channels[j]) if channels is not None and channels[j] else "ZXY"
                   for j in setup.rot_joints)
    mapped = setup.mapped
    extra = {}
    if smooth > 0:
        extra["smooth"] = smooth * smooth_scale(setup)
    if prior > 0:
        extra["prior"] = prior * smooth_scale(setup)
    return Problem(setup.rig.parents, mapped, setup.weights[mapped], setup.rot_joints, setup.trans_joints, orders,
                   **extra)


def retarget(source: Motion, target: Motion | None = None, *, remove=(), add=(), joint_map: JointMap | None = None,
             method: str = "lm", iterations: int | None = None, lengths: str = "source", directions: str = "auto",
             scale="units", init: str = "auto", local: bool = False, source_path: str | None = None,
             target_path: str | None = None, progress: Progress | None = None, contacts=None,
             root_scale: str = "off", prior: float | None = None, smooth: float = 0.0,
             compare: bool = False) -> RetargetResult:
    """Retarget ``source`` onto ``target`` (a skeleton; its animation is ignored) or onto
    the source's own skeleton with joints removed/added.

    Args:
        source: the motion to transfer.
        target: the target skeleton, or ``None`` to derive it from the source.
        remove: joint names to remove (children are re-parented to the parent).
        add: :class:`usdmotion.ops.retarget.hierarchy.AddSpec` s of joints to add.
        joint_map: target → source joint map (default: identity for derived rigs,
            automatic otherwise).
        method: ``"lm"`` (default) or ``"adam"`` (the paper's reference).
        iterations: LM's maximum (default 100; it stops once every frame has converged) or
            Adam's iteration count (default 500). With contacts the same solve runs, then the
            legs meet the contacts analytically (:mod:`usdmotion.ops.retarget.leg_ik`), a
            short LM contact phase re-fits hips and legs (:func:`usdmotion.ops.retarget.contact_phase.contact_phase`) and the
            legs meet the contacts again.
        lengths: ``"source"`` (step 1: mean source bone lengths) or ``"target"`` (keep).
        directions: ``"auto"``/``"mean"``/``"rest"`` for derived rigs (see module doc).
        scale: ``"units"``, ``"auto"`` or a number (targets from files only).
        init: ``"auto"``, ``"copy"``, ``"compose"`` (derived rigs) or ``"aim"``.
        local: optimise only joints around changed bones (derived rigs).
        source_path, target_path: file names for messages and the report.
        progress: optional :class:`usdmotion.progress.Progress` ``(frames done, n_frames, message)``,
            called after every chunk.
        contacts: ``None`` (off), ``"auto"`` (:func:`usdmotion.ops.contacts.detect_contacts`
            on the source) or the source's :class:`~usdmotion.ops.contacts.FootContacts`: the
            contact-aware solve (:mod:`usdmotion.ops.retarget.contact_terms`; needs ``lm``).
        root_scale: ``"off"`` or ``"legs"``: scale the root trajectory by the leg-length ratio.
        prior: weight of the pull towards the initial guess (default :data:`PRIOR` for rigs
            from files, 0 for derived rigs, whose composed initial guess is already exact).
        smooth: weight of the temporal term (second difference of world rotations over
            neighbouring frames, solved as a Jacobi sweep inside the batched solve;
            default 0: it slowed convergence and did not remove flips in our tests).
        compare: add the plain solve's and rotation copying's metrics to the report
            (``report["compare"]``; the plain solve runs a second time).

    Returns:
        :class:`RetargetResult` with the new motion (target skeleton, channel layout,
        units and up axis; the source's frame rate) and the report described in
        ``docs/retarget.md``.
    """
    start = time.perf_counter()
    if method not in METHODS:
        raise RetargetError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    if iterations is not None and not (isinstance(iterations, int) and 0 <= iterations <= 100_000):
        raise RetargetError(f"iterations must be an integer in 0..100000, got {iterations!r}")
    if source.n_frames == 0:
        raise RetargetError(f"{source_path or 'source'}: the motion has no frames")
    setup = prepare(source, target, remove=remove, add=add, joint_map=joint_map, lengths=lengths,
                    directions=directions, scale=scale, local=local, target_path=target_path,
                    source_path=source_path)
    if root_scale not in ROOT_SCALES:
        raise RetargetError(f"root_scale must be one of {', '.join(ROOT_SCALES)}, got {root_scale!r}")
    terms = None
    if contacts is not None and contacts != "off":
        if method != "lm":
            raise RetargetError("the contact-aware solve needs --method lm")
        if isinstance(contacts, str):
            if contacts != "auto":
                raise RetargetError(f"contacts must be 'auto', 'off' or contacts read from a file, got {contacts!r}")
            from usdmotion.ops.contacts import detect_contacts

            contacts = detect_contacts(source, source=source_path)
        terms = contact_terms(setup, source, contacts, root_scale)
        if terms is not None:  # the root trajectory scaled: every target moves with it
            setup.targets[:, setup.mapped] += terms.shift[:, setup.mapped]
            setup.translations[:, setup.anchor] += terms.root_shift
    if prior is None:
        prior = PRIOR if setup.mode == "target" and method == "lm" else 0.0
    rot_terms = (float(smooth), float(prior))
    init_name = _choose_init(setup, init, method)
    q0 = setup.inits[init_name]
    prepared = time.perf_counter()
    q, t, solution, terms = _solve(setup, q0, terms, rot_terms, method, iterations, progress)
    motion = _output_motion(source, setup, q, t)
    report = retarget_report.build(source, setup, motion, q0, init_name, method, iterations,
                                   {"setup": prepared - start, "compile": solution.compile_s, "solve": solution.run_s},
                                   source_path, target_path)
    report["chunks"] = {"frames_per_call": solution.chunk, "calls": solution.calls}
    report["iterations_run"] = solution.iterations
    report["rotation_terms"] = {"smooth": rot_terms[0], "prior": rot_terms[1]}
    report["quality"] = retarget_quality.quality(source, setup, motion, terms)
    if terms is not None:
        report["contacts"] = retarget_quality.contacts_summary(terms, root_scale)
    if compare:
        report["compare"] = _compare(source, setup, motion, q0, terms, rot_terms, iterations)
    retarget_quality.warn_if_far(setup, motion, report["loss"]["final"]["rms"], source_path)
    report["time_s"]["total"] = time.perf_counter() - start
    return RetargetResult(motion, report)


def _solve(setup: Setup, q0: np.ndarray, terms, rot_terms, method: str, iterations, progress,
           floor_height: float | None = None):
    """Step 2 and the unmapped-joint rules: ``(q (F,J,4), t (F,J,3), Solution, terms)``, ``terms``
    with the ankles' planted levels where the plain solve stands them (:func:`solved_ankle_levels`);
    ``floor_height`` (target units) for a floor root bone (default: the contacts' floor or estimated)."""
    centre = setup.translations[:, setup.anchor].copy()
    t0 = setup.translations.copy()
    t0[:, setup.anchor] -= centre
    targets = setup.targets[:, setup.mapped] - centre[:, None]
    problem = _problem(setup, *rot_terms)
    solution = solve(problem, q0, t0, targets, method=method, iterations=iterations, progress=progress)
    q, t = solution.q, solution.t
    t[:, setup.anchor] += centre
    if setup.mode == "target" and method == "lm":  # bones moving one point: onto it (see aim_single_points)
        q = aim_single_points(setup, q, t, initial=q0)
    if terms is None and not problem.smoothing and not problem.anchored:
        # keep, per frame, the better of the initial guess and the float32 solution in float64
        args = (setup.rig.parents, setup.mapped, setup.targets, setup.weights)
        worse = frame_losses(t, q, *args) > frame_losses(setup.translations, q0, *args)
        q[worse], t[worse] = q0[worse], setup.translations[worse]
    if terms is not None:  # the contact solve: the legs meet the contacts analytically ...
        began = time.perf_counter()
        contact_chain = with_ancestors(setup.rig.parents, terms.joints)  # what the ankles' heights need
        terms = solved_ankle_levels(setup, terms, fk_of(q, t, setup.rig.parents, contact_chain)[1])
        legs = legs_of(setup.rig.parents, terms.joints, terms.target_contacts.parts, setup.offsets, setup.top)
        place = (setup.rig.parents, setup.anchor, legs, terms.planted, terms.target_contacts.contact, terms.level,
                 terms.up, terms.target_contacts.fps, terms.floor, body_weight(setup, terms))
        q, t, _ = place_legs(q, t, *place)
        compiled = 0.0
        if CONTACT_ITERATIONS:  # ... the body re-fits the source around them, and the legs snap back
            q, t, phase = contact_phase(setup, terms, legs, q, t, problem, CONTACT_ITERATIONS)
            compiled = phase.compile_s
        solution = dataclasses.replace(solution, compile_s=solution.compile_s + compiled,
                                       run_s=solution.run_s + time.perf_counter() - began - compiled)
    q, t = unmapped_rules(setup, q, t, terms.floor if terms is not None else floor_height)
    return continuous_hemisphere(q), t, solution, terms


def _compare(source: Motion, setup: Setup, motion: Motion, q0: np.ndarray, terms, rot_terms, iterations) -> dict:
    """Quality of rotation copying, the plain solve and this result side by side."""
    floor = terms.floor if terms is not None else None
    copy_q, copy_t = unmapped_rules(setup, setup.inits["copy"], setup.translations.copy(), floor)
    rows = {"rotation_copy": _output_motion(source, setup, continuous_hemisphere(copy_q), copy_t)}
    solved = {}
    if terms is not None:
        q, t, solution, _ = _solve(setup, q0, None, rot_terms, "lm", iterations, None, floor)
        rows["plain"] = _output_motion(source, setup, q, t)
        solved["plain"] = {"frames_per_second_solve": source.n_frames / solution.run_s if solution.run_s else None,
                           "iterations_run": solution.iterations}
    rows["result"] = motion
    return {name: {**retarget_quality.quality(source, setup, m, terms), **solved.get(name, {})}
            for name, m in rows.items()}


def _output_motion(source: Motion, setup: Setup, q: np.ndarray, t: np.ndarray) -> Motion:
    rig = setup.rig
    moving = rig.animated.copy()
    moving[setup.trans_joints] = True
    moving[0] = False
    joint_translations = None
    if moving.any():
        joint_translations = np.broadcast_to(setup.offsets, t.shape).copy()
        joint_translations[:, moving] = t[:, moving]
    return Motion(joint_names=rig.joint_names, parents=rig.parents, offsets=setup.offsets, rotations=q,
                  root_translation=t[:, 0], fps=source.fps, joint_translations=joint_translations,
                  end_sites=rig.end_sites, meters_per_unit=rig.meters_per_unit, up_axis=rig.up_axis,
                  channels=rig.channels, root_offset=rig.root_offset)
