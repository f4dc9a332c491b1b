"""Operations on motions: ``Motion -> Motion`` (or arrays) functions.

Subpackages and modules: :mod:`usdmotion.ops.edit` (MotionLab-style editing: equaliser,
re-orientation, displacement maps, blending, speed, cycling, trimming).
"""
