"""Kinematic analysis: speeds, accelerations, joint angles, centre of mass.

=====================  =======================================================
``analyse``            ``Motion`` → ``Kinematics`` (arrays over frames, joints)
``FilterSpec``         smoothing before differentiation (``smoothing``)
``select_joints``      joint indices from names
``kinematics_table``   the per-frame table (``report``)
``write_kinematics``   write the table as CSV/Parquet (``report``)
=====================  =======================================================
"""

from usdmotion.ops.analyse.measures import Kinematics, analyse, select_joints
from usdmotion.ops.analyse.report import kinematics_table, summary, write_kinematics
from usdmotion.ops.analyse.smoothing import FilterSpec

__all__ = ["FilterSpec", "Kinematics", "analyse", "kinematics_table", "select_joints", "summary",
           "write_kinematics"]
