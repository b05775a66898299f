/* Compiled fits of the ruler measurement (issue 22), part of the _ckernels module: the tip zones'
 * strip contrasts (_ruler_tips.contrasts) and blurred steps (_ruler_tips.fit_tip), and the frame's
 * robust correction (_ruler_correction.fit_correction). The same arithmetic as the numpy reference
 * in those modules (their sums and solves in another order: equal to some 1e-15 relative), which
 * stays the tested reference (tests/vision/test_ruler_kernels.py).
 *
 * Plain C on the buffer protocol, like _ckernels.c (built with it, -O3 -ffp-contract=off).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_ruler_common.h"
#include "_ruler_kernels.h"

/* The k-th smallest of a[0..n-1] (quickselect, median-of-three pivots); reorders a so that
 * a[0..k-1] <= a[k] <= a[k+1..n-1]. */
static double select_kth(double *a, Py_ssize_t n, Py_ssize_t k) {
    Py_ssize_t lo = 0, hi = n - 1;
    while (hi > lo) {
        const Py_ssize_t mid = lo + (hi - lo) / 2;
        double x = a[lo], y = a[mid], z = a[hi];
        const double pivot = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        Py_ssize_t i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) i++;
            while (a[j] > pivot) j--;
            if (i <= j) {
                const double t = a[i];
                a[i] = a[j];
                a[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    return a[k];
}

/* The median of a[0..n-1] (no NaN) as numpy's: the middle one, or the mean of the two middle ones;
 * reorders a. */
static double median_inplace(double *a, Py_ssize_t n) {
    const double upper = select_kth(a, n, n / 2);
    if (n % 2) return upper;
    double lower = a[0];
    for (Py_ssize_t i = 1; i < n / 2; i++)
        if (a[i] > lower) lower = a[i];
    return (lower + upper) / 2.0;
}

/* ruler_tip_contrasts(bins, strip, profile, noise_floor, out_contrast, out_t) -> None
 *
 * _ruler_tips.contrasts: bins (n, 6) float64, strip (n,) int64 in 0 .. k-1 (k = len(out_contrast)),
 * profile (n,) float64; per strip the least-squares background and contrast of the profile in the
 * bins' mean levels (weights n), twice: the second time without the bins more than 4 robust sigmas
 * (at least noise_floor) off the first fit. out_contrast (k,) gets the contrast (NaN where a strip
 * has fewer than 3 bins or a singular fit), out_t (k,) the strip's mean t (NaN when empty). Sums in
 * the bins' order, as numpy's bincount. */
PyObject *ruler_tip_contrasts(PyObject *self, PyObject *args) {
    PyObject *o_b, *o_s, *o_p, *o_c, *o_t;
    double floor_dn;
    if (!PyArg_ParseTuple(args, "OOOdOO", &o_b, &o_s, &o_p, &floor_dn, &o_c, &o_t)) return NULL;
    RBuf bb = {0}, sb = {0}, pb = {0}, cb = {0}, tb = {0};
    PyObject *result = NULL;
    double *work = NULL;
    if (rget(o_p, &pb, 'd', -1, 0, 0, "profile") < 0) goto done;
    const Py_ssize_t n = pb.view.len / 8;
    if (rget(o_b, &bb, 'd', n * 6, 0, 0, "bins") < 0 || rget(o_c, &cb, 'd', -1, 1, 0, "out_contrast") < 0)
        goto done;
    const Py_ssize_t k = cb.view.len / 8;
    if (rget(o_t, &tb, 'd', k, 1, 0, "out_t") < 0) goto done;
    if (PyObject_GetBuffer(o_s, &sb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) goto done;
    sb.held = 1;
    const char *sf = sb.view.format ? sb.view.format : "B";
    if (*sf == '<' || *sf == '=' || *sf == '@') sf++;
    if (sb.view.itemsize != 8 || sb.view.len != n * 8 || (*sf != 'q' && *sf != 'l')) {
        PyErr_SetString(PyExc_TypeError, "ruler_tip_contrasts: strip must be (n,) int64");
        goto done;
    }
    const double *b = (const double *)bb.view.buf, *prof = (const double *)pb.view.buf;
    const int64_t *strip = (const int64_t *)sb.view.buf;
    double *contrast = (double *)cb.view.buf, *tmean = (double *)tb.view.buf;
    for (Py_ssize_t i = 0; i < n; i++)
        if (strip[i] < 0 || strip[i] >= k) {
            PyErr_SetString(PyExc_ValueError, "ruler_tip_contrasts: strip out of range");
            goto done;
        }
    /* per strip: s0 s1 s2 r0 r1 count background; per bin: level weight residual; scratch */
    work = (double *)PyMem_Malloc(((size_t)k * 7 + (size_t)n * 4 + 1) * sizeof(double));
    if (!work) {
        PyErr_NoMemory();
        goto done;
    }
    double *s0 = work, *s1 = s0 + k, *s2 = s1 + k, *r0 = s2 + k, *r1 = r0 + k, *cnt = r1 + k, *bg = cnt + k;
    double *level = bg + k, *weight = level + n, *res = weight + n, *scratch = res + n;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double nn = b[i * 6];
        level[i] = b[i * 6 + 1] / (nn > 1.0 ? nn : 1.0);
        weight[i] = nn;
    }
    for (int round = 0; round < 2; round++) {
        memset(s0, 0, (size_t)k * 6 * sizeof(double));
        for (Py_ssize_t i = 0; i < n; i++) {
            const Py_ssize_t j = (Py_ssize_t)strip[i];
            const double w = weight[i], p = prof[i], wp = w * p, wl = w * level[i];
            s0[j] += w;
            s1[j] += wp;
            s2[j] += wp * p;
            r0[j] += wl;
            r1[j] += wl * p;
            cnt[j] += w > 0 ? 1.0 : 0.0;
        }
        for (Py_ssize_t j = 0; j < k; j++) {
            const double det = s0[j] * s2[j] - s1[j] * s1[j];
            const double ref = s0[j] * s2[j] > 1e-300 ? s0[j] * s2[j] : 1e-300;
            if (cnt[j] >= 3 && fabs(det) > 1e-12 * ref) {
                bg[j] = (s2[j] * r0[j] - s1[j] * r1[j]) / det;
                contrast[j] = (s0[j] * r1[j] - s1[j] * r0[j]) / det;
            } else {
                bg[j] = NAN;
                contrast[j] = NAN;
            }
        }
        Py_ssize_t m = 0;
        for (Py_ssize_t i = 0; i < n; i++) {
            const Py_ssize_t j = (Py_ssize_t)strip[i];
            res[i] = (level[i] - bg[j] - contrast[j] * prof[i]) * sqrt(b[i * 6]);
            if (b[i * 6] > 0 && isfinite(res[i])) scratch[m++] = fabs(res[i]);
        }
        double spread = m ? 1.4826 * median_inplace(scratch, m) : 0.0;
        if (!(spread > floor_dn)) spread = floor_dn;
        for (Py_ssize_t i = 0; i < n; i++) {
            const int ok = b[i * 6] > 0 && isfinite(res[i]);
            weight[i] = ok && fabs(res[i]) < 4.0 * spread ? b[i * 6] : 0.0;
        }
    }
    memset(s0, 0, (size_t)k * 2 * sizeof(double));
    for (Py_ssize_t i = 0; i < n; i++) {
        s0[strip[i]] += b[i * 6];
        s1[strip[i]] += b[i * 6 + 3];
    }
    for (Py_ssize_t j = 0; j < k; j++) tmean[j] = s1[j] / (s0[j] > 0 ? s0[j] : NAN);
    Py_INCREF(Py_None);
    result = Py_None;
done:
    PyMem_Free(work);
    rrelease(&bb);
    rrelease(&sb);
    rrelease(&pb);
    rrelease(&cb);
    rrelease(&tb);
    return result;
}

/* The blurred step of a tip zone at parameters p (t_e, sigma, plateau, slope): residuals r = m - model
 * and the Jacobian of the model (n x 4, row-major), as _ruler_tips.fit_tip's residual(). */
static void tip_model(const double *t, const double *m, Py_ssize_t n, const double *p, double sign, double *r,
                      double *jac) {
    const double inv_sqrt2pi = 0.3989422804014327;
    for (Py_ssize_t i = 0; i < n; i++) {
        const double z = sign * (p[0] - t[i]) / p[1];
        const double step = 0.5 * erfc(-z / 1.4142135623730951);
        const double dens = exp(-0.5 * z * z) * inv_sqrt2pi;
        const double level = p[2] + p[3] * (t[i] - p[0]);
        double *j = jac + i * 4;
        j[0] = level * dens * sign / p[1] - p[3] * step;
        j[1] = -level * dens * z / p[1];
        j[2] = step;
        j[3] = (t[i] - p[0]) * step;
        r[i] = m[i] - level * step;
    }
}

/* ruler_tip_fit(t, m, params, sign, blur) -> None
 *
 * _ruler_tips.fit_tip's Levenberg-Marquardt loop: the model (p0 + p3 (t - t_e)) Phi(sign (t_e - t) /
 * sigma) fitted to m at t (n >= 1 float64 each), from params (4 float64: t_e, sigma, plateau, slope),
 * which gets the result; sigma kept at least 0.1 blur. At most 30 steps, stopping when t_e moves by
 * less than 1e-6 or the damping passes 1e8. */
PyObject *ruler_tip_fit(PyObject *self, PyObject *args) {
    PyObject *o_t, *o_m, *o_p;
    double sign, blur;
    if (!PyArg_ParseTuple(args, "OOOdd", &o_t, &o_m, &o_p, &sign, &blur)) return NULL;
    RBuf tb = {0}, mb = {0}, pb = {0};
    PyObject *result = NULL;
    double *work = NULL;
    if (rget(o_t, &tb, 'd', -1, 0, 0, "t") < 0) goto done;
    const Py_ssize_t n = tb.view.len / 8;
    if (rget(o_m, &mb, 'd', n, 0, 0, "m") < 0 || rget(o_p, &pb, 'd', 4, 1, 0, "params") < 0) goto done;
    work = (double *)PyMem_Malloc((size_t)n * 10 * sizeof(double) + 1);
    if (!work) {
        PyErr_NoMemory();
        goto done;
    }
    const double *t = (const double *)tb.view.buf, *m = (const double *)mb.view.buf;
    double *params = (double *)pb.view.buf;
    double *r = work, *jac = r + n, *r_new = jac + 4 * n, *jac_new = r_new + n;
    tip_model(t, m, n, params, sign, r, jac);
    double cost = 0.0, damping = 1e-3;
    for (Py_ssize_t i = 0; i < n; i++) cost += r[i] * r[i];
    for (int it = 0; it < 30; it++) {
        double a[16], b[4];
        for (int u = 0; u < 4; u++) {
            for (int v = 0; v < 4; v++) {
                double acc = 0.0;
                for (Py_ssize_t i = 0; i < n; i++) acc += jac[i * 4 + u] * jac[i * 4 + v];
                a[u * 4 + v] = acc;
            }
            double acc = 0.0;
            for (Py_ssize_t i = 0; i < n; i++) acc += jac[i * 4 + u] * r[i];
            b[u] = acc;
        }
        for (int u = 0; u < 4; u++) a[u * 4 + u] += damping * (a[u * 4 + u] + 1e-300);
        if (solve_small(a, b, 4) != 0) break;
        double trial[4];
        for (int u = 0; u < 4; u++) trial[u] = params[u] + b[u];
        trial[1] = fabs(trial[1]) > 0.1 * blur ? fabs(trial[1]) : 0.1 * blur;
        tip_model(t, m, n, trial, sign, r_new, jac_new);
        double cost_new = 0.0;
        for (Py_ssize_t i = 0; i < n; i++) cost_new += r_new[i] * r_new[i];
        if (cost_new < cost) {
            memcpy(params, trial, sizeof(trial));
            double *swap = r;
            r = r_new;
            r_new = swap;
            swap = jac;
            jac = jac_new;
            jac_new = swap;
            cost = cost_new;
            damping *= 0.3;
            if (fabs(b[0]) < 1e-6) break;
        } else {
            damping *= 10.0;
            if (damping > 1e8) break;
        }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    PyMem_Free(work);
    rrelease(&tb);
    rrelease(&mb);
    rrelease(&pb);
    return result;
}

/* Invert the p x p matrix a (row-major) into inv by Gauss-Jordan elimination with partial
 * pivoting; a is destroyed. 0 on success, -1 when singular. */
static int invert_small(double *a, double *inv, int p) {
    for (int i = 0; i < p; i++)
        for (int j = 0; j < p; j++) inv[i * p + j] = i == j ? 1.0 : 0.0;
    for (int col = 0; col < p; col++) {
        int piv = col;
        for (int r = col + 1; r < p; r++)
            if (fabs(a[r * p + col]) > fabs(a[piv * p + col])) piv = r;
        if (a[piv * p + col] == 0.0 || !isfinite(a[piv * p + col])) return -1;
        if (piv != col)
            for (int j = 0; j < p; j++) {
                double tmp = a[col * p + j];
                a[col * p + j] = a[piv * p + j];
                a[piv * p + j] = tmp;
                tmp = inv[col * p + j];
                inv[col * p + j] = inv[piv * p + j];
                inv[piv * p + j] = tmp;
            }
        const double d = a[col * p + col];
        for (int j = 0; j < p; j++) {
            a[col * p + j] /= d;
            inv[col * p + j] /= d;
        }
        for (int r = 0; r < p; r++) {
            if (r == col) continue;
            const double f = a[r * p + col];
            if (f == 0.0) continue;
            for (int j = 0; j < p; j++) {
                a[r * p + j] -= f * a[col * p + j];
                inv[r * p + j] -= f * inv[col * p + j];
            }
        }
    }
    return 0;
}

/* ruler_correction(moments, delta, info, noise, perspective, tukey, rounds, out_e, out_cov,
 *                  out_residual) -> (s_centre, used, scale), or None when the normal matrix is singular
 *
 * _ruler_phase.fit_correction: the frame's correction (5 terms) fitted to the windows' phases
 * delta (W) at their moments (W, 5: n, mean s, mean t, var s, cov s t), weighted by info / noise^2,
 * the perspective terms held by a prior of standard deviation perspective, Tukey-robust (constant
 * tukey) over rounds rounds. out_e (5), out_cov (25: the covariance times scale^2), out_residual (W). */
PyObject *ruler_correction(PyObject *self, PyObject *args) {
    PyObject *o_m, *o_d, *o_i, *o_e, *o_c, *o_r;
    double noise, perspective, tukey;
    int rounds;
    if (!PyArg_ParseTuple(args, "OOOdddiOOO", &o_m, &o_d, &o_i, &noise, &perspective, &tukey, &rounds, &o_e, &o_c,
                          &o_r))
        return NULL;
    RBuf mb = {0}, db = {0}, ib = {0}, eb = {0}, cb = {0}, rb = {0};
    PyObject *result = NULL;
    double *work = NULL;
    if (rget(o_d, &db, 'd', -1, 0, 0, "delta") < 0) goto done;
    const Py_ssize_t nw = db.view.len / 8;
    if (rget(o_m, &mb, 'd', nw * 5, 0, 0, "moments") < 0 || rget(o_i, &ib, 'd', nw, 0, 0, "info") < 0 ||
        rget(o_e, &eb, 'd', 5, 1, 0, "out_e") < 0 || rget(o_c, &cb, 'd', 25, 1, 0, "out_cov") < 0 ||
        rget(o_r, &rb, 'd', nw, 1, 0, "out_residual") < 0)
        goto done;
    const double *mo = (const double *)mb.view.buf, *delta = (const double *)db.view.buf;
    const double *info = (const double *)ib.view.buf;
    double *e = (double *)eb.view.buf, *cov = (double *)cb.view.buf, *residual = (double *)rb.view.buf;
    work = (double *)PyMem_Malloc(((size_t)nw * 10 + 1) * sizeof(double));
    if (!work) {
        PyErr_NoMemory();
        goto done;
    }
    double *sigma = work, *robust = sigma + nw, *design = robust + nw, *scratch = design + 5 * nw;
    unsigned char any_good = 0;
    double sw = 0.0, sws = 0.0;
    for (Py_ssize_t i = 0; i < nw; i++) {
        const int good = mo[i * 5] > 0 && info[i] > 0;
        sigma[i] = noise / sqrt(good ? info[i] : 1.0);
        robust[i] = good ? 1.0 : 0.0;
        if (good) {
            const double w = 1.0 / (sigma[i] * sigma[i]);
            sw += w;
            sws += mo[i * 5 + 1] * w;
            any_good = 1;
        }
    }
    const double s_centre = any_good ? sws / sw : NAN;
    for (Py_ssize_t i = 0; i < nw; i++) {
        const double u = mo[i * 5 + 1] - s_centre, t = mo[i * 5 + 2];
        double *d = design + i * 5;
        d[0] = 1.0;
        d[1] = u;
        d[2] = t;
        d[3] = -(u * u + mo[i * 5 + 3]);
        d[4] = -(u * t + mo[i * 5 + 4]);
    }
    const double prior = 1.0 / (perspective * perspective);
    double scale = 1.0;
    memset(e, 0, 5 * sizeof(double));
    memset(cov, 0, 25 * sizeof(double));
    memset(residual, 0, (size_t)nw * sizeof(double));
    for (int round = 0; round < rounds; round++) {
        double a[25] = {0}, b[5] = {0};
        for (Py_ssize_t i = 0; i < nw; i++) {
            const double w = robust[i] / (sigma[i] * sigma[i]);
            if (w == 0.0) continue;
            const double *d = design + i * 5;
            for (int u = 0; u < 5; u++) {
                for (int v = u; v < 5; v++) a[u * 5 + v] += d[u] * (d[v] * w);
                b[u] += d[u] * (w * delta[i]);
            }
        }
        for (int u = 0; u < 5; u++)
            for (int v = 0; v < u; v++) a[u * 5 + v] = a[v * 5 + u];
        a[18] += prior;
        a[24] += prior;
        if (invert_small(a, cov, 5) != 0) {
            Py_INCREF(Py_None);
            result = Py_None;
            goto done;
        }
        for (int u = 0; u < 5; u++) {
            double acc = 0.0;
            for (int v = 0; v < 5; v++) acc += cov[u * 5 + v] * b[v];
            e[u] = acc;
        }
        Py_ssize_t used = 0, m = 0;
        for (Py_ssize_t i = 0; i < nw; i++) {
            const double *d = design + i * 5;
            double fit = 0.0;
            for (int u = 0; u < 5; u++) fit += d[u] * e[u];
            residual[i] = delta[i] - fit;
            if (robust[i] > 0) used++;
            if (mo[i * 5] > 0 && info[i] > 0) scratch[m++] = fabs(residual[i] / sigma[i]);
        }
        scale = 1.0;
        if (used && m) {
            const double spread = 1.4826 * median_inplace(scratch, m);
            if (spread > 1.0) scale = spread;
        }
        for (Py_ssize_t i = 0; i < nw; i++) {
            const double r = residual[i] / sigma[i] / (tukey * scale);
            const int good = mo[i * 5] > 0 && info[i] > 0;
            robust[i] = good && fabs(r) < 1 ? (1 - r * r) * (1 - r * r) : 0.0;
        }
    }
    Py_ssize_t used = 0;
    for (Py_ssize_t i = 0; i < nw; i++) used += robust[i] > 0;
    for (int k = 0; k < 25; k++) cov[k] *= scale * scale;
    result = Py_BuildValue("(dnd)", s_centre, used, scale);
done:
    PyMem_Free(work);
    rrelease(&mb);
    rrelease(&db);
    rrelease(&ib);
    rrelease(&eb);
    rrelease(&cb);
    rrelease(&rb);
    return result;
}
