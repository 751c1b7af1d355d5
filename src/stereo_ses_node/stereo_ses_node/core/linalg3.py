"""Batched closed-form 3x3 algebra (adjugate inverse), faster than LAPACK for many tiny matrices."""

from __future__ import annotations

import numpy as np


def det_inv3(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(det (N,), inverse (N, 3, 3)) of N 3x3 matrices by cofactors; singular rows give inf/nan."""
    a, b, c = m[:, 0, 0], m[:, 0, 1], m[:, 0, 2]
    d, e, f = m[:, 1, 0], m[:, 1, 1], m[:, 1, 2]
    g, h, i = m[:, 2, 0], m[:, 2, 1], m[:, 2, 2]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    adj = np.stack([c00, c * h - b * i, b * f - c * e,
                    c01, a * i - c * g, c * d - a * f,
                    c02, b * g - a * h, a * e - b * d], axis=1).reshape(-1, 3, 3)
    with np.errstate(divide='ignore', invalid='ignore'):
        return det, adj / det[:, None, None]
