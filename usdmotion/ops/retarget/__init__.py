"""Retargeting: move a motion onto another joint hierarchy (ALGORITHMS.md §1).

=======================  ======================================================
``retarget``             source ``Motion`` → target skeleton (``RetargetResult``)
``retarget_files``       read/derive the target, retarget, write motion + report
``prepare``              the rig, joint map, offsets and targets (step 1)
``solve``                step 2: LM / Adam over all frames (JAX, imported lazily)
``load_joint_map``       a target → source joint map from JSON
=======================  ======================================================

Modules along the data flow: ``hierarchy`` (rigs, removing/adding joints), ``jointmap``,
``problem`` (the solvers' static structure and constants), ``losses``, ``tree_step``
(the O(joints) LM step), ``solve``, ``contact_terms`` and ``leg_ik`` (the contact-aware
solve: fixed points of the planted feet, then the legs meet them analytically), ``pipeline``
(``retarget``), ``report``, ``files``.
"""

from usdmotion.ops.retarget.files import retarget_files
from usdmotion.ops.retarget.hierarchy import AddSpec, RetargetError, UnitsMismatchError, parse_add
from usdmotion.ops.retarget.jointmap import JointMap, load_joint_map
from usdmotion.ops.retarget.pipeline import RetargetResult, prepare, retarget
from usdmotion.ops.retarget.solve import solve

__all__ = ["AddSpec", "JointMap", "RetargetError", "RetargetResult", "UnitsMismatchError", "load_joint_map",
           "parse_add", "prepare", "retarget", "retarget_files", "solve"]
