/* Compiled kernels of the measurement core (issue 12): the hot loops of precise mode's fine stage and
 * of paper mode, element for element the same arithmetic as the numpy reference in the Python
 * modules (which stays the tested reference; station/vision/_kernels.py chooses).
 *
 * Plain C on the buffer protocol: no numpy headers, nothing but Python.h and libm. Every array comes
 * in C-contiguous, of the item size checked below; outputs are numpy arrays the caller allocates.
 * Built with -ffp-contract=off: no fused multiply-add, so that each operation rounds as numpy's does.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- buffers */

typedef struct {
    Py_buffer view;
    int held;
} Buf;

static void release(Buf *b) {
    if (b->held) {
        PyBuffer_Release(&b->view);
        b->held = 0;
    }
}

/* kind: 'd' float64, 'f' float32, 'q' 8-byte integer, 'B' uint8, '?' bool. n < 0: any length. */
static int get(PyObject *obj, Buf *b, char kind, Py_ssize_t n, int writable, const char *name) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) return -1;
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    int ok;
    switch (kind) {
        case 'd': ok = *f == 'd' && b->view.itemsize == 8; break;
        case 'f': ok = *f == 'f' && b->view.itemsize == 4; break;
        case 'q': ok = strchr("lqLQ", *f) != NULL && b->view.itemsize == 8; break;
        case 'B': ok = *f == 'B' && b->view.itemsize == 1; break;
        case '?': ok = *f == '?' && b->view.itemsize == 1; break;
        default: ok = 0;
    }
    Py_ssize_t len = b->view.itemsize ? b->view.len / b->view.itemsize : 0;
    if (!ok || (n >= 0 && len != n)) {
        PyErr_Format(PyExc_TypeError, "%s: expected %zd items of kind '%c', got format '%s' (%zd items)", name,
                     n, kind, b->view.format ? b->view.format : "B", len);
        release(b);
        return -1;
    }
    return 0;
}

static Py_ssize_t items(const Buf *b) { return b->view.len / b->view.itemsize; }

/* ---------------------------------------------------------------- selection (upper median) */

static void swap_d(double *a, double *b) {
    double t = *a;
    *a = *b;
    *b = t;
}

/* The k-th smallest of v[0..n) (v is reordered): Hoare's quickselect, median-of-three pivot. */
static double select_k(double *v, Py_ssize_t n, Py_ssize_t k) {
    Py_ssize_t lo = 0, hi = n - 1;
    while (hi > lo) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        if (v[mid] < v[lo]) swap_d(&v[mid], &v[lo]);
        if (v[hi] < v[lo]) swap_d(&v[hi], &v[lo]);
        if (v[hi] < v[mid]) swap_d(&v[hi], &v[mid]);
        double pivot = v[mid];
        Py_ssize_t i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot) i++;
            while (v[j] > pivot) j--;
            if (i <= j) {
                swap_d(&v[i], &v[j]);
                i++;
                j--;
            }
        }
        if (k <= j)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            return v[k];
    }
    return v[k];
}

/* ---------------------------------------------------------------- precise: edge profiles */

#define N_EDGES 4
static const int VERTICAL[N_EDGES] = {0, 0, 1, 1};
static const double POLARITY[N_EDGES] = {-1.0, 1.0, -1.0, 1.0};
#define MAX_WINDOW 64

/* profiles(img, along, owner, mu, half, impulse_dn, colcoef, yn, ramp, with_spread,
 *          out_index, out_across, out_strength, out_spread) -> kept
 *
 * _precise._profile_points for every profile: profile i (edge owner[i], column/row along[i]) in a
 * window of n = 2 half + 2 samples from floor(mu[i]) - half. Profiles whose window leaves the image
 * are dropped; the kept ones are written in order, out_index giving each one's input index.
 * img: 2-D uint8 or float32; colcoef: (deg+1, w) float64 and yn: (h,) float64, or None (no flat
 * field); ramp: (n,) float64. */
static PyObject *profiles(PyObject *self, PyObject *args) {
    PyObject *o_img, *o_along, *o_owner, *o_mu, *o_col, *o_yn, *o_ramp, *o_idx, *o_across, *o_str, *o_spr;
    int half, with_spread;
    double impulse;
    if (!PyArg_ParseTuple(args, "OOOOidOOOpOOOO", &o_img, &o_along, &o_owner, &o_mu, &half, &impulse, &o_col,
                          &o_yn, &o_ramp, &with_spread, &o_idx, &o_across, &o_str, &o_spr))
        return NULL;
    Buf img = {0}, along = {0}, owner = {0}, mu = {0}, col = {0}, yn = {0}, ramp = {0}, idx = {0}, across = {0},
        str = {0}, spr = {0};
    PyObject *result = NULL;
    const int n = 2 * half + 2;
    if (half < 1 || n > MAX_WINDOW) {
        PyErr_SetString(PyExc_ValueError, "profiles: window half-width out of range");
        return NULL;
    }
    if (PyObject_GetBuffer(o_img, &img.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    img.held = 1;
    const char *f = img.view.format ? img.view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    const int is_float = *f == 'f' && img.view.itemsize == 4;
    if (img.view.ndim != 2 || !(is_float || (*f == 'B' && img.view.itemsize == 1))) {
        PyErr_SetString(PyExc_TypeError, "profiles: img must be a 2-D uint8 or float32 array");
        goto done;
    }
    const Py_ssize_t h = img.view.shape[0], w = img.view.shape[1];
    if (get(o_along, &along, 'q', -1, 0, "along") < 0) goto done;
    const Py_ssize_t N = items(&along);
    if (get(o_owner, &owner, 'q', N, 0, "owner") < 0 || get(o_mu, &mu, 'd', N, 0, "mu") < 0 ||
        get(o_ramp, &ramp, 'd', n, 0, "ramp") < 0 || get(o_idx, &idx, 'q', N, 1, "out_index") < 0 ||
        get(o_across, &across, 'd', N, 1, "out_across") < 0 || get(o_str, &str, 'd', N, 1, "out_strength") < 0 ||
        get(o_spr, &spr, 'd', N, 1, "out_spread") < 0)
        goto done;
    const int flat = o_col != Py_None;
    Py_ssize_t deg = 0;
    if (flat) {
        if (get(o_col, &col, 'd', -1, 0, "colcoef") < 0 || get(o_yn, &yn, 'd', h, 0, "yn") < 0) goto done;
        if (items(&col) % w != 0 || items(&col) / w < 1) {
            PyErr_SetString(PyExc_ValueError, "profiles: colcoef must be (degree + 1, width)");
            goto done;
        }
        deg = items(&col) / w - 1;
    }
    const uint8_t *img8 = (const uint8_t *)img.view.buf;
    const float *img32 = (const float *)img.view.buf;
    const int64_t *al = (const int64_t *)along.view.buf, *ow = (const int64_t *)owner.view.buf;
    const double *m = (const double *)mu.view.buf, *cc = (const double *)col.view.buf,
                 *yv = (const double *)yn.view.buf, *rp = (const double *)ramp.view.buf;
    int64_t *oi = (int64_t *)idx.view.buf;
    double *oa = (double *)across.view.buf, *os = (double *)str.view.buf, *osp = (double *)spr.view.buf;
    Py_ssize_t kept = 0;
    double s[MAX_WINDOW], med[MAX_WINDOW], d[MAX_WINDOW];
    for (Py_ssize_t i = 0; i < N; i++) {
        const int64_t e = ow[i];
        if (e < 0 || e >= N_EDGES) {
            PyErr_SetString(PyExc_ValueError, "profiles: owner out of range");
            goto done;
        }
        const int vert = VERTICAL[e];
        const double fl = floor(m[i]);
        const int64_t base = (int64_t)fl - half;
        const int64_t a = al[i];
        const Py_ssize_t across_size = vert ? w : h, along_size = vert ? h : w;
        if (base < 0 || base + n - 1 >= across_size || a < 0 || a >= along_size) continue;
        const Py_ssize_t start = vert ? a * w + base : base * w + a;
        const Py_ssize_t stride = vert ? 1 : w;
        for (int k = 0; k < n; k++) {
            const Py_ssize_t p = start + k * stride;
            s[k] = is_float ? (double)img32[p] : (double)img8[p];
        }
        if (flat) {
            /* the illumination at the window's two ends (Horner in y with the column's coefficients),
             * linear between them */
            double v[2];
            for (int end = 0; end < 2; end++) {
                const int64_t pos = base + (end ? n - 1 : 0);
                const int64_t x = vert ? pos : a, y = vert ? a : pos;
                double value = cc[deg * w + x];
                for (Py_ssize_t j = deg - 1; j >= 0; j--) value = value * yv[y] + cc[j * w + x];
                v[end] = value;
            }
            const double dv = v[1] - v[0];
            for (int k = 0; k < n; k++) s[k] /= v[0] + dv * rp[k];
        }
        /* isolated impulses: a sample farther than impulse_dn from its 3-median takes the median */
        for (int k = 1; k < n - 1; k++) {
            const double x0 = s[k - 1], x1 = s[k], x2 = s[k + 1];
            const double lo = x0 < x1 ? x0 : x1, hi = x0 < x1 ? x1 : x0;
            const double t = hi < x2 ? hi : x2;
            med[k] = lo > t ? lo : t;
        }
        for (int k = 1; k < n - 1; k++)
            if (fabs(s[k] - med[k]) > impulse) s[k] = med[k];
        for (int k = 0; k < n - 1; k++) d[k] = s[k + 1] - s[k];
        const double frac = m[i] - fl;
        d[0] *= 1.0 - frac;
        d[n - 2] *= frac;
        double m0 = 0.0, m1 = 0.0;
        for (int k = 0; k < n - 1; k++) {
            m0 += d[k];
            m1 += ((double)k + 0.5) * d[k];
        }
        const double strength = m0 * POLARITY[e];
        const double safe = strength > 0 ? m0 : 1.0;
        const double rel = m1 / safe;
        double spread = NAN;
        if (with_spread) {
            spread = 0.0;
            for (int k = 0; k < n - 1; k++) {
                const double dp = ((double)k + 0.5) - rel;
                spread += d[k] * (dp * dp);
            }
            spread /= safe;
        }
        oi[kept] = i;
        oa[kept] = (double)base + rel;
        os[kept] = strength;
        osp[kept] = spread;
        kept++;
    }
    result = PyLong_FromSsize_t(kept);
done:
    release(&img);
    release(&along);
    release(&owner);
    release(&mu);
    release(&col);
    release(&yn);
    release(&ramp);
    release(&idx);
    release(&across);
    release(&str);
    release(&spr);
    return result;
}

/* ---------------------------------------------------------------- precise: the four lines */

/* Per edge, the upper median of values[i] over the selected i of that edge (owner grouped):
 * sorted[count / 2]; inf for an empty group. */
static void grouped_median(const double *values, const uint8_t *sel, const Py_ssize_t *first,
                           const Py_ssize_t *count, double *work, double *out) {
    for (int e = 0; e < N_EDGES; e++) {
        Py_ssize_t c = 0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++)
            if (!sel || sel[i]) work[c++] = values[i];
        out[e] = c ? select_k(work, c, c / 2) : INFINITY;
    }
}

static Py_ssize_t grouped_count(const uint8_t *sel, Py_ssize_t first, Py_ssize_t count) {
    Py_ssize_t c = 0;
    for (Py_ssize_t i = first; i < first + count; i++) c += sel[i];
    return c;
}

/* total least squares per edge through the selected points: a x + b y = c */
static void tls(const double *x, const double *y, const uint8_t *sel, const Py_ssize_t *first,
                const Py_ssize_t *count, double *la, double *lb, double *lc) {
    for (int e = 0; e < N_EDGES; e++) {
        double n = 0.0, sx = 0.0, sy = 0.0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++)
            if (sel[i]) {
                n += 1.0;
                sx += x[i];
                sy += y[i];
            }
        if (n < 1.0) n = 1.0;
        const double mx = sx / n, my = sy / n;
        double sxx = 0.0, syy = 0.0, sxy = 0.0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++)
            if (sel[i]) {
                const double dx = x[i] - mx, dy = y[i] - my;
                sxx += dx * dx;
                syy += dy * dy;
                sxy += dx * dy;
            }
        const double phi = 0.5 * atan2(2.0 * sxy, sxx - syy);
        const double nx = -sin(phi), ny = cos(phi);
        la[e] = nx;
        lb[e] = ny;
        lc[e] = nx * mx + ny * my;
    }
}

/* fit(owner, along, across, strength, spread|None, slope, intercept, half, last, min_edge_points,
 *     min_contrast_dn, min_contrast_fraction, outlier_sigma, residual_limit, out_inliers, out_stats)
 *   -> (stage tuple, spread or None)
 *
 * _precise._fit_edges's arithmetic for all four edges. out_stats (9, 4) float64 receives rows:
 * counts, contrast, n_good, n_in, rms, a, b, c, (unused); out_inliers (N,) bool the final inliers.
 * stage[e]: 0 found, else the first test the edge failed (1 too few profiles, 2 contrast, 3 too few
 * good profiles, 4 not on a line (robust), 5 rms over the limit). */
static PyObject *fit(PyObject *self, PyObject *args) {
    PyObject *o_owner, *o_t, *o_a, *o_str, *o_spr, *o_slope, *o_icpt, *o_in, *o_stats;
    int half, last, min_points;
    double min_contrast, min_fraction, outlier_sigma, limit;
    if (!PyArg_ParseTuple(args, "OOOOOOOipiddddOO", &o_owner, &o_t, &o_a, &o_str, &o_spr, &o_slope, &o_icpt,
                          &half, &last, &min_points, &min_contrast, &min_fraction, &outlier_sigma, &limit,
                          &o_in, &o_stats))
        return NULL;
    Buf owner = {0}, tb = {0}, ab = {0}, strb = {0}, sprb = {0}, slb = {0}, icb = {0}, inb = {0}, stb = {0};
    PyObject *result = NULL;
    double *x = NULL, *y = NULL, *resid = NULL, *dev = NULL, *work = NULL;
    uint8_t *good = NULL;
    if (get(o_owner, &owner, 'q', -1, 0, "owner") < 0) return NULL;
    const Py_ssize_t N = items(&owner);
    if (get(o_t, &tb, 'd', N, 0, "along") < 0 || get(o_a, &ab, 'd', N, 0, "across") < 0 ||
        get(o_str, &strb, 'd', N, 0, "strength") < 0 || get(o_slope, &slb, 'd', N_EDGES, 0, "slope") < 0 ||
        get(o_icpt, &icb, 'd', N_EDGES, 0, "intercept") < 0 || get(o_in, &inb, '?', N, 1, "out_inliers") < 0 ||
        get(o_stats, &stb, 'd', 9 * N_EDGES, 1, "out_stats") < 0)
        goto done;
    const int has_spread = o_spr != Py_None;
    if (has_spread && get(o_spr, &sprb, 'd', N, 0, "spread") < 0) goto done;
    const int64_t *ow = (const int64_t *)owner.view.buf;
    const double *t = (const double *)tb.view.buf, *a = (const double *)ab.view.buf,
                 *strength = (const double *)strb.view.buf, *spr = (const double *)sprb.view.buf,
                 *slope = (const double *)slb.view.buf, *icpt = (const double *)icb.view.buf;
    uint8_t *inl = (uint8_t *)inb.view.buf;
    double *stats = (double *)stb.view.buf;
    Py_ssize_t first[N_EDGES], count[N_EDGES];
    for (int e = 0; e < N_EDGES; e++) count[e] = 0;
    for (Py_ssize_t i = 0; i < N; i++) {
        if (ow[i] < 0 || ow[i] >= N_EDGES || (i > 0 && ow[i] < ow[i - 1])) {
            PyErr_SetString(PyExc_ValueError, "fit: owner must be grouped edge indices 0-3");
            goto done;
        }
        count[ow[i]]++;
    }
    first[0] = 0;
    for (int e = 1; e < N_EDGES; e++) first[e] = first[e - 1] + count[e - 1];
    const Py_ssize_t alloc = N > 0 ? N : 1;
    x = malloc(alloc * sizeof(double));
    y = malloc(alloc * sizeof(double));
    resid = malloc(alloc * sizeof(double));
    dev = malloc(alloc * sizeof(double));
    work = malloc(alloc * sizeof(double));
    good = malloc(alloc);
    if (!x || !y || !resid || !dev || !work || !good) {
        PyErr_NoMemory();
        goto done;
    }
    int stage[N_EDGES] = {0, 0, 0, 0};
    double contrast[N_EDGES], n_good[N_EDGES], n_in[N_EDGES], rms[N_EDGES], la[N_EDGES], lb[N_EDGES],
        lc[N_EDGES], med[N_EDGES], sigma[N_EDGES];
    for (int e = 0; e < N_EDGES; e++)
        if (count[e] < min_points) stage[e] = 1;
    grouped_median(strength, NULL, first, count, work, contrast);
    for (int e = 0; e < N_EDGES; e++)
        if (!stage[e] && contrast[e] < min_contrast) stage[e] = 2;
    const double tol = last ? half / 2.0 : half - 2.0;
    for (int e = 0; e < N_EDGES; e++) {
        Py_ssize_t c = 0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++) {
            const int g = !stage[e] && strength[i] > min_fraction * contrast[e] &&
                          fabs(a[i] - (slope[e] * t[i] + icpt[e])) < tol;
            good[i] = (uint8_t)g;
            c += g;
            x[i] = VERTICAL[e] ? a[i] : t[i];
            y[i] = VERTICAL[e] ? t[i] : a[i];
        }
        n_good[e] = (double)c;
        if (!stage[e] && c < min_points) stage[e] = 3;
    }
    /* residuals from the previous models' normal forms */
    for (int e = 0; e < N_EDGES; e++) {
        const double norm = hypot(1.0, slope[e]);
        la[e] = (VERTICAL[e] ? 1.0 : -slope[e]) / norm;
        lb[e] = (VERTICAL[e] ? -slope[e] : 1.0) / norm;
        lc[e] = icpt[e] / norm;
    }
    for (int e = 0; e < N_EDGES; e++) {
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++) {
            inl[i] = good[i] && !stage[e];
            resid[i] = la[e] * x[i] + lb[e] * y[i] - lc[e];
        }
        n_in[e] = (double)grouped_count(inl, first[e], count[e]);
    }
    for (int round = 0; round < (last ? 2 : 1); round++) {
        grouped_median(resid, inl, first, count, work, med);
        for (Py_ssize_t i = 0; i < N; i++) dev[i] = fabs(resid[i] - med[ow[i]]);
        grouped_median(dev, inl, first, count, work, sigma);
        for (int e = 0; e < N_EDGES; e++) {
            sigma[e] = 1.4826 * sigma[e];
            if (!(sigma[e] >= 1e-3)) sigma[e] = sigma[e] != sigma[e] ? sigma[e] : 1e-3;
        }
        for (int e = 0; e < N_EDGES; e++) {
            const double band = outlier_sigma * sigma[e];
            for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++)
                inl[i] = good[i] && !stage[e] && dev[i] <= band;
            n_in[e] = (double)grouped_count(inl, first[e], count[e]);
            if (!stage[e] && n_in[e] < 3) stage[e] = 4;
            if (stage[e])
                for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++) inl[i] = 0;
        }
        tls(x, y, inl, first, count, la, lb, lc);
        for (Py_ssize_t i = 0; i < N; i++) resid[i] = la[ow[i]] * x[i] + lb[ow[i]] * y[i] - lc[ow[i]];
    }
    for (int e = 0; e < N_EDGES; e++) {
        const int flip = VERTICAL[e] ? la[e] < 0 : lb[e] < 0;
        const double sign = flip ? -1.0 : 1.0;
        la[e] *= sign;
        lb[e] *= sign;
        lc[e] *= sign;
        const double n = n_in[e] > 1.0 ? n_in[e] : 1.0;
        n_in[e] = n;
        double ss = 0.0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++)
            if (inl[i]) ss += resid[i] * resid[i];
        rms[e] = sqrt(ss / n);
        if (last && !stage[e] && rms[e] > limit) stage[e] = 5;
    }
    for (int e = 0; e < N_EDGES; e++) {
        stats[0 * N_EDGES + e] = (double)count[e];
        stats[1 * N_EDGES + e] = contrast[e];
        stats[2 * N_EDGES + e] = n_good[e];
        stats[3 * N_EDGES + e] = n_in[e];
        stats[4 * N_EDGES + e] = rms[e];
        stats[5 * N_EDGES + e] = la[e];
        stats[6 * N_EDGES + e] = lb[e];
        stats[7 * N_EDGES + e] = lc[e];
        stats[8 * N_EDGES + e] = 0.0;
    }
    PyObject *spread = Py_None;
    Py_INCREF(Py_None);
    int all_ok = 1;
    for (int e = 0; e < N_EDGES; e++) all_ok &= !stage[e];
    if (has_spread && all_ok) {
        double m4[N_EDGES];
        grouped_median(spr, good, first, count, work, m4);
        /* the upper median of the four: sorted[2] */
        for (int i = 1; i < N_EDGES; i++)
            for (int j = i; j > 0 && m4[j] < m4[j - 1]; j--) swap_d(&m4[j], &m4[j - 1]);
        Py_DECREF(Py_None);
        spread = PyFloat_FromDouble(m4[N_EDGES / 2]);
        if (!spread) goto done;
    }
    result = Py_BuildValue("(iiii)N", stage[0], stage[1], stage[2], stage[3], spread);
done:
    free(x);
    free(y);
    free(resid);
    free(dev);
    free(work);
    free(good);
    release(&owner);
    release(&tb);
    release(&ab);
    release(&strb);
    release(&sprb);
    release(&slb);
    release(&icb);
    release(&inb);
    release(&stb);
    return result;
}

/* ---------------------------------------------------------------- module */

static PyMethodDef methods[] = {
    {"profiles", profiles, METH_VARARGS, "Sub-pixel edge positions of precise mode's profiles."},
    {"fit", fit, METH_VARARGS, "Precise mode's robust line fits of the four edges."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_ckernels", NULL, -1, methods};

PyMODINIT_FUNC PyInit__ckernels(void) { return PyModule_Create(&module); }
