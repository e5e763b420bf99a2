"""Speed of the angle-domain core: TSA and the gear condition indicators of a 60 s, 48 kHz record on one core,
against scipy.signal.resample_poly doing the resampling on the same data in the same run.

Signal: the stage-1 mesh (order 11 of the sun relative to the carrier, 3 harmonics) at 45 deg/s output (sun shaft
15 Hz) plus white noise.  ``ours_s``: :func:`rvdiag.features.orders.angle_from_speed`, ``resample_to_angle``
(anti-alias FFT low-pass + Keys cubic interpolation, 2048 samples per revolution), ``tsa`` and
``condition_indicators``.  ``resample_poly_s``: ``scipy.signal.resample_poly(x, 16, 25)`` (exactly 2048 samples per
revolution at this speed: 48000 x 16/25 / 15) followed by the same ``tsa`` and ``condition_indicators``; a
rational resampler serves a constant speed only.  ``encoder_s``: ours again from a per-sample angle array (the
variable-speed path, np.interp for the sample instants).  Best of ``--repeat`` runs, wall and CPU time;
``ratio`` = ours_s / resample_poly_s (below 1: ours is faster).

Usage: ``OMP_NUM_THREADS=1 python bench/tsa_speed.py [--json] [--seconds S] [--repeat N]``
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
from scipy.signal import resample_poly  # noqa: E402

from rvdiag.features import orders as o  # noqa: E402

FS, F_SUN, SPR, MESH = 48000.0, 15.0, 2048, 11


def _best(fn, repeat):
    wall, cpu = [], []
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - w)
        cpu.append(time.process_time() - c)
    return min(wall), min(cpu), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    n = int(a.seconds * FS)
    t = np.arange(n) / FS
    x = sum(np.cos(2 * np.pi * h * MESH * F_SUN * t) / h for h in (1, 2, 3))
    x = x + np.random.default_rng(0).standard_normal(n)

    def ours():
        xa = o.resample_to_angle(x, FS, o.angle_from_speed(n, FS, F_SUN), SPR)
        return o.condition_indicators(o.tsa(xa, SPR), MESH)

    angle = 2 * np.pi * o.angle_from_speed(n, FS, F_SUN) * (1 + 1e-12 * t)  # not uniform: the general path

    def encoder():
        xa = o.resample_to_angle(x, FS, o.angle_from_encoder(angle, FS), SPR)
        return o.condition_indicators(o.tsa(xa, SPR), MESH)

    def poly():
        xa = resample_poly(x, 16, 25)
        return o.condition_indicators(o.tsa(xa, SPR), MESH)

    ours_w, ours_c, ci = _best(ours, a.repeat)
    enc_w, enc_c, _ = _best(encoder, a.repeat)
    poly_w, poly_c, ci_poly = _best(poly, a.repeat)
    res = {"seconds": a.seconds, "fs": FS, "samples_per_rev": SPR, "ours_s": ours_w, "ours_cpu_s": ours_c,
           "encoder_s": enc_w, "encoder_cpu_s": enc_c, "resample_poly_s": poly_w, "resample_poly_cpu_s": poly_c,
           "ratio": ours_w / poly_w, "ratio_cpu": ours_c / poly_c,
           "fm4": ci["fm4"], "fm4_resample_poly": ci_poly["fm4"]}
    if a.json:
        print(json.dumps(res))
        return
    for k, v in res.items():
        print(f"{k:22s} {v:.4g}")


if __name__ == "__main__":
    main()
