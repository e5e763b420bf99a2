"""The crack against its own baseline, beyond the feature families of research/monitoring_features.py (issue 27):
the model's own prediction of the crack's signature as a matched template, and averaging over several records.

    PYTHONPATH=src nice python research/monitoring_template.py out/monitoring_pairs.npz --out out/monitoring_template.npz

Per monitored record of research/monitoring_pairs.py: the TSA on the sun shaft relative to the carrier at the
record's speed (:func:`rvdiag.features.relative.sun_tsa`), its change since the mean of its reducer's aligned
baseline TSAs at the same nominal operating point, and the residual of that change (mesh harmonics and two shaft
orders removed).  The template is the residual of the simulated crack's TSA change: healthy and cracked (1.8 mm at
45 deg), noise-free, at the nominal operating point, either with the nominal parameters ("nominal") or with the
reducer's own specimen parameters, path included ("updated": an ideally updated model).  Statistic: the largest
correlation of the change with the template over its circular shifts (the crack's tooth is not known: a GLRT over
the phase; Kay vol. 2 sec. 7.6), over the template's norm, divided by the median of the same statistic of each
baseline TSA left out against the others (the reducer's own spread).  Printed per route: AUC against the healthy
monitored records, detection at 1 % and 5 % false alarms (thresholds from the pooled healthy records), and the
Spearman correlation of the index with the crack depth among the cracked records; then the mean index over the
five crack records of each reducer against the mean over 5 of its 12 healthy records (500 random subsets).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.features import orders as _o
from rvdiag.features.relative import align, sun_tsa
from rvdiag.library.states import tooth_faults
from rvdiag.params import ReducerParams

FS = 48000.0


def specimen_params(spec: dict, base: ReducerParams) -> ReducerParams:
    changes: dict[str, dict] = {}
    for name, f in spec["scales"].items():
        s, k = name.split(".")
        changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * f
    return base.replace(**changes).replace(mounting=spec["mounting"], modification=spec["modification"])


def residual(t: np.ndarray, mesh: int) -> np.ndarray:
    return _o.gear_signals(t, mesh, 2)["residual"]


def template(p: ReducerParams, speed: float, load: float, spr: int, mesh: int) -> np.ndarray:
    st = ModelSettings(transient_s=0.2, substeps=4)
    t = []
    for state, sev in (("T1", {}), ("T4", {"crack_depth": 1.8e-3, "crack_angle_deg": 45.0})):
        x = simulate(p, tooth_faults(state, **sev), output_speed_deg_s=speed, load_Nm=load, duration_s=1.0, fs=FS,
                     seed=0, settings=st).signal[0]
        t.append(sun_tsa(x, FS, speed, spr, p))
    return residual(t[1] - t[0], mesh)


def glrt(d: np.ndarray, tpl: np.ndarray) -> float:
    """max over circular shifts of <d, roll(tpl, s)> / ||tpl||."""
    c = np.fft.irfft(np.fft.rfft(d) * np.conj(np.fft.rfft(tpl)), d.size)
    return float(c.max() / np.linalg.norm(tpl))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pairs")
    ap.add_argument("--out", default="out/monitoring_template.npz")
    ap.add_argument("--spr", type=int, default=4096, help="angular samples per sun revolution")
    a = ap.parse_args()
    z = np.load(a.pairs)
    X, meta = z["X"], json.loads(str(z["meta"]))
    base = ReducerParams.default()
    mesh = int(base.stage1.sun_teeth)
    red = np.array([m["reducer"] for m in meta])
    op = np.array([m["op"] for m in meta])
    role = np.array([m["role"] for m in meta])
    ops = sorted({(m["op"], m["nominal_speed"], m["nominal_load"]) for m in meta})
    t0 = time.perf_counter()
    if os.path.exists(a.out):
        tz = np.load(a.out)
        tpl_nom, tpl_upd = tz["nominal"], tz["updated"]
    else:
        tpl_nom = np.array([template(base, v, L, a.spr, mesh) for _, v, L in ops])
        specs = {m["reducer"]: m["specimen"] for m in meta if "specimen" in m}
        tpl_upd = np.array([[template(specimen_params(specs[r], base), v, L, a.spr, mesh) for _, v, L in ops]
                            for r in sorted(specs)])
        np.savez(a.out, nominal=tpl_nom, updated=tpl_upd)
        print(f"{2 * (len(ops) + tpl_upd.shape[0] * len(ops))} template simulations in "
              f"{time.perf_counter() - t0:.0f} s")
    T = np.array([sun_tsa(X[i].astype(float), FS, meta[i]["output_speed_deg_s"], a.spr, base)
                  for i in range(len(meta))])
    mon = np.flatnonzero(role == "monitored")
    idx = {"nominal": [], "updated": [], "residual change (no template)": []}
    for i in mon:
        b = np.flatnonzero((red == red[i]) & (op == op[i]) & (role == "baseline"))
        Tb = [T[b[0]]] + [align(T[j], T[b[0]]) for j in b[1:]]
        ref = np.mean(Tb, axis=0)
        d = residual(align(T[i], ref) - ref, mesh)
        loo = [residual(Tb[j] - np.mean(Tb[:j] + Tb[j + 1:], axis=0), mesh) for j in range(len(Tb))]
        for name, tpl in (("nominal", tpl_nom[op[i]]), ("updated", tpl_upd[red[i], op[i]])):
            idx[name].append(glrt(d, tpl) / np.median([glrt(e, tpl) for e in loo]))
        idx["residual change (no template)"].append(np.linalg.norm(d) / np.median([np.linalg.norm(e) for e in loo]))
    y = np.array([meta[i]["state"] for i in mon])
    depth = np.array([meta[i].get("crack_depth", np.nan) for i in mon])
    rm = red[mon]
    report(idx, y, depth, rm)


def report(idx: dict, y, depth, rm) -> None:
    from scipy.stats import spearmanr
    from sklearn.metrics import roc_auc_score

    h, c = y == "T1", y == "T4"
    rng = np.random.default_rng(0)
    print(f"{h.sum()} healthy and {c.sum()} cracked monitored records (1.4-2.2 mm), {len(np.unique(rm))} reducers")
    for name, v in idx.items():
        v = np.log10(np.asarray(v))
        auc = roc_auc_score(np.r_[np.zeros(h.sum()), np.ones(c.sum())], np.r_[v[h], v[c]])
        det = {fa: float(np.mean(v[c] > np.quantile(v[h], 1 - fa))) for fa in (0.01, 0.05)}
        rho, pv = spearmanr(depth[c], v[c])
        others = {s: roc_auc_score(np.r_[np.zeros(h.sum()), np.ones((y == s).sum())], np.r_[v[h], v[y == s]])
                  for s in ("T2", "T3")}
        # averaging over records: each reducer's 5 crack records against 5 of its 12 healthy ones
        mc, mh = [], []
        for r in np.unique(rm):
            vh, vc = v[(rm == r) & h], v[(rm == r) & c]
            mc.append(vc.mean())
            mh += [vh[rng.choice(vh.size, vc.size, replace=False)].mean() for _ in range(500)]
        mc, mh = np.array(mc), np.array(mh)
        det_m = {fa: float(np.mean(mc > np.quantile(mh, 1 - fa))) for fa in (0.01, 0.05)}
        auc_m = roc_auc_score(np.r_[np.zeros(mh.size), np.ones(mc.size)], np.r_[mh, mc])
        print(f"{name:32s} AUC {auc:.3f}; detection {det[0.01]:.0%} at 1 %, {det[0.05]:.0%} at 5 % FA; "
              f"Spearman(depth) {rho:+.2f} (p {pv:.2f}); AUC T2 {others['T2']:.2f} T3 {others['T3']:.2f} | "
              f"mean of 5 records: AUC {auc_m:.3f}, detection {det_m[0.01]:.0%} / {det_m[0.05]:.0%} of "
              f"{mc.size} reducers")


if __name__ == "__main__":
    main()
