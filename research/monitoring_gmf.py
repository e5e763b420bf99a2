"""The generalised matched filter (GMF) of the crack against a reducer's own baseline (issue 27; docs/monitoring.md,
"The generalised matched filter").

    PYTHONPATH=src nice python research/monitoring_gmf.py out/monitoring_pairs.npz --refs out/gmf_refs

Data: the paired records of research/monitoring_pairs.py (12 reducers, 3 commissioning records at each of 4
operating points, then 12 healthy and 5 of each of T2..T6 monitored records, 1 s at 48 kHz, floor 20 dB).

Simulated references (:func:`rvdiag.evaluation.separability.gmf_reference`, resumable: one file per operating point
under ``--refs``): at each nominal operating point, the T1/T4 change (1.8 mm at 45 deg, noise-free) and ``--draws``
healthy records with the issue's run-to-run variation, on the nominal angle axis; once with the nominal parameters
and once with each reducer's own specimen parameters, path included (an oracle: an ideally updated model).  Seeds:
2000 + op (nominal), 1000 + 10 r + op (reducer r), drawn apart from the records' own.

Every record is put on the nominal angle axis by its speed ratio (:func:`rvdiag.features.gmf.on_angle_axis`; the
encoder's speed, every record starting at the same angle).  Statistic of a monitored record y: the standardised
GMF ``delta^T C^-1 (y - mu) / d`` (:class:`rvdiag.features.gmf.GeneralisedMatchedFilter`), mu the mean of its
reducer's 3 aligned commissioning records at the same operating point, C = (1 + 1/3)(Sigma_rr + sigma^2 I) with
Sigma_rr the Ledoit-Wolf-shrunk covariance of the simulated draws and sigma^2 the reducer's floor.  Variants:

- oracle / nominal: Sigma_rr and delta from the reducer's own parameters or from the nominal ones;
- "model mean": mu the mean of the simulated draws instead of the baseline (the bound's healthy signal known);
- "unwhitened": the correlator delta^T (y - mu) (white-noise matched filter) for comparison;
- crossed: the oracle template with the nominal Sigma_rr, and the nominal template with the oracle Sigma_rr;
- "no shrinkage": the sample covariance of the draws (rank K - 1) plus sigma^2 I only.

Thresholds: leave-3-reducers-out (4 folds); the split-conformal quantile of the other 9 reducers' 108 healthy
monitored records at 1 % and 5 %.  ``--extra-db`` adds white noise so that the floor lies that many dB lower
(10 dB SNR: ``--extra-db 10``), to every record, baseline included (seed 7).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT, gmf_reference
from rvdiag.features.gmf import GeneralisedMatchedFilter, on_angle_axis
from rvdiag.params import ReducerParams

FS = 48000.0
CRACK = {"crack_depth": 1.8e-3, "crack_angle_deg": 45.0}


def specimen_params(spec: dict, base: ReducerParams) -> ReducerParams:
    changes: dict[str, dict] = {}
    for name, f in spec["scales"].items():
        s, k = name.split(".")
        changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * f
    return base.replace(**changes).replace(mounting=spec["mounting"], modification=spec["modification"])


def references(meta, ops, refs: str, draws: int) -> None:
    """Simulate (or skip, when present) every reference file under ``refs``."""
    os.makedirs(refs, exist_ok=True)
    base = ReducerParams.default()
    specs = {m["reducer"]: m["specimen"] for m in meta if "specimen" in m}
    jobs = [(f"nominal_op{o}", base, v, L, 2000 + o) for o, v, L in ops]
    jobs += [(f"r{r}_op{o}", specimen_params(specs[r], base), v, L, 1000 + 10 * r + o)
             for r in sorted(specs) for o, v, L in ops]
    t0 = time.perf_counter()
    for name, p, v, L, seed in jobs:
        path = os.path.join(refs, name + ".npz")
        if os.path.exists(path):
            continue
        ref = gmf_reference("T4", ranges=RUN_TO_RUN_DEFAULT, draws=draws, params=p, output_speed_deg_s=v,
                            load_Nm=L, duration_s=1.0, fs=FS, transient_s=0.2, model={"substeps": 4},
                            severities=CRACK, seed=seed)
        tmp = path + ".part.npz"
        np.savez(tmp, healthy=ref["healthy"], template=ref["template"], draws=ref["draws"].astype(np.float32),
                 factors=json.dumps(ref["factors"]), seed=seed)
        os.replace(tmp, path)
        print(f"{name}: {draws + 2} simulations, {time.perf_counter() - t0:.0f} s", flush=True)


def evaluate(X, meta, ops, a) -> None:
    from scipy.stats import norm, spearmanr
    from sklearn.metrics import roc_auc_score

    n = int((X.shape[1] - 3) * (1.0 - RUN_TO_RUN_DEFAULT["speed"]))
    red = np.array([m["reducer"] for m in meta])
    op = np.array([m["op"] for m in meta])
    role = np.array([m["role"] for m in meta])
    state = np.array([m["state"] for m in meta])
    extra = 10 ** (a.extra_db / 10) - 1.0
    rng = np.random.default_rng(7)
    Y = np.empty((len(meta), n))
    for i, m in enumerate(meta):
        x = X[i].astype(float)
        if extra > 0:
            x = x + np.sqrt(extra) * m["noise_sigma"] * rng.standard_normal(x.size)
        Y[i] = on_angle_axis(x, m["output_speed_deg_s"] / m["nominal_speed"], n)
    noise_var = {m["reducer"]: m["noise_sigma"] ** 2 * (1 + extra) for m in meta}

    def load(name):
        path = os.path.join(a.refs, name + ".npz")
        return dict(np.load(path)) if os.path.exists(path) else None

    nominal = {o: load(f"nominal_op{o}") for o, _, _ in ops}
    names = ["GMF oracle", "GMF nominal", "GMF oracle, model mean", "GMF nominal, model mean",
             "unwhitened oracle", "unwhitened nominal", "GMF oracle, no shrinkage", "GMF nominal, no shrinkage",
             "GMF oracle template, nominal Sigma", "GMF nominal template, oracle Sigma"]
    stat = {k: np.full(len(meta), np.nan) for k in names}
    defl = {k: [] for k in names}
    for r in np.unique(red):
        for o, _, _ in ops:
            b = np.flatnonzero((red == r) & (op == o) & (role == "baseline"))
            mon = np.flatnonzero((red == r) & (op == o) & (role == "monitored"))
            mu_b = Y[b].mean(axis=0)
            own = load(f"r{r}_op{o}")
            for src, ref in (("oracle", own), ("nominal", nominal[o])):
                if ref is None:
                    continue
                H = ref["draws"].astype(float)
                for suffix, mu, nb, shrink in (("", mu_b, b.size, "ledoit-wolf"),
                                               (", model mean", H.mean(axis=0), H.shape[0], "ledoit-wolf"),
                                               (", no shrinkage", mu_b, b.size, 0.0)):
                    g = GeneralisedMatchedFilter(ref["template"], H, noise_var[r], nb, shrink).fit()
                    stat[f"GMF {src}{suffix}"][mon] = g.statistic(Y[mon], mu)
                    defl[f"GMF {src}{suffix}"].append(g.deflection_)
                # the white-noise correlator, standardised by its own standard deviation under the same model
                g = GeneralisedMatchedFilter(ref["template"], H, noise_var[r], b.size, "ledoit-wolf").fit()
                t = ref["template"]
                D = (H - H.mean(axis=0)) * np.sqrt((1 - g.shrinkage_) / (H.shape[0] - 1))
                s2 = noise_var[r] + g.shrinkage_ * float(np.sum((H - H.mean(axis=0)) ** 2)) / (H.shape[0] - 1) / n
                sd = np.sqrt((1 + 1 / b.size) * (np.sum((D @ t) ** 2) + s2 * t @ t))
                stat[f"unwhitened {src}"][mon] = (Y[mon] - mu_b) @ t / sd
                defl[f"unwhitened {src}"].append(float(t @ t) / sd)
            if own is not None:       # which half of the model must be the reducer's own: the template or Sigma_rr
                for name, tpl, H in (("GMF oracle template, nominal Sigma", own["template"], nominal[o]["draws"]),
                                     ("GMF nominal template, oracle Sigma", nominal[o]["template"], own["draws"])):
                    g = GeneralisedMatchedFilter(tpl, H.astype(float), noise_var[r], b.size).fit()
                    stat[name][mon] = g.statistic(Y[mon], mu_b)
                    defl[name].append(g.deflection_)
    report(stat, defl, red, role, state, meta, a)


def report(stat, defl, red, role, state, meta, a) -> None:
    from scipy.stats import norm, spearmanr
    from sklearn.metrics import roc_auc_score

    mon = role == "monitored"
    depth = np.array([m.get("crack_depth", np.nan) for m in meta])
    reducers = np.unique(red)
    folds = [reducers[k::4] for k in range(4)]
    print(f"floor {20 - a.extra_db:.0f} dB; {np.sum(mon & (state == 'T1'))} healthy, {np.sum(mon & (state == 'T4'))} "
          f"cracked monitored records, {reducers.size} reducers; thresholds leave-3-reducers-out")
    for name, v in stat.items():
        ok = mon & np.isfinite(v)
        if not np.any(ok & (state == "T4")):
            continue
        h, c = ok & (state == "T1"), ok & (state == "T4")

        def auc(pos, neg):
            return roc_auc_score(np.r_[np.zeros(neg.sum()), np.ones(pos.sum())], np.r_[v[neg], v[pos]])

        det, fa = {}, {}
        for alpha in (0.01, 0.05):
            hit, alarm, nh, nc = 0, 0, 0, 0
            for f in folds:
                test = np.isin(red, f)
                thr = GeneralisedMatchedFilter.calibrate(v[h & ~test], alpha)
                hit += int(np.sum(v[c & test] > thr))
                nc += int(np.sum(c & test))
                alarm += int(np.sum(v[h & test] > thr))
                nh += int(np.sum(h & test))
            det[alpha], fa[alpha] = hit / nc, alarm / nh
        gauss_fa = float(np.mean(v[h] > norm.ppf(0.99)))
        rho, pv = spearmanr(depth[c], v[c])
        others = {s: auc(ok & (state == s), h) for s in ("T2", "T3", "T5", "T6")}
        t5t2 = auc(ok & (state == "T5"), ok & (state == "T2"))
        print(f"{name:28s} n={c.sum()} AUC T4 {auc(c, h):.3f}; detection {det[0.01]:.0%} / {det[0.05]:.0%} at "
              f"FA {fa[0.01]:.1%} / {fa[0.05]:.1%}; Gaussian 1 % threshold FA {gauss_fa:.0%}; Spearman(depth) "
              f"{rho:+.2f} (p {pv:.2f}); median d {np.median(defl[name]):.1f}, T4 median {np.median(v[c]):.1f}, "
              f"T1 sd {np.std(v[h]):.1f}; AUC T2 {others['T2']:.2f} T3 {others['T3']:.2f} T5 {others['T5']:.2f} "
              f"T6 {others['T6']:.2f} T5-vs-T2 {t5t2:.2f}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("pairs")
    ap.add_argument("--refs", default="out/gmf_refs")
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--extra-db", type=float, default=0.0)
    ap.add_argument("--simulate-only", action="store_true")
    ap.add_argument("--no-simulate", action="store_true", help="evaluate with the references already simulated")
    a = ap.parse_args()
    z = np.load(a.pairs)
    X, meta = z["X"], json.loads(str(z["meta"]))
    ops = sorted({(m["op"], m["nominal_speed"], m["nominal_load"]) for m in meta})
    if not a.no_simulate:
        references(meta, ops, a.refs, a.draws)
    if a.simulate_only:
        return
    evaluate(X, meta, ops, a)


if __name__ == "__main__":
    main()
