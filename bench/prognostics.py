"""Change detection and remaining life on synthetic life histories with known truth (issue 35, items 3-4).

Usage::

    .venv/bin/python bench/prognostics.py                        # 1000 healthy, 200 per fault, 60 records a life
    .venv/bin/python bench/prognostics.py --healthy 200 --faults 50   # quicker
    .venv/bin/python bench/prognostics.py --log                  # also append the result to bench/HISTORY.md

Histories: :mod:`rvdiag.prognostics.synthetic` (the health index of a monitor whose per-reducer scale varies, wear
by Archard, a root crack by Paris' law that ends in a broken tooth, a sudden broken tooth; commissioning records
first).  Measured, in the same run:

* the share of healthy histories that ever alarm (Clopper-Pearson 95 % interval) for the conformal test martingale
  (stated bound delta), CUSUM and Page-Hinkley (no bound), and today's per-record alarm (index > 1 on any record);
* the detection delay in records after the first record at or after the onset, per fault (median, 90th
  percentile, share within 3 records, share detected before failure);
* remaining life at the prediction time lambda = 0.5 (Saxena et al. 2008, "Metrics for evaluating performance of
  prognostic techniques", PHM 2008; Saxena et al. 2010, IJPHM 1(1)): t_lambda = t_P + 0.5 (EoL - t_P), t_P the
  alarm, EoL the true failure; the first record at or after t_lambda (before failure) is the prediction.  The 80 %
  interval's coverage of the true remaining life, and alpha-lambda accuracy with alpha 0.2 and beta 0.5 (half the
  predicted distribution within +-20 % of the true remaining life) computed by ProgPy's
  ``progpy.metrics.alpha_lambda``; for the exponential degradation model and for linear extrapolation of the index.
  A history whose remaining life is not estimated at t_lambda counts as a miss for both.  Beside them: the
  median relative error of the predicted median, the share with the median within 20 %, and the 80 % interval's
  width relative to the true remaining life (why alpha-lambda with beta 0.5 fails where coverage holds).
"""

from __future__ import annotations

import argparse
import datetime as dt
import math
import time
from pathlib import Path

import numpy as np
from scipy import stats

from rvdiag.params import ReducerParams
from rvdiag.prognostics import ConformalMartingale, Cusum, PageHinkley, joint_prognosis
from rvdiag.prognostics.synthetic import HistorySpec, draw_history

ROOT = Path(__file__).resolve().parents[1]


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(stats.beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(stats.beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


def detectors(h, delta, seed):
    return {"martingale": ConformalMartingale(h.baseline, delta=delta, seed=seed).run(h.health_index),
            "cusum": Cusum(h.baseline).run(h.health_index),
            "page_hinkley": PageHinkley(h.baseline).run(h.health_index)}


def alpha_lambda_progpy(t_pred: float, toe_samples: np.ndarray, eol: float, alpha=0.2, beta=0.5) -> bool:
    from progpy.metrics import alpha_lambda
    from progpy.predictors import ToEPredictionProfile
    from progpy.uncertain_data import UnweightedSamples

    profile = ToEPredictionProfile()
    profile.add_prediction(t_pred, UnweightedSamples([{"f": float(v)} for v in toe_samples]))
    return bool(alpha_lambda(profile, {"f": float(eol)}, t_pred, alpha, beta)["f"])


def horizon_progpy(times, toe_samples, eol: float, alpha=0.2, beta=0.5) -> float | None:
    """ProgPy's prognostic horizon (EoL minus the first prediction time whose distribution has ``beta`` of its mass
    within +-``alpha`` of the true time to failure; Saxena et al. 2010), or None if no prediction meets it."""
    from progpy.metrics import prognostic_horizon
    from progpy.predictors import ToEPredictionProfile
    from progpy.uncertain_data import UnweightedSamples

    profile = ToEPredictionProfile()
    for t, toe in zip(times, toe_samples):
        profile.add_prediction(float(t), UnweightedSamples([{"f": float(v)} for v in toe]))

    def criterion(tte, truth):
        gt = truth["f"]
        return {"f": tte.percentage_in_bounds({"f": [gt * (1 - alpha), gt * (1 + alpha)]})["f"] >= beta}

    return prognostic_horizon(profile, criterion, {"f": float(eol)})["f"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--healthy", type=int, default=1000)
    ap.add_argument("--faults", type=int, default=200, help="histories per fault kind")
    ap.add_argument("--records", type=int, default=60, help="records per healthy life after commissioning")
    ap.add_argument("--baseline", type=int, default=20, help="commissioning records per joint")
    ap.add_argument("--delta", type=float, default=0.01)
    ap.add_argument("--scale-spread", type=float, default=0.25,
                    help="sd of the log of each reducer's own index scale (bench/prognostics_real.py measures it)")
    ap.add_argument("--samples", type=int, default=2000, help="Monte Carlo draws per remaining-life estimate")
    ap.add_argument("--models", default="size,paris,exponential",
                    help="remaining-life models (rvdiag.prognostics.rul.MODELS), each against linear extrapolation")
    ap.add_argument("--horizon", action="store_true",
                    help="also ProgPy's prognostic horizon (a prediction at every record from alarm to failure)")
    ap.add_argument("--log", action="store_true")
    args = ap.parse_args()
    params = ReducerParams.default()
    spec = HistorySpec(n_baseline=args.baseline, n_records=args.records, scale_spread=args.scale_spread)
    t0 = time.perf_counter()
    lines = [f"histories: {args.healthy} healthy x {args.records} records, {args.faults} per fault; "
             f"{args.baseline} commissioning records; delta = {args.delta}; record every {spec.interval_days} days; "
             f"reducer scale spread {spec.scale_spread}; "
             f"index threshold at failure {spec.threshold_index:.2f}"]

    # healthy lifetime false alarms
    ever = {"martingale": 0, "cusum": 0, "page_hinkley": 0, "per_record_index_gt_1": 0}
    for s in range(args.healthy):
        h = draw_history("healthy", 10_000 + s, params, spec)
        for name, d in detectors(h, args.delta, s).items():
            ever[name] += d.alarmed
        ever["per_record_index_gt_1"] += bool(np.any(h.health_index > 1.0))
    lines.append("healthy histories ever alarming (share, CI95):")
    for name, k in ever.items():
        lo, hi = clopper_pearson(k, args.healthy)
        bound = f"  (stated bound {args.delta})" if name == "martingale" else ""
        lines.append(f"  {name:24s} {k / args.healthy:.4f} [{lo:.4f}, {hi:.4f}]{bound}")

    # detection delay and remaining life
    for kind in ("broken", "crack", "wear"):
        delays = {n: [] for n in ("martingale", "cusum", "page_hinkley")}
        before_fail = {n: 0 for n in delays}
        models = args.models.split(",") + ["linear"]
        cover = {m: [] for m in models}
        al = {m: [] for m in models}
        rel_err = {m: [] for m in models}                  # |median - true| / true, estimated histories
        rel_width = {m: [] for m in models}                # (p90 - p10) / true
        estimated = {m: 0 for m in models}
        n_rul = 0
        horizon = {m: [] for m in (models[0], "linear")}   # prognostic horizon / (EoL - alarm), 0 if never met
        for s in range(args.faults):
            h = draw_history(kind, 20_000 + 1000 * ("broken", "crack", "wear").index(kind) + s, params, spec)
            i_on = h.onset_index
            dets = detectors(h, args.delta, s)
            for name, d in dets.items():
                ok = d.alarm_index is not None and d.alarm_index >= i_on
                delays[name].append(d.alarm_index - i_on if ok else math.inf)
                before_fail[name] += ok and (kind == "broken" or h.days[d.alarm_index] < h.failure_day)
            m = dets["martingale"]
            if kind == "broken" or m.alarm_index is None or h.days[m.alarm_index] >= h.failure_day:
                continue
            t_p = h.days[m.alarm_index]
            t_lam = t_p + 0.5 * (h.failure_day - t_p)
            k = int(np.searchsorted(h.days, t_lam, side="left"))
            if k >= len(h.days) or h.days[k] >= h.failure_day:
                k = int(np.searchsorted(h.days, h.failure_day, side="left")) - 1
            n_rul += 1
            true_rul = h.failure_day - h.days[k]
            # prognostic horizon over every record from the alarm to the last before failure (first model, linear)
            ks = range(m.alarm_index, int(np.searchsorted(h.days, h.failure_day, side="left")))
            profiles = {mm: ([], []) for mm in horizon}
            for kk in ks:
                pk = joint_prognosis(h.days[:kk + 1], health_index=h.health_index[:kk + 1],
                                     baseline_scores=h.baseline, threshold=h.threshold_index, delta=args.delta,
                                     seed=s, model=models[0], reference_level=spec.reference_level,
                                     ) if args.horizon else None
                for mm, r in (((models[0], pk.rul), ("linear", pk.rul_baseline)) if pk else ()):
                    if r.estimated:
                        profiles[mm][0].append(h.days[kk])
                        profiles[mm][1].append(h.days[kk] + r.samples_days[::10])
            if args.horizon:
                for mm, (tt, toe) in profiles.items():
                    ph = horizon_progpy(tt, toe, h.failure_day) if tt else None
                    horizon[mm].append(0.0 if ph is None else ph / (h.failure_day - t_p))
            results = {}
            for model in models[:-1]:
                p = joint_prognosis(h.days[:k + 1], health_index=h.health_index[:k + 1], baseline_scores=h.baseline,
                                    threshold=h.threshold_index, delta=args.delta, seed=s, model=model,
                                    reference_level=spec.reference_level)
                results[model] = p.rul
            results["linear"] = p.rul_baseline
            for model, r in results.items():
                if not r.estimated:
                    cover[model].append(False)
                    al[model].append(False)
                    continue
                estimated[model] += 1
                cover[model].append(r.p10_days <= true_rul <= r.p90_days)
                rel_err[model].append(abs(r.median_days - true_rul) / true_rul)
                rel_width[model].append((r.p90_days - r.p10_days) / true_rul)
                al[model].append(alpha_lambda_progpy(h.days[k], h.days[k] + r.samples_days, h.failure_day))
        lines.append(f"{kind}: detection delay in records after onset (median, p90, within 3, before failure):")
        for name, dl in delays.items():
            dl = np.array(dl)
            q50, q90 = (np.quantile(dl, q, method="inverted_cdf") for q in (0.5, 0.9))   # inf = never
            lines.append(f"  {name:24s} {q50:.0f}, {q90:.0f}, "
                         f"{np.mean(dl <= 2):.3f}, {before_fail[name] / len(dl):.3f}")
        if n_rul:
            lines.append(f"{kind}: remaining life at lambda = 0.5, {n_rul} histories alarmed before failure:")
            for model in cover:
                lo, hi = clopper_pearson(int(np.sum(cover[model])), n_rul)
                lines.append(f"  {model:12s} estimated {estimated[model] / n_rul:.3f}, 80 % interval coverage "
                             f"{np.mean(cover[model]):.3f} [{lo:.3f}, {hi:.3f}], alpha-lambda (0.2, beta 0.5) "
                             f"{np.mean(al[model]):.3f}; median |error| of the median {np.median(rel_err[model]):.2f}, "
                             f"median within 20 % {np.mean(np.array(rel_err[model]) <= 0.2):.2f}, "
                             f"80 % interval width {np.median(rel_width[model]):.2f} of the true life")
            for model, ph in horizon.items():
                if ph:
                    lines.append(f"  prognostic horizon ({model}, alpha 0.2, beta 0.5) as a share of alarm-to-failure:"
                                 f" median {np.median(ph):.2f}, met in {np.mean(np.array(ph) > 0):.2f}")
    lines.append(f"wall time {time.perf_counter() - t0:.0f} s")
    text = "\n".join(lines)
    print(text)
    if args.log:
        cmd = ".venv/bin/python bench/prognostics.py " + " ".join(
            f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items() if k != "log")
        with open(ROOT / "bench" / "HISTORY.md", "a") as f:
            f.write(f"\n## {dt.date.today()} prognostics on synthetic life histories (bench/prognostics.py)\n"
                    f"Command: `{cmd}`\n\n```\n{text}\n```\n")


if __name__ == "__main__":
    main()
