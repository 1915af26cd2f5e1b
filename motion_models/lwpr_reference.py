"""Plain NumPy reference implementation of LWPR, for testing and timing only.

This module spells out LWPR exactly as ``/work/shared/LWPR.md`` states it, one receptive field (RF) at a
time, with Python loops and small NumPy vectors. It is slow on purpose: it is the yardstick that the
numba kernels of :mod:`motion_models.lwpr` are tested against (same numbers to rounding) and timed
against (``demos/lwpr_cross.py`` reports the speed ratio). Use :class:`motion_models.lwpr.LWPR` in code.

    from motion_models.lwpr_reference import ReferenceLWPR

    ref = ReferenceLWPR(2, 1)
    ref.init_D = 50.0 * np.eye(2)
    ref.init_alpha = 250.0 * np.ones((2, 2))
    ref.update(np.array([0.1, 0.2]), np.array([1.0]))
    y = ref.predict(np.array([0.1, 0.2]))

Parameters are plain attributes with the library's names and defaults; no validation happens here.
Each RF is a dict whose keys are the field names of :meth:`motion_models.lwpr.LWPR.receptive_field`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["ReferenceLWPR"]


class ReferenceLWPR:
    """LWPR.md, section by section, in plain Python (see the module docstring)."""

    def __init__(self, n_in: int, n_out: int) -> None:
        self.n_in = int(n_in)
        self.n_out = int(n_out)
        # "Model and parameters": the library's defaults.
        self.init_D = 25.0 * np.eye(self.n_in)
        self.init_alpha = 50.0 * np.ones((self.n_in, self.n_in))
        self.diag_only = True
        self.update_D = True
        self.meta = False
        self.meta_rate = 250.0
        self.penalty = 1e-6
        self.w_gen = 0.1
        self.w_prune = 1.0
        self.init_lambda = 0.999
        self.final_lambda = 0.99999
        self.tau_lambda = 0.9999
        self.init_S2 = 1e-10
        self.add_threshold = 0.5
        self.kernel = "Gaussian"
        self.norm_in = np.ones(self.n_in)
        self.norm_out = np.ones(self.n_out)
        self.n_data = 0
        self.mean_x = np.zeros(self.n_in)
        self.var_x = np.zeros(self.n_in)
        self.rfs: list[list[dict]] = [[] for _ in range(self.n_out)]
        self.n_pruned = [0] * self.n_out

    @property
    def init_M(self) -> np.ndarray:
        # Upper-triangular M with D = M^T M ("Model and parameters").
        return np.linalg.cholesky(self.init_D).T.copy()

    @property
    def num_rfs(self) -> list[int]:
        return [len(rfs) for rfs in self.rfs]

    # ------------------------------------------------------------------ kernel
    def _activation(self, q: float) -> tuple[float, float, float]:
        """ "update(x, y)" step 1: activation w and its derivatives w_q, w_qq."""
        if self.kernel == "Gaussian":
            w = math.exp(-0.5 * q)
            return w, -0.5 * w, 0.25 * w
        a = 1.0 - 0.25 * q
        if a < 0.0:
            return 0.0, 0.0, 0.0
        return a * a, -0.5 * a, 0.125

    # ------------------------------------------------------------------ update
    def update(self, x, y) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64).reshape(self.n_in)
        y = np.asarray(y, dtype=np.float64).reshape(self.n_out)
        n_prev = float(self.n_data)
        self.n_data += 1
        inv = 1.0 / self.n_data
        self.mean_x = (self.mean_x * n_prev + x) * inv
        dev = x - self.mean_x
        self.var_x = (self.var_x * n_prev + dev * dev) * inv
        xn = x / self.norm_in
        yn = y / self.norm_out
        out = np.zeros(self.n_out)
        for dim in range(self.n_out):
            out[dim] = self._update_one(dim, xn, yn[dim]) * self.norm_out[dim]
        return out

    def _update_one(self, dim: int, xn: np.ndarray, yn: float) -> float:
        rfs = self.rfs[dim]
        w_max = w_sec = 0.0
        ind_max = ind_sec = -1
        sum_wy = sum_w = 0.0
        for k, rf in enumerate(rfs):
            dx = xn - rf["c"]
            q = float(dx @ rf["D"] @ dx)
            w, dwdq, ddwdqdq = self._activation(q)
            if w > w_sec:
                if w > w_max:
                    ind_sec, w_sec = ind_max, w_max
                    ind_max, w_max = k, w
                else:
                    ind_sec, w_sec = k, w
            if w > 0.001:
                yp_k = self._update_rf(rf, xn, yn, w, dwdq, ddwdqdq)
                if rf["trustworthy"]:
                    sum_wy += w * yp_k
                    sum_w += w
        prediction = sum_wy / sum_w if sum_w > 0.0 else 0.0

        # "update(x, y)" step 4: create or prune.
        if w_max <= self.w_gen:
            template = None
            if w_max > 0.1 * self.w_gen and rfs[ind_max]["trustworthy"]:
                template = rfs[ind_max]
            rfs.append(self._new_rf(xn, yn, template))
        elif w_sec > self.w_prune:
            tr_max = float(np.trace(rfs[ind_max]["D"]))
            tr_sec = float(np.trace(rfs[ind_sec]["D"]))
            prune = ind_max if tr_max < tr_sec else ind_sec
            last = rfs.pop()
            if prune < len(rfs):
                rfs[prune] = last
            self.n_pruned[dim] += 1
        return prediction

    def _new_rf(self, xn: np.ndarray, yn: float, template: dict | None) -> dict:
        n = self.n_in
        if template is None:
            n_reg = 2 if n > 1 else 1
            D, M, alpha, beta0 = self.init_D.copy(), self.init_M, self.init_alpha.copy(), yn
        else:
            n_reg = template["n_reg"]
            D, M, alpha = template["D"].copy(), template["M"].copy(), template["alpha"].copy()
            beta0 = template["beta0"]
        eye = np.eye(n)
        return {
            "c": xn.copy(),
            "D": D,
            "M": M,
            "alpha": alpha,
            "b": np.triu(np.log(alpha + 1e-10)),
            "h": np.zeros((n, n)),
            "mean_x": np.zeros(n),
            "var_x": np.zeros(n),
            "beta0": float(beta0),
            "n_reg": n_reg,
            "trustworthy": False,
            "U": eye[:n_reg].copy(),
            "P": eye[:n_reg].copy(),
            "SXresYres": np.zeros((n_reg, n)),
            "SSXres": np.zeros((n_reg, n)),
            "beta": np.zeros(n_reg),
            "SSs2": np.full(n_reg, self.init_S2),
            "SSYres": np.zeros(n_reg),
            "sum_w": np.full(n_reg, 1e-10),
            "n_data": np.full(n_reg, 1e-10),
            "lambda": np.full(n_reg, self.init_lambda),
            "sum_e_cv2": np.zeros(n_reg),
            "H": np.zeros(n_reg),
            "r": np.zeros(n_reg),
            "s": np.zeros(n_reg),
            "sum_e2": 0.0,
            "SSp": 0.0,
        }

    @staticmethod
    def _project(z: np.ndarray, U: np.ndarray, P: np.ndarray, n_reg: int) -> np.ndarray:
        """PLS projection s_j = u_j^T z_j, z_{j+1} = z_j - p_j s_j."""
        s = np.zeros(n_reg)
        res = z.copy()
        for j in range(n_reg):
            s[j] = float(np.dot(U[j], res))
            res = res - P[j] * s[j]
        return s

    def _update_rf(self, rf: dict, xn, yn, w, dwdq, ddwdqdq) -> float:
        """ "update(x, y)" step 2 for one activated RF; returns its prediction ŷ + β0."""
        n = self.n_in
        R = rf["n_reg"]
        lam = rf["lambda"]
        # Means, variances and β0.
        swl = rf["sum_w"][0] * lam[0]
        inv = 1.0 / (swl + w)
        rf["mean_x"] = (swl * rf["mean_x"] + w * xn) * inv
        z = xn - rf["mean_x"]
        rf["var_x"] = (swl * rf["var_x"] + w * z * z) * inv
        rf["beta0"] = (swl * rf["beta0"] + w * yn) * inv
        t = yn - rf["beta0"]

        # Project with the old U, P.
        s = np.zeros(R)
        zres = np.zeros((R, n))
        zres[0] = z
        for j in range(R):
            s[j] = float(np.dot(rf["U"][j], zres[j]))
            if j + 1 < R:
                zres[j + 1] = zres[j] - rf["P"][j] * s[j]
        yres = np.cumsum(rf["beta"] * s)
        rf["sum_w"] = rf["sum_w"] * lam + w
        e_cv = t - yres
        target = np.empty(R)
        target[0] = t
        target[1:] = e_cv[:-1]

        ws2_SSs2 = 0.0
        for j in range(R):
            rf["SXresYres"][j] = rf["SXresYres"][j] * (0.9 + 0.1 * lam[j]) + (w * target[j]) * zres[j]
            norm2 = float(np.sum(rf["SXresYres"][j] ** 2))
            if norm2 > 1e-24:
                rf["U"][j] = rf["SXresYres"][j] * (1.0 / math.sqrt(norm2))
            wsj = w * s[j]
            rf["SSs2"][j] = lam[j] * rf["SSs2"][j] + s[j] * wsj
            rf["SSYres"][j] = lam[j] * rf["SSYres"][j] + target[j] * wsj
            rf["SSXres"][j] = lam[j] * rf["SSXres"][j] + wsj * zres[j]
            inv_s2 = 1.0 / rf["SSs2"][j]
            rf["beta"][j] = rf["SSYres"][j] * inv_s2
            rf["P"][j] = rf["SSXres"][j] * inv_s2
            ws2_SSs2 += wsj * wsj * inv_s2
        rf["SSp"] = lam[R - 1] * rf["SSp"] + ws2_SSs2
        rf["s"] = s = self._project(z, rf["U"], rf["P"], R)

        if rf["n_data"][R - 1] > 2.0 * n:
            yp = float(np.sum(rf["beta"] * s))
            e_star = float(e_cv[R - 1])
        else:
            yp = float(np.sum(rf["beta"][: R - 1] * s[: R - 1]))
            e_star = float(e_cv[R - 2]) if R > 1 else 0.0
        e = t - yp
        if rf["n_data"][0] * (1.0 - lam[0]) > 0.1:
            rf["sum_e2"] = rf["sum_e2"] * lam[R - 1] + w * e * e
            rf["sum_e_cv2"] = rf["sum_e_cv2"] * lam + w * e_cv * e_cv
        if rf["n_data"][0] > 2.0 * n:
            rf["trustworthy"] = True
        yp_total = yp + rf["beta0"]

        if self.update_D:
            self._update_metric(rf, xn, w, dwdq, ddwdqdq, e_star, e)
        self._check_add_projection(rf)
        R = rf["n_reg"]
        rf["n_data"] = rf["n_data"] * rf["lambda"] + 1.0
        rf["lambda"] = self.tau_lambda * rf["lambda"] + self.final_lambda * (1.0 - self.tau_lambda)
        return yp_total

    def _update_metric(self, rf, xn, w, dwdq, ddwdqdq, e_star, e) -> None:
        """ "Metric update (per RF)"."""
        n = self.n_in
        R = rf["n_reg"]
        lam, s, SSs2 = rf["lambda"], rf["s"], rf["SSs2"]
        gamma = self.penalty / n
        ok = rf["n_data"] * (1.0 - lam[0]) > 0.1
        if not ok[0]:
            return
        e2 = e * e
        e_cv2 = e_star * e_star
        h = 0.0
        for i in range(R):
            if ok[i]:
                h += s[i] * s[i] / SSs2[i]
        h *= w
        W = rf["sum_w"][0]
        if R == 1:
            E = rf["sum_e_cv2"][0]
        elif rf["n_data"][R - 1] > 2 * n:
            E = rf["sum_e_cv2"][R - 1]
        else:
            E = rf["sum_e_cv2"][R - 2]
        T = rf["sum_e2"] / (E + 1e-10)
        T *= T
        T *= T
        T = min(T, 1.0)
        dJ1dw = -E / W + e_cv2
        Ps = np.zeros(R)
        Pse = np.zeros(R)
        for i in range(R):
            if ok[i]:
                Ps[i] = s[i] / SSs2[i]
                Pse[i] = e * Ps[i]
                dJ1dw -= 2.0 * Pse[i] * rf["H"][i] + 2.0 * Ps[i] * Ps[i] * rf["r"][i]
        dJ1dw /= W
        wW = w / W
        dx = xn - rf["c"]
        M, D = rf["M"], rf["D"]
        pen2 = 2.0 * gamma

        entries = [(i, i) for i in range(n)] if self.diag_only else [(a, b) for a in range(n) for b in range(a, n)]
        dwdM, dJ2dM, ddwdMdM, ddJ2dMdM = {}, {}, {}, {}
        for a, b in entries:
            if self.diag_only:
                aux = 2.0 * M[a, a]
                dqdM = dx[a] * dx[a] * aux
                dwdM[a, b] = dqdM * dwdq
                dJ2dM[a, b] = pen2 * D[a, a] * aux
                ddwdMdM[a, b] = ddwdqdq * dqdM * dqdM + 2.0 * dwdq * dx[a] * dx[a]
                ddJ2dMdM[a, b] = pen2 * (2.0 * D[a, a] + aux * aux)
            else:
                dq = sum_aux = sum_aux1 = 0.0
                for i in range(a, n):
                    dq += dx[i] * M[a, i]
                    sum_aux += D[i, b] * M[a, i]
                    sum_aux1 += (2.0 if i == b else 1.0) * M[a, i] * M[a, i]
                dqdM = dq * 2.0 * dx[b]
                dwdM[a, b] = dqdM * dwdq
                dJ2dM[a, b] = 2.0 * pen2 * sum_aux
                ddwdMdM[a, b] = ddwdqdq * dqdM * dqdM + 2.0 * dwdq * dx[b] * dx[b]
                ddJ2dMdM[a, b] = 2.0 * pen2 * (D[b, b] + sum_aux1)
        max_m = max(abs(M[a, b]) for a, b in entries)
        g = {ab: wW * dJ2dM[ab] + dwdM[ab] * dJ1dw for ab in entries}

        if self.meta:
            sPse = float(np.sum(s * Pse))
            ddJ1dwdw = 2.0 * (e2 * h / w - e_cv2 / W) + E / (W * W)
            for i in range(R):
                ddJ1dwdw += 4.0 * (Pse[i] / W + Ps[i] * sPse) * rf["H"][i]
            ddJ1dwdw /= W
            for ab in entries:
                G = wW * ddJ2dMdM[ab] + ddwdMdM[ab] * dJ1dw + dwdM[ab] * dwdM[ab] * ddJ1dwdw
                step = min(max(self.meta_rate * T * g[ab] * rf["h"][ab], -0.1), 0.1)
                b_new = min(max(rf["b"][ab] - step, -10.0), 10.0)
                rf["b"][ab] = b_new
                alpha = math.exp(b_new)
                rf["alpha"][ab] = alpha
                rf["h"][ab] = rf["h"][ab] * max(1.0 - alpha * G * T, 0.0) - alpha * T * g[ab]

        for ab in entries:
            delta = rf["alpha"][ab] * T * g[ab]
            if delta > 0.1 * max_m:
                rf["alpha"][ab] *= 0.5
            else:
                M[ab] -= delta
        if self.diag_only:
            for i in range(n):
                D[i, i] = M[i, i] * M[i, i]
        else:
            for j in range(n):
                for i in range(j, n):
                    D[i, j] = D[j, i] = float(np.dot(M[: j + 1, i], M[: j + 1, j]))

        for i in range(R):
            if ok[i]:
                rf["H"][i] = lam[i] * rf["H"][i] + (w / (1.0 - h)) * s[i] * e_star * T
                rf["r"][i] = lam[i] * rf["r"][i] + (w * w * e_cv2 / (1.0 - h)) * s[i] * s[i] * T

    def _check_add_projection(self, rf: dict) -> None:
        """ "Add a projection"."""
        n = self.n_in
        R = rf["n_reg"]
        if R >= n:
            return
        mse_r = rf["sum_e_cv2"][R - 1] / rf["sum_w"][R - 1] + 1e-10
        mse_r1 = rf["sum_e_cv2"][R - 2] / rf["sum_w"][R - 2] + 1e-10
        if (
            mse_r < self.add_threshold * mse_r1
            and rf["n_data"][R - 1] > 0.99 * rf["n_data"][0]
            and rf["n_data"][R - 1] * (1.0 - rf["lambda"][R - 1]) > 0.5
        ):
            unit = np.zeros((1, n))
            unit[0, R] = 1.0
            rf["U"] = np.vstack([rf["U"], unit])
            rf["P"] = np.vstack([rf["P"], unit])
            rf["SXresYres"] = np.vstack([rf["SXresYres"], np.zeros((1, n))])
            rf["SSXres"] = np.vstack([rf["SSXres"], np.zeros((1, n))])
            for key, value in (
                ("beta", 0.0),
                ("SSs2", self.init_S2),
                ("SSYres", 0.0),
                ("sum_w", 1e-10),
                ("n_data", 0.0),
                ("lambda", self.init_lambda),
                ("sum_e_cv2", 0.0),
                ("H", 0.0),
                ("r", 0.0),
                ("s", 0.0),
            ):
                rf[key] = np.append(rf[key], value)
            rf["n_reg"] = R + 1
            rf["SSp"] = 0.0

    # ----------------------------------------------------------------- predict
    def predict(self, x, cutoff: float = 0.001) -> np.ndarray:
        return self._predict(x, cutoff)[0]

    def predict_conf(self, x, cutoff: float = 0.001) -> tuple[np.ndarray, np.ndarray]:
        return self._predict(x, cutoff)

    def _predict(self, x, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
        """ "predict(x, cutoff=0.001)" with its confidence bound."""
        xn = np.asarray(x, dtype=np.float64).reshape(self.n_in) / self.norm_in
        y = np.zeros(self.n_out)
        conf = np.zeros(self.n_out)
        for dim, rfs in enumerate(self.rfs):
            sum_w = sum_wy = sum_wyy = sum_conf = 0.0
            for rf in rfs:
                dx = xn - rf["c"]
                w = self._activation(float(dx @ rf["D"] @ dx))[0]
                if not (w > cutoff and rf["trustworthy"]):
                    continue
                R = rf["n_reg"]
                if rf["n_data"][R - 1] <= 2 * self.n_in:
                    R -= 1
                s = self._project(xn - rf["mean_x"], rf["U"], rf["P"], R)
                y_k = rf["beta0"] + float(np.sum(s * rf["beta"][:R]))
                sigma2 = float(np.sum(s * s / rf["SSs2"][:R]))
                sigma2 = rf["sum_e_cv2"][R - 1] / (rf["sum_w"][R - 1] - rf["SSp"]) * (1.0 + w * sigma2)
                sum_w += w
                sum_wy += w * y_k
                sum_wyy += w * y_k * y_k
                sum_conf += w * sigma2
            if sum_w > 0.0:
                y[dim] = sum_wy / sum_w
                conf[dim] = math.sqrt(abs(sum_conf + sum_wyy - sum_wy * y[dim])) / sum_w
            else:
                conf[dim] = 1e20
        return y * self.norm_out, conf * self.norm_out
