"""Operations on motions: ``Motion`` → ``Motion`` (or arrays) functions, one package each.

Retargeting (:mod:`usdmotion.ops.retarget`, the only JAX importer among them), editing
(:mod:`usdmotion.ops.edit`: equaliser, re-orientation, displacement maps, blending, speed,
cycling, trimming), segmentation (:mod:`usdmotion.ops.segment`) and kinematic analysis
(:mod:`usdmotion.ops.analyse`).
"""
