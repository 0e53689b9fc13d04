"""The polish's normal equations assembled in one compiled loop over the clicks.

:class:`photomodel.modeling.bundle.BundleProblem` spends most of an iteration building the
Gauss–Newton system: per click a 2 × 7 camera Jacobian and a 2 × 3 point Jacobian, summed into
the camera block, the camera–point coupling and the 3 × 3 point blocks. In numpy that is ~40
array operations on (photos, features) arrays, each paying Python's call overhead; here it is one
loop, compiled by Numba (a kept JIT compiler for numpy code — chosen over Cython or a C extension
because it needs no build step; the compiled code is cached on disk, so only the first call on a
machine pays the compilation). Its gradient is checked against finite differences of the cost
(tests/test_bundle_kernel.py), and the polish's quadratic convergence from near the truth in
tests/test_bundle.py fails if any Jacobian term is off.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, fastmath=False)
def assemble(m, R, t2, s, f, O, sw, cols, C):
    """Normal equations of the weighted reprojection residuals.

    Parameters
    ----------
    m (n, 3), R (k, 3, 3), t2 (k, 2), s (k,), f (k,) focal per photo, O (k, n, 2) centred clicks,
    sw (k, n) √weights (0 where not clicked), cols (k, nc) unknown index of each camera column
    (nc = 7 with the log focal length as an unknown, 6 without), C number of camera unknowns.

    Returns
    -------
    U (C, C), gc (C,), W2 (C, 3 n), Vp (n, 3, 3), gp (n, 3).
    """
    k, n = sw.shape
    nc = cols.shape[1]
    U = np.zeros((C, C))
    gc = np.zeros(C)
    W2 = np.zeros((C, 3 * n))
    Vp = np.zeros((n, 3, 3))
    gp = np.zeros((n, 3))
    Jc = np.zeros((2, 7))
    Jm = np.zeros((2, 3))
    r = np.zeros(2)
    for j in range(k):
        eta = s[j] / f[j]
        for i in range(n):
            w = sw[j, i]
            if w == 0.0:
                continue
            qx = R[j, 0, 0] * m[i, 0] + R[j, 0, 1] * m[i, 1] + R[j, 0, 2] * m[i, 2]
            qy = R[j, 1, 0] * m[i, 0] + R[j, 1, 1] * m[i, 1] + R[j, 1, 2] * m[i, 2]
            qz = R[j, 2, 0] * m[i, 0] + R[j, 2, 1] * m[i, 1] + R[j, 2, 2] * m[i, 2]
            D = 1.0 + eta * qz
            a = s[j] / D
            b = -eta / D
            Px = a * (qx + t2[j, 0])
            Py = a * (qy + t2[j, 1])
            r[0] = (Px - O[j, i, 0]) * w
            r[1] = (Py - O[j, i, 1]) * w
            bPx = b * Px
            bPy = b * Py
            Jc[0, 0] = bPx * qy
            Jc[0, 1] = a * qz - bPx * qx
            Jc[0, 2] = -a * qy
            Jc[1, 0] = -a * qz + bPy * qy
            Jc[1, 1] = -bPy * qx
            Jc[1, 2] = a * qx
            Jc[0, 3] = a
            Jc[1, 3] = 0.0
            Jc[0, 4] = 0.0
            Jc[1, 4] = a
            Jc[0, 5] = Px / (s[j] * D)
            Jc[1, 5] = Py / (s[j] * D)
            Jc[0, 6] = -b * qz * Px
            Jc[1, 6] = -b * qz * Py
            for d in range(3):
                Jm[0, d] = a * R[j, 0, d] + bPx * R[j, 2, d]
                Jm[1, d] = a * R[j, 1, d] + bPy * R[j, 2, d]
            for row in range(2):
                for c in range(nc):
                    Jc[row, c] *= w
                for d in range(3):
                    Jm[row, d] *= w
            for c1 in range(nc):
                g1 = cols[j, c1]
                gc[g1] += Jc[0, c1] * r[0] + Jc[1, c1] * r[1]
                for c2 in range(nc):
                    U[g1, cols[j, c2]] += Jc[0, c1] * Jc[0, c2] + Jc[1, c1] * Jc[1, c2]
                for d in range(3):
                    W2[g1, 3 * i + d] += Jc[0, c1] * Jm[0, d] + Jc[1, c1] * Jm[1, d]
            for d1 in range(3):
                gp[i, d1] += Jm[0, d1] * r[0] + Jm[1, d1] * r[1]
                for d2 in range(3):
                    Vp[i, d1, d2] += Jm[0, d1] * Jm[0, d2] + Jm[1, d1] * Jm[1, d2]
    return U, gc, W2, Vp, gp
