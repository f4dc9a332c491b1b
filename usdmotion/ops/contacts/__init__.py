"""Foot contacts and contact-quality metrics.

* :func:`detect_contacts` (``detect.py``): per heel/ankle and toe joint, the frames it is
  planted, from height above the floor and speed, with hysteresis and minimum durations
  → :class:`FootContacts`; :func:`contacts_on_rig` puts them on another rig's joints (a
  retargeting target) by part.
* :func:`foot_metrics` (``metrics.py``): foot skate, floor penetration and floating of
  joint positions given contacts → :class:`FootMetrics`.
* ``files.py``: the contacts JSON (``schemas/contacts.schema.json``) and the plot.
"""

from usdmotion.ops.contacts.detect import (ContactThresholds, FootContacts, contact_joints, contact_signals,
                                           contacts_on_rig, detect_contacts)
from usdmotion.ops.contacts.metrics import (FootMetrics, below_floor, floating, floor_penetration, foot_metrics,
                                            foot_skate, motion_foot_metrics)

__all__ = ["ContactThresholds", "FootContacts", "FootMetrics", "below_floor", "contact_joints", "contact_signals",
           "contacts_on_rig", "detect_contacts", "floating", "floor_penetration", "foot_metrics", "foot_skate",
           "motion_foot_metrics"]
