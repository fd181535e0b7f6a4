"""One thread for numba, OpenMP and BLAS in the footage benchmarks, whose figures are for
one core. Imported first, before numpy, OpenCV or numba load (they read these variables
once, when they start). In a process where numba already runs (a test that loads a
script) it changes nothing: numba refuses a changed ``NUMBA_NUM_THREADS`` at its next
compilation."""

import os
import sys

if "numba" not in sys.modules:
    for _name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                  "MKL_NUM_THREADS"):
        os.environ[_name] = "1"
