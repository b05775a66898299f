/* Helpers shared by the ruler's compiled kernels (_ruler_kernels.c, _ruler_fits.c): buffers of
 * the buffer protocol checked for kind and length, and a small linear solve. Static: each file that
 * includes this header gets its own copy. */
#ifndef STATION_RULER_COMMON_H
#define STATION_RULER_COMMON_H
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

typedef struct {
    Py_buffer view;
    int held;
} RBuf;

static inline void rrelease(RBuf *b) {
    if (b->held) {
        PyBuffer_Release(&b->view);
        b->held = 0;
    }
}

/* kind: 'd' float64, 'B' uint8. n < 0: any length. obj None with optional: left unheld (returns 1). */
static inline int rget(PyObject *obj, RBuf *b, char kind, Py_ssize_t n, int writable, int optional, const char *name) {
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

/* Solve the p x p system a x = b in place (Gaussian elimination, partial pivoting); 0 on success. */
static inline int solve_small(double *a, double *b, int p) {
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

#endif
