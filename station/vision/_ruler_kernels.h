/* The ruler measurement's compiled kernels (_ruler_kernels.c, _ruler_template.c, _ruler_fits.c), part
 * of the _ckernels module. */
#ifndef STATION_RULER_KERNELS_H
#define STATION_RULER_KERNELS_H
#include <Python.h>

PyObject *ruler_bins(PyObject *self, PyObject *args);
PyObject *ruler_fit(PyObject *self, PyObject *args);
PyObject *ruler_profile(PyObject *self, PyObject *args);
PyObject *ruler_cosines(PyObject *self, PyObject *args);
PyObject *ruler_tip_contrasts(PyObject *self, PyObject *args);
PyObject *ruler_tip_fit(PyObject *self, PyObject *args);
PyObject *ruler_correction(PyObject *self, PyObject *args);
PyObject *ruler_windows(PyObject *self, PyObject *args);
PyObject *ruler_template(PyObject *self, PyObject *args);

#define RULER_KERNEL_METHODS                                                                              \
    {"ruler_bins", ruler_bins, METH_VARARGS, "The ruler's pass over the pixels: each into its strip's bin."}, \
    {"ruler_fit", ruler_fit, METH_VARARGS, "One least-squares round of every ruler phase window."},         \
    {"ruler_profile", ruler_profile, METH_VARARGS, "The ruler windows' profiles folded into fine bins."},   \
    {"ruler_cosines", ruler_cosines, METH_VARARGS, "The ruler template's cosine moments."},                \
    {"ruler_tip_contrasts", ruler_tip_contrasts, METH_VARARGS, "The ruler tip zones' strip contrasts."},   \
    {"ruler_tip_fit", ruler_tip_fit, METH_VARARGS, "The ruler tip zone's blurred step, fitted."},           \
    {"ruler_correction", ruler_correction, METH_VARARGS, "The ruler frame's robust correction, fitted."},  \
    {"ruler_windows", ruler_windows, METH_VARARGS, "The ruler's phase windows from their bins."},         \
    {"ruler_template", ruler_template, METH_VARARGS, "The ruler's template and its slope at phases."},

#endif
