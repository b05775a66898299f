/* Compiled kernels of the measurement core (issue 12): the hot loops of precise mode's fine stage and
 * of paper mode, element for element the same arithmetic as the numpy reference in the Python
 * modules (which stays the tested reference; station/vision/_kernels.py chooses).
 *
 * Plain C on the buffer protocol: no numpy headers, nothing but Python.h and libm. Every array comes
 * in C-contiguous, of the item size checked below; outputs are numpy arrays the caller allocates.
 * Built with -O3 -ffp-contract=off: no fused multiply-add, so that each operation rounds as numpy's does.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "_ruler_kernels.h" /* the ruler measurement's kernels, in _ruler_kernels.c */

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

/* The image the profiles are read from: 8-bit or float32, row-major h x w. */
typedef struct {
    const uint8_t *u8;
    const float *f32;
    Py_ssize_t h, w;
} Image;

/* The flat field (_coarse.Illumination.pixel_tables): per column the coefficients of y^0..y^deg,
 * (deg+1, w), and each row's normalised y; cc == NULL: none. */
typedef struct {
    const double *cc, *yn;
    Py_ssize_t deg;
} Flat;

/* _precise._profile_points_numpy for profiles 0..N-1; returns how many were kept (written in order,
 * oi[k] the input index of the k-th kept one). ramp: n = 2 half + 2 interpolation weights. */
static Py_ssize_t profile_core(const Image *im, const Flat *fl, const int64_t *al, const int64_t *ow,
                               const double *m, Py_ssize_t N, int half, double impulse, const double *rp,
                               int with_spread, int64_t *oi, double *oa, double *os, double *osp) {
    const int n = 2 * half + 2;
    const Py_ssize_t h = im->h, w = im->w;
    Py_ssize_t kept = 0;
    double s[MAX_WINDOW], med[MAX_WINDOW], d[MAX_WINDOW];
    for (Py_ssize_t i = 0; i < N; i++) {
        const int64_t e = ow[i];
        const int vert = VERTICAL[e];
        const double flo = floor(m[i]);
        if (!(flo > -1e15 && flo < 1e15)) continue; /* numpy's cast of such values lands outside too */
        const int64_t base = (int64_t)flo - half;
        const int64_t a = al[i];
        const Py_ssize_t across_size = vert ? w : h, along_size = vert ? h : w;
        if (base < 0 || base + n - 1 >= across_size || a < 0 || a >= along_size) continue;
        const Py_ssize_t start = vert ? a * w + base : base * w + a;
        const Py_ssize_t stride = vert ? 1 : w;
        if (im->f32)
            for (int k = 0; k < n; k++) s[k] = (double)im->f32[start + k * stride];
        else
            for (int k = 0; k < n; k++) s[k] = (double)im->u8[start + k * stride];
        if (fl->cc) {
            /* the illumination at the window's two ends (Horner in y with the column's coefficients),
             * linear between them */
            double v[2];
            for (int end = 0; end < 2; end++) {
                const int64_t pos = base + (end ? n - 1 : 0);
                const int64_t x = vert ? pos : a, y = vert ? a : pos;
                double value = fl->cc[fl->deg * w + x];
                for (Py_ssize_t j = fl->deg - 1; j >= 0; j--) value = value * fl->yn[y] + fl->cc[j * w + x];
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
        const double frac = m[i] - flo;
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
    return kept;
}

/* np.linspace(0, 1, n) */
static void linspace01(int n, double *out) {
    const double step = 1.0 / (double)(n - 1);
    for (int k = 0; k < n; k++) out[k] = (double)k * step;
    out[n - 1] = 1.0;
}

static int get_image(PyObject *obj, Buf *b, Image *im) {
    if (PyObject_GetBuffer(obj, &b->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return -1;
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    const int is_float = *f == 'f' && b->view.itemsize == 4;
    if (b->view.ndim != 2 || !(is_float || (*f == 'B' && b->view.itemsize == 1))) {
        PyErr_SetString(PyExc_TypeError, "img must be a 2-D uint8 or float32 array");
        return -1;
    }
    im->h = b->view.shape[0];
    im->w = b->view.shape[1];
    im->u8 = is_float ? NULL : (const uint8_t *)b->view.buf;
    im->f32 = is_float ? (const float *)b->view.buf : NULL;
    return 0;
}

static int get_flat(PyObject *o_col, PyObject *o_yn, Buf *col, Buf *yn, const Image *im, Flat *fl) {
    fl->cc = fl->yn = NULL;
    fl->deg = 0;
    if (o_col == Py_None) return 0;
    if (get(o_col, col, 'd', -1, 0, "colcoef") < 0 || get(o_yn, yn, 'd', im->h, 0, "yn") < 0) return -1;
    if (items(col) % im->w != 0 || items(col) / im->w < 1) {
        PyErr_SetString(PyExc_ValueError, "colcoef must be (degree + 1, width)");
        return -1;
    }
    fl->deg = items(col) / im->w - 1;
    fl->cc = (const double *)col->view.buf;
    fl->yn = (const double *)yn->view.buf;
    return 0;
}

/* profiles(img, along, owner, mu, half, impulse_dn, colcoef, yn, with_spread,
 *          out_index, out_across, out_strength, out_spread) -> kept
 *
 * _precise._profile_points for every profile: profile i (edge owner[i], column/row along[i]) in a
 * window of n = 2 half + 2 samples from floor(mu[i]) - half. Profiles whose window leaves the image
 * are dropped; the kept ones are written in order, out_index giving each one's input index.
 * img: 2-D uint8 or float32; colcoef: (deg+1, w) float64 and yn: (h,) float64, or None (no flat
 * field). */
static PyObject *profiles(PyObject *self, PyObject *args) {
    PyObject *o_img, *o_along, *o_owner, *o_mu, *o_col, *o_yn, *o_idx, *o_across, *o_str, *o_spr;
    int half, with_spread;
    double impulse;
    if (!PyArg_ParseTuple(args, "OOOOidOOpOOOO", &o_img, &o_along, &o_owner, &o_mu, &half, &impulse, &o_col,
                          &o_yn, &with_spread, &o_idx, &o_across, &o_str, &o_spr))
        return NULL;
    Buf img = {0}, along = {0}, owner = {0}, mu = {0}, col = {0}, yn = {0}, idx = {0}, across = {0}, str = {0},
        spr = {0};
    PyObject *result = NULL;
    Image im;
    Flat fl;
    double ramp[MAX_WINDOW];
    if (half < 1 || 2 * half + 2 > MAX_WINDOW) {
        PyErr_SetString(PyExc_ValueError, "profiles: window half-width out of range");
        return NULL;
    }
    if (get_image(o_img, &img, &im) < 0 || get(o_along, &along, 'q', -1, 0, "along") < 0) goto done;
    const Py_ssize_t N = items(&along);
    if (get(o_owner, &owner, 'q', N, 0, "owner") < 0 || get(o_mu, &mu, 'd', N, 0, "mu") < 0 ||
        get(o_idx, &idx, 'q', N, 1, "out_index") < 0 || get(o_across, &across, 'd', N, 1, "out_across") < 0 ||
        get(o_str, &str, 'd', N, 1, "out_strength") < 0 || get(o_spr, &spr, 'd', N, 1, "out_spread") < 0 ||
        get_flat(o_col, o_yn, &col, &yn, &im, &fl) < 0)
        goto done;
    const int64_t *ow = (const int64_t *)owner.view.buf;
    for (Py_ssize_t i = 0; i < N; i++)
        if (ow[i] < 0 || ow[i] >= N_EDGES) {
            PyErr_SetString(PyExc_ValueError, "profiles: owner out of range");
            goto done;
        }
    linspace01(2 * half + 2, ramp);
    const Py_ssize_t kept =
        profile_core(&im, &fl, (const int64_t *)along.view.buf, ow, (const double *)mu.view.buf, N, half, impulse,
                     ramp, with_spread, (int64_t *)idx.view.buf, (double *)across.view.buf,
                     (double *)str.view.buf, (double *)spr.view.buf);
    result = PyLong_FromSsize_t(kept);
done:
    release(&img);
    release(&along);
    release(&owner);
    release(&mu);
    release(&col);
    release(&yn);
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

typedef struct {
    int min_points;
    double min_contrast, min_fraction, outlier_sigma, limit;
} FitParams;

/* Work space of fit_core for up to n profiles. */
typedef struct {
    double *x, *y, *resid, *dev, *work;
    uint8_t *good;
} FitWork;

/* _precise._fit_edges_numpy's arithmetic for all four edges (owner grouped by edge 0..3).
 * Writes inl (the final inliers), stats (9 x 4: counts, contrast, n_good, n_in, rms, a, b, c, -),
 * stage[e] (0 found, else the first test failed: 1 too few profiles, 2 contrast, 3 too few good
 * profiles, 4 not on a line (robust), 5 rms over the limit) and *spread (the median line spread when
 * spr is given and every edge passed, else NAN). x, y: the points in image coordinates. */
static void fit_core(const int64_t *ow, const double *t, const double *a, const double *strength,
                     const double *spr, Py_ssize_t N, const double *slope, const double *icpt, int half, int last,
                     const FitParams *fp, FitWork *ws, uint8_t *inl, double *stats, int *stage, double *spread) {
    double *x = ws->x, *y = ws->y, *resid = ws->resid, *dev = ws->dev, *work = ws->work;
    uint8_t *good = ws->good;
    Py_ssize_t first[N_EDGES], count[N_EDGES];
    for (int e = 0; e < N_EDGES; e++) count[e] = 0;
    for (Py_ssize_t i = 0; i < N; i++) count[ow[i]]++;
    first[0] = 0;
    for (int e = 1; e < N_EDGES; e++) first[e] = first[e - 1] + count[e - 1];
    double contrast[N_EDGES], n_good[N_EDGES], n_in[N_EDGES], rms[N_EDGES], la[N_EDGES], lb[N_EDGES],
        lc[N_EDGES], med[N_EDGES], sigma[N_EDGES];
    for (int e = 0; e < N_EDGES; e++) stage[e] = count[e] < fp->min_points ? 1 : 0;
    grouped_median(strength, NULL, first, count, work, contrast);
    for (int e = 0; e < N_EDGES; e++)
        if (!stage[e] && contrast[e] < fp->min_contrast) stage[e] = 2;
    const double tol = last ? half / 2.0 : half - 2.0;
    for (int e = 0; e < N_EDGES; e++) {
        Py_ssize_t c = 0;
        for (Py_ssize_t i = first[e]; i < first[e] + count[e]; i++) {
            const int g = !stage[e] && strength[i] > fp->min_fraction * contrast[e] &&
                          fabs(a[i] - (slope[e] * t[i] + icpt[e])) < tol;
            good[i] = (uint8_t)g;
            c += g;
            x[i] = VERTICAL[e] ? a[i] : t[i];
            y[i] = VERTICAL[e] ? t[i] : a[i];
        }
        n_good[e] = (double)c;
        if (!stage[e] && c < fp->min_points) stage[e] = 3;
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
            if (!(sigma[e] >= 1e-3) && sigma[e] == sigma[e]) sigma[e] = 1e-3; /* np.maximum keeps NaN */
        }
        for (int e = 0; e < N_EDGES; e++) {
            const double band = fp->outlier_sigma * sigma[e];
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
        if (last && !stage[e] && rms[e] > fp->limit) stage[e] = 5;
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
    *spread = NAN;
    int all_ok = 1;
    for (int e = 0; e < N_EDGES; e++) all_ok &= !stage[e];
    if (spr && all_ok) {
        double m4[N_EDGES];
        grouped_median(spr, good, first, count, work, m4);
        /* the upper median of the four: sorted[2] */
        for (int i = 1; i < N_EDGES; i++)
            for (int j = i; j > 0 && m4[j] < m4[j - 1]; j--) swap_d(&m4[j], &m4[j - 1]);
        *spread = m4[N_EDGES / 2];
    }
}

/* fine(img, slope, intercept, colcoef, yn, passes, window_px, window_sigmas, profile_step,
 *      corner_margin_px, impulse_dn, min_edge_points, min_contrast_dn, min_contrast_fraction,
 *      outlier_sigma, residual_limit_px, out_stats, out_points) -> (stages, last, n_points)
 *
 * _precise.precise_edges's passes after the coarse stage, all in one call: per pass the profile grid
 * without the crossing's corners, the profiles, the four fits, the new models and window. slope and
 * intercept: the initial models (4,), float64, updated in place. Stops at the first pass with a
 * failed edge: stages (4 ints) as fit_core's, last: whether that was the last pass. out_stats (9, 4)
 * as fit_core's; out_points (>= 2 (w + h), 2) float64 receives the last pass's inliers (x, y),
 * grouped by edge (stats row 3 the counts). window_px < 0: automatic. */
static PyObject *fine(PyObject *self, PyObject *args) {
    PyObject *o_img, *o_slope, *o_icpt, *o_col, *o_yn, *o_stats, *o_pts;
    int passes, window_px, step, min_points;
    double window_sigmas, margin, impulse, min_contrast, min_fraction, outlier_sigma, limit;
    if (!PyArg_ParseTuple(args, "OOOOOiididdiddddOO", &o_img, &o_slope, &o_icpt, &o_col, &o_yn, &passes,
                          &window_px, &window_sigmas, &step, &margin, &impulse, &min_points, &min_contrast,
                          &min_fraction, &outlier_sigma, &limit, &o_stats, &o_pts))
        return NULL;
    Buf img = {0}, slb = {0}, icb = {0}, col = {0}, yn = {0}, stb = {0}, ptb = {0};
    PyObject *result = NULL;
    Image im;
    Flat fl;
    int64_t *al = NULL, *ow = NULL, *idx = NULL, *kow = NULL;
    double *mu = NULL, *across = NULL, *str = NULL, *spr = NULL, *t = NULL, *kspr = NULL;
    uint8_t *inl = NULL;
    FitWork ws = {0};
    if (passes < 1 || step < 1 || (window_px >= 0 && (window_px < 1 || 2 * window_px + 2 > MAX_WINDOW))) {
        PyErr_SetString(PyExc_ValueError, "fine: passes, profile step or window out of range");
        return NULL;
    }
    if (get_image(o_img, &img, &im) < 0 || get(o_slope, &slb, 'd', N_EDGES, 1, "slope") < 0 ||
        get(o_icpt, &icb, 'd', N_EDGES, 1, "intercept") < 0 || get_flat(o_col, o_yn, &col, &yn, &im, &fl) < 0 ||
        get(o_stats, &stb, 'd', 9 * N_EDGES, 1, "out_stats") < 0 || get(o_pts, &ptb, 'd', -1, 1, "out_points") < 0)
        goto done;
    const Py_ssize_t h = im.h, w = im.w, cap = 2 * (w + h);
    if (items(&ptb) < 2 * cap) {
        PyErr_SetString(PyExc_ValueError, "fine: out_points must hold 2 (w + h) points");
        goto done;
    }
    double *slope = (double *)slb.view.buf, *icpt = (double *)icb.view.buf, *stats = (double *)stb.view.buf,
           *pts = (double *)ptb.view.buf;
    al = malloc(cap * sizeof(int64_t));
    ow = malloc(cap * sizeof(int64_t));
    idx = malloc(cap * sizeof(int64_t));
    kow = malloc(cap * sizeof(int64_t));
    mu = malloc(cap * sizeof(double));
    across = malloc(cap * sizeof(double));
    str = malloc(cap * sizeof(double));
    spr = malloc(cap * sizeof(double));
    t = malloc(cap * sizeof(double));
    kspr = malloc(cap * sizeof(double));
    inl = malloc(cap);
    ws.x = malloc(cap * sizeof(double));
    ws.y = malloc(cap * sizeof(double));
    ws.resid = malloc(cap * sizeof(double));
    ws.dev = malloc(cap * sizeof(double));
    ws.work = malloc(cap * sizeof(double));
    ws.good = malloc(cap);
    if (!al || !ow || !idx || !kow || !mu || !across || !str || !spr || !t || !kspr || !inl || !ws.x || !ws.y ||
        !ws.resid || !ws.dev || !ws.work || !ws.good) {
        PyErr_NoMemory();
        goto done;
    }
    const FitParams fp = {min_points, min_contrast, min_fraction, outlier_sigma, limit};
    /* the first pass steers from the coarse cross: a wide window */
    int half = window_px >= 0 ? window_px : 8;
    int stage[N_EDGES] = {0, 0, 0, 0}, last = 0;
    Py_ssize_t kept = 0;
    for (int pass = 0; pass < passes; pass++) {
        last = pass == passes - 1;
        /* _profile_grid: every step-th column (row) at least half + 2 px from the border */
        const int64_t border = half + 2, grid = last ? step : 8;
        /* _crossing_extent: per edge, the mean and half-range of the along coordinates of the four
         * vertices */
        double xs[2][2], ys[2][2];
        for (int i = 0; i < 2; i++)
            for (int j = 0; j < 2; j++) {
                const double sh = slope[i], ih = icpt[i], sv = slope[2 + j], iv = icpt[2 + j];
                xs[i][j] = (sv * ih + iv) / (1.0 - sv * sh);
                ys[i][j] = sh * xs[i][j] + ih;
            }
        double centre[N_EDGES], reach[N_EDGES];
        for (int e = 0; e < N_EDGES; e++) {
            const double *v = e < 2 ? &xs[0][0] : &ys[0][0];
            double lo = v[0], hi = v[0];
            for (int k = 1; k < 4; k++) {
                lo = v[k] < lo ? v[k] : lo;
                hi = v[k] > hi ? v[k] : hi;
            }
            centre[e] = (v[0] + ((v[1] + v[2]) + v[3])) / 4.0; /* numpy's order for a row of 4 */
            reach[e] = (hi - lo) / 2.0 + margin;
        }
        Py_ssize_t N = 0;
        for (int e = 0; e < N_EDGES; e++) {
            const Py_ssize_t size = VERTICAL[e] ? h : w;
            for (int64_t a = border; a < size - border; a += grid) {
                if (!(fabs((double)a - centre[e]) > reach[e])) continue; /* the rounded land corners */
                al[N] = a;
                ow[N] = e;
                mu[N] = slope[e] * (double)a + icpt[e];
                N++;
            }
        }
        double ramp[MAX_WINDOW];
        linspace01(2 * half + 2, ramp);
        kept = profile_core(&im, &fl, al, ow, mu, N, half, impulse, ramp, !last, idx, across, str, spr);
        for (Py_ssize_t k = 0; k < kept; k++) {
            kow[k] = ow[idx[k]];
            t[k] = (double)al[idx[k]];
        }
        double spread;
        fit_core(kow, t, across, str, last ? NULL : spr, kept, slope, icpt, half, last, &fp, &ws, inl, stats,
                 stage, &spread);
        if (stage[0] || stage[1] || stage[2] || stage[3]) break;
        for (int e = 0; e < N_EDGES; e++) {
            const double la = stats[5 * N_EDGES + e], lb = stats[6 * N_EDGES + e], lc = stats[7 * N_EDGES + e];
            slope[e] = VERTICAL[e] ? -lb / la : -la / lb;
            icpt[e] = VERTICAL[e] ? lc / la : lc / lb;
        }
        if (window_px < 0 && !isnan(spread)) {
            /* window_sigmas line-spread sigmas + 1 px (the spread includes the first difference's two
             * unit boxes: 2/12 px^2) */
            const double v = spread - 1.0 / 6.0;
            const double sigma = sqrt(v > 0.1 ? v : 0.1);
            double hw = ceil(window_sigmas * sigma) + 1.0;
            hw = hw < 3.0 ? 3.0 : (hw > 12.0 ? 12.0 : hw);
            half = (int)hw;
        }
    }
    Py_ssize_t n_points = 0;
    if (last && !(stage[0] || stage[1] || stage[2] || stage[3]))
        for (Py_ssize_t k = 0; k < kept; k++)
            if (inl[k]) {
                pts[2 * n_points] = ws.x[k];
                pts[2 * n_points + 1] = ws.y[k];
                n_points++;
            }
    result = Py_BuildValue("(iiii)in", stage[0], stage[1], stage[2], stage[3], last, n_points);
done:
    free(al);
    free(ow);
    free(idx);
    free(kow);
    free(mu);
    free(across);
    free(str);
    free(spr);
    free(t);
    free(kspr);
    free(inl);
    free(ws.x);
    free(ws.y);
    free(ws.resid);
    free(ws.dev);
    free(ws.work);
    free(ws.good);
    release(&img);
    release(&slb);
    release(&icb);
    release(&col);
    release(&yn);
    release(&stb);
    release(&ptb);
    return result;
}

/* ---------------------------------------------------------------- precise: the coarse projections */

/* project(small, shape_h, shape_w, scale, theta, out_u, out_v, out_counts, out_sums) -> (base_v, bins_v,
 *                                                                                    base_u, bins_u)
 *
 * _coarse.coarse_cross's projections of the reduced image (float32, (sh, sw)) along the two grooves:
 * per reduced pixel its full-resolution coordinates relative to the image centre (_centred_grid),
 * u along the horizontal groove and v along the vertical one (written to out_u, out_v: (sh, sw)
 * float64), then for v and for u the pixels binned by floor(coord / scale) - base (base: the
 * smallest), with each bin's count and sum of values: out_counts, out_sums (2, cap) float64, row 0
 * for v, row 1 for u, zero beyond each row's bins. */
static PyObject *project(PyObject *self, PyObject *args) {
    PyObject *o_small, *o_u, *o_v, *o_counts, *o_sums;
    Py_ssize_t h, w;
    int scale;
    double theta;
    if (!PyArg_ParseTuple(args, "OnnidOOOO", &o_small, &h, &w, &scale, &theta, &o_u, &o_v, &o_counts, &o_sums))
        return NULL;
    Buf sb = {0}, ub = {0}, vb = {0}, cb = {0}, smb = {0};
    PyObject *result = NULL;
    if (PyObject_GetBuffer(o_small, &sb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    sb.held = 1;
    const char *f = sb.view.format ? sb.view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    if (sb.view.ndim != 2 || *f != 'f' || sb.view.itemsize != 4 || scale < 1) {
        PyErr_SetString(PyExc_TypeError, "project: small must be a 2-D float32 array, scale >= 1");
        goto done;
    }
    const Py_ssize_t sh = sb.view.shape[0], sw = sb.view.shape[1], n = sh * sw;
    if (get(o_u, &ub, 'd', n, 1, "out_u") < 0 || get(o_v, &vb, 'd', n, 1, "out_v") < 0 ||
        get(o_counts, &cb, 'd', -1, 1, "out_counts") < 0 || get(o_sums, &smb, 'd', items(&cb), 1, "out_sums") < 0)
        goto done;
    const Py_ssize_t cap = items(&cb) / 2;
    const float *val = (const float *)sb.view.buf;
    double *u = (double *)ub.view.buf, *v = (double *)vb.view.buf, *counts = (double *)cb.view.buf,
           *sums = (double *)smb.view.buf;
    const double c = cos(theta), sn = sin(theta), s = (double)scale;
    /* x / s as x * (1 / s) where that is exact (s a power of two): a multiply instead of a divide */
    const int pow2 = (scale & (scale - 1)) == 0;
    const double inv_s = 1.0 / s;
    const double half_s = (double)(scale - 1) / 2.0, cx = (double)(w - 1) / 2.0, cy = (double)(h - 1) / 2.0;
    double vmin = INFINITY, umin = INFINITY;
    for (Py_ssize_t i = 0; i < sh; i++) {
        const double yf = (double)i * s + half_s - cy;
        for (Py_ssize_t j = 0; j < sw; j++) {
            const double xf = (double)j * s + half_s - cx;
            const double uu = xf * c + yf * sn, vv = -xf * sn + yf * c;
            u[i * sw + j] = uu;
            v[i * sw + j] = vv;
            const double qu = pow2 ? uu * inv_s : uu / s, qv = pow2 ? vv * inv_s : vv / s;
            umin = qu < umin ? qu : umin;
            vmin = qv < vmin ? qv : vmin;
        }
    }
    const double base[2] = {floor(vmin), floor(umin)};
    Py_ssize_t bins[2] = {0, 0};
    for (Py_ssize_t k = 0; k < 2 * cap; k++) counts[k] = sums[k] = 0.0;
    for (int g = 0; g < 2; g++) {
        const double *coord = g == 0 ? v : u;
        double *cn = counts + g * cap, *sm = sums + g * cap;
        for (Py_ssize_t k = 0; k < n; k++) {
            const double q = pow2 ? coord[k] * inv_s : coord[k] / s;
            const Py_ssize_t b = (Py_ssize_t)(q - base[g]); /* non-negative: truncation is floor */
            if (b < 0 || b >= cap) {
                PyErr_SetString(PyExc_ValueError, "project: out_counts too short for the bins");
                goto done;
            }
            cn[b] += 1.0;
            sm[b] += (double)val[k];
            if (b + 1 > bins[g]) bins[g] = b + 1;
        }
    }
    result = Py_BuildValue("dndn", base[0], bins[0], base[1], bins[1]);
done:
    release(&sb);
    release(&ub);
    release(&vb);
    release(&cb);
    release(&smb);
    return result;
}

/* ---------------------------------------------------------------- precise: the illumination fit */

#define MAX_TERMS 32

/* Least squares by the normal equations over the selected points (sel == NULL: all n), by
 * Cholesky; 0 when the normal matrix is not positive definite. P: (n, terms) row-major (point-major:
 * each point's update of the normal matrix is one vectorisable pass over independent sums). */
static int normal_solve(const double *P, Py_ssize_t terms, Py_ssize_t n, const double *val, const uint8_t *sel,
                        double *coef) {
    double M[MAX_TERMS * MAX_TERMS], r[MAX_TERMS], L[MAX_TERMS * MAX_TERMS];
    for (Py_ssize_t i = 0; i < terms * terms; i++) M[i] = 0.0;
    for (Py_ssize_t i = 0; i < terms; i++) r[i] = 0.0;
    for (Py_ssize_t k = 0; k < n; k++) {
        if (sel && !sel[k]) continue;
        const double *p = P + k * terms;
        const double vk = val[k];
        for (Py_ssize_t i = 0; i < terms; i++) {
            const double pi = p[i];
            double *row = M + i * terms;
            for (Py_ssize_t j = 0; j <= i; j++) row[j] += pi * p[j]; /* the lower triangle */
            r[i] += pi * vk;
        }
    }
    for (Py_ssize_t i = 0; i < terms; i++)
        for (Py_ssize_t j = i + 1; j < terms; j++) M[i * terms + j] = M[j * terms + i];
    for (Py_ssize_t i = 0; i < terms; i++)
        for (Py_ssize_t j = 0; j <= i; j++) {
            double acc = M[i * terms + j];
            for (Py_ssize_t k = 0; k < j; k++) acc -= L[i * terms + k] * L[j * terms + k];
            if (i == j) {
                if (!(acc > 0.0)) return 0;
                L[i * terms + i] = sqrt(acc);
            } else
                L[i * terms + j] = acc / L[j * terms + j];
        }
    double z[MAX_TERMS];
    for (Py_ssize_t i = 0; i < terms; i++) {
        double acc = r[i];
        for (Py_ssize_t k = 0; k < i; k++) acc -= L[i * terms + k] * z[k];
        z[i] = acc / L[i * terms + i];
    }
    for (Py_ssize_t i = terms - 1; i >= 0; i--) {
        double acc = z[i];
        for (Py_ssize_t k = i + 1; k < terms; k++) acc -= L[k * terms + i] * coef[k];
        coef[i] = acc / L[i * terms + i];
    }
    return 1;
}

/* illumination(small, land, basis, out_coef) -> 1 fitted, 0 none (too few lands, or the fit ran
 * wild), -1 singular (the caller's general solver decides)
 *
 * _coarse.fit_illumination: every fourth land pixel of the reduced image (float32 (sh, sw); land:
 * bool (sh, sw)), the polynomial terms of basis ((terms, sh*sw) float64) fitted by least squares,
 * refitted without the points beyond 3 robust sigmas (1.4826 MAD), normalised to mean 1 over the
 * points kept. */
static PyObject *illumination(PyObject *self, PyObject *args) {
    PyObject *o_small, *o_land, *o_basis, *o_coef;
    if (!PyArg_ParseTuple(args, "OOOO", &o_small, &o_land, &o_basis, &o_coef)) return NULL;
    Buf sb = {0}, lb = {0}, bb = {0}, cb = {0};
    PyObject *result = NULL;
    double *A = NULL, *val = NULL, *resid = NULL, *work = NULL;
    uint8_t *keep = NULL;
    if (get(o_small, &sb, 'f', -1, 0, "small") < 0) return NULL;
    const Py_ssize_t npx = items(&sb);
    if (get(o_land, &lb, '?', npx, 0, "land") < 0 || get(o_basis, &bb, 'd', -1, 0, "basis") < 0 ||
        get(o_coef, &cb, 'd', -1, 1, "out_coef") < 0)
        goto done;
    const Py_ssize_t terms = items(&cb);
    if (terms < 1 || terms > MAX_TERMS || items(&bb) != terms * npx) {
        PyErr_SetString(PyExc_ValueError, "illumination: basis must be (terms, pixels)");
        goto done;
    }
    const float *small = (const float *)sb.view.buf;
    const uint8_t *land = (const uint8_t *)lb.view.buf;
    const double *basis = (const double *)bb.view.buf;
    double *coef = (double *)cb.view.buf;
    /* every fourth land pixel */
    Py_ssize_t n = 0, seen = 0;
    for (Py_ssize_t k = 0; k < npx; k++)
        if (land[k]) n += (seen++ % 4) == 0;
    if (n < 10 * terms) {
        result = PyLong_FromLong(0);
        goto done;
    }
    A = malloc(terms * n * sizeof(double));
    val = malloc(n * sizeof(double));
    resid = malloc(n * sizeof(double));
    work = malloc(n * sizeof(double));
    keep = malloc(n);
    if (!A || !val || !resid || !work || !keep) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t m = 0;
    seen = 0;
    for (Py_ssize_t k = 0; k < npx; k++)
        if (land[k] && (seen++ % 4) == 0) {
            for (Py_ssize_t t = 0; t < terms; t++) A[m * terms + t] = basis[t * npx + k];
            val[m++] = (double)small[k];
        }
    if (!normal_solve(A, terms, n, val, NULL, coef)) {
        result = PyLong_FromLong(-1);
        goto done;
    }
    for (Py_ssize_t k = 0; k < n; k++) {
        double fit = 0.0;
        for (Py_ssize_t t = 0; t < terms; t++) fit += coef[t] * A[k * terms + t];
        resid[k] = val[k] - fit;
        work[k] = resid[k];
    }
    const double med = select_k(work, n, n / 2);
    for (Py_ssize_t k = 0; k < n; k++) work[k] = fabs(resid[k] - med);
    double mad = select_k(work, n, n / 2);
    mad = mad > 1e-6 ? mad : 1e-6;
    const double band = 3.0 * 1.4826 * mad;
    for (Py_ssize_t k = 0; k < n; k++) keep[k] = fabs(resid[k]) <= band;
    if (!normal_solve(A, terms, n, val, keep, coef)) {
        result = PyLong_FromLong(-1);
        goto done;
    }
    double sum = 0.0, lo = INFINITY, count = 0.0;
    for (Py_ssize_t k = 0; k < n; k++)
        if (keep[k]) {
            double fit = 0.0;
            for (Py_ssize_t t = 0; t < terms; t++) fit += coef[t] * A[k * terms + t];
            sum += fit;
            lo = fit < lo ? fit : lo;
            count += 1.0;
        }
    const double level = sum / count;
    if (!(level > 0) || lo <= 0.05 * level) {
        result = PyLong_FromLong(0); /* the fit ran wild (too few lands in view) */
        goto done;
    }
    for (Py_ssize_t t = 0; t < terms; t++) coef[t] /= level;
    result = PyLong_FromLong(1);
done:
    free(A);
    free(val);
    free(resid);
    free(work);
    free(keep);
    release(&sb);
    release(&lb);
    release(&bb);
    release(&cb);
    return result;
}

/* ---------------------------------------------------------------- paper: the TestBox */

/* testbox(response, sign, axis, reverse, level, candidates, testheight, testwidth, skip, backoff,
 *         out_points) -> count
 *
 * _testbox.segment_edge_sparse for one edge: of the candidates (flat indices of the float32
 * response (h, w), ascending, each beyond the level in the edge's polarity sign), those meeting the
 * TestBox's rules 2 and 3 (column A: C is the extreme of the 2 testheight + 1 values along the scan,
 * those inside the image; columns E and F, testwidth before and after along the edge, each hold a
 * value beyond the level), then the walk of section 3.2.4 over them (_testbox.scan_columns: every
 * skip-th column of the scan view, the first accepted row at or after the start, the start backing
 * off by backoff rows after a hit, row 0 after a miss). axis 0 scans down the rows (top; bottom when
 * reversed, from the bottom up), axis 1 along the columns (left; right reversed). out_points:
 * (>= columns, 2) int64 image (x, y), in the walk's order. */
static PyObject *testbox(PyObject *self, PyObject *args) {
    PyObject *o_r, *o_c, *o_out;
    double sign, level;
    int axis, reverse, th, tw, skip, backoff;
    if (!PyArg_ParseTuple(args, "OdipdOiiiiO", &o_r, &sign, &axis, &reverse, &level, &o_c, &th, &tw, &skip,
                          &backoff, &o_out))
        return NULL;
    Buf rb = {0}, cb = {0}, ob = {0};
    PyObject *result = NULL;
    int64_t *rows = NULL, *start_of = NULL;
    uint8_t *ok = NULL;
    if (PyObject_GetBuffer(o_r, &rb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    rb.held = 1;
    const char *f = rb.view.format ? rb.view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    if (rb.view.ndim != 2 || *f != 'f' || rb.view.itemsize != 4 || th < 0 || tw < 0 || skip < 1 || backoff < 0 ||
        (axis != 0 && axis != 1)) {
        PyErr_SetString(PyExc_ValueError, "testbox: a 2-D float32 response and valid TestBox parameters");
        goto done;
    }
    const Py_ssize_t h = rb.view.shape[0], w = rb.view.shape[1];
    if (get(o_c, &cb, 'q', -1, 0, "candidates") < 0 || get(o_out, &ob, 'q', -1, 1, "out_points") < 0) goto done;
    const Py_ssize_t n = items(&cb);
    const Py_ssize_t n_across = axis == 0 ? h : w, n_along = axis == 0 ? w : h;
    const Py_ssize_t s_across = axis == 0 ? w : 1, s_along = axis == 0 ? 1 : w;
    if (items(&ob) < 2 * ((n_along + skip - 1) / skip)) {
        PyErr_SetString(PyExc_ValueError, "testbox: out_points too short");
        goto done;
    }
    const float *r = (const float *)rb.view.buf;
    const int64_t *cand = (const int64_t *)cb.view.buf;
    int64_t *out = (int64_t *)ob.view.buf;
    const float lv = (float)level;
    if ((double)lv != level) {
        PyErr_SetString(PyExc_ValueError, "testbox: level must be exactly a float32 value");
        goto done;
    }
    const int up = sign > 0;
    ok = malloc(n > 0 ? n : 1);
    rows = malloc((n > 0 ? n : 1) * sizeof(int64_t));
    start_of = calloc(n_along + 1, sizeof(int64_t));
    if (!ok || !rows || !start_of) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        const int64_t fl = cand[i];
        if (fl < 0 || fl >= h * w) {
            PyErr_SetString(PyExc_ValueError, "testbox: candidate outside the response");
            goto done;
        }
        const int64_t y = fl / w, x = fl % w;
        const int64_t across = axis == 0 ? y : x, along = axis == 0 ? x : y;
        const float value = r[fl];
        int keep = 1;
        /* rule 2: C is the extreme of column A (the positions inside the image) */
        for (int k = -th; k <= th && keep; k++) {
            const int64_t pos = across + k;
            if (pos < 0 || pos >= n_across) continue;
            const float v = r[fl + k * s_across];
            keep = up ? v <= value : v >= value;
        }
        /* rule 3: columns E and F each hold a value beyond the level */
        keep = keep && along >= tw && along < n_along - tw;
        for (int side = -1; side <= 1 && keep; side += 2) {
            const int64_t centre = fl + side * tw * s_along;
            int any = 0;
            for (int k = -th; k <= th && !any; k++) {
                const int64_t pos = across + k;
                if (pos < 0 || pos >= n_across) continue;
                const float v = r[centre + k * s_across];
                any = up ? v > lv : v < -lv;
            }
            keep = any;
        }
        ok[i] = (uint8_t)keep;
        if (keep) start_of[along + 1]++;
    }
    /* the accepted rows of each scan column, ascending (counting sort by column; within a column the
     * candidates' flat order is monotonic in the row) */
    for (Py_ssize_t c = 0; c < n_along; c++) start_of[c + 1] += start_of[c];
    {
        int64_t *fill = malloc((n_along + 1) * sizeof(int64_t));
        if (!fill) {
            PyErr_NoMemory();
            goto done;
        }
        memcpy(fill, start_of, (n_along + 1) * sizeof(int64_t));
        for (Py_ssize_t i = 0; i < n; i++) {
            if (!ok[i]) continue;
            const int64_t y = cand[i] / w, x = cand[i] % w;
            const int64_t across = axis == 0 ? y : x, along = axis == 0 ? x : y;
            rows[fill[along]++] = reverse ? n_across - 1 - across : across;
        }
        free(fill);
    }
    if (reverse)
        for (Py_ssize_t c = 0; c < n_along; c++)
            for (int64_t a = start_of[c], b = start_of[c + 1] - 1; a < b; a++, b--) {
                const int64_t t = rows[a];
                rows[a] = rows[b];
                rows[b] = t;
            }
    /* the walk */
    Py_ssize_t count = 0;
    int64_t start = 0;
    for (Py_ssize_t c = 0; c < n_along; c += skip) {
        int64_t k = start_of[c];
        while (k < start_of[c + 1] && rows[k] < start) k++;
        if (k == start_of[c + 1]) {
            start = 0;
            continue;
        }
        const int64_t row = rows[k];
        start = row - backoff > 0 ? row - backoff : 0;
        int64_t x, y;
        if (axis == 0) {
            x = c;
            y = reverse ? h - 1 - row : row;
        } else {
            x = reverse ? w - 1 - row : row;
            y = c;
        }
        out[2 * count] = x;
        out[2 * count + 1] = y;
        count++;
    }
    result = PyLong_FromSsize_t(count);
done:
    free(ok);
    free(rows);
    free(start_of);
    release(&rb);
    release(&cb);
    release(&ob);
    return result;
}

/* ---------------------------------------------------------------- paper: moments and the line fit */

static double pearson(double n, double st, double ss, double stt, double sts, double sss) {
    const double vt = n * stt - st * st, vs = n * sss - ss * ss;
    if (vt <= 0 || vs <= 0) return 0.0;
    return (n * sts - st * ss) / sqrt(vt * vs);
}

/* edge_fit(gray, pixels, vertical, corr_tol, change_tol, max_removals, min_points, out_points,
 *          out_kept) -> (valid, status, slope, intercept, removed, rms)
 *
 * _paper._edge_fit's stages 5-6 for one edge: the 3x3 raw-intensity moment of every segmented pixel
 * ((N, 2) int64 (x, y); _moment.intensity_moment: those with a whole neighbourhood inside the image
 * and a non-zero sum are valid, written in order to out_points (N, 2) float64), then the seed's
 * recursive fit of across = slope * along + intercept (_linefit.recursive_fit: the farthest point
 * removed while the correlation is below corr_tol or its removal improves it by more than change_tol,
 * at most max_removals, never below min_points), out_kept (N,) bool marking the valid points kept.
 * status: 0 fitted, 1 fewer than min_points valid points, 2 the points are all in one column. */
static PyObject *edge_fit(PyObject *self, PyObject *args) {
    PyObject *o_g, *o_p, *o_pts, *o_kept;
    int vertical, max_removals, min_points;
    double corr_tol, change_tol;
    if (!PyArg_ParseTuple(args, "OOpddiiOO", &o_g, &o_p, &vertical, &corr_tol, &change_tol, &max_removals,
                          &min_points, &o_pts, &o_kept))
        return NULL;
    Buf gb = {0}, pb = {0}, ob = {0}, kb = {0};
    PyObject *result = NULL;
    double *t = NULL, *s = NULL;
    if (PyObject_GetBuffer(o_g, &gb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    gb.held = 1;
    const char *f = gb.view.format ? gb.view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    if (gb.view.ndim != 2 || *f != 'B' || gb.view.itemsize != 1) {
        PyErr_SetString(PyExc_TypeError, "edge_fit: gray must be a 2-D uint8 array");
        goto done;
    }
    const Py_ssize_t h = gb.view.shape[0], w = gb.view.shape[1];
    if (get(o_p, &pb, 'q', -1, 0, "pixels") < 0) goto done;
    const Py_ssize_t N = items(&pb) / 2;
    if (get(o_pts, &ob, 'd', 2 * N, 1, "out_points") < 0 || get(o_kept, &kb, '?', N, 1, "out_kept") < 0) goto done;
    const uint8_t *I = (const uint8_t *)gb.view.buf;
    const int64_t *px = (const int64_t *)pb.view.buf;
    double *pts = (double *)ob.view.buf;
    uint8_t *kept = (uint8_t *)kb.view.buf;
    Py_ssize_t n = 0;
    for (Py_ssize_t i = 0; i < N; i++) {
        const int64_t x = px[2 * i], y = px[2 * i + 1];
        if (x < 1 || x > w - 2 || y < 1 || y > h - 2) continue;
        int64_t total = 0, mx = 0, my = 0;
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                const int64_t v = I[(y + dy) * w + (x + dx)];
                total += v;
                mx += dx * v;
                my += dy * v;
            }
        if (total <= 0) continue;
        pts[2 * n] = (double)x + (double)mx / (double)total;
        pts[2 * n + 1] = (double)y + (double)my / (double)total;
        n++;
    }
    for (Py_ssize_t i = 0; i < N; i++) kept[i] = 0;
    if (n < min_points || n < 3) {
        result = Py_BuildValue("nidddd", n, 1, 0.0, 0.0, 0.0, 0.0);
        goto done;
    }
    t = malloc(n * sizeof(double));
    s = malloc(n * sizeof(double));
    if (!t || !s) {
        PyErr_NoMemory();
        goto done;
    }
    double t0 = 0.0, s0 = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        t0 += pts[2 * i + (vertical ? 1 : 0)];
        s0 += pts[2 * i + (vertical ? 0 : 1)];
    }
    t0 /= (double)n;
    s0 /= (double)n;
    double sn = (double)n, st = 0.0, ss = 0.0, stt = 0.0, sts = 0.0, sss = 0.0;
    for (Py_ssize_t i = 0; i < n; i++) {
        t[i] = pts[2 * i + (vertical ? 1 : 0)] - t0;
        s[i] = pts[2 * i + (vertical ? 0 : 1)] - s0;
        st += t[i];
        ss += s[i];
        stt += t[i] * t[i];
        sts += t[i] * s[i];
        sss += s[i] * s[i];
        kept[i] = 1;
    }
    int removed = 0, status = 0;
    double slope = 0.0, intercept = 0.0;
    for (;;) {
        const double den = sn * stt - st * st;
        if (den <= 0) {
            status = 2;
            break;
        }
        slope = (sn * sts - st * ss) / den;
        intercept = (ss - slope * st) / sn;
        if (!(removed < max_removals && sn > min_points)) break;
        Py_ssize_t k = 0;
        double best = -INFINITY;
        for (Py_ssize_t i = 0; i < n; i++) {
            const double d = kept[i] ? fabs(s[i] - (slope * t[i] + intercept)) : -1.0;
            if (d > best) {
                best = d;
                k = i;
            }
        }
        const double tk = t[k], sk = s[k];
        const double r_all = fabs(pearson(sn, st, ss, stt, sts, sss));
        const double r_less =
            fabs(pearson(sn - 1, st - tk, ss - sk, stt - tk * tk, sts - tk * sk, sss - sk * sk));
        if (!(r_all < corr_tol || r_less - r_all > change_tol)) break;
        sn -= 1;
        st -= tk;
        ss -= sk;
        stt -= tk * tk;
        sts -= tk * sk;
        sss -= sk * sk;
        kept[k] = 0;
        removed++;
    }
    if (status) {
        result = Py_BuildValue("nidddd", n, status, 0.0, 0.0, 0.0, 0.0);
        goto done;
    }
    const double norm = sqrt(1.0 + slope * slope);
    double sq = 0.0;
    for (Py_ssize_t i = 0; i < n; i++)
        if (kept[i]) {
            const double r = (s[i] - (slope * t[i] + intercept)) / norm;
            sq += r * r;
        }
    const double rms = sqrt(sq / sn);
    result = Py_BuildValue("nidddd", n, 0, slope, intercept + s0 - slope * t0, (double)removed, rms);
done:
    free(t);
    free(s);
    release(&gb);
    release(&pb);
    release(&ob);
    release(&kb);
    return result;
}

/* ---------------------------------------------------------------- the cross check (_sanity) */

/* numpy's pairwise summation of float32 values (its add.reduce over a contiguous run) */
static float pairwise_f32(const float *a, Py_ssize_t n) {
    if (n < 8) {
        float res = 0.0f;
        for (Py_ssize_t i = 0; i < n; i++) res += a[i];
        return res;
    }
    if (n <= 128) {
        float r[8];
        for (int j = 0; j < 8; j++) r[j] = a[j];
        Py_ssize_t i;
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++) r[j] += a[i + j];
        float res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++) res += a[i];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_f32(a, n2) + pairwise_f32(a + n2, n - n2);
}

/* The middle of three values (NaN when any is). */
static double median3_d(double a, double b, double c) {
    if (a != a || b != b || c != c) return NAN;
    const double lo = a < b ? a : b, hi = a < b ? b : a;
    const double m = hi < c ? hi : c;
    return lo > m ? lo : m;
}

/* The middle of the seen (not NaN) values among three: the median of three, the mean of two, the one;
 * NaN when none is seen. */
static double middle_seen(double a, double b, double c) {
    const double x[3] = {a, b, c};
    double total = 0.0;
    int count = 0;
    for (int i = 0; i < 3; i++)
        if (x[i] == x[i]) {
            total += x[i];
            count++;
        }
    if (count == 3) return median3_d(a, b, c);
    if (count == 2) return 0.5 * total;
    return count == 1 ? total : NAN;
}

/* edge_contrast(values, out) -> None
 *
 * _sanity._Groove's contrast of each wall at each step along a groove from its remapped samples
 * (float32 (11, T): 5 across the groove from -0.3 w to +0.3 w, 3 on the + land, 3 on the - land; NaN
 * outside the frame): out (2, T) float64, row 0 the - wall (the middle of the seen samples among 8-10
 * minus the middle of samples 0-2), row 1 the + wall (5-7 and 2-4); NaN when a groove sample or
 * every land sample of the wall is outside the frame. */
static PyObject *edge_contrast(PyObject *self, PyObject *args) {
    PyObject *o_v, *o_out;
    if (!PyArg_ParseTuple(args, "OO", &o_v, &o_out)) return NULL;
    Buf vb = {0}, ob = {0};
    PyObject *result = NULL;
    if (get(o_v, &vb, 'f', -1, 0, "values") < 0) return NULL;
    if (items(&vb) % 11 != 0) {
        PyErr_SetString(PyExc_ValueError, "edge_contrast: values must be (11, steps)");
        goto done;
    }
    const Py_ssize_t T = items(&vb) / 11;
    if (get(o_out, &ob, 'd', 2 * T, 1, "out") < 0) goto done;
    const float *v = (const float *)vb.view.buf;
    double *out = (double *)ob.view.buf;
    static const int rows[2][6] = {{0, 1, 2, 8, 9, 10}, {4, 3, 2, 5, 6, 7}}; /* groove x3, land x3 */
    for (int e = 0; e < 2; e++)
        for (Py_ssize_t j = 0; j < T; j++) {
            double x[6];
            for (int i = 0; i < 6; i++) x[i] = (double)v[rows[e][i] * T + j];
            out[e * T + j] = middle_seen(x[3], x[4], x[5]) - median3_d(x[0], x[1], x[2]);
        }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    release(&vb);
    release(&ob);
    return result;
}

/* second_band(turned, row, width, depth_fraction) -> distance in reduced rows, or None
 *
 * _sanity._second_band: the profile across the groove (each row of the turned image averaged over its
 * finite values, rows at least a quarter seen), its baseline (the median of the rows clear of the
 * groove), the groove's depth below it, and the first run of other rows darker than the baseline by
 * depth_fraction of that depth and at least max(2, width / 3) rows long: its centre's distance from
 * the groove's row. */
static PyObject *second_band(PyObject *self, PyObject *args) {
    PyObject *o_t;
    double row, width, fraction;
    if (!PyArg_ParseTuple(args, "Oddd", &o_t, &row, &width, &fraction)) return NULL;
    Buf tb = {0};
    PyObject *result = NULL;
    double *profile = NULL, *work = NULL;
    uint8_t *seen = NULL;
    if (PyObject_GetBuffer(o_t, &tb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    tb.held = 1;
    const char *f = tb.view.format ? tb.view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    if (tb.view.ndim != 2 || *f != 'f' || tb.view.itemsize != 4) {
        PyErr_SetString(PyExc_TypeError, "second_band: a 2-D float32 image");
        goto done;
    }
    const Py_ssize_t h = tb.view.shape[0], w = tb.view.shape[1];
    const float *img = (const float *)tb.view.buf;
    profile = malloc((h > 0 ? h : 1) * sizeof(double));
    work = malloc((h > 0 ? h : 1) * sizeof(double));
    seen = malloc(h > 0 ? h : 1);
    if (!profile || !work || !seen) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < h; i++) {
        const float *r = img + i * w;
        /* add.reduce(where=finite): the identity, then every run of finite values by pairwise sums */
        float total = 0.0f;
        int64_t count = 0;
        Py_ssize_t j = 0;
        while (j < w) {
            while (j < w && r[j] != r[j]) j++;
            const Py_ssize_t a = j;
            while (j < w && r[j] == r[j]) j++;
            if (j > a) {
                total += pairwise_f32(r + a, j - a);
                count += j - a;
            }
        }
        seen[i] = (double)count >= 0.25 * (double)w;
        profile[i] = seen[i] ? (double)total / (double)(count > 1 ? count : 1) : NAN;
        seen[i] = seen[i] && isfinite(profile[i]);
    }
    const double half = 0.5 * width + 1.0;
    int any_band = 0;
    Py_ssize_t n_around = 0;
    double band_min = INFINITY;
    for (Py_ssize_t i = 0; i < h; i++) {
        if (!seen[i]) continue;
        const double d = fabs((double)i - row);
        if (d <= half) {
            any_band = 1;
            band_min = profile[i] < band_min ? profile[i] : band_min;
        } else if (d > 2 * half)
            work[n_around++] = profile[i];
    }
    if (!any_band || n_around < 4) goto none;
    {
        const Py_ssize_t k = n_around - 1 < (Py_ssize_t)(0.5 * n_around) ? n_around - 1 : (Py_ssize_t)(0.5 * n_around);
        const double baseline = select_k(work, n_around, k);
        const double depth = baseline - band_min;
        if (depth <= 0) goto none;
        const double limit = baseline - fraction * depth, need = width / 3.0 > 2.0 ? width / 3.0 : 2.0;
        Py_ssize_t i = 0;
        while (i < h) {
            const int dark_i = seen[i] && fabs((double)i - row) > 2 * half && profile[i] < limit;
            if (!dark_i) {
                i++;
                continue;
            }
            const Py_ssize_t a = i;
            while (i < h && seen[i] && fabs((double)i - row) > 2 * half && profile[i] < limit) i++;
            if ((double)(i - a) >= need) {
                result = PyFloat_FromDouble(fabs((double)(a + i - 1) / 2.0 - row));
                goto done;
            }
        }
    }
none:
    Py_INCREF(Py_None);
    result = Py_None;
done:
    free(profile);
    free(work);
    free(seen);
    release(&tb);
    return result;
}

/* arms(edges_h, distance_h, edges_v, distance_v, width_h, width_v, present_fraction, tolerance,
 *      out_farthest) -> bits
 *
 * _sanity._missing_arms: the steps of each arm (right, left on the horizontal groove; lower, upper
 * on the vertical one; edges (2, T): each wall's contrast, NaN where unseen) from past the
 * perpendicular groove's rounded corners on. A step shows the groove when either wall's contrast
 * reaches present_fraction of the upper quartile of every seen wall step's (at least 5); it is the
 * groove when a neighbouring step on the arm shows it too. An arm is missing (bit i) when its farthest
 * step with a wall seen lies more than tolerance beyond its farthest groove step (out_farthest[i]). */
static PyObject *arms(PyObject *self, PyObject *args) {
    PyObject *o_eh, *o_dh, *o_ev, *o_dv, *o_out;
    double wh, wv, fraction, tolerance;
    if (!PyArg_ParseTuple(args, "OOOOddddO", &o_eh, &o_dh, &o_ev, &o_dv, &wh, &wv, &fraction, &tolerance, &o_out))
        return NULL;
    Buf ehb = {0}, dhb = {0}, evb = {0}, dvb = {0}, ob = {0};
    PyObject *result = NULL;
    double *work = NULL;
    if (get(o_dh, &dhb, 'd', -1, 0, "distance_h") < 0 || get(o_eh, &ehb, 'd', 2 * items(&dhb), 0, "edges_h") < 0 ||
        get(o_dv, &dvb, 'd', -1, 0, "distance_v") < 0 || get(o_ev, &evb, 'd', 2 * items(&dvb), 0, "edges_v") < 0 ||
        get(o_out, &ob, 'd', 4, 1, "out_farthest") < 0)
        goto done;
    const double *edg[2] = {(const double *)ehb.view.buf, (const double *)evb.view.buf};
    const double *dist[2] = {(const double *)dhb.view.buf, (const double *)dvb.view.buf};
    const Py_ssize_t len[2] = {items(&dhb), items(&dvb)};
    const int which[4] = {0, 0, 1, 1};
    const double sign[4] = {1.0, -1.0, 1.0, -1.0};
    const double widths[2] = {wh, wv};
    double start[4];
    double *far = (double *)ob.view.buf;
    work = malloc((4 * (len[0] + len[1]) + 1) * sizeof(double));
    if (!work) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t n = 0;
    for (int a = 0; a < 4; a++) {
        const int g = which[a];
        const double other = widths[1 - g], width = widths[g];
        const double q = 0.25 * width;
        start[a] = 0.5 * other + (6.0 > q ? 6.0 : q);
        for (int e = 0; e < 2; e++)
            for (Py_ssize_t k = 0; k < len[g]; k++) {
                const double c = edg[g][e * len[g] + k];
                if (sign[a] * dist[g][k] >= start[a] && isfinite(c)) work[n++] = c;
            }
    }
    if (n == 0) {
        result = PyLong_FromLong(0);
        goto done;
    }
    const Py_ssize_t kq = n - 1 < (Py_ssize_t)(0.75 * n) ? n - 1 : (Py_ssize_t)(0.75 * n);
    const double quart = select_k(work, n, kq);
    const double threshold = fraction * (quart > 5.0 ? quart : 5.0);
    long bits = 0;
    for (int a = 0; a < 4; a++) {
        const int g = which[a];
        const Py_ssize_t T = len[g];
        const double *e0 = edg[g], *e1 = edg[g] + T;
        double seen_max = -INFINITY, groove_max = -INFINITY;
        int any_seen = 0, any_groove = 0;
#define ON_ARM(k) ((k) >= 0 && (k) < T && sign[a] * dist[g][(k)] >= start[a])
#define SHOWS(k) (e0[(k)] >= threshold || e1[(k)] >= threshold)
        for (Py_ssize_t k = 0; k < T; k++) {
            if (!ON_ARM(k)) continue;
            const double t = sign[a] * dist[g][k];
            if (!(isfinite(e0[k]) || isfinite(e1[k]))) continue;
            any_seen = 1;
            seen_max = t > seen_max ? t : seen_max;
            if (SHOWS(k) && ((ON_ARM(k - 1) && SHOWS(k - 1)) || (ON_ARM(k + 1) && SHOWS(k + 1)))) {
                any_groove = 1;
                groove_max = t > groove_max ? t : groove_max;
            }
        }
#undef ON_ARM
#undef SHOWS
        far[a] = any_groove ? groove_max : start[a];
        if (any_seen && seen_max - far[a] > tolerance) bits |= 1L << a;
    }
    result = PyLong_FromLong(bits);
done:
    free(work);
    release(&ehb);
    release(&dhb);
    release(&evb);
    release(&dvb);
    release(&ob);
    return result;
}

/* ---------------------------------------------------------------- the coarse stage's small steps */

static Py_ssize_t argmin_d(const double *v, Py_ssize_t n) {
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 1; i < n; i++)
        if (v[i] < v[k]) k = i;
    return k;
}

static Py_ssize_t argmax_d(const double *v, Py_ssize_t n) {
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 1; i < n; i++)
        if (v[i] > v[k]) k = i;
    return k;
}

/* band_edges(profile, counts) -> (status, falling, rising)
 *
 * _coarse._band_edges: over the bins holding at least max(3, a fifth of the fullest) pixels, the
 * profile smoothed by a 3-box, its differences, and the darkest band's (strongest fall, strongest rise
 * after it, or the other way round) indices. status 0 found; 1 no dark band stands out of the
 * profile's noise (or no rise after the fall); -1 a case the numpy code handles (fewer than 3 bins). */
static PyObject *band_edges(PyObject *self, PyObject *args) {
    PyObject *o_p, *o_c;
    if (!PyArg_ParseTuple(args, "OO", &o_p, &o_c)) return NULL;
    Buf pb = {0}, cb = {0};
    PyObject *result = NULL;
    double *sm = NULL, *d = NULL, *work = NULL;
    if (get(o_p, &pb, 'd', -1, 0, "profile") < 0 || get(o_c, &cb, 'd', items(&pb), 0, "counts") < 0) goto done;
    const Py_ssize_t n = items(&pb);
    const double *profile = (const double *)pb.view.buf, *counts = (const double *)cb.view.buf;
    double cmax = -INFINITY;
    for (Py_ssize_t i = 0; i < n; i++) cmax = counts[i] > cmax ? counts[i] : cmax;
    const double need = 0.2 * cmax > 3.0 ? 0.2 * cmax : 3.0;
    Py_ssize_t lo = -1, hi = -1;
    for (Py_ssize_t i = 0; i < n; i++)
        if (counts[i] >= need) {
            if (lo < 0) lo = i;
            hi = i;
        }
    if (lo < 0 || hi - lo + 1 < 3) {
        result = Py_BuildValue("inn", -1, (Py_ssize_t)0, (Py_ssize_t)0);
        goto done;
    }
    const double *p = profile + lo;
    const Py_ssize_t m = hi - lo + 1;
    sm = malloc(m * sizeof(double));
    d = malloc(m * sizeof(double));
    work = malloc(m * sizeof(double));
    if (!sm || !d || !work) {
        PyErr_NoMemory();
        goto done;
    }
    const double k3 = 1.0 / 3.0;
    sm[0] = p[0];
    sm[m - 1] = p[m - 1];
    for (Py_ssize_t i = 1; i < m - 1; i++) sm[i] = p[i - 1] * k3 + p[i] * k3 + p[i + 1] * k3;
    const Py_ssize_t nd = m - 1;
    for (Py_ssize_t i = 0; i < nd; i++) d[i] = sm[i + 1] - sm[i];
    memcpy(work, d, nd * sizeof(double));
    const double med = select_k(work, nd, nd / 2);
    for (Py_ssize_t i = 0; i < nd; i++) work[i] = fabs(d[i] - med);
    const double noise = 1.4826 * select_k(work, nd, nd / 2);
    const Py_ssize_t fall = argmin_d(d, nd);
    if (fall + 1 >= nd) {
        result = Py_BuildValue("inn", 1, (Py_ssize_t)0, (Py_ssize_t)0);
        goto done;
    }
    Py_ssize_t rise = fall + 1 + argmax_d(d + fall + 1, nd - fall - 1), best_fall = fall;
    const Py_ssize_t rise2 = argmax_d(d, nd);
    if (rise2 > 0) {
        const Py_ssize_t fall2 = argmin_d(d, rise2);
        const double depth1 = d[rise] - d[fall], depth2 = d[rise2] - d[fall2];
        if (depth2 > depth1) {
            best_fall = fall2;
            rise = rise2;
        }
    }
    const double a = -d[best_fall], b = d[rise], floor_ = 8.0 * noise > 2.0 ? 8.0 * noise : 2.0;
    const int status = (a < b ? a : b) < floor_ ? 1 : 0;
    result = Py_BuildValue("inn", status, lo + best_fall, lo + rise);
done:
    free(sm);
    free(d);
    free(work);
    release(&pb);
    release(&cb);
    return result;
}

/* lands(u, v, v_mid, v_half, u_mid, u_half, out) -> None
 *
 * _coarse.coarse_cross's lands for the illumination fit: a reduced pixel is land when it lies beyond
 * both grooves (|v - v_mid| > v_half and |u - u_mid| > u_half); out (sh // 2, sw // 2) bool: both
 * diagonal pixels of each 2x2 block are land. */
static PyObject *lands(PyObject *self, PyObject *args) {
    PyObject *o_u, *o_v, *o_out;
    double vm, vh, um, uh;
    if (!PyArg_ParseTuple(args, "OOddddO", &o_u, &o_v, &vm, &vh, &um, &uh, &o_out)) return NULL;
    Buf ub = {0}, vb = {0}, ob = {0};
    PyObject *result = NULL;
    if (PyObject_GetBuffer(o_u, &ub.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    ub.held = 1;
    if (ub.view.ndim != 2 || ub.view.itemsize != 8) {
        PyErr_SetString(PyExc_TypeError, "lands: u must be a 2-D float64 array");
        goto done;
    }
    const Py_ssize_t sh = ub.view.shape[0], sw = ub.view.shape[1], h2 = sh / 2, w2 = sw / 2;
    if (get(o_v, &vb, 'd', sh * sw, 0, "v") < 0 || get(o_out, &ob, '?', h2 * w2, 1, "out") < 0) goto done;
    const double *u = (const double *)ub.view.buf, *v = (const double *)vb.view.buf;
    uint8_t *out = (uint8_t *)ob.view.buf;
    for (Py_ssize_t i = 0; i < h2; i++)
        for (Py_ssize_t j = 0; j < w2; j++) {
            const Py_ssize_t a = (2 * i) * sw + 2 * j, b = (2 * i + 1) * sw + 2 * j + 1;
            const int la = fabs(v[a] - vm) > vh && fabs(u[a] - um) > uh;
            const int lb = fabs(v[b] - vm) > vh && fabs(u[b] - um) > uh;
            out[i * w2 + j] = (uint8_t)(la && lb);
        }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    release(&ub);
    release(&vb);
    release(&ob);
    return result;
}

/* quality(gray) -> (lo, hi, saturated)
 *
 * _image.check_quality's statistics of every fourth pixel of every fourth row: the grey levels at
 * the 1st and 99th percentiles (the first level whose cumulative fraction reaches them, the
 * fraction in float32 as numpy's of OpenCV's float32 histogram) and the fraction at 255. */
static PyObject *quality(PyObject *self, PyObject *args) {
    PyObject *o_g;
    if (!PyArg_ParseTuple(args, "O", &o_g)) return NULL;
    Buf gb = {0};
    PyObject *result = NULL;
    if (PyObject_GetBuffer(o_g, &gb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    gb.held = 1;
    if (gb.view.ndim != 2 || gb.view.itemsize != 1) {
        PyErr_SetString(PyExc_TypeError, "quality: a 2-D uint8 image");
        goto done;
    }
    const Py_ssize_t h = gb.view.shape[0], w = gb.view.shape[1];
    const uint8_t *g = (const uint8_t *)gb.view.buf;
    int64_t hist[256] = {0}, size = 0;
    for (Py_ssize_t i = 0; i < h; i += 4)
        for (Py_ssize_t j = 0; j < w; j += 4) {
            hist[g[i * w + j]]++;
            size++;
        }
    int lo = 256, hi = 256;
    float cum = 0.0f;
    for (int k = 0; k < 256; k++) {
        cum += (float)hist[k];
        const double cdf = (double)(cum / (float)size);
        if (lo == 256 && cdf >= 0.01) lo = k;
        if (hi == 256 && cdf >= 0.99) hi = k;
    }
    result = Py_BuildValue("iid", lo, hi, (double)((float)hist[255] / (float)size)); /* float32, as numpy's */
done:
    release(&gb);
    return result;
}

/* ---------------------------------------------------------------- paper: operators and threshold */

/* prewitt(gray, out_gy, out_gx) -> (gy min, gy max, gx min, gx max)
 *
 * _edges.operator_responses on an 8-bit image (eq. 4: gy = the sum of the row below minus that of the
 * row above over three columns; gx its transpose; borders replicated) as float32 (whole numbers:
 * exactly OpenCV's values), and their extremes (cv2.minMaxLoc's). Per row: the column differences D
 * and sums S (int16), then gy = D[c-1] + D[c] + D[c+1] and gx = S[c+1] - S[c-1], branch-free. */
static PyObject *prewitt(PyObject *self, PyObject *args) {
    PyObject *o_img, *o_gy, *o_gx;
    if (!PyArg_ParseTuple(args, "OOO", &o_img, &o_gy, &o_gx)) return NULL;
    Buf img = {0}, gyb = {0}, gxb = {0};
    PyObject *result = NULL;
    int16_t *D = NULL, *S = NULL;
    if (PyObject_GetBuffer(o_img, &img.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    img.held = 1;
    if (img.view.ndim != 2 || img.view.itemsize != 1 || img.view.shape[0] < 1 || img.view.shape[1] < 1) {
        PyErr_SetString(PyExc_TypeError, "prewitt: gray must be a non-empty 2-D uint8 array");
        goto done;
    }
    const Py_ssize_t h = img.view.shape[0], w = img.view.shape[1];
    if (get(o_gy, &gyb, 'f', h * w, 1, "out_gy") < 0 || get(o_gx, &gxb, 'f', h * w, 1, "out_gx") < 0) goto done;
    D = malloc((w + 2) * sizeof(int16_t));
    S = malloc((w + 2) * sizeof(int16_t));
    if (!D || !S) {
        PyErr_NoMemory();
        goto done;
    }
    const uint8_t *I = (const uint8_t *)img.view.buf;
    float *gy = (float *)gyb.view.buf, *gx = (float *)gxb.view.buf;
    int ylo = INT32_MAX, yhi = INT32_MIN, xlo = INT32_MAX, xhi = INT32_MIN;
    for (Py_ssize_t r = 0; r < h; r++) {
        const uint8_t *restrict up = I + (r > 0 ? r - 1 : 0) * w, *restrict mid = I + r * w,
                                *restrict dn = I + (r < h - 1 ? r + 1 : r) * w;
        int16_t *restrict d = D + 1, *restrict sm = S + 1;
        for (Py_ssize_t c = 0; c < w; c++) {
            d[c] = (int16_t)((int16_t)dn[c] - (int16_t)up[c]);
            sm[c] = (int16_t)((int16_t)up[c] + (int16_t)mid[c] + (int16_t)dn[c]);
        }
        D[0] = D[1];
        D[w + 1] = D[w];
        S[0] = S[1];
        S[w + 1] = S[w];
        float *restrict oy = gy + r * w, *restrict ox = gx + r * w;
        int16_t rylo = INT16_MAX, ryhi = INT16_MIN, rxlo = INT16_MAX, rxhi = INT16_MIN;
        for (Py_ssize_t c = 0; c < w; c++) {
            const int16_t vy = (int16_t)(D[c] + D[c + 1] + D[c + 2]);
            const int16_t vx = (int16_t)(S[c + 2] - S[c]);
            oy[c] = (float)vy;
            ox[c] = (float)vx;
            rylo = vy < rylo ? vy : rylo;
            ryhi = vy > ryhi ? vy : ryhi;
            rxlo = vx < rxlo ? vx : rxlo;
            rxhi = vx > rxhi ? vx : rxhi;
        }
        ylo = rylo < ylo ? rylo : ylo;
        yhi = ryhi > yhi ? ryhi : yhi;
        xlo = rxlo < xlo ? rxlo : xlo;
        xhi = rxhi > xhi ? rxhi : xhi;
    }
    result = Py_BuildValue("dddd", (double)ylo, (double)yhi, (double)xlo, (double)xhi);
done:
    free(D);
    free(S);
    release(&img);
    release(&gyb);
    release(&gxb);
    return result;
}

/* above(response, level) -> bytes of int64 flat indices
 *
 * np.flatnonzero(np.abs(response) > level) on a float32 response (level exactly a float32 value):
 * counted first (blocks of 16 without such a value passed over by one vectorised test), then
 * written to a buffer of exactly that size. */
static Py_ssize_t above_pass(const float *r, Py_ssize_t n, float lv, int64_t *out) {
    /* |x| > lv on the bits: for finite floats, the magnitude's bits order as the magnitudes do (the
     * responses are whole numbers, never NaN) */
    uint32_t lb;
    memcpy(&lb, &lv, sizeof lb);
    const uint32_t *u = (const uint32_t *)(const void *)r;
    Py_ssize_t k = 0, i = 0;
    for (; i + 32 <= n; i += 32) {
        uint32_t hits = 0;
        for (int j = 0; j < 32; j++) hits += (u[i + j] & 0x7fffffffu) > lb;
        if (!hits) continue;
        for (int j = 0; j < 32; j++)
            if ((u[i + j] & 0x7fffffffu) > lb) {
                if (out) out[k] = i + j;
                k++;
            }
    }
    for (; i < n; i++)
        if ((u[i] & 0x7fffffffu) > lb) {
            if (out) out[k] = i;
            k++;
        }
    return k;
}

static PyObject *above(PyObject *self, PyObject *args) {
    PyObject *o_r;
    double level;
    if (!PyArg_ParseTuple(args, "Od", &o_r, &level)) return NULL;
    Buf rb = {0};
    PyObject *result = NULL;
    if (get(o_r, &rb, 'f', -1, 0, "response") < 0) return NULL;
    const Py_ssize_t n = items(&rb);
    const float lv = (float)level;
    if ((double)lv != level || !(lv >= 0)) {
        PyErr_SetString(PyExc_ValueError, "above: level must be exactly a non-negative float32 value");
        goto done;
    }
    const float *r = (const float *)rb.view.buf;
    const Py_ssize_t count = above_pass(r, n, lv, NULL);
    result = PyBytes_FromStringAndSize(NULL, count * (Py_ssize_t)sizeof(int64_t));
    if (!result) goto done;
    above_pass(r, n, lv, (int64_t *)PyBytes_AS_STRING(result));
done:
    release(&rb);
    return result;
}

/* groove_maps(c0, c1, u0, u1, n0, n1, t_from, w, gap, out_mapx, out_mapy) -> None
 *
 * _sanity._Groove's sampling maps (float32 (11, T)): steps t = t_from, t_from + 1, ... along the
 * groove (direction u) from c, at 11 offsets s across it (direction n): 5 over the groove's middle
 * (np.linspace(-0.3 w, 0.3 w, 5)), then 3 on each land (0.5 w + gap + (0, 0.15, 0.3) w, and their
 * negatives): map = (c + t u) + s n, rounded to float32. */
static PyObject *groove_maps(PyObject *self, PyObject *args) {
    double c0, c1, u0, u1, n0, n1, t_from, w, gap;
    PyObject *o_x, *o_y;
    if (!PyArg_ParseTuple(args, "dddddddddOO", &c0, &c1, &u0, &u1, &n0, &n1, &t_from, &w, &gap, &o_x, &o_y))
        return NULL;
    Buf xb = {0}, yb = {0};
    PyObject *result = NULL;
    if (get(o_x, &xb, 'f', -1, 1, "out_mapx") < 0) return NULL;
    if (items(&xb) % 11 != 0 || get(o_y, &yb, 'f', items(&xb), 1, "out_mapy") < 0) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "groove_maps: maps must be (11, steps)");
        goto done;
    }
    const Py_ssize_t T = items(&xb) / 11;
    double sv[11];
    /* np.linspace(a, b, 5): a + k * step, the last exactly b */
    const double a = -0.3 * w, b = 0.3 * w, step = (b - a) / 4.0;
    for (int k = 0; k < 5; k++) sv[k] = (double)k * step + a;
    sv[4] = b;
    const double frac[3] = {0.0, 0.15, 0.3};
    for (int k = 0; k < 3; k++) {
        const double land = 0.5 * w + gap + frac[k] * w;
        sv[5 + k] = land;
        sv[8 + k] = -land;
    }
    float *mx = (float *)xb.view.buf, *my = (float *)yb.view.buf;
    for (int k = 0; k < 11; k++)
        for (Py_ssize_t j = 0; j < T; j++) {
            const double t = t_from + (double)j;
            mx[k * T + j] = (float)(c0 + t * u0 + sv[k] * n0);
            my[k * T + j] = (float)(c1 + t * u1 + sv[k] * n1);
        }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    release(&xb);
    release(&yb);
    return result;
}

/* ---------------------------------------------------------------- module */

static PyMethodDef methods[] = {
    {"profiles", profiles, METH_VARARGS, "Sub-pixel edge positions of precise mode's profiles."},
    {"fine", fine, METH_VARARGS, "Precise mode's fine stage: every pass's profiles and line fits."},
    {"project", project, METH_VARARGS, "Precise mode's coarse projections along the two grooves."},
    {"illumination", illumination, METH_VARARGS, "Precise mode's illumination fit over the lands."},
    {"testbox", testbox, METH_VARARGS, "Paper mode's TestBox segmentation of one edge."},
    {"edge_fit", edge_fit, METH_VARARGS, "Paper mode's moments and recursive line fit of one edge."},
    {"edge_contrast", edge_contrast, METH_VARARGS, "The cross check's contrast of a groove's two walls."},
    {"second_band", second_band, METH_VARARGS, "The cross check's search for a second groove."},
    {"arms", arms, METH_VARARGS, "The cross check's arms that end inside the field of view."},
    {"groove_maps", groove_maps, METH_VARARGS, "The cross check's sampling maps along a groove."},
    {"band_edges", band_edges, METH_VARARGS, "The coarse stage's darkest band in a projected profile."},
    {"lands", lands, METH_VARARGS, "The coarse stage's land mask for the illumination fit."},
    {"quality", quality, METH_VARARGS, "The image quality check's percentiles and saturation."},
    {"prewitt", prewitt, METH_VARARGS, "Paper mode's operators on an 8-bit image, with their extremes."},
    {"above", above, METH_VARARGS, "Flat indices of the responses above a level in magnitude."},
    RULER_KERNEL_METHODS
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_ckernels", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__ckernels(void) { return PyModule_Create(&module); }
