"""The LM step of the retarget solver computed independently in float64 NumPy (tests only)."""

from __future__ import annotations

import numpy as np

from usdmotion.ops.retarget.problem import LM_DIAG_FLOOR, LM_NULL_DAMPING


def reference_lm_step(jacobian: np.ndarray, residual: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Solve the damped normal equations per batch.

    Args:
        jacobian: (B, R, P) residual Jacobian per batch item (P = 3 per joint).
        residual: (B, R) residuals at the linearisation point.
        lam: (B,) LM damping factors.

    Returns:
        (B, P) the step ``-(JᵀJ + D)⁻¹ Jᵀr`` with the solver's per-joint diagonal damping D.
    """
    h = np.einsum("bri,brj->bij", jacobian, jacobian)
    g = np.einsum("bri,br->bi", jacobian, residual)
    blocks = np.diagonal(h, axis1=1, axis2=2).reshape(len(h), -1, 3)
    mean = blocks.mean(-1, keepdims=True)
    damp = (lam[:, None, None] * (blocks + LM_DIAG_FLOOR * mean + 1e-12) + LM_NULL_DAMPING * mean).reshape(len(h), -1)
    return -np.linalg.solve(h + damp[:, :, None] * np.eye(h.shape[-1]), g[..., None])[..., 0]
