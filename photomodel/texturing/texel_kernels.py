"""The cylindrical texture's per-texel arithmetic in compiled loops (Pighin et al. 2002, §5.2.1–5.2.2).

A 1024² texture of the sample head has ~880k surface texels, and each of the five photographs
looks at every one of them: projection, positional certainty, the depth test, then the blend.
In numpy (:mod:`photomodel.rendering.depth`, :mod:`photomodel.texturing.weights`) each step is a
pass over (t, 3) arrays with its temporaries; here each is one loop, compiled by Numba (the kept
JIT compiler, see :mod:`photomodel.modeling.bundle_kernel`; its compiled code is cached on disk).
The formulas are those of the numpy functions named in each docstring, in the same precision
(``tests/test_texture.py`` compares the texture with the numpy route's, texel for texel).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from photomodel.rendering.depth import FAR_SENTINEL_MM

__all__ = ["blend_single_view", "cylinder_points", "photo_texels"]


@njit(cache=True, fastmath=False)
def photo_texels(M, RT, pts, nrm, depth, tol_mm):
    """Where one photograph sees each surface texel, and how squarely.

    :func:`photomodel.rendering.depth.project_points`,
    :func:`photomodel.texturing.weights.positional_certainty` and the bilinear
    :func:`photomodel.rendering.depth.depth_visible` in one pass.

    Parameters
    ----------
    M : (4, 4) float64, the homogeneous projection of :func:`~photomodel.rendering.depth.project_points`.
    RT : (3, 4) float64, ``[R | t]`` of the camera.
    pts, nrm : (t, 3) float32, texel points (mm) and unit normals.
    depth : (H, W) float32, the photo's depth map, ``inf`` on the background.
    tol_mm : float, the depth test's tolerance.

    Returns
    -------
    uv : (t, 2) float32 px; P : (t,) float32, ``max(n · d_k, 0)``; visible : (t,) bool, seen
    (in the image, in front, not hidden) and front-facing (``P > 0``).
    """
    n = pts.shape[0]
    H, W = depth.shape
    uv = np.empty((n, 2), np.float32)
    P = np.empty(n, np.float32)
    visible = np.empty(n, np.bool_)
    far = np.float32(FAR_SENTINEL_MM)
    for i in range(n):
        x, y, z = np.float64(pts[i, 0]), np.float64(pts[i, 1]), np.float64(pts[i, 2])
        w = x * M[3, 0] + y * M[3, 1] + z * M[3, 2] + M[3, 3]
        if abs(w) > 2.220446049250313e-16:
            w = 1.0 / w
            u = np.float32((x * M[0, 0] + y * M[0, 1] + z * M[0, 2] + M[0, 3]) * w)
            v = np.float32((x * M[1, 0] + y * M[1, 1] + z * M[1, 2] + M[1, 3]) * w)
            zc = np.float32(1.0) / np.float32(w)
        else:
            u = np.float32(0.0)
            v = np.float32(0.0)
            zc = np.float32(np.inf)
        uv[i, 0] = u
        uv[i, 1] = v
        # positional certainty in camera coordinates (float32, as positional_certainty)
        xc = np.float32(RT[0, 0] * x + RT[0, 1] * y + RT[0, 2] * z + RT[0, 3])
        yc = np.float32(RT[1, 0] * x + RT[1, 1] * y + RT[1, 2] * z + RT[1, 3])
        zz = np.float32(RT[2, 0] * x + RT[2, 1] * y + RT[2, 2] * z + RT[2, 3])
        a, b, c = np.float64(nrm[i, 0]), np.float64(nrm[i, 1]), np.float64(nrm[i, 2])
        nx = np.float32(RT[0, 0] * a + RT[0, 1] * b + RT[0, 2] * c)
        ny = np.float32(RT[1, 0] * a + RT[1, 1] * b + RT[1, 2] * c)
        nz = np.float32(RT[2, 0] * a + RT[2, 1] * b + RT[2, 2] * c)
        dist = np.sqrt(xc * xc + yc * yc + zz * zz)
        cos = -(nx * xc + ny * yc + nz * zz) / max(dist, np.float32(1e-12))
        p = max(cos, np.float32(0.0))
        P[i] = p
        # the bilinear depth test, background read as a far surface
        seen = p > 0 and zc > 0 and u >= 0 and u <= W - 1 and v >= 0 and v <= H - 1
        if seen:
            c0 = int(np.floor(u))
            r0 = int(np.floor(v))
            c1 = min(c0 + 1, W - 1)
            r1 = min(r0 + 1, H - 1)
            fu = u - np.float32(c0)
            fv = v - np.float32(r0)
            d00, d01, d10, d11 = depth[r0, c0], depth[r0, c1], depth[r1, c0], depth[r1, c1]
            d00 = d00 if np.isfinite(d00) else far
            d01 = d01 if np.isfinite(d01) else far
            d10 = d10 if np.isfinite(d10) else far
            d11 = d11 if np.isfinite(d11) else far
            top = d00 + (d01 - d00) * fu
            bottom = d10 + (d11 - d10) * fu
            surface = top + (bottom - top) * fv
            seen = zc <= surface + tol_mm
        visible[i] = seen
    return uv, P, visible


@njit(cache=True, fastmath=False)
def blend_single_view(g, colors, single):
    """:func:`photomodel.texturing.weights.apply_single_view` then
    :func:`~photomodel.texturing.weights.blend`, per texel, in float32 as they compute.

    Parameters
    ----------
    g : (k, t) float32 weights ``g_k``; colors : (k, t, 3) uint8; single : (t,) float32 ``s``.

    Returns
    -------
    color : (t, 3) float32, 0 where every weight vanishes; total : (t,) float32, the weights'
    sum after the single-view mix (what ``blend`` returns as ``total``).
    """
    k, n = g.shape
    color = np.zeros((n, 3), np.float32)
    total_out = np.zeros(n, np.float32)
    w = np.empty(k, np.float32)
    for i in range(n):
        total = np.float32(0.0)
        best = 0
        for j in range(k):
            total += g[j, i]
            if g[j, i] > g[best, i]:
                best = j
        s = min(max(single[i], np.float32(0.0)), np.float32(1.0))
        if total > 0:
            scale = (np.float32(1.0) - s) / total
            for j in range(k):
                w[j] = g[j, i] * scale
            w[best] += s
        else:
            for j in range(k):
                w[j] = np.float32(0.0)
        t = np.float32(0.0)
        r = np.float32(0.0)
        gg = np.float32(0.0)
        b = np.float32(0.0)
        for j in range(k):
            t += w[j]
            r += w[j] * np.float32(colors[j, i, 0])
            gg += w[j] * np.float32(colors[j, i, 1])
            b += w[j] * np.float32(colors[j, i, 2])
        total_out[i] = t
        if t > 0:
            color[i, 0] = r / t
            color[i, 1] = gg / t
            color[i, 2] = b / t
    return color, total_out


@njit(cache=True, fastmath=False)
def cylinder_points(rows, cols, fid, normals, offset, sin_t, cos_t, y_row, r_raster, cx, cz, size):
    """The texels' exact ray–plane points (see :func:`photomodel.texturing.cylindrical.rasterise_cylinder`).

    Parameters
    ----------
    rows, cols, fid : (t,) int, each surface texel's position and triangle.
    normals : (M, 3) float64, the triangles' (unnormalised) normals ``n``; offset : (M,) float64,
    ``n·a − n_x c_x − n_z c_z`` (``a`` a corner).
    sin_t, cos_t : (S,) float64 per column; y_row : (S,) float64 per row.
    r_raster : (t,) float64, the rasterised radius, kept where the plane is degenerate or grazed.
    cx, cz : the axis; size : S.

    Returns
    -------
    radius : (S, S) float32, NaN off the surface; points : (S, S, 3) float32, NaN off the surface.
    """
    radius = np.full((size, size), np.nan, np.float32)
    points = np.full((size, size, 3), np.nan, np.float32)
    for i in range(rows.shape[0]):
        row, col, f = rows[i], cols[i], fid[i]
        nd = normals[f, 0] * sin_t[col] + normals[f, 2] * cos_t[col]
        r = r_raster[i]
        if nd != 0.0:
            exact = (offset[f] - normals[f, 1] * y_row[row]) / nd
            if np.isfinite(exact) and abs(exact - r) < 1.0:  # guard degenerate/grazing
                r = exact
        radius[row, col] = r
        points[row, col, 0] = cx + sin_t[col] * r
        points[row, col, 1] = y_row[row]
        points[row, col, 2] = cz + cos_t[col] * r
    return radius, points
