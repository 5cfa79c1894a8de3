"""Visual inspection (paper section 2.2).

The inspection multiplies many small arrays (thousands of points by a 3x3 rotation): OpenBLAS's
worker threads cost more there than they save, and far more when another process holds a core
(`vi_benchmark`, 640x480 scans of paper_14: 45 -> 36 ms per scan idle, 76 -> 47 ms beside a busy
core). Every inspection process therefore runs BLAS on one thread unless the user says otherwise;
this must happen before NumPy is first imported, which every executable of this package does after
importing the package.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
