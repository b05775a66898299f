"""The compiled kernels of the measurement core (station/vision/_ckernels.c, issue 12; the ruler's,
station/vision/_ruler_*.c, issue 22).

Everything else about the package is declared in pyproject.toml. The extension is plain C on the
buffer protocol (Python.h and libm only, no numpy headers at build time), at -O3 (vectorised loops;
sums are never reassociated without -ffast-math). It is optional: without a C compiler the install
still succeeds and the measurement runs its numpy reference (station/vision/_kernels.py).
-ffp-contract=off: no fused multiply-add, each operation rounds as numpy's does.
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "station.vision._ckernels",
            sources=[
                "station/vision/_ckernels.c",
                "station/vision/_ruler_kernels.c",
                "station/vision/_ruler_template.c",
                "station/vision/_ruler_fits.c",
            ],
            depends=["station/vision/_ruler_kernels.h", "station/vision/_ruler_common.h"],
            extra_compile_args=["-O3", "-ffp-contract=off", "-fno-fast-math", "-std=c99"],
            optional=True,
        )
    ]
)
