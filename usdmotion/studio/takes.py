"""What the browser draws for a take, computed by the library (server side).

Everything here is in the viewer's frame: metres, Y up (a Z-up file is turned by
``(x, y, z) → (x, z, −y)``). Joint positions come from :func:`usdmotion.kinematics.joint_positions`,
the plots from :func:`usdmotion.ops.analyse.analyse`; JavaScript only indexes these arrays.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from usdmotion.motion import Motion
from usdmotion.studio.library import Entry, read_take

#: Quantities the plots offer: key → (label, unit). ``bend``/``speed`` are per joint.
QUANTITIES = {
    "bend": ("joint angle", "deg"),
    "speed": ("joint speed", "m/s"),
    "com_height": ("centre-of-mass height", "m"),
    "com_speed": ("centre-of-mass speed", "m/s"),
}


def to_view(points: np.ndarray, up_axis: str) -> np.ndarray:
    """File axes ``(..., 3)`` → viewer axes (Y up, right-handed)."""
    if up_axis == "Y":
        return points
    return np.stack([points[..., 0], points[..., 2], -points[..., 1]], axis=-1)


class TakeCache:
    """Motions and their analysis, read once per (path, size, mtime); a few kept (LRU)."""

    def __init__(self, options: dict, size: int = 6) -> None:
        self.options = options
        self.size = size
        self._items: OrderedDict[tuple, dict] = OrderedDict()
        self._lock = threading.Lock()

    def _slot(self, entry: Entry) -> dict:
        key = (str(entry.path), entry.size, entry.mtime_ns)
        with self._lock:
            slot = self._items.get(key)
            if slot is None:
                slot = self._items[key] = {"locks": {}}
                while len(self._items) > self.size:
                    self._items.popitem(last=False)
            self._items.move_to_end(key)
        return slot

    def _computed(self, slot: dict, what: str, compute):
        """``slot[what]``, computed once: one lock per value, so a slow value (the body) never
        holds up a quick one (the positions) of the same take."""
        with self._lock:
            lock = slot["locks"].setdefault(what, threading.Lock())
        with lock:
            if what not in slot:
                slot[what] = compute()
            return slot[what]

    def get(self, entry: Entry, what: str, compute):
        """``compute(motion)`` for this take, cached under ``what`` (the motion under ``"motion"``)."""
        slot = self._slot(entry)
        motion = self._computed(slot, "motion", lambda: read_take(entry, self.options))
        return motion if what == "motion" else self._computed(slot, what, lambda: compute(motion))

    def motion(self, entry: Entry) -> Motion:
        return self.get(entry, "motion", None)


def skeleton(motion: Motion) -> dict:
    """Topology and timing for the viewer (JSON-ready)."""
    return {
        "joint_names": list(motion.joint_names),
        "parents": [int(p) for p in motion.parents],
        "end_sites": [bool(e) for e in motion.end_sites],
        "frames": motion.n_frames,
        "fps": motion.fps,
        "duration_s": motion.duration,
        "meters_per_unit": motion.meters_per_unit,
        "up_axis": motion.up_axis,
    }


def view_positions(motion: Motion) -> np.ndarray:
    """World joint positions ``(F, J, 3)`` float32, metres, viewer axes."""
    from usdmotion.kinematics import joint_positions

    p = to_view(joint_positions(motion) * motion.meters_per_unit, motion.up_axis)
    return np.ascontiguousarray(p, dtype=np.float32)


def edited_view_positions(original: Motion, original_view: np.ndarray, edited: Motion) -> np.ndarray:
    """:func:`view_positions` of ``edited`` (an edit of ``original``, whose ``original_view``
    positions are known): when the skeleton and frames are the same, only the joints below a
    changed local rotation or translation go through the FK (with their ancestors); the rest are
    ``original_view``'s. The same numbers, much less work for an edit of one limb.
    """
    from usdmotion.kinematics import fk_arrays, local_translations

    same = (edited.n_frames == original.n_frames and edited.joint_names == original.joint_names
            and np.array_equal(edited.parents, original.parents) and edited.up_axis == original.up_axis
            and edited.meters_per_unit == original.meters_per_unit)
    if not same:
        return view_positions(edited)
    translations = local_translations(edited)
    changed = (np.any(edited.rotations != original.rotations, axis=(0, 2))
               | np.any(translations != local_translations(original), axis=(0, 2)))
    parents = edited.parents
    dirty = changed.copy()
    for j in range(1, len(parents)):  # parents before children: one pass marks every descendant
        dirty[j] |= parents[j] >= 0 and dirty[parents[j]]
    if not dirty.any():
        return original_view
    needed = dirty.copy()
    for j in range(len(parents) - 1, 0, -1):  # and every ancestor of a dirty joint
        if needed[j] and parents[j] >= 0:
            needed[parents[j]] = True
    if needed.all():
        return view_positions(edited)
    subset = np.flatnonzero(needed)
    position = {int(j): i for i, j in enumerate(subset)}
    sub_parents = np.array([position[int(parents[j])] if parents[j] >= 0 else -1 for j in subset])
    _, p = fk_arrays(edited.rotations[:, subset], translations[:, subset], sub_parents)
    out = np.array(original_view)
    rows = np.flatnonzero(dirty[subset])
    out[:, subset[rows]] = to_view(p[:, rows] * edited.meters_per_unit, edited.up_axis)
    return out


def analysis(motion: Motion):
    """The library's kinematics of every frame, with centre of mass where the body model fits."""
    from usdmotion.anthropometry import body_model
    from usdmotion.errors import UsdMotionError
    from usdmotion.ops.analyse import analyse

    try:
        body = body_model(motion)
    except (UsdMotionError, ValueError):
        body = None
    return analyse(motion, body=body)


def series(kin, joints: list[str], quantities: list[str]) -> dict:
    """Plot series ``{"time": (F,), "series": [{key, joint, label, unit, values}]}``.

    ``bend``: the angle at the joint between its parent and child bones (0 = straight),
    ``speed``: the joint's speed, ``com_*``: centre of mass (up component / speed). NaN → null.
    """
    index = {n: j for j, n in enumerate(kin.joint_names)}
    out = []
    for q in quantities:
        label, unit = QUANTITIES[q]
        if q in ("bend", "speed"):
            for name in joints:
                j = index[name]
                v = kin.bend[:, j] if q == "bend" else np.linalg.norm(kin.velocities[:, j], axis=-1)
                out.append({"key": q, "joint": name, "label": f"{name} {label}", "unit": unit, "values": v})
        elif kin.com is not None:
            v = kin.com[:, kin.up_index] if q == "com_height" else np.linalg.norm(kin.com_velocity, axis=-1)
            out.append({"key": q, "joint": None, "label": label, "unit": unit, "values": v})
    for s in out:
        v = np.round(np.asarray(s["values"], dtype=np.float64), 5)
        s["values"] = np.where(np.isfinite(v), v, None).tolist()  # JSON has no NaN: null
    return {"time": np.round(kin.time, 6).tolist(), "series": out, "com": kin.com is not None}


def series_query(kin, params, max_joints: int = 200) -> dict:
    """:func:`series` for a request's ``joints`` (comma-separated) and ``q`` (quantities)
    parameters; ``StudioError`` 400 for a name the take does not have."""
    from usdmotion.studio.errors import StudioError

    joints = [j for j in params.get("joints", "").split(",") if j][:max_joints]
    quantities = [q for q in params.get("q", "bend,speed,com_height,com_speed").split(",") if q]
    bad = [j for j in joints if j not in kin.joint_names] + [q for q in quantities if q not in QUANTITIES]
    if bad:
        raise StudioError(400, f"unknown joint or quantity {bad[0]!r}")
    return series(kin, joints, quantities)
