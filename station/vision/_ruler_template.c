/* Compiled kernels of the ruler measurement's template (issue 22), part of the _ckernels module:
 * the fold of the windows' profiles into the template's fine bins (_ruler_phase._folded), its cosine
 * moments (_ruler_phase._cosine_sums) and the template read at many phases
 * (_ruler_phase.template_value). The same arithmetic as the numpy reference in that module (the
 * cosine moments summed in another order), which stays the tested reference
 * (tests/vision/test_ruler_kernels.py).
 *
 * Plain C on the buffer protocol, like _ckernels.c (built with it, -O3 -ffp-contract=off).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
#include <string.h>

#include "_ruler_common.h"
#include "_ruler_kernels.h"

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
