"""Can the impulsive part of the sun TSA (each tooth-mesh period minus the median tooth) see a broken sun tooth under
heavy wear (T5 / T6 against T3)?  Measured on the paired records of research/monitoring_pairs.py and on a paired
sample store (the monitoring library, configs/monitoring.toml: wear 10-80 um).

    PYTHONPATH=src nice python research/tooth_impulse.py pairs out/pairs_r0.npz ... out/pairs_r11.npz \\
        --out out/tooth_impulse_pairs.npz
    PYTHONPATH=src nice python research/tooth_impulse.py store out/monitoring.zarr --out out/tooth_impulse_store.npz

Idea (the residual / difference signal, as defined in the review of Lebold et al. 2000 after Stewart 1977; McFadden
1987, MSSP 1(2), is cited for it but was not verified here: what is left of the TSA once the regular meshing part is
removed carries a local tooth fault; here the regular part is the median tooth of
:func:`rvdiag.features.orders.median_tooth` rather than the mesh harmonics): wear of every tooth would move every
period alike, so the median tooth would absorb it and the per-period deviations from it would not grow; a broken
tooth moves the two or three periods its N = 2 impacts per revolution fall in.  Candidates, with ``e`` the
per-period deviation energies and ``D`` the deviation signal (segments minus median tooth):

- one TSA: ``dev_max`` max(e) / median(e), ``dev_top2`` / ``dev_top3`` the mean of the 2 / 3 largest over
  median(e), ``dev_kurt`` the normalised fourth moment of D, ``dev_peak`` max|D| / rms(median tooth),
  ``dev_top2_over_tooth`` mean of the 2 largest e over the median tooth's mean square, ``sdev_max`` /
  ``sdev_top2`` as ``dev_*`` after each period's own least-squares scale of the median tooth (an amplitude
  modulation absorbed), ``diff_top2`` / ``diff_kurt`` the largest pitch-slot energies over their median and the
  kurtosis of the difference signal (orders within 2 of a mesh harmonic removed: mesh harmonics, shaft orders,
  the first two planet-pass sidebands), ``dev_med`` median(e) (only its change is meaningful),
  ``dev_med_over_tooth`` / ``dev_med_over_tsa`` median(e) over the median tooth's mean square / the TSA's
  variance, ``dev_top2_e`` the mean of the 2 largest e;
- baseline-referenced: ``r_*`` log10 of the figure minus the mean log10 of the same figure of each baseline TSA
  (each baseline TSA alone: the same averaging, the same noise, as the monitored TSA), ``z_*`` that over the
  median |r| of each baseline TSA against the others; ``c_dev_top2`` / ``c_sdev_top2`` / ``c_diff_top2`` /
  ``c_dev_kurt`` the same figures of the change T - T_b (aligned), ``c_dev_top2_over_b`` the 2 largest
  deviation energies of the change over the median deviation energy of the baseline TSAs.

Result (docs/monitoring.md, "Wear under a broken tooth: the median tooth"; bench/HISTORY.md 2026-11-27): negative.
Wear does not move every period alike in the simulated TSA: it raises the median period's deviation energy by
about as much as a broken tooth raises its two largest, so no candidate beats the existing ``log10_tooth_peak``
on T5 / T6 against T3, and none improves the classifier.

The TSA-change features (:func:`rvdiag.features.relative.tsa_change_features` with the median tooth) are computed
from the same TSAs (:func:`rvdiag.features.relative.tsa_change_from_tsa`).  Prints pooled AUCs (max(a, 1 - a)) of
T5 vs T3, T6 vs T3, T2 vs T1, T3 vs T1, T5 vs T2, by wear-depth bin, and BaselineMonitor figures (pairs:
leave-3-reducers-out; store: its train split against its held-out reducers, one row per record = the mean of its
windows' features, as ``rvdiag train`` scores a record) with and without the new features.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from rvdiag.features import orders as _o
from rvdiag.features.relative import MEDIAN_TOOTH_NAMES, TSA_CHANGE_NAMES, align, sun_tsa

BASE = ("dev_max", "dev_top2", "dev_top3", "dev_kurt", "dev_peak", "dev_top2_over_tooth", "sdev_max", "sdev_top2",
        "diff_top2", "diff_kurt", "dev_med", "dev_med_over_tooth", "dev_med_over_tsa", "dev_top2_e",
        "dev_near_mesh")
NAMES = (list(BASE) + [f"r_{n}" for n in BASE] + [f"z_{n}" for n in BASE]
         + ["c_dev_top2", "c_dev_top2_over_b", "c_dev_kurt", "c_sdev_top2", "c_diff_top2"])


def scaled_dev(S, M):
    """Per-period deviation energies after each period's own least-squares scale of the median tooth (S_k - a_k M,
    a_k = <S_k, M> / <M, M>): an amplitude modulation of every tooth (planet pass, load) absorbed."""
    a = S @ M / max(float(M @ M), 1e-300)
    return ((S - a[:, None] * M) ** 2).mean(axis=1)


def difference(t, teeth, keep_from: int = 3):
    """Stewart's difference signal, for a planetary: the TSA without its orders within ``keep_from - 1`` of a mesh
    harmonic (k Z1 +- 0..2: the mesh harmonics, the shaft orders and the first two planet-pass sidebands)."""
    T = np.fft.rfft(t - t.mean())
    o = np.arange(T.size) % teeth
    T[np.minimum(o, teeth - o) < keep_from] = 0
    return np.fft.irfft(T, t.size)


def near_mesh_share(D, teeth, within: int = 2) -> float:
    """Share of the energy of the deviation signal ``D`` (one revolution) within ``within`` orders of a mesh
    harmonic (orders k Z1 +- 0..within): what a modulation of the mesh signal around the revolution puts there."""
    F = np.abs(np.fft.rfft(D - D.mean())) ** 2
    o = np.arange(F.size) % teeth
    return float(F[np.minimum(o, teeth - o) <= within].sum() / max(F.sum(), 1e-300))


def _slot_top(d, slots, top=2):
    n = d.size - d.size % slots
    e = np.sort((d[:n].reshape(slots, -1) ** 2).sum(axis=1))
    return e[-top:].mean() / max(float(np.median(e)), 1e-300)


def _figures(t, teeth):
    mt = _o.median_tooth(t, teeth)
    S, M, e = mt["segments"], mt["median"], mt["deviation"]
    D = S - M
    s = np.sort(e)
    med = float(np.median(e))
    es = np.sort(scaled_dev(S, M))
    df = difference(t, teeth)
    return np.array([s[-1] / med, s[-2:].mean() / med, s[-3:].mean() / med, _o.normalised_moment(D.ravel(), 4),
                     np.max(np.abs(D)) / np.std(M), s[-2:].mean() / np.mean(M**2), es[-1] / np.median(es),
                     es[-2:].mean() / np.median(es), _slot_top(df, teeth), _o.normalised_moment(df, 4), med, med / np.mean(M**2),
                     med / np.var(t), s[-2:].mean(), near_mesh_share(D.ravel(), teeth)]), med


def impulse_features(t, Tb, teeth):
    """:data:`NAMES` of the TSA ``t`` against the baseline TSAs ``Tb`` (list, same sampling)."""
    Tb = [Tb[0]] + [align(b, Tb[0]) for b in Tb[1:]]
    ref = np.mean(Tb, axis=0)
    f, _ = _figures(t, teeth)
    fb = [_figures(b, teeth) for b in Tb]
    Lb = np.log10(np.array([x[0] for x in fb]))
    r = np.log10(f) - Lb.mean(axis=0)
    if len(Tb) >= 2:
        loo = np.array([np.abs(Lb[j] - np.delete(Lb, j, axis=0).mean(axis=0)) for j in range(len(Tb))])
        z = r / np.median(loo, axis=0)
    else:
        z = np.full(r.size, np.nan)
    d = align(t, ref) - ref
    mt = _o.median_tooth(d, teeth)
    e = np.sort(mt["deviation"])
    cb = float(np.median([x[1] for x in fb]))
    c = np.log10([e[-2:].mean() / np.median(e), e[-2:].mean() / cb,
                  _o.normalised_moment((mt["segments"] - mt["median"]).ravel(), 4)])
    es = np.sort(scaled_dev(mt["segments"], mt["median"]))
    c = np.r_[c, np.log10([es[-2:].mean() / np.median(es), _slot_top(difference(d, teeth), teeth)])]
    return np.r_[np.log10(f), r, z, c]


def tsa_change(t, Tb, teeth):
    from rvdiag.features.relative import tsa_change_from_tsa

    return tsa_change_from_tsa(t, Tb, teeth, 2, median_tooth=True)


def _tsas(X, speed, fs, p, teeth):
    out = []
    for x, v in zip(X, speed):
        f = _o.shaft_frequency("sun", p, output_speed_deg_s=float(v))
        out.append(sun_tsa(x, fs, v, _o.default_samples_per_rev(fs, f, teeth), p))
    return out


def pairs_features(paths) -> dict:
    import importlib.util

    spec = importlib.util.spec_from_file_location("tooth_median", os.path.join(os.path.dirname(__file__),
                                                                               "tooth_median.py"))
    tm = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tm)
    X, meta, fs = tm.load_pairs(paths)
    p = _o._params(None)
    teeth = int(p.stage1.sun_teeth)
    speed = np.array([m["output_speed_deg_s"] for m in meta])
    red = np.array([m["reducer"] for m in meta])
    op = np.array([m["op"] for m in meta])
    role = np.array([m["role"] for m in meta])
    T = _tsas(X, speed, fs, p, teeth)
    mon = np.flatnonzero(role == "monitored")
    F, C = [], []
    for i in mon:
        b = np.flatnonzero((red == red[i]) & (op == op[i]) & (role == "baseline"))
        F.append(impulse_features(T[i], [T[j] for j in b], teeth))
        C.append(tsa_change(T[i], [T[j] for j in b], teeth))
    return {"impulse": np.array(F), "tsa_change": np.array(C), "state": np.array([meta[i]["state"] for i in mon]),
            "reducer": red[mon], "record": mon, "split": np.full(mon.size, ""),
            "wear_depth": np.array([meta[i].get("wear_depth", np.nan) for i in mon])}


def store_features(path) -> dict:
    from rvdiag.datasets.store import SampleStore
    from rvdiag.monitoring.pairing import match_baseline

    st = SampleStore.open(path)
    s = st.load("all")
    fs = float(st.fs)
    p = _o._params(None)
    teeth = int(p.stage1.sun_teeth)
    role = np.asarray(s.meta["role"]).astype(str)
    bi, mi = np.flatnonzero(role == "baseline"), np.flatnonzero(role != "baseline")
    X, speed = s.X.astype(np.float64), np.asarray(s.meta["output_speed_deg_s"], dtype=np.float64)
    cache: dict = {}

    def tsa(i, spr):  # every TSA at the monitored window's sampling, as tsa_change_features takes them
        if (i, spr) not in cache:
            cache[(i, spr)] = sun_tsa(X[i], fs, speed[i], spr, p)
        return cache[(i, spr)]

    groups = match_baseline({k: v[mi] for k, v in s.meta.items()}, {k: v[bi] for k, v in s.meta.items()})
    F, C = [], []
    for k, i in enumerate(mi):
        spr = _o.default_samples_per_rev(fs, _o.shaft_frequency("sun", p, output_speed_deg_s=speed[i]), teeth)
        t, Tb = tsa(i, spr), [tsa(bi[j], spr) for j in groups[k]]
        F.append(impulse_features(t, Tb, teeth))
        C.append(tsa_change(t, Tb, teeth))
    m = {k: np.asarray(v)[mi] for k, v in s.meta.items()}
    return {"impulse": np.array(F), "tsa_change": np.array(C), "state": s.y[mi].astype(str),
            "reducer": m["reducer"].astype(int), "record": m["simulation"].astype(int),
            "split": m["split"].astype(str), "wear_depth": m["wear_depth"].astype(float)}


def auc(a, b) -> float:
    from sklearn.metrics import roc_auc_score

    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if a.size == 0 or b.size == 0:
        return float("nan")
    v = roc_auc_score(np.r_[np.zeros(len(a)), np.ones(len(b))], np.r_[a, b])
    return max(v, 1 - v)


PAIRS = (("T5", "T3"), ("T6", "T3"), ("T2", "T1"), ("T3", "T1"), ("T5", "T2"))


def per_record(d):
    """One row per record: the mean of its windows' features (as a monitor scores a record)."""
    key = d["reducer"].astype(np.int64) * 1_000_000 + d["record"].astype(np.int64)  # simulation: per reducer
    idx = [np.flatnonzero(key == k) for k in np.unique(key)]
    out = {k: np.array([d[k][i[0]] for i in idx]) for k in ("state", "reducer", "split", "wear_depth")}
    for k in ("impulse", "tsa_change"):
        out[k] = np.array([np.nanmean(d[k][i], axis=0) for i in idx])
    return out


def evaluate(F, y, red, split, names, classes=None, folds=4, alpha=0.05):
    from rvdiag.monitoring import BaselineMonitor

    keep = np.all(np.isfinite(F), axis=1) & (np.isin(y, classes) if classes is not None else True)
    if np.any(split != ""):
        parts = [(split == "train", split != "train")]
    else:
        reds = np.unique(red)
        parts = [(~np.isin(red, reds[k::folds]), np.isin(red, reds[k::folds])) for k in range(folds)]
    alarm = np.zeros(y.size, bool)
    pred = np.empty(y.size, dtype=object)
    tested = np.zeros(y.size, bool)
    for tr, te in parts:
        tr, te = tr & keep, te & keep
        m = BaselineMonitor(alpha=alpha, calibration="split", feature_names=list(names)).fit(F[tr], y[tr],
                                                                                             groups=red[tr])
        alarm[te] = m.alarm(F[te])
        pred[te] = m.predict(F[te])
        tested |= te
    rec = {c: float(np.mean(pred[tested & (y == c)] == c)) for c in np.unique(y[tested])}
    return (f"FA {alarm[tested & (y == 'T1')].mean():.1%}; recall "
            + " ".join(f"{c} {v:.0%}" for c, v in rec.items())
            + f"; accuracy {np.mean(pred[tested] == y[tested]):.1%}")


def confusion(F, y, red, split, names, merge, alpha=0.05, folds=4):
    """Crack-free confusion with T6 counted as T5 (rows true T1 T2 T3 T5, cols predicted)."""
    from rvdiag.monitoring import BaselineMonitor

    y = np.where(y == "T6", "T5", y) if merge else y
    classes = ["T1", "T2", "T3", "T5"]
    keep = np.all(np.isfinite(F), axis=1) & np.isin(y, classes)
    if np.any(split != ""):
        parts = [(split == "train", split != "train")]
    else:
        reds = np.unique(red)
        parts = [(~np.isin(red, reds[k::folds]), np.isin(red, reds[k::folds])) for k in range(folds)]
    pred = np.empty(y.size, dtype=object)
    alarm = np.zeros(y.size, bool)
    tested = np.zeros(y.size, bool)
    for tr, te in parts:
        tr, te = tr & keep, te & keep
        m = BaselineMonitor(alpha=alpha, calibration="split", feature_names=list(names)).fit(F[tr], y[tr],
                                                                                             groups=red[tr])
        pred[te], alarm[te] = m.predict(F[te]), m.alarm(F[te])
        tested |= te
    C = np.array([[np.sum(tested & (y == a) & (pred == b)) for b in classes] for a in classes])
    return C, float(np.mean(pred[tested] == y[tested])), float(alarm[tested & (y == "T1")].mean())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("kind", choices=["pairs", "store"])
    ap.add_argument("paths", nargs="+")
    ap.add_argument("--out", required=True)
    ap.add_argument("--reuse", action="store_true")
    ap.add_argument("--add", nargs="+", default=["c_sdev_top2", "r_dev_top2_e"],
                    help="the new features added to the monitor's default ones")
    a = ap.parse_args()
    if a.reuse and os.path.exists(a.out):
        d = dict(np.load(a.out, allow_pickle=False))
    else:
        d = pairs_features(a.paths) if a.kind == "pairs" else store_features(a.paths[0])
        np.savez(a.out, **d)
    if a.kind == "store":
        d = per_record(d)
    y, wear = d["state"], d["wear_depth"] * 1e6
    tc_names = list(TSA_CHANGE_NAMES) + list(MEDIAN_TOOTH_NAMES)
    fams = {"impulse": (d["impulse"], NAMES), "tsa_change (+ median tooth)": (d["tsa_change"], tc_names)}
    lo, hi = np.nanmin(wear), np.nanmax(wear)
    bins = [(10, 30), (30, 80)] if hi > 35 else [(5, 12), (12, 20)]
    print(f"{len(y)} monitored records; wear {lo:.1f}-{hi:.1f} um; per state "
          + " ".join(f"{c} {np.sum(y == c)}" for c in np.unique(y)))
    hdr = " ".join(f"{p}v{q}" for p, q in PAIRS) + " " + " ".join(f"T5vT3@{b0}-{b1} T6vT3@{b0}-{b1}"
                                                                 for b0, b1 in bins)
    print(f"AUC pooled, max(a, 1-a)\n  {'feature':28s} {hdr}")

    def inbin(c, b):
        return (y == c) & (wear >= b[0]) & (wear < b[1] + 1e-9)

    for fam, (F, names) in fams.items():
        print(f" [{fam}]")
        for j, n in enumerate(names):
            v = [auc(F[y == q, j], F[y == p, j]) for p, q in PAIRS]
            for b in bins:
                v += [auc(F[inbin("T3", b), j], F[inbin("T5", b), j]), auc(F[inbin("T3", b), j], F[inbin("T6", b), j])]
            print(f"  {n:28s} " + " ".join(f"{x:.3f}" for x in v))
    def col(n):
        return d["impulse"][:, NAMES.index(n)]

    print("change since baseline, decades (median over records): top-2 period energy | median period energy")
    for c in ("T1", "T2", "T3", "T5", "T6"):
        parts = [f"all {np.median(col('r_dev_top2_e')[y == c]):+.2f} | {np.median(col('r_dev_med')[y == c]):+.2f}"]
        if c in ("T3", "T5", "T6"):
            parts += [f"{b0}-{b1} um {np.median(col('r_dev_top2_e')[inbin(c, (b0, b1))]):+.2f} | "
                      f"{np.median(col('r_dev_med')[inbin(c, (b0, b1))]):+.2f}" for b0, b1 in bins]
        print(f"  {c}: " + "; ".join(parts))
    print("share of the deviation energy within 2 orders of a mesh harmonic (median over records): "
          + " ".join(f"{c} {np.median(10 ** col('dev_near_mesh')[y == c]):.2f}" for c in ("T1", "T2", "T3", "T5")))
    print("bin sizes: " + " ".join(f"{c}@{b}: {np.sum(inbin(c, b))}" for b in bins for c in ("T3", "T5", "T6")))
    add = [NAMES.index(n) for n in a.add]
    sets = {"tsa_change + median tooth (9)": (d["tsa_change"], tc_names),
            f"+ {' '.join(a.add)}": (np.column_stack([d["tsa_change"], d["impulse"][:, add]]),
                                     tc_names + list(a.add))}
    how = "train split -> held-out reducers" if np.any(d["split"] != "") else "leave-3-reducers-out"
    print(f"BaselineMonitor ({how}), alarm alpha 5 %, split calibration")
    for cls, label in ((None, "six-state"), (["T1", "T2", "T3", "T5"], "crack-free (T1 T2 T3 T5)")):
        for name, (F, names) in sets.items():
            print(f"  {label:26s} {name:40s} {evaluate(F, y, d['reducer'], d['split'], names, classes=cls)}")
    for name, (F, names) in sets.items():
        C, acc, fa = confusion(F, y, d["reducer"], d["split"], names, merge=True)
        print(f"  crack-free, T6 as T5        {name:40s} accuracy {acc:.1%} FA {fa:.1%} confusion "
              f"{C.tolist()}")


if __name__ == "__main__":
    main()
