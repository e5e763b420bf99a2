"""EEMD speed: rvdiag's numba EEMD against PyEMD's EEMD on 8000-point signals, same ensemble size.

Usage::

    .venv/bin/python bench/eemd_speed.py [--n 8000] [--trials 100] [--repeats 2] [--imfs 6]

Both decompose the same signal (two tones, a trend and white noise) into ``--imfs`` IMFs with the same
ensemble size and the same noise std (PyEMD scales its noise by the signal's range, rvdiag by its std;
the script converts).  PyEMD runs single-process (``parallel=False``), rvdiag on one thread, so the ratio
is per core.  The first rvdiag call (numba compilation or cache load) is not timed.  Prints one line per
implementation and the ratio of the median wall times.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def signal(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    return (np.sin(2 * np.pi * 0.03 * t) + 0.5 * np.sin(2 * np.pi * 0.003 * t) + 1e-4 * t
            + 0.3 * rng.standard_normal(n))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=8000)
    ap.add_argument("--trials", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--imfs", type=int, default=6)
    ap.add_argument("--noise", type=float, default=0.2, help="noise std relative to the signal std")
    a = ap.parse_args(argv)

    from PyEMD import EEMD

    from rvdiag.features.eemd import eemd

    x = signal(a.n)
    eemd(x[:64], n_imfs=a.imfs, ensemble_size=2)  # compile / load the numba cache
    ours, ref = [], []
    for r in range(a.repeats):
        t0 = time.perf_counter()
        eemd(x, n_imfs=a.imfs, ensemble_size=a.trials, noise_width=a.noise, seed=r)
        ours.append(time.perf_counter() - t0)
        e = EEMD(trials=a.trials, noise_width=a.noise * x.std() / np.ptp(x), parallel=False)
        e.noise_seed(r)
        t0 = time.perf_counter()
        e.eemd(x, max_imf=a.imfs)
        ref.append(time.perf_counter() - t0)
    mo, mr = statistics.median(ours), statistics.median(ref)
    print(f"signal n={a.n}, ensemble={a.trials}, imfs={a.imfs}, repeats={a.repeats}")
    print(f"rvdiag numba EEMD : median {mo:.3f} s  ({', '.join(f'{v:.3f}' for v in ours)})")
    print(f"PyEMD EEMD        : median {mr:.3f} s  ({', '.join(f'{v:.3f}' for v in ref)})")
    print(f"speed ratio PyEMD / rvdiag = {mr / mo:.1f}x")


if __name__ == "__main__":
    main()
