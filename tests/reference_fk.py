"""An independent forward kinematics of BVH channel data, for tests only.

Shares no code with ``usdmotion.rotations`` or ``usdmotion.kinematics``: Euler angles go
through SciPy's ``Rotation.from_euler`` (intrinsic, upper-case order), transforms are
plain 4×4 matrices multiplied joint by joint down the parent chain.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def reference_world_positions(parents, offsets, channels, values, root_offset: str) -> np.ndarray:
    """World joint positions ``(F, J, 3)`` from raw BVH arrays.

    ``root_offset``: ``"add"`` (root at OFFSET + channels) or ``"replace"`` (channels replace
    the OFFSET per axis). Non-root position channels replace the OFFSET.
    """
    n_frames = values.shape[0]
    n_joints = len(parents)
    world = np.zeros((n_frames, n_joints, 4, 4))
    column = 0
    for j in range(n_joints):
        names = channels[j]
        local = np.tile(np.eye(4), (n_frames, 1, 1))
        translation = np.tile(np.asarray(offsets[j], float), (n_frames, 1))
        rot_axes, rot_cols = "", []
        for k, name in enumerate(names):
            col = values[:, column + k]
            axis = "XYZ".index(name[0])
            if name.endswith("position"):
                if j == 0 and root_offset == "add":
                    translation[:, axis] = offsets[j][axis] + col
                else:
                    translation[:, axis] = col
            else:
                rot_axes += name[0]
                rot_cols.append(col)
        column += len(names)
        if rot_axes:
            angles = np.stack(rot_cols, axis=1)
            local[:, :3, :3] = Rotation.from_euler(rot_axes.upper(), angles, degrees=True).as_matrix()
        local[:, :3, 3] = translation
        world[:, j] = local if parents[j] < 0 else world[:, parents[j]] @ local
    return world[:, :, :3, 3]


def usd_world_positions(path) -> np.ndarray:
    """Joint world positions ``(F, J, 3)`` evaluated by usd-core at every authored frame."""
    from pxr import Usd, UsdGeom, UsdSkel

    stage = Usd.Stage.Open(str(path))
    skeleton = next(UsdSkel.Skeleton(p) for p in stage.Traverse() if p.IsA(UsdSkel.Skeleton))
    query = UsdSkel.Cache().GetSkelQuery(skeleton)
    start, end = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    frames = []
    for t in range(start, end + 1):
        transforms = np.array(query.ComputeJointWorldTransforms(UsdGeom.XformCache(t)))
        frames.append(transforms[:, 3, :3])  # row-vector matrices: translation in the last row
    return np.asarray(frames)
