"""Segmentation of a take into movements (ALGORITHMS.md, docs/segment.md).

====================  ==========================================================
``segment``           cut points of a ``Motion`` (``"kcpd"`` or ``"heuristic"``)
``clip``              one segment as a ``Motion``
``find_roles``        which joints are hips, knees, wrists... (``roles``)
``score_cuts``        detected cuts against labels (``evaluate``)
``cut_confidence``    confidence and change region of each kcpd cut (``cuts``)
``export_clips``      write the segments as motion files (``files``)
``edited``            a segmentation with a person's cuts (``files``; the Studio's editor)
``segments_document`` the segments JSON, with segment labels (``files``)
====================  ==========================================================
"""

from usdmotion.ops.segment.detect import Segmentation, clip, segment
from usdmotion.ops.segment.evaluate import load_labels, score_cuts
from usdmotion.ops.segment.files import (edited, export_clips, plot_segmentation, segments_document,
                                         write_segments_json)
from usdmotion.ops.segment.roles import find_roles

__all__ = ["Segmentation", "clip", "edited", "export_clips", "find_roles", "load_labels", "plot_segmentation",
           "score_cuts", "segment", "segments_document", "write_segments_json"]
