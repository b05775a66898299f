/* Compiled kernels of the ruler measurement (issue 22), part of the _ckernels module: the pass over
 * the pixels (_ruler_bins.fold), one least-squares round of the phase windows
 * (_ruler_phase._round), the fold of the windows' profiles into the template's fine bins
 * (_ruler_phase._folded) and the template's cosine moments (_ruler_phase._cosine_sums). Element for element the same arithmetic, in the same order, as the
 * numpy reference in those modules, which stays the tested reference (tests/vision/test_ruler_kernels.py).
 *
 * Plain C on the buffer protocol, like _ckernels.c (built with it, -O3 -ffp-contract=off).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_ruler_kernels.h"

typedef struct {
    Py_buffer view;
    int held;
} RBuf;

static void rrelease(RBuf *b) {
    if (b->held) {
        PyBuffer_Release(&b->view);
        b->held = 0;
    }
}

/* kind: 'd' float64, 'B' uint8. n < 0: any length. obj None with optional: left unheld (returns 1). */
static int rget(PyObject *obj, RBuf *b, char kind, Py_ssize_t n, int writable, int optional, const char *name) {
    if (optional && obj == Py_None) return 1;
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) return -1;
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (*f == '<' || *f == '=' || *f == '@') f++;
    int ok = kind == 'd' ? (*f == 'd' && b->view.itemsize == 8) : (*f == 'B' && b->view.itemsize == 1);
    Py_ssize_t len = b->view.itemsize ? b->view.len / b->view.itemsize : 0;
    if (!ok || (n >= 0 && len != n)) {
        PyErr_Format(PyExc_TypeError, "%s: expected %zd items of kind '%c', got format '%s' (%zd items)", name, n,
                     kind, b->view.format ? b->view.format : "B", len);
        rrelease(b);
        return -1;
    }
    return 0;
}

/* ruler_bins(gray, xs, ys, m, table, step, out) -> None
 *
 * _ruler_bins.fold: gray (H, W) uint8; xs, ys (H, W) float64 undistorted coordinates or None (the
 * pixel centres); m the frame's 3x3 matrix (9 float64); table (K, 5) float64 rows (t_lo, t_hi, s_lo,
 * per_period, bins), sorted by t_lo; every step-th pixel of every step-th row; out (total bins, 6)
 * float64 accumulates (n, sum I, sum s, sum t, sum s^2, sum s t). Without coordinates each row is
 * scanned only where t can fall in the table's range (t is monotonic along a row): the test per
 * pixel is the reference's, so the result is the same. */
PyObject *ruler_bins(PyObject *self, PyObject *args) {
    PyObject *o_g, *o_x, *o_y, *o_m, *o_t, *o_out;
    Py_ssize_t step;
    if (!PyArg_ParseTuple(args, "OOOOOnO", &o_g, &o_x, &o_y, &o_m, &o_t, &step, &o_out)) return NULL;
    RBuf gb = {0}, xb = {0}, yb = {0}, mb = {0}, tb = {0}, ob = {0};
    PyObject *result = NULL;
    double *offsets = NULL;
    if (step < 1) {
        PyErr_SetString(PyExc_ValueError, "ruler_bins: step must be >= 1");
        return NULL;
    }
    if (PyObject_GetBuffer(o_g, &gb.view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | PyBUF_ND) < 0) return NULL;
    gb.held = 1;
    if (gb.view.ndim != 2 || gb.view.itemsize != 1) {
        PyErr_SetString(PyExc_TypeError, "ruler_bins: gray must be a 2-D uint8 array");
        goto done;
    }
    const Py_ssize_t h = gb.view.shape[0], w = gb.view.shape[1];
    int nx = rget(o_x, &xb, 'd', h * w, 0, 1, "xs"), ny = rget(o_y, &yb, 'd', h * w, 0, 1, "ys");
    if (nx < 0 || ny < 0 || nx != ny) {
        if (nx >= 0 && ny >= 0) PyErr_SetString(PyExc_TypeError, "ruler_bins: give both xs and ys, or neither");
        goto done;
    }
    if (rget(o_m, &mb, 'd', 9, 0, 0, "m") < 0 || rget(o_t, &tb, 'd', -1, 0, 0, "table") < 0) goto done;
    const Py_ssize_t k = (tb.view.len / 8) / 5;
    if (k < 1 || k * 5 * 8 != tb.view.len) {
        PyErr_SetString(PyExc_TypeError, "ruler_bins: table must be (k, 5) float64 with k >= 1");
        goto done;
    }
    const double *tab = (const double *)tb.view.buf, *m = (const double *)mb.view.buf;
    offsets = (double *)PyMem_Malloc((size_t)(k + 1) * sizeof(double));
    if (!offsets) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t total = 0;
    for (Py_ssize_t i = 0; i < k; i++) {
        offsets[i] = (double)total;
        total += (Py_ssize_t)tab[i * 5 + 4];
    }
    if (rget(o_out, &ob, 'd', total * 6, 1, 0, "out") < 0) goto done;
    const uint8_t *g = (const uint8_t *)gb.view.buf;
    const double *xs = nx == 0 ? (const double *)xb.view.buf : NULL, *ys = ny == 0 ? (const double *)yb.view.buf : NULL;
    double *out = (double *)ob.view.buf;
    const double t_min = tab[0], t_max = tab[(k - 1) * 5 + 1];
    Py_ssize_t strip = 0;
    for (Py_ssize_t r = 0; r < h; r += step) {
        Py_ssize_t c0 = 0, c1 = w - 1;
        if (!xs) { /* columns where t_min - 2 px <= t < t_max + 2 px can hold: t is monotonic in x */
            const double y = (double)r;
            double lo = 0.0, hi = (double)(w - 1);
            for (int side = 0; side < 2; side++) {
                const double tv = side == 0 ? t_min : t_max;
                const double a = m[3] - tv * m[6], b = m[4] * y + m[5] - tv * (m[7] * y + m[8]);
                /* side 0 keeps a x + b >= 0, side 1 keeps a x + b < 0 */
                const double sgn = side == 0 ? 1.0 : -1.0;
                if (fabs(a) < 1e-300) {
                    if (sgn * b < 0) lo = 1.0, hi = 0.0;
                    continue;
                }
                const double x0 = -b / a;
                if (sgn * a > 0) lo = fmax(lo, x0);
                else hi = fmin(hi, x0);
            }
            if (!(lo <= hi + 4.0)) continue;
            c0 = (Py_ssize_t)fmax(0.0, floor(lo) - 2.0);
            c1 = (Py_ssize_t)fmin((double)(w - 1), ceil(hi) + 2.0);
            c0 = ((c0 + step - 1) / step) * step;
        }
        for (Py_ssize_t c = c0; c <= c1; c += step) {
            const Py_ssize_t p = r * w + c;
            const double X = xs ? xs[p] : (double)c, Y = ys ? ys[p] : (double)r;
            const double inv = 1.0 / (m[6] * X + m[7] * Y + m[8]);
            const double s = (m[0] * X + m[1] * Y + m[2]) * inv;
            const double t = (m[3] * X + m[4] * Y + m[5]) * inv;
            if (!(t >= t_min) || !(t < t_max)) continue;
            /* the last strip with t_lo <= t (searchsorted 'right' - 1): t changes little from one
             * pixel to the next, so walk from the previous pixel's strip */
            while (strip + 1 < k && tab[(strip + 1) * 5] <= t) strip++;
            while (strip > 0 && tab[strip * 5] > t) strip--;
            const double *row = tab + strip * 5;
            if (!(t < row[1])) continue;
            const double v = (s - row[2]) * row[3];
            if (!(v >= 0) || !(v < row[4])) continue; /* v >= 0: truncation is floor */
            double *o = out + ((Py_ssize_t)offsets[strip] + (Py_ssize_t)v) * 6;
            o[0] += 1.0;
            o[1] += (double)g[p];
            o[2] += s;
            o[3] += t;
            o[4] += s * s;
            o[5] += s * t;
        }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    PyMem_Free(offsets);
    rrelease(&gb);
    rrelease(&xb);
    rrelease(&yb);
    rrelease(&mb);
    rrelease(&tb);
    rrelease(&ob);
    return result;
}

/* Solve the p x p system a x = b in place (Gaussian elimination, partial pivoting); 0 on success. */
static int solve_small(double *a, double *b, int p) {
    for (int col = 0; col < p; col++) {
        int piv = col;
        for (int r = col + 1; r < p; r++)
            if (fabs(a[r * p + col]) > fabs(a[piv * p + col])) piv = r;
        if (a[piv * p + col] == 0.0) return -1;
        if (piv != col) {
            for (int j = 0; j < p; j++) {
                const double tmp = a[col * p + j];
                a[col * p + j] = a[piv * p + j];
                a[piv * p + j] = tmp;
            }
            const double tmp = b[col];
            b[col] = b[piv];
            b[piv] = tmp;
        }
        for (int r = col + 1; r < p; r++) {
            const double f = a[r * p + col] / a[col * p + col];
            for (int j = col; j < p; j++) a[r * p + j] -= f * a[col * p + j];
            b[r] -= f * b[col];
        }
    }
    for (int r = p - 1; r >= 0; r--) {
        double acc = b[r];
        for (int j = r + 1; j < p; j++) acc -= a[r * p + j] * b[j];
        b[r] = acc / a[r * p + r];
    }
    return 0;
}

/* ruler_fit(n, level, s, u, weight, grid, delta, out_coef, out_residual) -> None
 *
 * One round of _ruler_phase._round_numpy for every window (rows of the (W, B) arrays): the
 * profile T and its slope T' at phase s + delta[w] (Catmull-Rom through grid, G samples per
 * period), then the least-squares fit of level on (1, u, T, u T, T') with weights weight:
 * out_coef (W, 6) gets the 5 coefficients and sum(weight T'^2); out_residual (W, B) or None gets
 * (level - fit without the T' term) * sqrt(n). A singular window gets NaN coefficients. */
PyObject *ruler_fit(PyObject *self, PyObject *args) {
    PyObject *o_n, *o_l, *o_s, *o_u, *o_w, *o_g, *o_d, *o_c, *o_r;
    if (!PyArg_ParseTuple(args, "OOOOOOOOO", &o_n, &o_l, &o_s, &o_u, &o_w, &o_g, &o_d, &o_c, &o_r)) return NULL;
    RBuf nb = {0}, lb = {0}, sb = {0}, ub = {0}, wb = {0}, gb = {0}, db = {0}, cb = {0}, rb = {0};
    PyObject *result = NULL;
    if (rget(o_d, &db, 'd', -1, 0, 0, "delta") < 0) goto done;
    const Py_ssize_t nw = db.view.len / 8;
    if (rget(o_n, &nb, 'd', -1, 0, 0, "n") < 0) goto done;
    const Py_ssize_t total = nb.view.len / 8;
    if (nw < 1 || total % nw != 0) {
        PyErr_SetString(PyExc_TypeError, "ruler_fit: n must be (windows, bins) with windows = len(delta)");
        goto done;
    }
    const Py_ssize_t nbins = total / nw;
    int nr;
    if (rget(o_l, &lb, 'd', total, 0, 0, "level") < 0 || rget(o_s, &sb, 'd', total, 0, 0, "s") < 0 ||
        rget(o_u, &ub, 'd', total, 0, 0, "u") < 0 || rget(o_w, &wb, 'd', total, 0, 0, "weight") < 0 ||
        rget(o_g, &gb, 'd', -1, 0, 0, "grid") < 0 || rget(o_c, &cb, 'd', nw * 6, 1, 0, "out_coef") < 0 ||
        (nr = rget(o_r, &rb, 'd', total, 1, 1, "out_residual")) < 0)
        goto done;
    const double *n = (const double *)nb.view.buf, *lv = (const double *)lb.view.buf;
    const double *sv = (const double *)sb.view.buf, *uv = (const double *)ub.view.buf;
    const double *wv = (const double *)wb.view.buf, *grid = (const double *)gb.view.buf;
    const double *delta = (const double *)db.view.buf;
    double *coef = (double *)cb.view.buf, *res = nr == 0 ? (double *)rb.view.buf : NULL;
    const Py_ssize_t size = gb.view.len / 8;
    for (Py_ssize_t win = 0; win < nw; win++) {
        /* upper triangle of the normal matrix of (1, u, T, u T, T'): 15 sums, and the right side */
        double s00 = 0, s01 = 0, s02 = 0, s03 = 0, s04 = 0, s11 = 0, s12 = 0, s13 = 0, s14 = 0, s22 = 0, s23 = 0,
               s24 = 0, s33 = 0, s34 = 0, s44 = 0, r0 = 0, r1 = 0, r2 = 0, r3 = 0, r4 = 0;
        const Py_ssize_t base = win * nbins;
        const double dw = delta[win], scale = (double)size;
        for (Py_ssize_t i = 0; i < nbins; i++) {
            const Py_ssize_t q = base + i;
            const double phase = sv[q] + dw;
            const double x = (phase - floor(phase)) * scale; /* >= 0: truncation is floor */
            Py_ssize_t i0 = (Py_ssize_t)x;
            const double f = x - (double)i0;
            if (i0 >= size) i0 -= size;
            const Py_ssize_t im = i0 == 0 ? size - 1 : i0 - 1;
            const Py_ssize_t i1 = i0 + 1 >= size ? i0 + 1 - size : i0 + 1;
            const Py_ssize_t i2 = i1 + 1 >= size ? i1 + 1 - size : i1 + 1;
            const double ga = grid[i0], gbv = grid[i1], gam = grid[im], gbp = grid[i2];
            const double c1 = gbv - gam;
            const double c2 = 2 * gam - 5 * ga + 4 * gbv - gbp;
            const double c3 = 3 * (ga - gbv) + gbp - gam;
            const double value = ga + 0.5 * f * (c1 + f * (c2 + f * c3));
            const double slope = 0.5 * (c1 + f * (2 * c2 + 3 * f * c3)) * scale;
            if (res) res[q] = value; /* the model's T, finished below */
            const double wt = wv[q];
            if (wt == 0.0) continue;
            const double u = uv[q], uvv = u * value, l = lv[q];
            const double wu = wt * u, wv2 = wt * value, wuv = wt * uvv, ws = wt * slope;
            s00 += wt;
            s01 += wu;
            s02 += wv2;
            s03 += wuv;
            s04 += ws;
            s11 += wu * u;
            s12 += wu * value;
            s13 += wu * uvv;
            s14 += wu * slope;
            s22 += wv2 * value;
            s23 += wv2 * uvv;
            s24 += wv2 * slope;
            s33 += wuv * uvv;
            s34 += wuv * slope;
            s44 += ws * slope;
            r0 += wt * l;
            r1 += wu * l;
            r2 += wv2 * l;
            r3 += wuv * l;
            r4 += ws * l;
        }
        double a[25] = {s00, s01, s02, s03, s04, s01, s11, s12, s13, s14, s02, s12, s22, s23, s24,
                        s03, s13, s23, s33, s34, s04, s14, s24, s34, s44};
        double rhs[5] = {r0, r1, r2, r3, r4};
        for (int r = 0; r < 5; r++) {
            const double d = a[r * 5 + r] > 1e-300 ? a[r * 5 + r] : 1e-300;
            a[r * 5 + r] += 1e-12 * d;
        }
        double *cw = coef + win * 6;
        if (solve_small(a, rhs, 5) != 0) {
            for (int j = 0; j < 5; j++) cw[j] = NAN;
        } else {
            for (int j = 0; j < 5; j++) cw[j] = rhs[j];
        }
        cw[5] = s44;
        if (res)
            for (Py_ssize_t i = 0; i < nbins; i++) {
                const Py_ssize_t q = base + i;
                const double model = cw[0] + cw[1] * uv[q] + (cw[2] + cw[3] * uv[q]) * res[q];
                res[q] = (lv[q] - model) * sqrt(n[q]);
            }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    rrelease(&nb);
    rrelease(&lb);
    rrelease(&sb);
    rrelease(&ub);
    rrelease(&wb);
    rrelease(&gb);
    rrelease(&db);
    rrelease(&cb);
    rrelease(&rb);
    return result;
}

/* ruler_profile(level, s, u, weight, coef, delta, out) -> None
 *
 * _ruler_phase._folded: every bin of the (W, B) windows normalised by its window's background and
 * contrast (coef (W, 4): c0 + c1 u background, c2 + c3 u contrast), folded about a graduation's
 * centre (x = |phase - rint(phase)|, phase = s + delta[w]) and summed into out (F, 3): per fine bin
 * (x * 2F, F = len(out) / 3) the weight w n contrast^2, and its sums of x and of the normalised level.
 * Bins without information (weight 0, a contrast of 0 or NaN, a level that is not finite) are left
 * out. Summed in the bins' order, as numpy's bincount. */
PyObject *ruler_profile(PyObject *self, PyObject *args) {
    PyObject *o_l, *o_s, *o_u, *o_w, *o_c, *o_d, *o_o;
    if (!PyArg_ParseTuple(args, "OOOOOOO", &o_l, &o_s, &o_u, &o_w, &o_c, &o_d, &o_o)) return NULL;
    RBuf lb = {0}, sb = {0}, ub = {0}, wb = {0}, cb = {0}, db = {0}, ob = {0};
    PyObject *result = NULL;
    if (rget(o_d, &db, 'd', -1, 0, 0, "delta") < 0 || rget(o_l, &lb, 'd', -1, 0, 0, "level") < 0) goto done;
    const Py_ssize_t nw = db.view.len / 8, total = lb.view.len / 8;
    if (nw < 1 || total % nw != 0) {
        PyErr_SetString(PyExc_TypeError, "ruler_profile: level must be (windows, bins) with windows = len(delta)");
        goto done;
    }
    if (rget(o_s, &sb, 'd', total, 0, 0, "s") < 0 || rget(o_u, &ub, 'd', total, 0, 0, "u") < 0 ||
        rget(o_w, &wb, 'd', total, 0, 0, "weight") < 0 || rget(o_c, &cb, 'd', nw * 4, 0, 0, "coef") < 0 ||
        rget(o_o, &ob, 'd', -1, 1, 0, "out") < 0)
        goto done;
    const Py_ssize_t fold = (ob.view.len / 8) / 3;
    if (fold < 1 || fold * 3 * 8 != ob.view.len) {
        PyErr_SetString(PyExc_TypeError, "ruler_profile: out must be (fine bins, 3) float64");
        goto done;
    }
    const Py_ssize_t nbins = total / nw;
    const double *lv = (const double *)lb.view.buf, *sv = (const double *)sb.view.buf;
    const double *uv = (const double *)ub.view.buf, *wv = (const double *)wb.view.buf;
    const double *cf = (const double *)cb.view.buf, *delta = (const double *)db.view.buf;
    double *out = (double *)ob.view.buf;
    memset(out, 0, (size_t)fold * 3 * sizeof(double));
    const double scale = 2.0 * (double)fold;
    for (Py_ssize_t win = 0; win < nw; win++) {
        const double *c = cf + win * 4;
        const double dw = delta[win];
        for (Py_ssize_t i = 0; i < nbins; i++) {
            const Py_ssize_t q = win * nbins + i;
            const double u = uv[q];
            double contrast = c[2] + c[3] * u;
            const double divisor = fabs(contrast) > 1e-9 ? contrast : 1e-9;
            const double normal = (lv[q] - c[0] - c[1] * u) / divisor;
            if (isnan(contrast)) contrast = 0.0;
            else if (isinf(contrast)) contrast = contrast > 0 ? DBL_MAX : -DBL_MAX;
            const double informed = wv[q] * (contrast * contrast);
            if (!(informed > 0) || !isfinite(normal)) continue;
            const double phase = sv[q] + dw;
            const double x = fabs(phase - rint(phase));
            Py_ssize_t k = (Py_ssize_t)(x * scale);
            if (k > fold - 1) k = fold - 1;
            double *o = out + k * 3;
            o[0] += informed;
            o[1] += informed * x;
            o[2] += informed * normal;
        }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    rrelease(&lb);
    rrelease(&sb);
    rrelease(&ub);
    rrelease(&wb);
    rrelease(&cb);
    rrelease(&db);
    rrelease(&ob);
    return result;
}

/* ruler_cosines(x, weight, value, out_moments, out_rhs) -> None
 *
 * _ruler_phase._cosine_sums: out_moments[j] = sum weight cos(2 pi j x) (j < len(out_moments)) and
 * out_rhs[k] = sum weight value cos(2 pi k x) (k < len(out_rhs) <= len(out_moments)), the powers of
 * exp(2 pi i x) each from the last, as the reference computes them (its sums are in another order:
 * equal to some 1e-15 relative). */
PyObject *ruler_cosines(PyObject *self, PyObject *args) {
    PyObject *o_x, *o_w, *o_v, *o_m, *o_r;
    if (!PyArg_ParseTuple(args, "OOOOO", &o_x, &o_w, &o_v, &o_m, &o_r)) return NULL;
    RBuf xb = {0}, wb = {0}, vb = {0}, mb = {0}, rb = {0};
    PyObject *result = NULL;
    double *work = NULL;
    if (rget(o_x, &xb, 'd', -1, 0, 0, "x") < 0) goto done;
    const Py_ssize_t n = xb.view.len / 8;
    if (rget(o_w, &wb, 'd', n, 0, 0, "weight") < 0 || rget(o_v, &vb, 'd', n, 0, 0, "value") < 0 ||
        rget(o_m, &mb, 'd', -1, 1, 0, "out_moments") < 0 || rget(o_r, &rb, 'd', -1, 1, 0, "out_rhs") < 0)
        goto done;
    const Py_ssize_t top = mb.view.len / 8, kmax = rb.view.len / 8;
    if (kmax > top) {
        PyErr_SetString(PyExc_ValueError, "ruler_cosines: out_rhs longer than out_moments");
        goto done;
    }
    const double *x = (const double *)xb.view.buf, *wt = (const double *)wb.view.buf;
    const double *val = (const double *)vb.view.buf;
    double *m = (double *)mb.view.buf, *r = (double *)rb.view.buf;
    memset(r, 0, (size_t)kmax * sizeof(double));
    const double two_pi = 6.283185307179586;
    /* a row of powers at a time (the complex products vectorise), each sum in four interleaved parts
     * (no chain of dependent additions): the same terms as the reference, summed in another order */
    work = (double *)PyMem_Malloc(((size_t)n * 6 + 1) * sizeof(double));
    if (!work) {
        PyErr_NoMemory();
        goto done;
    }
    double *pr = work, *pi = pr + n, *zr = pi + n, *zi = zr + n, *wv = zi + n, *wt2 = wv + n;
    for (Py_ssize_t i = 0; i < n; i++) {
        zr[i] = cos(two_pi * x[i]);
        zi[i] = sin(two_pi * x[i]);
        pr[i] = 1.0;
        pi[i] = 0.0;
        wt2[i] = wt[i];
        wv[i] = wt[i] * val[i];
    }
    for (Py_ssize_t k = 0; k < top; k++) {
        double a[4] = {0.0, 0.0, 0.0, 0.0}, c[4] = {0.0, 0.0, 0.0, 0.0};
        Py_ssize_t i = 0;
        for (; i + 4 <= n; i += 4)
            for (int j = 0; j < 4; j++) {
                a[j] += wt2[i + j] * pr[i + j];
                c[j] += wv[i + j] * pr[i + j];
            }
        for (; i < n; i++) {
            a[0] += wt2[i] * pr[i];
            c[0] += wv[i] * pr[i];
        }
        m[k] = (a[0] + a[1]) + (a[2] + a[3]);
        if (k < kmax) r[k] = (c[0] + c[1]) + (c[2] + c[3]);
        for (i = 0; i < n; i++) {
            const double nr = pr[i] * zr[i] - pi[i] * zi[i], ni = pr[i] * zi[i] + pi[i] * zr[i];
            pr[i] = nr;
            pi[i] = ni;
        }
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    PyMem_Free(work);
    rrelease(&xb);
    rrelease(&wb);
    rrelease(&vb);
    rrelease(&mb);
    rrelease(&rb);
    return result;
}

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

/* ruler_windows(bins, starts, lengths, out_n, out_level, out_s, out_u, out_moments) -> None
 *
 * _ruler_phase.windows_from_bins: bins (W * B, 6) float64 grouped into W windows of B bins (B =
 * len(out_n) / W), window w starting at starts[w] and lengths[w] periods long. Per bin the count,
 * mean level, mean s (the bin's centre when empty) and s from the window's centre (out_n, out_level,
 * out_s, out_u, each (W, B)); per window its moments (n, mean s, mean t, var s, cov s t) (W, 5). */
PyObject *ruler_windows(PyObject *self, PyObject *args) {
    PyObject *o_b, *o_st, *o_l, *o_n, *o_lv, *o_s, *o_u, *o_m;
    if (!PyArg_ParseTuple(args, "OOOOOOOO", &o_b, &o_st, &o_l, &o_n, &o_lv, &o_s, &o_u, &o_m)) return NULL;
    RBuf bb = {0}, stb = {0}, lb = {0}, nb = {0}, lvb = {0}, sb = {0}, ub = {0}, mb = {0};
    PyObject *result = NULL;
    if (rget(o_st, &stb, 'd', -1, 0, 0, "starts") < 0) goto done;
    const Py_ssize_t nw = stb.view.len / 8;
    if (rget(o_l, &lb, 'd', nw, 0, 0, "lengths") < 0 || rget(o_n, &nb, 'd', -1, 1, 0, "out_n") < 0) goto done;
    const Py_ssize_t total = nb.view.len / 8;
    if (nw < 1 || total % nw != 0) {
        PyErr_SetString(PyExc_TypeError, "ruler_windows: out_n must be (windows, bins) with windows = len(starts)");
        goto done;
    }
    const Py_ssize_t nbins = total / nw;
    if (rget(o_b, &bb, 'd', total * 6, 0, 0, "bins") < 0 || rget(o_lv, &lvb, 'd', total, 1, 0, "out_level") < 0 ||
        rget(o_s, &sb, 'd', total, 1, 0, "out_s") < 0 || rget(o_u, &ub, 'd', total, 1, 0, "out_u") < 0 ||
        rget(o_m, &mb, 'd', nw * 5, 1, 0, "out_moments") < 0)
        goto done;
    const double *b = (const double *)bb.view.buf, *starts = (const double *)stb.view.buf;
    const double *lengths = (const double *)lb.view.buf;
    double *on = (double *)nb.view.buf, *ol = (double *)lvb.view.buf, *os = (double *)sb.view.buf;
    double *ou = (double *)ub.view.buf, *om = (double *)mb.view.buf;
    for (Py_ssize_t w = 0; w < nw; w++) {
        double tn = 0.0, ts = 0.0, tt = 0.0, tss = 0.0, tst = 0.0;
        const double mid = starts[w] + lengths[w] / 2;
        for (Py_ssize_t i = 0; i < nbins; i++) {
            const Py_ssize_t q = w * nbins + i;
            const double *row = b + q * 6;
            const double n = row[0], safe = n > 1.0 ? n : 1.0;
            const double centre = starts[w] + (((double)i + 0.5) / (double)nbins) * lengths[w];
            const double s = n > 0 ? row[2] / safe : centre;
            on[q] = n;
            ol[q] = row[1] / safe;
            os[q] = s;
            ou[q] = s - mid;
            tn += n;
            ts += row[2];
            tt += row[3];
            tss += row[4];
            tst += row[5];
        }
        const double ok = tn > 1.0 ? tn : 1.0;
        const double mean_s = ts / ok, mean_t = tt / ok;
        double *m = om + w * 5;
        m[0] = tn;
        m[1] = mean_s;
        m[2] = mean_t;
        m[3] = tss / ok - mean_s * mean_s;
        m[4] = tst / ok - mean_s * mean_t;
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    rrelease(&bb);
    rrelease(&stb);
    rrelease(&lb);
    rrelease(&nb);
    rrelease(&lvb);
    rrelease(&sb);
    rrelease(&ub);
    rrelease(&mb);
    return result;
}

/* ruler_template(grid, phase, out_value, out_slope) -> None
 *
 * _ruler_phase.template_value: the periodic template (Catmull-Rom cubic through grid, G samples per
 * period) and its derivative at each phase (any length n; out_value, out_slope n each), element for
 * element the reference's arithmetic. */
PyObject *ruler_template(PyObject *self, PyObject *args) {
    PyObject *o_g, *o_p, *o_v, *o_s;
    if (!PyArg_ParseTuple(args, "OOOO", &o_g, &o_p, &o_v, &o_s)) return NULL;
    RBuf gb = {0}, pb = {0}, vb = {0}, sb = {0};
    PyObject *result = NULL;
    if (rget(o_g, &gb, 'd', -1, 0, 0, "grid") < 0 || rget(o_p, &pb, 'd', -1, 0, 0, "phase") < 0) goto done;
    const Py_ssize_t size = gb.view.len / 8, n = pb.view.len / 8;
    if (size < 4) {
        PyErr_SetString(PyExc_ValueError, "ruler_template: grid needs at least 4 samples");
        goto done;
    }
    if (rget(o_v, &vb, 'd', n, 1, 0, "out_value") < 0 || rget(o_s, &sb, 'd', n, 1, 0, "out_slope") < 0) goto done;
    const double *grid = (const double *)gb.view.buf, *ph = (const double *)pb.view.buf;
    double *ov = (double *)vb.view.buf, *os = (double *)sb.view.buf;
    const double scale = (double)size;
    for (Py_ssize_t k = 0; k < n; k++) {
        const double x = (ph[k] - floor(ph[k])) * scale;
        const double fl = floor(x);
        if (!isfinite(fl)) {
            ov[k] = NAN;
            os[k] = NAN;
            continue;
        }
        Py_ssize_t i0 = (Py_ssize_t)fl;
        const double f = x - fl;
        i0 %= size;
        if (i0 < 0) i0 += size;
        const Py_ssize_t im = i0 == 0 ? size - 1 : i0 - 1;
        const Py_ssize_t i1 = i0 + 1 >= size ? i0 + 1 - size : i0 + 1;
        const Py_ssize_t i2 = i1 + 1 >= size ? i1 + 1 - size : i1 + 1;
        const double a = grid[i0], b = grid[i1], am = grid[im], bp = grid[i2];
        const double c1 = b - am;
        const double c2 = 2 * am - 5 * a + 4 * b - bp;
        const double c3 = 3 * (a - b) + bp - am;
        ov[k] = a + 0.5 * f * (c1 + f * (c2 + f * c3));
        os[k] = 0.5 * (c1 + f * (2 * c2 + 3 * f * c3)) * scale;
    }
    Py_INCREF(Py_None);
    result = Py_None;
done:
    rrelease(&gb);
    rrelease(&pb);
    rrelease(&vb);
    rrelease(&sb);
    return result;
}
