"""Similarity of a simulated and a measured healthy signal: Pearson correlation of spectra (or of the records).

Model updating needs a score that says how much a simulated record looks like a measured one although the two
were never started together.  Three are offered; every one is the Pearson correlation coefficient (PCC) of two
feature vectors, so 1 is a perfect match and the score does not depend on the overall gain:

``logspec`` (default)
    PCC of the log power spectra (Welch, Hann window, same ``nperseg`` and ``fs`` for both records) over
    ``(0, min(fs/2, 12 kHz)]``.  A power spectrum does not depend on where a stationary record starts, so two
    independent records of the same machine compare; the logarithm weighs a resonance 40 dB down as much as the
    dominant mesh line (the linear spectrum would be decided by its two highest peaks); and a gain error (sensor
    sensitivity, an unknown transfer gain) adds a constant to the log spectrum, to which the PCC is blind.  What
    is left is the shape: where the resonances sit and how wide they are, which is what the stiffnesses, masses
    and damping ratios set.  A measured record also holds noise the model lacks (sensor, amplifier, other
    machines); where the machine's spectrum is weak this floor is all the measured spectrum shows, and the
    log weighs it as much as the resonances.  So the simulated power spectrum gets a fitted floor before the
    logarithm: ``P_sim(f) + r s(f)``, with ``s`` white (flat) or pink (``1/f``), both scaled to the band mean
    of ``P_sim``, and the level ``r`` (none, or -80..+10 dB) chosen for the best PCC (a nuisance parameter,
    fitted per record in microseconds; with no floor in the measured record ``r`` tends to none).
``envelope``
    PCC of the envelope spectra (amplitude of the Hilbert envelope's spectrum) over ``(0, 1 kHz]``: the rates of
    the impacts and modulations that excite the resonances, the classical tool of bearing and gear diagnostics
    (Randall 2011, *Vibration-based Condition Monitoring*, Wiley, ch. 5.5).  Blind to where the resonances sit.
``time``
    PCC of the records themselves (the first common samples).  Depends on phase: only meaningful when the
    measured record is phase-locked to the simulation (e.g. a simulated record, or a record triggered on the
    same shaft angle); between two independent records it is near 0 whatever the parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal as sps

from rvdiag.errors import ParameterError

OBJECTIVES = ("logspec", "envelope", "time")
#: upper end of the log-spectrum band (Hz): an industrial accelerometer's useful band ends near 10 kHz
LOGSPEC_FMAX_HZ = 12000.0
#: upper end of the envelope-spectrum band (Hz): mesh, pin and shaft rates of an RV reducer lie below it
ENVELOPE_FMAX_HZ = 1000.0


def pcc(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation coefficient of two equally long vectors (0 when either is constant)."""
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.shape != b.shape:
        raise ValueError(f"pcc needs vectors of one length, got {a.size} and {b.size}")
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float(a @ a) * float(b @ b))
    if not den > 0 or not math.isfinite(den):
        return 0.0
    return float(np.clip((a @ b) / den, -1.0, 1.0))


def _rowwise_pcc(rows: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """PCC of every row of ``rows`` with ``ref``."""
    a = rows - rows.mean(axis=1, keepdims=True)
    b = ref - ref.mean()
    den = np.sqrt((a * a).sum(axis=1) * float(b @ b))
    with np.errstate(invalid="ignore", divide="ignore"):
        out = (a @ b) / den
    return np.where(np.isfinite(out), out, -1.0)


def welch_nperseg(n_samples: int) -> int:
    """Welch segment length used for a record of ``n_samples``: the largest power of 2 <= n/4 (at least 64).

    A 0.5 s record at 48 kHz gets 4096 (11.7 Hz resolution, 10 half-overlapping segments).
    """
    return max(64, 1 << int(math.floor(math.log2(max(n_samples // 4, 64)))))


def log_spectrum(x: np.ndarray, fs: float, nperseg: int, fmax: float = LOGSPEC_FMAX_HZ,
                 power: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies and log power spectrum (dB, Welch, Hann, 50 % overlap) over ``(0, min(fs/2, fmax)]``.

    A floor 120 dB below the spectrum's maximum keeps an empty band finite; it scales with the signal, so the
    PCC stays exactly gain-invariant.  ``power=True`` returns the power spectrum itself (no log, no floor).
    """
    x = np.asarray(x, dtype=np.float64)
    f, p = sps.welch(x - x.mean(), fs=fs, nperseg=min(nperseg, x.size), detrend=False)
    keep = (f > 0) & (f <= min(0.5 * fs, fmax))
    p = p[keep]
    if power:
        return f[keep], p
    floor = 1e-12 * float(p.max()) if p.size and p.max() > 0 else 1e-300
    return f[keep], 10.0 * np.log10(p + floor)


def envelope_spectrum(x: np.ndarray, fs: float, nperseg: int,
                      fmax: float = ENVELOPE_FMAX_HZ) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies and amplitude of the envelope spectrum over ``(0, min(fs/4, fmax)]``.

    The envelope is the modulus of the analytic signal (Hilbert transform) of the mean-free record; its mean is
    removed and its power spectrum estimated by Welch; the square root is returned (Randall 2011, ch. 5.5).
    """
    x = np.asarray(x, dtype=np.float64)
    env = np.abs(sps.hilbert(x - x.mean()))
    f, p = sps.welch(env - env.mean(), fs=fs, nperseg=min(nperseg, env.size), detrend=False)
    keep = (f > 0) & (f <= min(0.25 * fs, fmax))
    return f[keep], np.sqrt(p[keep])


@dataclass
class Objective:
    """A measured record and the feature it is compared on; :meth:`score` gives the PCC of a simulated record.

    Parameters
    ----------
    name : {"logspec", "envelope", "time"}
    measured : ndarray, 1-D
    fs : float
    sim_samples : int
        Length of the simulated records that will be scored; sets ``nperseg`` (the same for both records, so the
        two spectra share their frequency grid and resolution).
    fit_floor : bool
        ``logspec`` only: add the fitted noise floor of :meth:`noise_floor` to the simulated spectrum.
    """

    name: str
    measured: np.ndarray
    fs: float
    sim_samples: int
    fit_floor: bool = True
    nperseg: int = field(init=False)
    reference: np.ndarray = field(init=False, repr=False)
    freqs: np.ndarray | None = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.name not in OBJECTIVES:
            raise ParameterError(f"unknown objective {self.name!r}; choose one of {', '.join(OBJECTIVES)}")
        self.measured = np.asarray(self.measured, dtype=np.float64)
        if self.name == "envelope":
            self.nperseg = max(64, 1 << int(math.floor(math.log2(max(self.sim_samples // 2, 64)))))
        else:
            self.nperseg = welch_nperseg(self.sim_samples)
        self.freqs, self.reference = self.feature(self.measured)

    def feature(self, x: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        """(frequencies or None, feature vector) of a record: what the PCC is taken of."""
        x = np.asarray(x, dtype=np.float64)
        if self.name == "logspec":
            return log_spectrum(x, self.fs, self.nperseg)
        if self.name == "envelope":
            return envelope_spectrum(x, self.fs, self.nperseg)
        return None, x - x.mean()

    def noise_floor(self, psd: np.ndarray) -> tuple[float, np.ndarray]:
        """Best PCC of ``log(psd + r s)`` with the measured log spectrum, and the floor ``r s`` that gives it.

        ``psd`` is a simulated power spectrum on :attr:`freqs`; the candidates are no floor and a white or pink
        floor from -80 to +10 dB of its band mean (2 dB grid, then a 0.25 dB grid around the best).
        """
        mean = float(psd.mean()) if psd.size and psd.mean() > 0 else 1.0
        shapes = (np.ones_like(self.freqs), self.freqs.mean() / self.freqs)
        best = (-2.0, np.zeros_like(psd))

        def try_levels(shape: np.ndarray, levels_db: np.ndarray) -> None:
            nonlocal best
            floors = (mean * 10.0 ** (levels_db / 10.0))[:, None] * shape[None, :]
            scores = _rowwise_pcc(10.0 * np.log10(psd[None, :] + floors + 1e-300), self.reference)
            k = int(np.argmax(scores))
            if scores[k] > best[0]:
                best = (float(scores[k]), floors[k])

        best = (pcc(10.0 * np.log10(psd + 1e-12 * max(float(psd.max()), 1e-300)), self.reference),
                np.zeros_like(psd))
        for shape in shapes:
            before = best[0]
            try_levels(shape, np.arange(-80.0, 10.01, 2.0))
            if best[0] > before:
                level = 10.0 * np.log10(float(best[1][0] / shape[0]) / mean)
                try_levels(shape, level + np.arange(-2.0, 2.01, 0.25))
        return best

    def score(self, simulated: np.ndarray) -> float:
        """PCC between the simulated record's feature and the measured one's (-1 when the record is not finite)."""
        simulated = np.asarray(simulated, dtype=np.float64)
        if simulated.size == 0 or not np.all(np.isfinite(simulated)):
            return -1.0
        ref = self.reference
        if self.name == "logspec" and self.fit_floor:
            _, psd = log_spectrum(simulated, self.fs, self.nperseg, power=True)
            return self.noise_floor(psd)[0]
        _, feat = self.feature(simulated)
        if self.name == "time":
            n = min(feat.size, ref.size)
            return pcc(feat[:n], ref[:n])
        return pcc(feat, ref)
