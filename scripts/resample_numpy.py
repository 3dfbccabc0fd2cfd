#!/usr/bin/env python3
"""Time scipy.signal.resample of 1800 points to 131072 on this machine.

The reference for the Rust figure of `cargo bench -p survey-tables --bench
pipeline` ("spectral resampling 1800 -> 131072"): the same band-limited
(FFT zero-padding) resampling, the same sizes, a signal like the paper's
Figure 8 positioner (20:1 gear pass, its 2nd harmonic, eccentricity).

Needs numpy and scipy from PyPI:

    python3 -m venv /tmp/np && /tmp/np/bin/pip install numpy scipy
    /tmp/np/bin/python scripts/resample_numpy.py

Prints the median and best time of one call, in milliseconds, after a
warm-up (scipy.fft caches its plans, as the Rust Resampler does), and checks
the result against the signal itself.
"""

import statistics
import sys
import time

import numpy as np
import scipy
from scipy.signal import resample

N, M = 1800, 131072
REPEATS = 200


def signal(theta_deg):
    t = np.radians(theta_deg)
    return 0.0078 * np.sin(20 * t) + 0.0025 * np.sin(40 * t + np.radians(60)) + 0.0015 * np.sin(t + np.radians(110))


def main():
    y = signal(np.arange(N) * 360.0 / N)
    out = resample(y, M)  # warm-up: plans cached
    err = np.max(np.abs(out - signal(np.arange(M) * 360.0 / M)))
    if err > 1e-12:
        sys.exit(f"resampling is not exact: max error {err:.3e}")
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        resample(y, M)
        times.append(time.perf_counter() - start)
    ms = [t * 1e3 for t in times]
    print(
        f"scipy.signal.resample {N} -> {M}: median {statistics.median(ms):.3f} ms, best {min(ms):.3f} ms "
        f"over {REPEATS} calls (numpy {np.__version__}, scipy {scipy.__version__})"
    )


if __name__ == "__main__":
    main()
