"""The test package. Imported before any conftest (so before numpy): one BLAS thread per test process.

Discovery's products are short (tens of thousands of samples), where OpenBLAS's threads cost more than
they save, and with pytest-xdist's two workers on two cores each worker's second thread spins against
the other worker: under load a dot product of 20 000 samples took 12 ms instead of 4 us, and one seed
of the month matrix ran 2.4 x faster single-threaded. One thread also makes the last digits the same
on every machine (OpenBLAS splits a long dot product into one partial sum per thread). xdist's workers
inherit the setting, and so do the commands the tests start (`nckemu` run by hand is not affected);
OPENBLAS_NUM_THREADS set outside wins."""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
