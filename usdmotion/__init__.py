"""usdmotion: motion capture (BVH, OpenUSD) in, OpenUSD / BVH / video / tables out.

The short public API (each name is imported on first use, so ``import usdmotion`` and the
CLI's start-up stay fast)::

    import usdmotion as um
    walk = um.read("walk.bvh", units="asf")          # Motion: (F, J, 4) wxyz rotations, ...
    positions = um.joint_positions(walk)             # (F, J, 3) world positions, file units
    short = um.retarget(walk, remove=["LHipJoint", "RHipJoint"]).motion
    um.write(short, "walk_short.usdc")
    kin = um.analyse(walk)                           # speeds, angles, centre of mass
    cuts = um.segment(walk).cuts                     # frame indices of the segment boundaries
    um.write(um.trim(walk, 1, 200), "first.bvh")     # the edits: equalize, reorient, blend, ...

============================  ==================================================
``read`` / ``write``          :func:`usdmotion.io.read_motion` / ``write_motion``
``Motion``                    the frozen, array-only motion (:mod:`usdmotion.motion`)
``fk`` / ``joint_positions``  forward kinematics (:mod:`usdmotion.kinematics`)
``retarget``                  :func:`usdmotion.ops.retarget.retarget` (JAX, lazily)
``segment``                   :func:`usdmotion.ops.segment.segment`
``analyse``                   :func:`usdmotion.ops.analyse.analyse`
``render_motion``             :func:`usdmotion.render.render_motion` (pyrender, EGL)
edits                         ``equalize reorient displace layer blend speed resample cycle trim``
============================  ==================================================
"""

from __future__ import annotations

import importlib

#: Public name → (module, attribute): resolved on first access (PEP 562), so importing the
#: package imports neither NumPy nor any heavy dependency.
_PUBLIC = {
    "read": ("usdmotion.io", "read_motion"),
    "write": ("usdmotion.io", "write_motion"),
    "Motion": ("usdmotion.motion", "Motion"),
    "fk": ("usdmotion.kinematics", "fk"),
    "joint_positions": ("usdmotion.kinematics", "joint_positions"),
    "retarget": ("usdmotion.ops.retarget", "retarget"),
    "segment": ("usdmotion.ops.segment", "segment"),
    "analyse": ("usdmotion.ops.analyse", "analyse"),
    # not "render": that name is the usdmotion.render package, which Python binds on import
    "render_motion": ("usdmotion.render", "render_motion"),
    **{name: ("usdmotion.ops.edit", name)
       for name in ("equalize", "reorient", "displace", "layer", "blend", "speed", "resample", "cycle", "trim")},
}

__all__ = sorted(_PUBLIC)


def __getattr__(name: str):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'usdmotion' has no attribute {name!r}")
    module, attribute = _PUBLIC[name]
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
