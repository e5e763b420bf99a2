"""Can a median-tooth feature see wear of the sun under a broken sun tooth (T5 against T2)?  Measured on the paired
records of research/monitoring_pairs.py.

    PYTHONPATH=src nice python research/monitoring_pairs.py --reducers 12 --per-state 5 --out out/monitoring_pairs.npz
    PYTHONPATH=src nice python research/tooth_median.py out/monitoring_pairs.npz --out out/tooth_median.npz

(or one pair file per reducer, ``monitoring_pairs.py --only R --out out/pairs_rR.npz`` for R = 0..11, all of them
given here: the same records, two processes at a time).

Idea: a broken sun tooth acts on one tooth (per planet pass), wear on every tooth.  The sun TSA relative to the
carrier (:func:`rvdiag.features.relative.sun_tsa`) is cut into its ``Z1`` tooth-mesh segments (Fourier-resampled to
a multiple of Z1 points; the TSA is periodic) and the median over the segments is taken point by point: a robust
"typical tooth" (the periodic mesh part) that ignores the few segments the broken tooth's impacts fall in.  Each
segment minus the median tooth is the impulsive part.  With Z1 = 11 teeth and N = 2 planets the broken tooth's two
impacts per revolution fall half a pitch apart in phase (11 / 2 = 5.5 pitches), i.e. into two or three of the
eleven segments; the median over eleven ignores up to five.

Features per record (absolute) and of the change since the same reducer's baseline windows at the same nominal
operating point (mean of their aligned TSAs, as :func:`rvdiag.features.relative.tsa_change_features`); see
:func:`absolute_features` and :func:`change_features` for the list.  Prints AUCs pooled over the reducers (max(a,
1-a)) of T5 vs T2, T6 vs T2, T3 vs T1, T2 vs T1, T5 vs T1 for each feature, and leave-3-reducers-out figures of
:class:`rvdiag.monitoring.BaselineMonitor` on the TSA change features with and without the best of these
added.
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np

from rvdiag.features import orders as _o
from rvdiag.features.relative import MEDIAN_TOOTH_NAMES, TSA_CHANGE_NAMES, align, sun_tsa, tsa_change_features
from rvdiag.features.tsa import tooth_indicators

H = 4  # mesh harmonics of the median tooth


def tooth_segments(t: np.ndarray, teeth: int) -> np.ndarray:
    """The periodic TSA ``t`` Fourier-resampled to ``teeth * m`` points (m = ceil(n / teeth)) and cut into
    ``teeth`` rows of one tooth-mesh period each."""
    n = t.size
    m = int(np.ceil(n / teeth))
    L = teeth * m
    T = np.fft.rfft(t)
    if n % 2 == 0 and L > n:
        T[-1] *= 0.5  # the Nyquist bin becomes an interior bin (its conjugate half is added by irfft)
    return (np.fft.irfft(T, L) * (L / n)).reshape(teeth, m)


def tooth_parts(t, teeth: int, trim: int = 3):
    """Median tooth, trimmed-mean tooth (``trim`` largest-deviation segments left out) and per-segment deviation
    energies (from the median) of the TSA ``t``."""
    S = tooth_segments(t - t.mean(), teeth)
    M = np.median(S, axis=0)
    e = ((S - M) ** 2).mean(axis=1)
    keep = np.argsort(e)[: teeth - trim]
    Mt = S[keep].mean(axis=0)
    return S, M, Mt, e


def harmonics(M, k: int = H) -> np.ndarray:
    """Amplitudes of the first ``k`` harmonics of one tooth period ``M`` (mesh harmonics 1..k)."""
    return np.abs(np.fft.rfft(M))[1:k + 1] * 2.0 / M.size


BANDS = ((1, 4), (5, 16), (17, 10**6))  # mesh-harmonic bands of the median tooth


def band_rms(M) -> np.ndarray:
    """RMS of the median tooth ``M`` in each of :data:`BANDS` (mesh harmonics lo..hi)."""
    a = np.abs(np.fft.rfft(M)) * 2.0 / M.size
    return np.array([np.sqrt(np.sum(a[lo:min(hi, a.size - 1) + 1] ** 2) / 2) for lo, hi in BANDS])


def rms(v) -> float:
    v = np.asarray(v, dtype=np.float64)
    return float(np.sqrt(np.mean((v - v.mean()) ** 2)))


ABS_NAMES = ([f"med_h{k}_over_tsa" for k in range(1, H + 1)] + [f"med_h{k}_over_raw" for k in range(1, H + 1)]
             + [f"med_h{k}_over_crank" for k in range(1, H + 1)] + [f"med_h{k}_share" for k in range(1, H + 1)]
             + ["med_rms_over_tsa", "med_rms_over_raw", "med_rms_over_crank", "med_ptp_over_rms",
                "trim_h1_over_tsa", "trim_rms_over_tsa", "trim_rms_over_raw",
                "dev_all_over_med", "dev_trim_over_med", "dev_max_over_median_dev", "dev_trim_over_tsa",
                "med_crest"] + [f"med_band{b}_over_tsa" for b in range(len(BANDS))]
             + [f"med_band{b}_over_crank" for b in range(len(BANDS))])


def crank_level(x, fs, speed, params) -> float:
    """RMS of the crank-shaft TSA's cycloid mesh harmonics (the second stage: no sun fault acts on it), the level
    the sun's median tooth is normalised by in ``*_over_crank``."""
    f = _o.shaft_frequency("crank", params, output_speed_deg_s=speed)
    m = _o.mesh_order("crank", params)
    spr = _o.default_samples_per_rev(fs, f, m)
    xa = _o.resample_to_angle(x, fs, _o.angle_from_speed(x.size, fs, f), spr)
    amp = _o.gear_signals(_o.tsa(xa, spr), m)["amplitude"]
    return float(np.sqrt(np.sum(amp[[k * m for k in range(1, 4) if k * m < amp.size]] ** 2) / 2))


def absolute_features(t, raw_rms, crank, teeth):
    S, M, Mt, e = tooth_parts(t, teeth)
    h, ht = harmonics(M), harmonics(Mt)
    tr = rms(t)
    srt = np.sort(e)
    pm = float(np.mean(M**2))
    v = (list(h / tr) + list(h / raw_rms) + list(h / crank) + list(h / np.sqrt(np.sum(h**2)))
         + [rms(M) / tr, rms(M) / raw_rms, rms(M) / crank, np.ptp(M) / rms(M), ht[0] / tr, rms(Mt) / tr,
            rms(Mt) / raw_rms, e.mean() / pm, srt[:-3].mean() / pm, srt[-1] / np.median(e), srt[:-3].mean() / tr**2,
            np.max(np.abs(M)) / rms(M)] + list(band_rms(M) / tr) + list(band_rms(M) / crank))
    return np.log10(np.maximum(np.array(v, dtype=np.float64), 1e-12))


CHG_NAMES = (["d_med", "d_trim"] + [f"r_med_h{k}" for k in range(1, H + 1)]
             + [f"r_med_h{k}_over_crank" for k in range(1, H + 1)]
             + ["r_med_rms", "r_med_rms_over_crank", "r_med_rms_over_raw", "r_trim_rms", "r_dev_trim",
                "d_med_z", "d_trim_z", "d_med_over_tsa_change"] + [f"r_med_band{b}" for b in range(len(BANDS))]
             + ["r_med_rms_z", "r_med_band2_z"])


def _align_tooth(M, ref):
    return align(M, ref)


def _chg(t, ref, teeth, crank, crank_b, raw, raw_b):
    """Raw change figures of the TSA ``t`` against the reference TSA ``ref`` (both of the same reducer)."""
    t = align(t, ref)
    _, M, Mt, e = tooth_parts(t, teeth)
    _, Mb, Mtb, eb = tooth_parts(ref, teeth)
    M, Mt = _align_tooth(M, Mb), _align_tooth(Mt, Mtb)
    h, hb = harmonics(M), harmonics(Mb)
    d_med = np.linalg.norm(M - Mb) / np.linalg.norm(Mb)
    d_trim = np.linalg.norm(Mt - Mtb) / np.linalg.norm(Mtb)
    tsa_c = np.linalg.norm(t - ref) / np.linalg.norm(ref)
    trim_dev = np.sort(e)[:-3].mean() / np.sort(eb)[:-3].mean()
    return (d_med, d_trim, h / hb, (h / crank) / (hb / crank_b), rms(M) / rms(Mb),
            (rms(M) / crank) / (rms(Mb) / crank_b), (rms(M) / raw) / (rms(Mb) / raw_b), rms(Mt) / rms(Mtb),
            trim_dev, tsa_c, band_rms(M) / band_rms(Mb))


def change_features(t, Tb, teeth, crank, crank_bs, raw, raw_bs):
    """Median-tooth change of ``t`` against the mean of the aligned baseline TSAs ``Tb``: ``d_med`` ||M - M_b|| /
    ||M_b|| of the median tooth (aligned within one pitch), ``d_trim`` the same of the trimmed-mean tooth, ``r_*``
    ratios of the median tooth's harmonic amplitudes, RMS (alone, over the crank mesh level, over the raw RMS), of
    the trimmed tooth's RMS and of the trimmed deviation energy; ``*_z`` over the median of the same figure of each
    baseline window left out against the others (the reducer's run-to-run spread)."""
    Tb = [Tb[0]] + [align(b, Tb[0]) for b in Tb[1:]]
    ref = np.mean(Tb, axis=0)
    cb, rb = float(np.mean(crank_bs)), float(np.mean(raw_bs))
    c = _chg(t, ref, teeth, crank, cb, raw, rb)
    loo = []
    for j in range(len(Tb)):
        o = [i for i in range(len(Tb)) if i != j]
        cj = _chg(Tb[j], np.mean([Tb[i] for i in o], axis=0), teeth, crank_bs[j], np.mean([crank_bs[i] for i in o]),
                  raw_bs[j], np.mean([raw_bs[i] for i in o]))
        loo.append((cj[0], cj[1], abs(np.log(cj[4])), abs(np.log(cj[10][2]))))
    own = np.median(loo, axis=0)
    v = np.r_[c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[0] / own[0], c[1] / own[1], c[0] / c[9], c[10],
              np.exp(np.log(c[4]) / own[2]), np.exp(np.log(c[10][2]) / own[3])]
    return np.log10(np.maximum(v, 1e-12))


def load_pairs(paths) -> tuple[np.ndarray, list, float]:
    """Records, metadata and rate of one or more outputs of research/monitoring_pairs.py (e.g. one per reducer
    from its ``--only``), concatenated."""
    X, meta, fs = [], [], set()
    for path in paths:
        z = np.load(path)
        X.append(z["X"].astype(np.float64))
        meta += json.loads(str(z["meta"]))
        fs.add(float(z["fs"]))
    if len(fs) != 1:
        raise SystemExit(f"the pair files have different rates {sorted(fs)}")
    return np.concatenate(X), meta, fs.pop()


def features(paths) -> dict:
    X, meta, fs = load_pairs(paths)
    p = _o._params(None)
    teeth = int(p.stage1.sun_teeth)
    speed = np.array([m["output_speed_deg_s"] for m in meta])
    red = np.array([m["reducer"] for m in meta])
    op = np.array([m["op"] for m in meta])
    role = np.array([m["role"] for m in meta])
    T, A, L, crank, raw = [], [], [], [], []
    for x, v in zip(X, speed):
        f = _o.shaft_frequency("sun", p, output_speed_deg_s=v)
        spr = _o.default_samples_per_rev(fs, f, teeth)  # a power of two: the same for +-1 % speed
        t = sun_tsa(x, fs, v, spr, p)
        T.append(t)
        crank.append(crank_level(x, fs, v, p))
        raw.append(rms(x))
        A.append(absolute_features(t, raw[-1], crank[-1], teeth))
        L.append(np.log10(np.maximum(list(tooth_indicators(t, teeth, 2 * int(p.stage1.n_planets)).values()), 1e-12)))
    mon = np.flatnonzero(role == "monitored")
    C, TC = [], []
    for i in mon:
        b = np.flatnonzero((red == red[i]) & (op == op[i]) & (role == "baseline"))
        C.append(change_features(T[i], [T[j] for j in b], teeth, crank[i], [crank[j] for j in b], raw[i],
                                 [raw[j] for j in b]))
        TC.append(tsa_change_features(X[i], speed[i], [X[j] for j in b], speed[b], fs, median_tooth=True))
    TC = np.array(TC)
    return {"absolute": np.array(A)[mon], "change": np.array(C), "tsa_change": TC[:, :len(TSA_CHANGE_NAMES)],
            "library_change": TC[:, len(TSA_CHANGE_NAMES):], "library_absolute": np.array(L)[mon],
            "state": np.array([meta[i]["state"] for i in mon]), "reducer": red[mon], "op": op[mon],
            "wear_depth": np.array([meta[i].get("wear_depth", np.nan) for i in mon]),
            "broken_fraction": np.array([meta[i].get("broken_fraction", np.nan) for i in mon])}


def absolute_route(paths):
    """tsa-ci with the median-tooth indicators (columns 9, 10) and the orders set of every monitored record, as
    research/monitoring_features.py computes its absolute features."""
    from rvdiag.features.tsa import OrderSpectrumFeatures, TSAIndicatorFeatures

    X, meta, fs = load_pairs(paths)
    speed = np.array([m["output_speed_deg_s"] for m in meta])
    mon = np.array([m["role"] == "monitored" for m in meta])
    Xs = np.column_stack([X[mon], speed[mon]])
    ci = TSAIndicatorFeatures(fs=fs, speed_column="output_speed_deg_s", median_tooth=True).fit(Xs)
    od = OrderSpectrumFeatures(fs=fs, speed_column="output_speed_deg_s").fit(Xs)
    return (np.column_stack([ci.transform(Xs), od.transform(Xs)]),
            list(ci.get_feature_names_out()) + list(od.get_feature_names_out()))


def auc(a, b) -> float:
    from sklearn.metrics import roc_auc_score

    v = roc_auc_score(np.r_[np.zeros(len(a)), np.ones(len(b))], np.r_[a, b])
    return max(v, 1 - v)


PAIRS = (("T5", "T2"), ("T6", "T2"), ("T3", "T1"), ("T2", "T1"), ("T5", "T1"))


def cross_validate(F, y, reducer, names, folds=4, alpha=0.05, classes=None) -> str:
    folds = min(folds, np.unique(reducer).size)
    from rvdiag.monitoring import BaselineMonitor

    keep = np.all(np.isfinite(F), axis=1) & (np.isin(y, classes) if classes is not None else True)
    reds = np.unique(reducer)
    alarm = np.zeros(y.size, bool)
    pred = np.empty(y.size, dtype=object)
    for k in range(folds):
        test = np.isin(reducer, reds[k::folds]) & keep
        train = ~np.isin(reducer, reds[k::folds]) & keep
        # the split calibration its documented figures were measured with (the monitor's default is now CV+)
        m = BaselineMonitor(alpha=alpha, calibration="split", feature_names=list(names)).fit(
            F[train], y[train], groups=reducer[train])
        alarm[test] = m.alarm(F[test])
        pred[test] = m.predict(F[test])
    parts = [f"FA {alarm[keep & (y == 'T1')].mean():.1%}"]
    rec = {c: float(np.mean(pred[keep & (y == c)] == c)) for c in np.unique(y[keep])}
    parts.append("recall " + " ".join(f"{c} {v:.0%}" for c, v in rec.items()))
    parts.append(f"accuracy {np.mean(pred[keep] == y[keep]):.1%}")
    return "; ".join(parts)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pairs", nargs="+", help="output(s) of research/monitoring_pairs.py")
    ap.add_argument("--out", default="out/tooth_median.npz")
    ap.add_argument("--reuse", action="store_true", help="read the features of --out instead of computing them")
    ap.add_argument("--absolute", action="store_true",
                    help="also the absolute route: tsa-ci (median_tooth=True) + orders of each monitored record, "
                         "leave-3-reducers-out with and without the two median-tooth indicators (a few minutes)")
    a = ap.parse_args()
    if a.reuse and os.path.exists(a.out):
        d = dict(np.load(a.out, allow_pickle=False))
    else:
        d = features(a.pairs)
        np.savez(a.out, **d)
    y = d["state"]
    fams = {"absolute": (d["absolute"], ABS_NAMES), "change": (d["change"], CHG_NAMES),
            "tsa_change": (d["tsa_change"], list(TSA_CHANGE_NAMES)),
            "library: tsa_change_features(median_tooth=True)": (d["library_change"], list(MEDIAN_TOOTH_NAMES)),
            "library: TSAIndicatorFeatures(median_tooth=True)": (d["library_absolute"],
                                                                 ["log10_median_tooth_rms_ratio",
                                                                  "log10_tooth_deviation_trimmed"])}
    print("AUC pooled over reducers, max(a, 1 - a); per feature")
    print(f"  {'feature':28s} " + " ".join(f"{p}v{q}" for p, q in PAIRS))
    for fam, (F, names) in fams.items():
        print(f" [{fam}]")
        for j, n in enumerate(names):
            print(f"  {n:28s} " + " ".join(f"{auc(F[y == q, j], F[y == p, j]):.3f}" for p, q in PAIRS))
    print("T5 vs T2 within each reducer: mean over reducers of the per-reducer AUC (5 + 5 records)")
    for fam, (F, names) in fams.items():
        best = []
        for j, n in enumerate(names):
            r = [auc(F[(d["reducer"] == k) & (y == "T2"), j], F[(d["reducer"] == k) & (y == "T5"), j])
                 for k in np.unique(d["reducer"])]
            best.append((np.mean(r), n))
        best.sort(reverse=True)
        print(f"  {fam}: " + ", ".join(f"{n} {v:.3f}" for v, n in best[:4]))
    print("leave-3-reducers-out BaselineMonitor, alarm alpha 5 %")
    sel = [CHG_NAMES.index(n) for n in ("d_med", "d_med_z", "r_med_h1", "r_med_h2", "r_med_rms")]
    sets = {"tsa_change": (d["tsa_change"], list(TSA_CHANGE_NAMES)),
            "tsa_change + library median tooth (2)": (np.column_stack([d["tsa_change"], d["library_change"]]),
                                                      list(TSA_CHANGE_NAMES) + list(MEDIAN_TOOTH_NAMES)),
            "tsa_change + median tooth (5)": (np.column_stack([d["tsa_change"], d["change"][:, sel]]),
                                             list(TSA_CHANGE_NAMES) + [CHG_NAMES[j] for j in sel]),
            "tsa_change + median tooth (all)": (np.column_stack([d["tsa_change"], d["change"]]),
                                                list(TSA_CHANGE_NAMES) + CHG_NAMES)}
    if a.absolute:
        F, names = absolute_route(a.pairs)
        n = len(names)
        sets["absolute tsa-ci + orders"] = (F[:, [j for j in range(n) if j not in (9, 10)]],
                                            [names[j] for j in range(n) if j not in (9, 10)])
        sets["absolute + median tooth (2)"] = (F, names)
        for j in (9, 10):
            print(f"  absolute {names[j]}: " + " ".join(f"{p}v{q} {auc(F[y == q, j], F[y == p, j]):.3f}"
                                                       for p, q in PAIRS))
    for cls, label in ((None, "six-state"), (["T1", "T2", "T3", "T5"], "crack-free (T1 T2 T3 T5)")):
        for name, (F, names) in sets.items():
            print(f"  {label:26s} {name:38s} {cross_validate(F, y, d['reducer'], names, classes=cls)}")


if __name__ == "__main__":
    main()
