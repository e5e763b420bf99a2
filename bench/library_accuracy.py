"""Accuracy of the library's RK4 sub-steps: 4 and 9 sub-steps against 72, per health state.

    .venv/bin/python bench/library_accuracy.py

0.5 s at 45 deg/s and 75 N m (after 0.1 s), x channel, 48 kHz.  Prints, per state and sub-step count, the RMS
of the difference of the Welch log-PSD (4096 points) over 50 Hz-20 kHz against 72 sub-steps, the relative L2
difference of the signal and its RMS ratio.  docs/model.md section 7 ("Accuracy at the library's 4
sub-steps") holds the figures.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch
from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.library.states import tooth_faults
from rvdiag.params import ReducerParams

P0 = ReducerParams.default()
CASES = {"T1": {}, "T2": {"broken_fraction": 1.0}, "T3": {"wear_depth": 10e-6},
         "T4": {"crack_depth": 1.8e-3, "crack_angle_deg": 35.0},
         "T6": {"broken_fraction": 1.0, "wear_depth": 10e-6, "crack_depth": 1.8e-3, "crack_angle_deg": 35.0}}


def main() -> None:
    for st, sev in CASES.items():
        f = tooth_faults(st, **sev)
        out = {}
        for S in (4, 9, 72):
            r = simulate(P0, f, output_speed_deg_s=45.0, load_Nm=75.0, duration_s=0.5, fs=48000.0,
                         settings=ModelSettings(substeps=S, transient_s=0.1))
            fr, p = welch(r.signal[0], 48000.0, nperseg=4096)
            out[S] = (r.signal[0], 10 * np.log10(p))
        band = (fr >= 50) & (fr <= 20000)
        ref_s, ref_p = out[72]
        for S in (4, 9):
            s, p = out[S]
            print(st, S, "logPSD rms dB %.2f" % np.sqrt(np.mean((p - ref_p)[band] ** 2)),
                  "rel L2 %.3f" % (np.linalg.norm(s - ref_s) / np.linalg.norm(ref_s)),
                  "rms ratio %.3f" % (s.std() / ref_s.std()), flush=True)


if __name__ == "__main__":
    main()
