/* Compiled kernels of the ruler measurement (issue 22), part of the _ckernels module: the pass over
 * the pixels (_ruler_bins.fold), the phase windows from their bins (_ruler_phase.windows_from_bins)
 * and one least-squares round of the windows (_ruler_phase._round). The template: _ruler_template.c;
 * the fits of the tips and of the frame's correction: _ruler_fits.c. Element for element the same
 * arithmetic as the numpy reference in those modules, which stays the tested reference
 * (tests/vision/test_ruler_kernels.py).
 *
 * Plain C on the buffer protocol, like _ckernels.c (built with it, -O3 -ffp-contract=off).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_ruler_common.h"
#include "_ruler_kernels.h"

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
