"""LWPR: locally weighted projection regression, as the reference LWPR library 1.2.x computes it.

Incremental, online non-linear regression (Vijayakumar, D'Souza & Schaal 2005) in the exact form of the
reference LWPR library (the specification is ``LWPR.md``): receptive fields (RFs) created and pruned on the
fly, PLS projections added as needed, distance-metric learning with optional IDBD meta-learning, and
confidence bounds. Rouxel et al. use it to learn footstep odometry corrections (three single-output models).

Recommended import and use (the parameter names and defaults are the library's)::

    import numpy as np
    from motion_models.lwpr import LWPR

    model = LWPR(2, 1)                       # n_in, n_out
    model.init_D = 50.0 * np.eye(2)          # or a scalar for a spherical metric
    model.init_alpha = 250.0                 # or an (n_in, n_in) matrix
    model.w_gen = 0.2
    for x, y in samples:                     # x: (2,), y: (1,)
        y_train = model.update(x, y)         # returns the prediction made while training
    y = model.predict(np.array([0.1, -0.3]))                 # (n_out,)
    y, conf = model.predict_conf(np.array([0.1, -0.3]))      # with confidence bounds
    ys = model.predict(np.zeros((100, 2)))                   # a batch of points: (100, n_out)
    model.num_rfs                                            # RFs per output, e.g. array([47])
    model.save("odometry_x.npz")
    same = LWPR.load("odometry_x.npz")                       # or LWPR("odometry_x.npz")

Parameters (settable attributes, validated): ``init_D`` (25·I), ``init_alpha`` (50), ``diag_only`` (True),
``update_D`` (True), ``meta`` (False), ``meta_rate`` (250), ``penalty`` (1e-6), ``w_gen`` (0.1),
``w_prune`` (1.0), ``init_lambda`` (0.999), ``final_lambda`` (0.99999), ``tau_lambda`` (0.9999),
``init_S2`` (1e-10), ``add_threshold`` (0.5), ``kernel`` ("Gaussian" or "BiSquare"), ``norm_in`` and
``norm_out`` (ones). Read-only: ``n_in``/``nIn``, ``n_out``/``nOut``, ``n_data``, ``mean_x``, ``var_x``,
``init_M``, ``num_rfs``, ``n_pruned``; :meth:`LWPR.receptive_field` returns one RF's state and
:meth:`LWPR.copy` an independent copy.

Errors: a wrong shape, a non-finite value, predicting before any update, or a model file that is truncated,
of another format version or missing a field raise ``ValueError`` naming the problem. Sizes are bounded:
``n_in`` at most ``MAX_INPUTS`` (1000), ``n_out`` at most ``MAX_OUTPUTS`` (1000), and the storage a new model
allocates at most ``MAX_INITIAL_BYTES`` (1 GiB); :meth:`LWPR.load` checks every field of a file (type, shape,
range) against these before it allocates anything, so a damaged or hostile file raises ``ValueError`` naming
the file and the field (a missing file stays ``FileNotFoundError``, a path of the wrong type is a
``TypeError``). Inputs are checked before any state changes, so a rejected call leaves the model exactly as it
was; an accepted update runs to completion in one compiled call. The same data in the same order give the same model, bit for bit.

Implementation: each output's RFs live in preallocated numpy arrays (capacity doubles when full) and the
update and prediction loops are ``numba.njit(cache=True)`` kernels. The whole model is four flat buffers, so a
kernel call passes few arguments (numba's dispatch costs time per array argument, per call); a model
pickles and copies as those buffers. ``motion_models.lwpr_reference`` holds a plain-Python
implementation of the same equations that the tests compare against.
"""

from __future__ import annotations

import math
import os
import struct
import zipfile
import zlib
from typing import Any

import numba
import numpy as np
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic
from numpy.lib.stride_tricks import as_strided

from field.checks import show as _short_repr

__all__ = ["LWPR", "FORMAT_VERSION", "MAX_INPUTS", "MAX_OUTPUTS", "MAX_INITIAL_BYTES"]

#: Version of the ``.npz`` model file layout written by :meth:`LWPR.save`.
FORMAT_VERSION = 1
_FORMAT_NAME = "robocup-mcl LWPR model"

#: Largest input dimension ``n_in`` of a model (constructor and model files). A receptive field stores nine
#: n_in × n_in matrices (72·n_in² bytes: 72 MB at 1000 inputs), and the metric update costs O(n_in²) per field
#: and sample; the footstep models here have 7 or 9 inputs.
MAX_INPUTS = 1000
#: Largest output dimension ``n_out`` of a model (constructor and model files); each output has receptive
#: fields of its own.
MAX_OUTPUTS = 1000
#: Most bytes a new model may allocate: its parameters and room for its first receptive fields (8 per output).
#: ``LWPR(1000, 1)`` needs 0.6 GB and fits; ``LWPR(1000, 2)`` or ``LWPR(100, 1000)`` do not.
MAX_INITIAL_BYTES = 1 << 30

# ---------------------------------------------------------------------------------------------------------
# Packed receptive-field storage. Every array is indexed [output, rf, field, ...]; R_max = n_in.
#   vec  (n_out, K, 3, n)           centre, mean_x, var_x
#   mat  (n_out, K, 5, n, n)        D, M (upper triangular, D = MᵀM), alpha, b (meta), h (meta memory)
#   proj (n_out, K, 4, R_max, n)    PLS directions U, loadings P, SXresYres, SSXres (one row per direction)
#   reg  (n_out, K, 10, R_max)      per-direction statistics
#   scal (n_out, K, 4)              beta0, sum_e2, SSp, last activation w
#   ints (n_out, K, 2)              number of projections R, trustworthy flag
#   counts (n_out, 2)               number of RFs, number pruned
# They are views of two flat buffers, `rf` (float: vec, mat, proj, reg, scal, one block after the other) and
# `rf_int` (int: counts, then ints), and the model-wide values are views of `model` (float: norm_in, norm_out,
# the float parameters, init, xstats) and `ipar` (int: the switches, the kernel and n_data). A kernel call
# thus takes four state arrays, and `_model_views` / `_rf_views` rebuild the views inside the kernel.
# ---------------------------------------------------------------------------------------------------------
_C, _MEAN_X, _VAR_X = 0, 1, 2
_N_VEC = 3
_D, _M, _ALPHA, _B, _HMETA = 0, 1, 2, 3, 4
_N_MAT = 5
_U, _P, _SXY, _SSX = 0, 1, 2, 3
_N_PROJ = 4
_BETA, _SSS2, _SSY, _SUM_W, _N_DATA, _LAMBDA, _SUM_ECV2, _H, _R, _S = range(10)
_N_REG = 10
_BETA0, _SUM_E2, _SSP, _W = 0, 1, 2, 3
_N_SCAL = 4
_NREG, _TRUST = 0, 1
_N_INTS = 2
_NUM_RFS, _N_PRUNED = 0, 1

# Scalar parameters (float) and switches (int), in the order of the parameter arrays handed to the kernels.
_FLOAT_PARAMS = (
    "penalty",
    "w_gen",
    "w_prune",
    "init_lambda",
    "final_lambda",
    "tau_lambda",
    "init_S2",
    "add_threshold",
    "meta_rate",
)
_PENALTY, _W_GEN, _W_PRUNE, _INIT_LAMBDA, _FINAL_LAMBDA, _TAU_LAMBDA, _INIT_S2, _ADD_THRESHOLD, _META_RATE = range(9)
_FLOAT_DEFAULTS = (1e-6, 0.1, 1.0, 0.999, 0.99999, 0.9999, 1e-10, 0.5, 250.0)
_BOOL_PARAMS = ("diag_only", "update_D", "meta")
_DIAG_ONLY, _UPDATE_D, _META, _KERNEL, _SAMPLES = 0, 1, 2, 3, 4
_BOOL_DEFAULTS = (True, True, False)
_KERNELS = ("Gaussian", "BiSquare")
_GAUSSIAN, _BISQUARE = 0, 1
# init (3, n, n): init_D, init_M, init_alpha
_INIT_D, _INIT_M, _INIT_ALPHA = 0, 1, 2

_RF_ARRAYS = ("vec", "mat", "proj", "reg", "scal", "ints")
# Attributes that are views of the four flat buffers: never stored, made again by LWPR._bind.
_VIEWS = (
    "_norm_in",
    "_norm_out",
    "_fpar",
    "_init",
    "_xstats",
    "_vec",
    "_mat",
    "_proj",
    "_reg",
    "_scal",
    "_ints",
    "_counts",
)
_FLOAT64 = np.dtype(np.float64)
_N_FLOAT_PARAMS = len(_FLOAT_PARAMS)


@intrinsic
def _c_contiguous(typingctx, array):
    """The same array, typed C-contiguous: for a view that is C-ordered by construction (`_view2` ...), so that
    the kernels index it as they index a C array."""

    def codegen(context, builder, signature, args):
        return impl_ret_borrowed(context, builder, signature.return_type, args[0])

    return array.copy(layout="C")(array), codegen


# The views are made by as_strided, which costs nothing, where a reshape costs tens of ns per call.
@numba.njit(cache=True, inline="always")
def _view2(buffer, start, d0, d1):
    return _c_contiguous(as_strided(buffer[start:], shape=(d0, d1), strides=(8 * d1, 8)))


@numba.njit(cache=True, inline="always")
def _view3(buffer, start, d0, d1, d2):
    return _c_contiguous(as_strided(buffer[start:], shape=(d0, d1, d2), strides=(8 * d1 * d2, 8 * d2, 8)))


@numba.njit(cache=True, inline="always")
def _view4(buffer, start, d0, d1, d2, d3):
    return _c_contiguous(
        as_strided(buffer[start:], shape=(d0, d1, d2, d3), strides=(8 * d1 * d2 * d3, 8 * d2 * d3, 8 * d3, 8))
    )


@numba.njit(cache=True, inline="always")
def _view5(buffer, start, d0, d1, d2, d3, d4):
    return _c_contiguous(
        as_strided(
            buffer[start:],
            shape=(d0, d1, d2, d3, d4),
            strides=(8 * d1 * d2 * d3 * d4, 8 * d2 * d3 * d4, 8 * d3 * d4, 8 * d4, 8),
        )
    )


@numba.njit(cache=True)
def _model_views(model, n, n_out):
    """norm_in (n,), norm_out (n_out,), fpar, init (3, n, n), xstats (2, n): views of the flat `model`."""
    a = n + n_out
    b = a + _N_FLOAT_PARAMS
    c = b + 3 * n * n
    return model[:n], model[n:a], model[a:b], _view3(model, b, 3, n, n), _view2(model, c, 2, n)


@numba.njit(cache=True)
def _rf_views(rf, rf_int, n, n_out):
    """vec, mat, proj, reg, scal, ints, counts (shapes above): views of the flat `rf` and `rf_int`."""
    capacity = (rf_int.shape[0] - 2 * n_out) // (_N_INTS * n_out)
    m = n_out * capacity
    a = m * _N_VEC * n
    b = a + m * _N_MAT * n * n
    c = b + m * _N_PROJ * n * n
    d = c + m * _N_REG * n
    return (
        _view4(rf, 0, n_out, capacity, _N_VEC, n),
        _view5(rf, a, n_out, capacity, _N_MAT, n, n),
        _view5(rf, b, n_out, capacity, _N_PROJ, n, n),
        _view4(rf, c, n_out, capacity, _N_REG, n),
        _view3(rf, d, n_out, capacity, _N_SCAL),
        _view3(rf_int, 2 * n_out, n_out, capacity, _N_INTS),
        _view2(rf_int, 0, n_out, 2),
    )


# =========================================================================================================
# Kernels
# =========================================================================================================
@numba.njit(cache=True, inline="always")
def _activation(q, kernel):
    """LWPR.md "update(x, y)" step 1: activation w(q) and its derivatives w_q, w_qq."""
    if kernel == _GAUSSIAN:
        w = math.exp(-0.5 * q)
        return w, -0.5 * w, 0.25 * w
    a = 1.0 - 0.25 * q
    if a < 0.0:
        return 0.0, 0.0, 0.0
    return a * a, -0.5 * a, 0.125


@numba.njit(cache=True, inline="always")
def _distance(xn, vec, mat, o, k, dx):
    """q = (x − c)ᵀ D (x − c) of RF k of output o, summed in the library's order (dx is scratch space).

    Indexes the packed arrays directly: in this loop over every RF, array views would cost reference
    counting that is several times the arithmetic."""
    n = xn.shape[0]
    for i in range(n):
        dx[i] = xn[i] - vec[o, k, _C, i]
    q = 0.0
    for j in range(n):
        row = 0.0
        for i in range(n):
            row += mat[o, k, _D, j, i] * dx[i]
        q += dx[j] * row
    return q


@numba.njit(cache=True, inline="always")
def _project(z, U, P, n_reg, s, xu):
    """PLS projection with the current U, P: s_j = u_jᵀ z_j, z_{j+1} = z_j − p_j s_j."""
    n = z.shape[0]
    for i in range(n):
        xu[i] = z[i]
    for j in range(n_reg):
        sj = 0.0
        for i in range(n):
            sj += U[j, i] * xu[i]
        s[j] = sj
        if j + 1 < n_reg:
            for i in range(n):
                xu[i] -= P[j, i] * sj


# The update and prediction kernels take the packed arrays in groups (tuples):
#     rfs         (vec, mat, proj, reg, scal, ints, counts): the receptive fields, as `_rf_views` returns them
#     params      (fpar, ipar): the float and integer parameters
#     activation  (w, dwdq, ddwdqdq): an RF's activation and its derivatives (`_activation`)
#     scratch     (work, mwork): the update's vector and matrix scratch
@numba.njit(cache=True)
def _init_rf(o, k, template, xn, yn, fpar, init, rfs):
    """LWPR.md "update(x, y)" step 4: a new RF at x, from ``template`` (an RF index) or from the defaults."""
    vec, mat, proj, reg, scal, ints, _ = rfs
    n = xn.shape[0]
    vec[o, k] = 0.0
    mat[o, k] = 0.0
    proj[o, k] = 0.0
    reg[o, k] = 0.0
    scal[o, k] = 0.0
    if template < 0:
        n_reg = 2 if n > 1 else 1
        mat[o, k, _D] = init[_INIT_D]
        mat[o, k, _M] = init[_INIT_M]
        mat[o, k, _ALPHA] = init[_INIT_ALPHA]
        scal[o, k, _BETA0] = yn
    else:
        n_reg = ints[o, template, _NREG]
        mat[o, k, _D] = mat[o, template, _D]
        mat[o, k, _M] = mat[o, template, _M]
        mat[o, k, _ALPHA] = mat[o, template, _ALPHA]
        scal[o, k, _BETA0] = scal[o, template, _BETA0]
    for i in range(n):
        vec[o, k, _C, i] = xn[i]
    ints[o, k, _NREG] = n_reg
    ints[o, k, _TRUST] = 0
    for j in range(n_reg):
        reg[o, k, _SSS2, j] = fpar[_INIT_S2]
        proj[o, k, _U, j, j] = 1.0
        proj[o, k, _P, j, j] = 1.0
        reg[o, k, _SUM_W, j] = 1e-10
        reg[o, k, _N_DATA, j] = 1e-10
        reg[o, k, _LAMBDA, j] = fpar[_INIT_LAMBDA]
    for j in range(n):
        for i in range(j + 1):
            mat[o, k, _B, i, j] = math.log(mat[o, k, _ALPHA, i, j] + 1e-10)


@numba.njit(cache=True, inline="always")
def _update_metric(o, k, xn, activation, e_star, e, params, rfs, scratch):
    """LWPR.md "Metric update (per RF)": gradient step on M (optionally IDBD meta-learning of α)."""
    w, dwdq, ddwdqdq = activation
    fpar, ipar = params
    vec, mat, _, reg, scal, ints, _ = rfs
    work, mwork = scratch
    n = xn.shape[0]
    R = ints[o, k, _NREG]
    s = reg[o, k, _S]
    SSs2 = reg[o, k, _SSS2]
    lam = reg[o, k, _LAMBDA]
    n_data = reg[o, k, _N_DATA]
    sum_ecv2 = reg[o, k, _SUM_ECV2]
    Hs = reg[o, k, _H]
    rs = reg[o, k, _R]
    c = vec[o, k, _C]
    D = mat[o, k, _D]
    M = mat[o, k, _M]
    alpha = mat[o, k, _ALPHA]
    diag_only = ipar[_DIAG_ONLY] != 0
    meta = ipar[_META] != 0

    if not n_data[0] * (1.0 - lam[0]) > 0.1:
        return
    ok = work[0]  # 1.0 where n_data_j (1 − λ₁) > 0.1
    Ps = work[1]
    Pse = work[2]
    dx = work[3]
    for i in range(R):
        ok[i] = 1.0 if n_data[i] * (1.0 - lam[0]) > 0.1 else 0.0
    penalty = fpar[_PENALTY] / n
    e2 = e * e
    e_cv2 = e_star * e_star
    h = 0.0
    for i in range(R):
        if ok[i] != 0.0:
            h += s[i] * s[i] / SSs2[i]
    h *= w
    W = reg[o, k, _SUM_W, 0]
    if R == 1:
        E = sum_ecv2[0]
    elif n_data[R - 1] > 2 * n:
        E = sum_ecv2[R - 1]
    else:
        E = sum_ecv2[R - 2]
    T = scal[o, k, _SUM_E2] / (E + 1e-10)
    T *= T
    T *= T
    if T > 1.0:
        T = 1.0
    dJ1dw = -E / W + e_cv2
    for i in range(R):
        if ok[i] != 0.0:
            Ps[i] = s[i] / SSs2[i]
            Pse[i] = e * Ps[i]
            dJ1dw -= 2.0 * Pse[i] * Hs[i] + 2.0 * Ps[i] * Ps[i] * rs[i]
        else:
            Ps[i] = 0.0
            Pse[i] = 0.0
    dJ1dw /= W
    wW = w / W
    for i in range(n):
        dx[i] = xn[i] - c[i]

    # ∂w/∂M, ∂J2/∂M and, for meta, the second derivatives; the penalty appears doubled.
    dwdM = mwork[0]
    dJdM = mwork[1]
    ddwdMdM = mwork[2]
    ddJ2dMdM = mwork[3]
    pen2 = penalty + penalty
    max_m = 0.0
    for a in range(n):
        b_hi = a + 1 if diag_only else n
        for b in range(a, b_hi):
            if diag_only:
                aux = 2.0 * M[a, a]
                dqdM = dx[a] * dx[a] * aux
                dwdM[a, b] = dqdM * dwdq
                dJdM[a, b] = pen2 * D[a, a] * aux
                if meta:
                    ddwdMdM[a, b] = ddwdqdq * dqdM * dqdM + 2.0 * dwdq * dx[a] * dx[a]
                    ddJ2dMdM[a, b] = pen2 * (2.0 * D[a, a] + aux * aux)
            else:
                dq = 0.0
                sum_aux = 0.0
                sum_aux1 = 0.0
                for i in range(a, n):
                    m_ai = M[a, i]
                    dq += dx[i] * m_ai
                    sum_aux += D[i, b] * m_ai
                    if i == b:
                        sum_aux1 += 2.0 * m_ai * m_ai
                    else:
                        sum_aux1 += m_ai * m_ai
                dqdM = dq * 2.0 * dx[b]
                dwdM[a, b] = dqdM * dwdq
                dJdM[a, b] = 2.0 * pen2 * sum_aux
                if meta:
                    ddwdMdM[a, b] = ddwdqdq * dqdM * dqdM + 2.0 * dwdq * dx[b] * dx[b]
                    ddJ2dMdM[a, b] = 2.0 * pen2 * (D[b, b] + sum_aux1)
            m_abs = abs(M[a, b])
            if m_abs > max_m:
                max_m = m_abs
            # g = (w/W) ∂J2/∂M + w_q (∂q/∂M) dJ1/dw, stored over ∂J2/∂M.
            dJdM[a, b] = wW * dJdM[a, b] + dwdM[a, b] * dJ1dw

    if meta:
        hmeta = mat[o, k, _HMETA]
        bmeta = mat[o, k, _B]
        meta_rate = fpar[_META_RATE]
        sPse = 0.0
        for i in range(R):
            sPse += s[i] * Pse[i]
        ddJ1dwdw = 2.0 * (e2 * h / w - e_cv2 / W) + E / (W * W)
        for i in range(R):
            ddJ1dwdw += 4.0 * (Pse[i] / W + Ps[i] * sPse) * Hs[i]
        ddJ1dwdw /= W
        for a in range(n):
            b_hi = a + 1 if diag_only else n
            for b in range(a, b_hi):
                G = wW * ddJ2dMdM[a, b] + ddwdMdM[a, b] * dJ1dw + dwdM[a, b] * dwdM[a, b] * ddJ1dwdw
                step = meta_rate * T * dJdM[a, b] * hmeta[a, b]
                if step > 0.1:
                    step = 0.1
                elif step < -0.1:
                    step = -0.1
                b_new = bmeta[a, b] - step
                if b_new > 10.0:
                    b_new = 10.0
                elif b_new < -10.0:
                    b_new = -10.0
                bmeta[a, b] = b_new
                alpha_ab = math.exp(b_new)
                alpha[a, b] = alpha_ab
                shrink = 1.0 - alpha_ab * G * T
                if shrink < 0.0:
                    shrink = 0.0
                hmeta[a, b] = hmeta[a, b] * shrink - alpha_ab * T * dJdM[a, b]

    for a in range(n):
        b_hi = a + 1 if diag_only else n
        for b in range(a, b_hi):
            delta = alpha[a, b] * T * dJdM[a, b]
            if delta > 0.1 * max_m:
                alpha[a, b] *= 0.5
            else:
                M[a, b] -= delta
    if diag_only:
        for j in range(n):
            D[j, j] = M[j, j] * M[j, j]
    else:
        for j in range(n):
            for i in range(j, n):
                acc = 0.0
                for m in range(j + 1):
                    acc += M[m, i] * M[m, j]
                D[i, j] = acc
                D[j, i] = acc

    for i in range(R):
        if ok[i] != 0.0:
            Hs[i] = lam[i] * Hs[i] + (w / (1.0 - h)) * s[i] * e_star * T
            rs[i] = lam[i] * rs[i] + (w * w * e_cv2 / (1.0 - h)) * s[i] * s[i] * T


@numba.njit(cache=True, inline="always")
def _check_add_projection(o, k, n, fpar, proj, reg, scal, ints):
    """LWPR.md "Add a projection"."""
    R = ints[o, k, _NREG]
    if R >= n:
        return
    mse_r = reg[o, k, _SUM_ECV2, R - 1] / reg[o, k, _SUM_W, R - 1] + 1e-10
    mse_r1 = reg[o, k, _SUM_ECV2, R - 2] / reg[o, k, _SUM_W, R - 2] + 1e-10
    n_data_r = reg[o, k, _N_DATA, R - 1]
    if (
        mse_r < fpar[_ADD_THRESHOLD] * mse_r1
        and n_data_r > 0.99 * reg[o, k, _N_DATA, 0]
        and n_data_r * (1.0 - reg[o, k, _LAMBDA, R - 1]) > 0.5
    ):
        proj[o, k, :, R, :] = 0.0
        reg[o, k, :, R] = 0.0
        proj[o, k, _U, R, R] = 1.0
        proj[o, k, _P, R, R] = 1.0
        reg[o, k, _SSS2, R] = fpar[_INIT_S2]
        reg[o, k, _SUM_W, R] = 1e-10
        reg[o, k, _LAMBDA, R] = fpar[_INIT_LAMBDA]
        ints[o, k, _NREG] = R + 1
        scal[o, k, _SSP] = 0.0


@numba.njit(cache=True, inline="always")
def _update_rf(o, k, xn, yn, activation, params, rfs, scratch):
    """LWPR.md "update(x, y)" step 2 for one activated RF; returns the RF's prediction ŷ + β0."""
    w = activation[0]
    fpar, ipar = params
    vec, _, proj, reg, scal, ints, _ = rfs
    work, mwork = scratch
    n = xn.shape[0]
    R = ints[o, k, _NREG]
    mean_x = vec[o, k, _MEAN_X]
    var_x = vec[o, k, _VAR_X]
    U = proj[o, k, _U]
    P = proj[o, k, _P]
    SXY = proj[o, k, _SXY]
    SSX = proj[o, k, _SSX]
    beta = reg[o, k, _BETA]
    SSs2 = reg[o, k, _SSS2]
    SSY = reg[o, k, _SSY]
    sum_w = reg[o, k, _SUM_W]
    n_data = reg[o, k, _N_DATA]
    lam = reg[o, k, _LAMBDA]
    sum_ecv2 = reg[o, k, _SUM_ECV2]
    s = reg[o, k, _S]
    z = work[4]
    e_cv = work[5]
    target = work[6]
    xu = work[7]
    zres = mwork[4]  # (R_max, n): row j is z_j

    # Weighted means, variances and β0.
    swl = sum_w[0] * lam[0]
    inv = 1.0 / (swl + w)
    for i in range(n):
        mx = (swl * mean_x[i] + w * xn[i]) * inv
        mean_x[i] = mx
        z[i] = xn[i] - mx
        var_x[i] = (swl * var_x[i] + w * z[i] * z[i]) * inv
    beta0 = (swl * scal[o, k, _BETA0] + w * yn) * inv
    scal[o, k, _BETA0] = beta0
    t = yn - beta0

    # Project with the old U, P; residuals e_cv,j and regression targets.
    for i in range(n):
        zres[0, i] = z[i]
    yres = 0.0
    for j in range(R):
        sj = 0.0
        for i in range(n):
            sj += U[j, i] * zres[j, i]
        s[j] = sj
        if j + 1 < R:
            for i in range(n):
                zres[j + 1, i] = zres[j, i] - P[j, i] * sj
        yres += beta[j] * sj
        sum_w[j] = sum_w[j] * lam[j] + w
        e_cv[j] = t - yres
    target[0] = t
    for j in range(1, R):
        target[j] = e_cv[j - 1]

    ws2_SSs2 = 0.0
    for j in range(R):
        lam_slow = 0.9 + 0.1 * lam[j]
        wtar = w * target[j]
        norm2 = 0.0
        for i in range(n):
            v = SXY[j, i] * lam_slow + wtar * zres[j, i]
            SXY[j, i] = v
            norm2 += v * v
        if norm2 > 1e-24:
            inv_norm = 1.0 / math.sqrt(norm2)
            for i in range(n):
                U[j, i] = inv_norm * SXY[j, i]
        wsj = w * s[j]
        SSs2[j] = lam[j] * SSs2[j] + s[j] * wsj
        SSY[j] = lam[j] * SSY[j] + target[j] * wsj
        inv_s2 = 1.0 / SSs2[j]
        for i in range(n):
            SSX[j, i] = lam[j] * SSX[j, i] + wsj * zres[j, i]
            P[j, i] = SSX[j, i] * inv_s2
        beta[j] = SSY[j] * inv_s2
        ws2_SSs2 += wsj * wsj * inv_s2
    scal[o, k, _SSP] = lam[R - 1] * scal[o, k, _SSP] + ws2_SSs2
    _project(z, U, P, R, s, xu)

    # The last direction counts only once it has seen more than 2N points.
    yp = 0.0
    if n_data[R - 1] > 2.0 * n:
        for j in range(R):
            yp += beta[j] * s[j]
        e_star = e_cv[R - 1]
    else:
        for j in range(R - 1):
            yp += beta[j] * s[j]
        e_star = e_cv[R - 2] if R > 1 else 0.0
    e = t - yp
    if n_data[0] * (1.0 - lam[0]) > 0.1:
        scal[o, k, _SUM_E2] = scal[o, k, _SUM_E2] * lam[R - 1] + w * e * e
        for j in range(R):
            sum_ecv2[j] = sum_ecv2[j] * lam[j] + w * e_cv[j] * e_cv[j]
    if n_data[0] > 2.0 * n:
        ints[o, k, _TRUST] = 1

    if ipar[_UPDATE_D] != 0:
        _update_metric(o, k, xn, activation, e_star, e, params, rfs, scratch)
    _check_add_projection(o, k, n, fpar, proj, reg, scal, ints)
    tau = fpar[_TAU_LAMBDA]
    final = fpar[_FINAL_LAMBDA]
    for j in range(ints[o, k, _NREG]):
        n_data[j] = n_data[j] * lam[j] + 1.0
        lam[j] = tau * lam[j] + final * (1.0 - tau)
    return yp + beta0


@numba.njit(cache=True)
def _update_output(o, xn, yn, params, init, rfs, scratch):
    """LWPR.md "update(x, y)" for one output: update every activated RF, then create or prune."""
    fpar, ipar = params
    vec, mat, proj, reg, scal, ints, counts = rfs
    work = scratch[0]
    n = xn.shape[0]
    kernel = ipar[_KERNEL]
    num = counts[o, _NUM_RFS]
    w_max = 0.0
    w_sec = 0.0
    ind_max = -1
    ind_sec = -1
    sum_wy = 0.0
    sum_w = 0.0
    dx = work[3]
    # The activations first (RFs are independent within an update), then the updates of active RFs.
    for k in range(num):
        w = _activation(_distance(xn, vec, mat, o, k, dx), kernel)[0]
        scal[o, k, _W] = w if w > 0.001 else 0.0
        if w > w_sec:
            if w > w_max:
                ind_sec = ind_max
                w_sec = w_max
                ind_max = k
                w_max = w
            else:
                ind_sec = k
                w_sec = w
    for k in range(num):
        if scal[o, k, _W] == 0.0:
            continue
        activation = _activation(_distance(xn, vec, mat, o, k, dx), kernel)
        w = activation[0]
        yp_k = _update_rf(o, k, xn, yn, activation, params, rfs, scratch)
        if ints[o, k, _TRUST] != 0:
            sum_wy += w * yp_k
            sum_w += w
    prediction = sum_wy / sum_w if sum_w > 0.0 else 0.0

    if w_max <= fpar[_W_GEN]:
        template = -1
        if w_max > 0.1 * fpar[_W_GEN] and ints[o, ind_max, _TRUST] != 0:
            template = ind_max
        _init_rf(o, num, template, xn, yn, fpar, init, rfs)
        counts[o, _NUM_RFS] = num + 1
    elif w_sec > fpar[_W_PRUNE]:
        tr_max = 0.0
        tr_sec = 0.0
        for i in range(n):
            tr_max += mat[o, ind_max, _D, i, i]
            tr_sec += mat[o, ind_sec, _D, i, i]
        prune = ind_max if tr_max < tr_sec else ind_sec
        last = num - 1
        if prune < last:
            vec[o, prune] = vec[o, last]
            mat[o, prune] = mat[o, last]
            proj[o, prune] = proj[o, last]
            reg[o, prune] = reg[o, last]
            scal[o, prune] = scal[o, last]
            ints[o, prune] = ints[o, last]
        counts[o, _NUM_RFS] = last
        counts[o, _N_PRUNED] += 1
    return prediction


@numba.njit(cache=True)
def _update_kernel(x, y, model, ipar, rf, rf_int, y_train):
    """One training sample for every output. Returns −1 / −2 for a non-finite x / y (nothing changed),
    otherwise the largest number of RFs of any output after the update (and n_data has grown by one)."""
    n = x.shape[0]
    n_out = y.shape[0]
    for i in range(n):
        if not np.isfinite(x[i]):
            return -1
    for i in range(n_out):
        if not np.isfinite(y[i]):
            return -2
    norm_in, norm_out, fpar, init, xstats = _model_views(model, n, n_out)
    rfs = _rf_views(rf, rf_int, n, n_out)
    counts = rfs[6]
    # Model-wide input statistics, on the unscaled input as the library keeps them.
    prev = float(ipar[_SAMPLES])
    ipar[_SAMPLES] += 1
    inv_n = 1.0 / (prev + 1.0)
    for i in range(n):
        mx = (xstats[0, i] * prev + x[i]) * inv_n
        xstats[0, i] = mx
        d = x[i] - mx
        xstats[1, i] = (xstats[1, i] * prev + d * d) * inv_n
    xn = np.empty(n)
    for i in range(n):
        xn[i] = x[i] / norm_in[i]
    scratch = (np.zeros((8, n)), np.zeros((5, n, n)))
    largest = 0
    for o in range(n_out):
        yn = y[o] / norm_out[o]
        y_train[o] = _update_output(o, xn, yn, (fpar, ipar), init, rfs, scratch) * norm_out[o]
        if counts[o, _NUM_RFS] > largest:
            largest = counts[o, _NUM_RFS]
    return largest


@numba.njit(cache=True, inline="always")
def _predict_point(x, cutoff, kernel, norms, rfs, y, conf, with_conf, scratch):
    """LWPR.md "predict(x, cutoff=0.001)" at one point x (n,), into y and conf (n_out,); norms: (norm_in,
    norm_out); rfs: the group above; scratch: (xn, z, dx)."""
    norm_in, norm_out = norms
    vec, mat, proj, reg, scal, ints, counts = rfs
    xn, z, dx = scratch
    n = x.shape[0]
    for i in range(n):
        xn[i] = x[i] / norm_in[i]
    for o in range(y.shape[0]):
        sum_w = 0.0
        sum_wy = 0.0
        sum_wyy = 0.0
        sum_conf = 0.0
        for k in range(counts[o, _NUM_RFS]):
            if ints[o, k, _TRUST] == 0:
                continue
            q = _distance(xn, vec, mat, o, k, dx)
            if kernel == _GAUSSIAN:
                w = math.exp(-0.5 * q)
            else:
                a = 1.0 - 0.25 * q
                w = 0.0 if a < 0.0 else a * a
            if not w > cutoff:
                continue
            R = ints[o, k, _NREG]
            if reg[o, k, _N_DATA, R - 1] <= 2 * n:
                R -= 1
            # The PLS projection of x − mean_x, written out on the packed arrays (see _distance).
            for i in range(n):
                z[i] = xn[i] - vec[o, k, _MEAN_X, i]
            y_k = scal[o, k, _BETA0]
            sig = 0.0
            for j in range(R):
                sj = 0.0
                for i in range(n):
                    sj += proj[o, k, _U, j, i] * z[i]
                if j + 1 < R:
                    for i in range(n):
                        z[i] -= proj[o, k, _P, j, i] * sj
                y_k += sj * reg[o, k, _BETA, j]
                sig += sj * sj / reg[o, k, _SSS2, j]
            sum_w += w
            sum_wy += w * y_k
            if with_conf:
                sig = reg[o, k, _SUM_ECV2, R - 1] / (reg[o, k, _SUM_W, R - 1] - scal[o, k, _SSP]) * (1.0 + w * sig)
                sum_wyy += w * y_k * y_k
                sum_conf += w * sig
        if sum_w > 0.0:
            y_hat = sum_wy / sum_w
            y[o] = y_hat * norm_out[o]
            if with_conf:
                conf[o] = math.sqrt(abs(sum_conf + sum_wyy - sum_wy * y_hat)) / sum_w * norm_out[o]
        else:
            y[o] = 0.0
            if with_conf:
                conf[o] = 1e20 * norm_out[o]


@numba.njit(cache=True)
def _predict_kernel(X, cutoff, model, ipar, rf, rf_int, Y, CONF, with_conf):
    """`_predict_point` for each row of X (m, n) into Y, CONF (m, n_out). Returns the first row holding a
    non-finite value (nothing computed), or −1."""
    m, n = X.shape
    n_out = Y.shape[1]
    for p in range(m):
        for i in range(n):
            if not np.isfinite(X[p, i]):
                return p
    norm_in, norm_out, _, _, _ = _model_views(model, n, n_out)
    rfs = _rf_views(rf, rf_int, n, n_out)
    scratch = (np.empty(n), np.empty(n), np.empty(n))
    for p in range(m):
        _predict_point(X[p], cutoff, ipar[_KERNEL], (norm_in, norm_out), rfs, Y[p], CONF[p], with_conf, scratch)
    return -1


@numba.njit(cache=True)
def _predict_one_kernel(x, cutoff, model, ipar, rf, rf_int, y, conf, with_conf):
    """`_predict_point` at one point x (n,) into y, conf (n_out,). Returns 0 if x holds a non-finite value
    (nothing computed), or −1."""
    n = x.shape[0]
    n_out = y.shape[0]
    for i in range(n):
        if not np.isfinite(x[i]):
            return 0
    norm_in, norm_out, _, _, _ = _model_views(model, n, n_out)
    rfs = _rf_views(rf, rf_int, n, n_out)
    scratch = np.empty((3, n))
    _predict_point(
        x, cutoff, ipar[_KERNEL], (norm_in, norm_out), rfs, y, conf, with_conf, (scratch[0], scratch[1], scratch[2])
    )
    return -1


# =========================================================================================================
# Public class
# =========================================================================================================
def _float_param(index: int, name: str, low: float, high: float, low_open: bool, high_open: bool):
    def getter(self: LWPR) -> float:
        return float(self._fpar[index])

    def setter(self: LWPR, value: Any) -> None:
        v = _scalar(value, name)
        if not ((v > low if low_open else v >= low) and (v < high if high_open else v <= high)):
            lo = "(" if low_open else "["
            hi = ")" if high_open else "]"
            raise ValueError(f"LWPR.{name} must lie in {lo}{low}, {high}{hi}, got {value!r}")
        self._fpar[index] = v

    return property(getter, setter, doc=f"{name} (default {_FLOAT_DEFAULTS[index]!r}).")


def _bool_param(index: int, name: str):
    def getter(self: LWPR) -> bool:
        return bool(self._ipar[index])

    def setter(self: LWPR, value: Any) -> None:
        if not isinstance(value, (bool, np.bool_)):
            raise ValueError(f"LWPR.{name} must be a bool, got {value!r}")
        self._ipar[index] = int(bool(value))

    return property(getter, setter, doc=f"{name} (default {_BOOL_DEFAULTS[index]!r}).")


def _scalar(value: Any, name: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"LWPR.{name} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"LWPR.{name} must be finite, got {value!r}")
    return v


def _check_size(n: int, n_out: int) -> None:
    """Raise ValueError unless a model of n inputs and n_out outputs is within MAX_INPUTS, MAX_OUTPUTS and
    MAX_INITIAL_BYTES."""
    if n > MAX_INPUTS:
        raise ValueError(f"LWPR n_in must be at most MAX_INPUTS = {MAX_INPUTS}, got {n}")
    if n_out > MAX_OUTPUTS:
        raise ValueError(f"LWPR n_out must be at most MAX_OUTPUTS = {MAX_OUTPUTS}, got {n_out}")
    need = LWPR._initial_bytes(n, n_out)
    if need > MAX_INITIAL_BYTES:
        raise ValueError(
            f"LWPR n_in = {n} with n_out = {n_out} needs {need / 2**30:.2f} GiB for the model and "
            f"its first {LWPR._INITIAL_CAPACITY} receptive fields per output; at most "
            f"MAX_INITIAL_BYTES = {MAX_INITIAL_BYTES} bytes (1 GiB)"
        )


def _checked_path(path: Any) -> str | bytes:
    """os.fspath(path), or TypeError naming the argument when it is no path."""
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"path = {_short_repr(path)} must be a str or os.PathLike, not {type(path).__name__}")
    return os.fspath(path)


def _as_float_array(value: Any, name: str) -> np.ndarray:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be an array of real numbers, got {value!r}") from exc


class LWPR:
    """Locally weighted projection regression from ``n_in`` inputs to ``n_out`` outputs.

    ``LWPR(n_in, n_out)`` makes an empty model with the library's defaults; ``LWPR(path)`` loads a model
    written by :meth:`save`. See the module docstring for the parameters.
    """

    penalty = _float_param(_PENALTY, "penalty", 0.0, math.inf, False, True)
    w_gen = _float_param(_W_GEN, "w_gen", 0.0, 1.0, True, True)
    w_prune = _float_param(_W_PRUNE, "w_prune", 0.0, math.inf, True, True)
    init_lambda = _float_param(_INIT_LAMBDA, "init_lambda", 0.0, 1.0, True, False)
    final_lambda = _float_param(_FINAL_LAMBDA, "final_lambda", 0.0, 1.0, True, False)
    tau_lambda = _float_param(_TAU_LAMBDA, "tau_lambda", 0.0, 1.0, False, False)
    init_S2 = _float_param(_INIT_S2, "init_S2", 0.0, math.inf, True, True)
    add_threshold = _float_param(_ADD_THRESHOLD, "add_threshold", 0.0, math.inf, True, True)
    meta_rate = _float_param(_META_RATE, "meta_rate", 0.0, math.inf, True, True)
    diag_only = _bool_param(_DIAG_ONLY, "diag_only")
    update_D = _bool_param(_UPDATE_D, "update_D")
    meta = _bool_param(_META, "meta")

    _INITIAL_CAPACITY = 8

    def __init__(self, n_in: int | str | os.PathLike, n_out: int | None = None) -> None:
        if isinstance(n_in, (str, os.PathLike)):
            if n_out is not None:
                raise ValueError(f"LWPR(path) takes no n_out, got n_out={n_out!r}")
            self.__dict__.update(LWPR.load(n_in).__dict__)
            return
        for name, value in (("n_in", n_in), ("n_out", n_out)):
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"LWPR {name} must be a positive integer, got {_short_repr(value)}")
        assert n_out is not None  # checked above
        n, n_out = int(n_in), int(n_out)
        _check_size(n, n_out)
        self._n_in = n
        self._n_out = n_out
        # The four flat buffers the kernels take (see "Packed receptive-field storage"); every other array
        # attribute is a view of one of them, made by _bind.
        self._model = np.zeros(n + n_out + _N_FLOAT_PARAMS + 3 * n * n + 2 * n)
        self._ipar = np.array([*(int(b) for b in _BOOL_DEFAULTS), _GAUSSIAN, 0], dtype=np.int64)
        self._rf_int = np.zeros(2 * n_out, dtype=np.int64)  # the counts, until _allocate adds the RFs
        self._bind_model()
        self._fpar[:] = _FLOAT_DEFAULTS
        self._init[_INIT_D] = 25.0 * np.eye(n)
        self._init[_INIT_M] = 5.0 * np.eye(n)
        self._init[_INIT_ALPHA] = 50.0
        self._norm_in[:] = 1.0
        self._norm_out[:] = 1.0
        self._allocate(self._INITIAL_CAPACITY)

    # ------------------------------------------------------------------ storage
    def _allocate(self, capacity: int) -> None:
        """Fresh, zeroed RF storage for ``capacity`` RFs per output (the counts are kept)."""
        n, n_out = self._n_in, self._n_out
        per_rf = _N_VEC * n + (_N_MAT + _N_PROJ) * n * n + _N_REG * n + _N_SCAL
        counts = self._rf_int[: 2 * n_out].copy()
        self._rf = np.zeros(n_out * capacity * per_rf)
        self._rf_int = np.zeros(2 * n_out + n_out * capacity * _N_INTS, dtype=np.int64)
        self._rf_int[: 2 * n_out] = counts
        self._capacity = capacity
        self._bind()

    def _bind_model(self) -> None:
        self._norm_in, self._norm_out, self._fpar, self._init, self._xstats = _model_views(
            self._model, self._n_in, self._n_out
        )

    def _bind(self) -> None:
        self._bind_model()
        self._vec, self._mat, self._proj, self._reg, self._scal, self._ints, self._counts = _rf_views(
            self._rf, self._rf_int, self._n_in, self._n_out
        )

    def _grow(self, capacity: int) -> None:
        old = {name: getattr(self, "_" + name) for name in _RF_ARRAYS}
        used = self._capacity
        self._allocate(capacity)
        for name, array in old.items():
            getattr(self, "_" + name)[:, :used] = array

    # --------------------------------------------------------------- properties
    @staticmethod
    def _initial_bytes(n: int, n_out: int) -> int:
        """Bytes ``LWPR(n, n_out)`` allocates: the model buffer and the first `_INITIAL_CAPACITY` RFs."""
        per_rf = _N_VEC * n + (_N_MAT + _N_PROJ) * n * n + _N_REG * n + _N_SCAL
        floats = n + n_out + _N_FLOAT_PARAMS + 3 * n * n + 2 * n + n_out * LWPR._INITIAL_CAPACITY * per_rf
        ints = len(_BOOL_DEFAULTS) + 2 + 2 * n_out + n_out * LWPR._INITIAL_CAPACITY * _N_INTS
        return 8 * (floats + ints)

    @property
    def n_in(self) -> int:
        """Input dimension."""
        return self._n_in

    @property
    def n_out(self) -> int:
        """Output dimension."""
        return self._n_out

    nIn = n_in
    nOut = n_out

    @property
    def n_data(self) -> int:
        """Number of training samples seen."""
        return int(self._ipar[_SAMPLES])

    @property
    def mean_x(self) -> np.ndarray:
        """Mean of the (unscaled) training inputs."""
        return self._xstats[0].copy()

    @property
    def var_x(self) -> np.ndarray:
        """Variance of the (unscaled) training inputs."""
        return self._xstats[1].copy()

    @property
    def num_rfs(self) -> np.ndarray:
        """Number of receptive fields of each output, shape (n_out,)."""
        return self._counts[:, _NUM_RFS].copy()

    @property
    def n_pruned(self) -> np.ndarray:
        """Number of receptive fields pruned so far, per output."""
        return self._counts[:, _N_PRUNED].copy()

    @property
    def kernel(self) -> str:
        """Activation kernel: "Gaussian" (default) or "BiSquare"."""
        return _KERNELS[int(self._ipar[_KERNEL])]

    @kernel.setter
    def kernel(self, value: Any) -> None:
        for index, name in enumerate(_KERNELS):
            if isinstance(value, str) and value.lower() == name.lower():
                self._ipar[_KERNEL] = index
                return
        raise ValueError(f"LWPR.kernel must be 'Gaussian' or 'BiSquare', got {value!r}")

    @property
    def init_D(self) -> np.ndarray:
        """Initial distance metric of a new RF, (n_in, n_in) positive definite; a scalar d means d·I."""
        return self._init[_INIT_D].copy()

    @init_D.setter
    def init_D(self, value: Any) -> None:
        D = self._square(value, "init_D")
        if not np.allclose(D, D.T, rtol=1e-12, atol=0.0):
            raise ValueError(f"LWPR.init_D must be symmetric, got {value!r}")
        try:
            L = np.linalg.cholesky(D)
        except np.linalg.LinAlgError:
            raise ValueError(f"LWPR.init_D must be positive definite, got {value!r}") from None
        self._init[_INIT_D] = D
        self._init[_INIT_M] = L.T

    @property
    def init_M(self) -> np.ndarray:
        """Upper-triangular Cholesky factor of init_D (init_D = init_Mᵀ init_M)."""
        return self._init[_INIT_M].copy()

    @property
    def init_alpha(self) -> np.ndarray:
        """Initial learning rates of the metric update, (n_in, n_in) positive; a scalar fills every entry."""
        return self._init[_INIT_ALPHA].copy()

    @init_alpha.setter
    def init_alpha(self, value: Any) -> None:
        alpha = self._square(value, "init_alpha")
        if not np.all(alpha > 0.0):
            raise ValueError(f"LWPR.init_alpha must be positive, got {value!r}")
        self._init[_INIT_ALPHA] = alpha

    @property
    def norm_in(self) -> np.ndarray:
        """Input scales: the model works on x / norm_in."""
        return self._norm_in.copy()

    @norm_in.setter
    def norm_in(self, value: Any) -> None:
        self._norm_in[:] = self._positive_vector(value, self._n_in, "norm_in")

    @property
    def norm_out(self) -> np.ndarray:
        """Output scales: the model works on y / norm_out."""
        return self._norm_out.copy()

    @norm_out.setter
    def norm_out(self, value: Any) -> None:
        self._norm_out[:] = self._positive_vector(value, self._n_out, "norm_out")

    def _square(self, value: Any, name: str) -> np.ndarray:
        a = _as_float_array(value, f"LWPR.{name}")
        n = self._n_in
        if a.ndim == 0:
            a = np.eye(n) * a if name == "init_D" else np.full((n, n), float(a))
        if a.shape != (n, n):
            raise ValueError(f"LWPR.{name} must have shape ({n}, {n}), got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"LWPR.{name} must be finite, got {value!r}")
        return np.ascontiguousarray(a, dtype=np.float64).copy()

    @staticmethod
    def _positive_vector(value: Any, n: int, name: str) -> np.ndarray:
        a = _as_float_array(value, f"LWPR.{name}")
        if a.ndim == 0:
            a = np.full(n, float(a))
        if a.shape != (n,):
            raise ValueError(f"LWPR.{name} must have shape ({n},), got shape {a.shape}")
        if not np.all(np.isfinite(a) & (a > 0.0)):
            raise ValueError(f"LWPR.{name} must be finite and positive, got {value!r}")
        return a.copy()

    # ---------------------------------------------------------------- training
    @staticmethod
    def _vector(value: Any, n: int, name: str, method: str) -> np.ndarray:
        if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == (n,):
            return value if value.flags.c_contiguous else np.ascontiguousarray(value)
        a = _as_float_array(value, f"LWPR.{method}: {name}")
        if a.shape != (n,):
            if a.size == n and (a.ndim == 0 or (a.ndim == 2 and 1 in a.shape)):
                a = a.reshape(n)
            else:
                raise ValueError(f"LWPR.{method}: {name} must have shape ({n},), got shape {a.shape}")
        return np.ascontiguousarray(a)

    def update(self, x: Any, y: Any) -> np.ndarray:
        """Train on one sample (LWPR.md "update(x, y)"); returns the training prediction, shape (n_out,).

        x has shape (n_in,), y shape (n_out,) (scalars are accepted when the dimension is 1). A non-finite
        value raises ValueError and leaves the model untouched.
        """
        n, n_out = self._n_in, self._n_out
        # The common case, float64 vectors of the right shape, is checked here without a call; the kernel
        # checks finiteness before it changes anything.
        if not (type(x) is np.ndarray and x.dtype is _FLOAT64 and x.shape == (n,) and x.flags.c_contiguous):
            x = self._vector(x, n, "x", "update")
        if not (type(y) is np.ndarray and y.dtype is _FLOAT64 and y.shape == (n_out,) and y.flags.c_contiguous):
            y = self._vector(y, n_out, "y", "update")
        y_train = np.empty(n_out)
        status = _update_kernel(x, y, self._model, self._ipar, self._rf, self._rf_int, y_train)
        if status < 0:
            name, value = ("x", x) if status == -1 else ("y", y)
            raise ValueError(f"LWPR.update: {name} must be finite, got {value!r}")
        if status >= self._capacity:
            # At most one RF per output is created per update: keep one free slot for the next call.
            self._grow(2 * self._capacity)
        return y_train

    # -------------------------------------------------------------- prediction
    def _predict(self, x: Any, cutoff: Any, with_conf: bool, method: str):
        if self._ipar[_SAMPLES] == 0:
            raise ValueError(f"LWPR.{method}: the model is untrained (no update() yet)")
        if type(cutoff) is float and cutoff >= 0.0:
            c = cutoff
        else:
            c = _scalar(cutoff, f"{method}: cutoff")
            if c < 0.0:
                raise ValueError(f"LWPR.{method}: cutoff must be non-negative, got {cutoff!r}")
        n = self._n_in
        if type(x) is np.ndarray and x.dtype is _FLOAT64 and x.shape == (n,):
            # One point, the common case: no reshaping on the way in or out.
            x = x if x.flags.c_contiguous else np.ascontiguousarray(x)
            y = np.empty(self._n_out)
            conf = np.empty(self._n_out) if with_conf else y
            if _predict_one_kernel(x, c, self._model, self._ipar, self._rf, self._rf_int, y, conf, with_conf) >= 0:
                raise ValueError(f"LWPR.{method}: x must be finite, got {x!r}")
            return (y, conf) if with_conf else y
        a = x if type(x) is np.ndarray and x.dtype == np.float64 else _as_float_array(x, f"LWPR.{method}: x")
        single = True
        if a.shape == (n,) or (a.ndim == 0 and n == 1):
            X = a.reshape(1, n)
        elif a.ndim == 2 and a.shape[1] == n:
            X = a
            single = False
        else:
            raise ValueError(f"LWPR.{method}: x must have shape ({n},) or (m, {n}), got shape {a.shape}")
        X = np.ascontiguousarray(X)
        Y = np.empty((X.shape[0], self._n_out))
        conf = np.empty((X.shape[0], self._n_out)) if with_conf else Y
        bad = _predict_kernel(X, c, self._model, self._ipar, self._rf, self._rf_int, Y, conf, with_conf)
        if bad >= 0:
            raise ValueError(f"LWPR.{method}: x must be finite, got {X[bad]!r}")
        if single:
            return (Y[0], conf[0]) if with_conf else Y[0]
        return (Y, conf) if with_conf else Y

    def predict(self, x: Any, cutoff: float = 0.001) -> np.ndarray:
        """Prediction at x (LWPR.md "predict(x, cutoff=0.001)").

        x of shape (n_in,) gives shape (n_out,); x of shape (m, n_in) gives (m, n_out). Only trustworthy
        RFs activated above ``cutoff`` contribute; where none does, the prediction is 0.
        """
        return self._predict(x, cutoff, False, "predict")

    def predict_conf(self, x: Any, cutoff: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
        """Prediction and its confidence bound (LWPR.md "predict", Confidence); the bound is 1e20·norm_out
        where no RF is active."""
        return self._predict(x, cutoff, True, "predict_conf")

    # ------------------------------------------------------------- inspection
    def receptive_field(self, dim: int, index: int) -> dict[str, Any]:
        """State of RF ``index`` of output ``dim`` (copies), keyed by the library's field names."""
        if not (isinstance(dim, (int, np.integer)) and 0 <= dim < self._n_out):
            raise ValueError(f"LWPR.receptive_field: dim must be in [0, {self._n_out}), got {dim!r}")
        num = int(self._counts[dim, _NUM_RFS])
        if not (isinstance(index, (int, np.integer)) and 0 <= index < num):
            raise ValueError(f"LWPR.receptive_field: index must be in [0, {num}), got {index!r}")
        o, k = int(dim), int(index)
        R = int(self._ints[o, k, _NREG])
        v, m, p, r, s = self._vec[o, k], self._mat[o, k], self._proj[o, k], self._reg[o, k], self._scal[o, k]
        return {
            "c": v[_C].copy(),
            "mean_x": v[_MEAN_X].copy(),
            "var_x": v[_VAR_X].copy(),
            "D": m[_D].copy(),
            "M": m[_M].copy(),
            "alpha": m[_ALPHA].copy(),
            "b": m[_B].copy(),
            "h": m[_HMETA].copy(),
            "U": p[_U, :R].copy(),
            "P": p[_P, :R].copy(),
            "SXresYres": p[_SXY, :R].copy(),
            "SSXres": p[_SSX, :R].copy(),
            "beta": r[_BETA, :R].copy(),
            "SSs2": r[_SSS2, :R].copy(),
            "SSYres": r[_SSY, :R].copy(),
            "sum_w": r[_SUM_W, :R].copy(),
            "n_data": r[_N_DATA, :R].copy(),
            "lambda": r[_LAMBDA, :R].copy(),
            "sum_e_cv2": r[_SUM_ECV2, :R].copy(),
            "H": r[_H, :R].copy(),
            "r": r[_R, :R].copy(),
            "s": r[_S, :R].copy(),
            "beta0": float(s[_BETA0]),
            "sum_e2": float(s[_SUM_E2]),
            "SSp": float(s[_SSP]),
            "w": float(s[_W]),
            "n_reg": R,
            "trustworthy": bool(self._ints[o, k, _TRUST]),
        }

    def copy(self) -> LWPR:
        """An independent copy of the model (parameters and every receptive field)."""
        twin = object.__new__(LWPR)
        twin.__setstate__(
            {
                key: (value.copy() if isinstance(value, np.ndarray) else value)
                for key, value in self.__getstate__().items()
            }
        )
        return twin

    def __getstate__(self) -> dict[str, Any]:
        # The flat buffers only: pickled views would come back as arrays of their own.
        return {key: value for key, value in self.__dict__.items() if key not in _VIEWS}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind()

    def __repr__(self) -> str:
        return f"LWPR(n_in={self._n_in}, n_out={self._n_out}, n_data={self.n_data}, num_rfs={self.num_rfs.tolist()})"

    # ------------------------------------------------------------ save / load
    def save(self, path: str | os.PathLike) -> None:
        """Write the model to ``path`` (a versioned ``.npz``; written to a temporary file, then renamed)."""
        used = max(1, int(self._counts[:, _NUM_RFS].max()))
        fields: dict[str, np.ndarray] = {
            "format": np.array(_FORMAT_NAME),
            "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
            "n_in": np.array(self._n_in, dtype=np.int64),
            "n_out": np.array(self._n_out, dtype=np.int64),
            "n_data": np.array(self.n_data, dtype=np.int64),
            "kernel": np.array(self.kernel),
            "init_D": self._init[_INIT_D],
            "init_M": self._init[_INIT_M],
            "init_alpha": self._init[_INIT_ALPHA],
            "norm_in": self._norm_in,
            "norm_out": self._norm_out,
            "mean_x": self._xstats[0],
            "var_x": self._xstats[1],
            "counts": self._counts,
        }
        for index, name in enumerate(_FLOAT_PARAMS):
            fields[name] = np.array(self._fpar[index])
        for index, name in enumerate(_BOOL_PARAMS):
            fields[name] = np.array(bool(self._ipar[index]))
        for name in _RF_ARRAYS:
            fields["rf_" + name] = getattr(self, "_" + name)[:, :used]
        save_npz_atomically(path, fields)

    @classmethod
    def load(cls, path: str | os.PathLike) -> LWPR:
        """Read a model written by :meth:`save`. A truncated or foreign file, another format version, a
        missing field, a field of the wrong type, shape or range, or sizes beyond ``MAX_INPUTS``,
        ``MAX_OUTPUTS`` or ``MAX_INITIAL_BYTES`` raise ValueError naming the file and the field; every field is
        checked before the model is allocated. A missing file raises FileNotFoundError, a path that is not a
        str or os.PathLike TypeError."""
        file = _checked_path(path)
        data = load_npz(file, "an LWPR model file")
        where = f"LWPR model file {file!r}"
        kinds = {"f": "real numbers", "i": "integers", "iu": "integers", "b": "a bool", "U": "a string"}

        def need(key: str, kind: str, shape: tuple | None = None) -> np.ndarray:
            """The field `key`, checked: present, of dtype kind `kind` ("f" also takes integers), of `shape`
            (if given), finite if numeric."""
            if key not in data:
                raise ValueError(f"{where} lacks the field {key!r}")
            array = data[key]
            accepted = "fiu" if kind == "f" else kind
            if array.dtype.kind not in accepted:
                raise ValueError(
                    f"{where}: field {key!r} = {_short_repr(array)} has dtype {array.dtype}; expected {kinds[kind]}"
                )
            if shape is not None and array.shape != shape:
                raise ValueError(f"{where}: field {key!r} has shape {array.shape}, expected {shape}")
            if kind == "f" and not np.all(np.isfinite(array)):
                raise ValueError(f"{where}: field {key!r} holds non-finite values")
            return array

        def integer(key: str, low: int, high: int) -> int:
            value = int(need(key, "i" if key != "n_data" else "iu", ()))
            if not low <= value <= high:
                raise ValueError(f"{where}: field {key!r} = {value} must lie in [{low}, {high}]")
            return value

        fmt = data.get("format")
        if fmt is None:
            raise ValueError(f"{where} lacks the field 'format'")
        if fmt.shape != () or fmt.dtype.kind != "U" or str(fmt) != _FORMAT_NAME:
            raise ValueError(f"{where} is not an LWPR model file (format {_short_repr(fmt)})")
        version = int(need("format_version", "i", ()))
        if version != FORMAT_VERSION:
            raise ValueError(
                f"{where} has format version {version}; this version of robocup-mcl reads version {FORMAT_VERSION}"
            )
        # The header scalars, then every array against the sizes they give; nothing is allocated before all
        # of them passed.
        n = integer("n_in", 1, MAX_INPUTS)
        n_out = integer("n_out", 1, MAX_OUTPUTS)
        try:
            _check_size(n, n_out)
        except ValueError as exc:
            raise ValueError(f"{where}: fields 'n_in' and 'n_out': {exc}") from None
        n_data = integer("n_data", 0, np.iinfo(np.int64).max)
        floats = {name: float(need(name, "f", ())) for name in _FLOAT_PARAMS}
        bools = {name: bool(need(name, "b", ())) for name in _BOOL_PARAMS}
        kernel = str(need("kernel", "U", ()))
        square = {key: need(key, "f", (n, n)) for key in ("init_D", "init_M", "init_alpha")}
        norm_in = need("norm_in", "f", (n,))
        norm_out = need("norm_out", "f", (n_out,))
        xstats = [need(key, "f", (n,)) for key in ("mean_x", "var_x")]
        counts = need("counts", "i", (n_out, 2))
        vec = need("rf_vec", "f")
        if vec.ndim != 4:
            raise ValueError(
                f"{where}: field 'rf_vec' has shape {vec.shape}, expected (n_out, used, {_N_VEC}, "
                f"{n}) with n_out = {n_out}"
            )
        used = vec.shape[1]
        expected = {
            "vec": (n_out, used, _N_VEC, n),
            "mat": (n_out, used, _N_MAT, n, n),
            "proj": (n_out, used, _N_PROJ, n, n),
            "reg": (n_out, used, _N_REG, n),
            "scal": (n_out, used, _N_SCAL),
            "ints": (n_out, used, _N_INTS),
        }
        arrays = {name: need("rf_" + name, "i" if name == "ints" else "f", shape) for name, shape in expected.items()}
        if counts.min() < 0 or counts[:, _NUM_RFS].max() > used:
            raise ValueError(f"{where}: field 'counts' = {_short_repr(counts.tolist())} does not fit {used} stored RFs")
        n_reg = arrays["ints"][..., _NREG]
        for o in range(n_out):
            live = n_reg[o, : counts[o, _NUM_RFS]]
            if live.size and (live.min() < 1 or live.max() > n):
                raise ValueError(
                    f"{where}: field 'rf_ints': an RF of output {o} has {live.min()}..{live.max()} "
                    f"projections, outside [1, {n}]"
                )
        try:
            model = cls(n, n_out)
            for name, value in floats.items():
                setattr(model, name, value)
            for name, value in bools.items():
                setattr(model, name, value)
            model.kernel = kernel
            model.init_D = square["init_D"]
            model._init[_INIT_M] = square["init_M"]
            model.init_alpha = square["init_alpha"]
            model.norm_in = norm_in
            model.norm_out = norm_out
        except ValueError as exc:
            raise ValueError(f"{where} is inconsistent: {exc}") from None
        for row, array in enumerate(xstats):
            model._xstats[row] = array
        model._ipar[_SAMPLES] = n_data
        capacity = max(cls._INITIAL_CAPACITY, 2 * used)
        model._allocate(capacity)
        for name, array in arrays.items():
            getattr(model, "_" + name)[:, :used] = array
        model._counts[:] = counts
        return model


#: Deflate cannot expand data by more than this factor: a zip member claiming more is damaged.
_MAX_DEFLATE_RATIO = 1032


def load_npz(path: str | bytes, what: str) -> dict[str, np.ndarray]:
    """Every array of an `.npz` file; a truncated, damaged or foreign file raises ValueError saying it is not
    `what` (a missing file stays FileNotFoundError).

    Each member's zip entry and ``.npy`` header are checked before its array is allocated: stored or deflated,
    not encrypted, no larger than the file can hold, no Python objects, and the header's shape and dtype
    exactly the size of the data. So no file makes this allocate more than the data it really holds.
    Members whose names do not end in ``.npy`` are skipped."""
    try:
        archive_size = os.path.getsize(path)
        with zipfile.ZipFile(os.fsdecode(path)) as archive:  # zipfile takes no bytes path
            arrays = {}
            for info in archive.infolist():
                if info.filename.endswith(".npy"):
                    arrays[info.filename[:-4]] = _read_npy(archive, info, archive_size)
            return arrays
    except FileNotFoundError:
        raise
    # zipfile raises NotImplementedError for an unknown compression method, RuntimeError for an encrypted
    # member, zlib.error and struct.error for damaged data; numpy raises ValueError for a bad header.
    except (
        zipfile.BadZipFile,
        zipfile.LargeZipFile,
        EOFError,
        OSError,
        ValueError,
        KeyError,
        NotImplementedError,
        RuntimeError,
        OverflowError,
        zlib.error,
        struct.error,
    ) as exc:
        raise ValueError(f"{path!r} is truncated or not {what}: {exc}") from None


def _read_npy(archive: zipfile.ZipFile, info: zipfile.ZipInfo, archive_size: int) -> np.ndarray:
    """The array of one ``.npy`` member, its sizes checked before it is allocated (see `load_npz`)."""
    name = info.filename
    if info.flag_bits & 0x1:
        raise ValueError(f"member {name!r} is encrypted")
    if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
        raise ValueError(
            f"member {name!r} uses compression method {info.compress_type}; only stored and deflated members are read"
        )
    ratio = 1 if info.compress_type == zipfile.ZIP_STORED else _MAX_DEFLATE_RATIO
    if info.compress_size > archive_size or info.file_size > ratio * info.compress_size:
        raise ValueError(
            f"member {name!r} claims {info.file_size} bytes from {info.compress_size} stored bytes, "
            f"in a file of {archive_size} bytes"
        )
    with archive.open(info) as member:
        version = np.lib.format.read_magic(member)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(member)
        elif version in ((2, 0), (3, 0)):
            shape, _, dtype = np.lib.format.read_array_header_2_0(member)
        else:
            raise ValueError(f"member {name!r} has .npy format version {version}")
        if dtype.hasobject:
            raise ValueError(f"member {name!r} holds Python objects")
        count = math.prod(shape)
        data_bytes = info.file_size - member.tell()
        if dtype.itemsize == 0 or count < 0 or count * dtype.itemsize != data_bytes:
            raise ValueError(
                f"member {name!r} declares shape {_short_repr(shape)} of {dtype} but holds {data_bytes} bytes of data"
            )
        member.seek(0)
        return np.lib.format.read_array(member, allow_pickle=False)


def save_npz_atomically(path: str | os.PathLike, fields: dict) -> None:
    """np.savez to a temporary file, then renamed: a reader never sees a half-written file."""
    path = os.fspath(path)
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **fields)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
