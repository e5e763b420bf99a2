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
import time
from pathlib import Path

import numpy as np

from rvdiag.evaluation.metrics import binomial_interval
from rvdiag.library.life import FATE_STATES
from rvdiag.params import ReducerParams
from rvdiag.prognostics import ConformalMartingale, joint_prognosis
from rvdiag.prognostics.metrics import LifeHistory, score_histories, summarise
from rvdiag.prognostics.synthetic import HistorySpec, draw_history

ROOT = Path(__file__).resolve().parents[1]
#: the fault state of each synthetic kind at its onset (as a life store's fates), in the order their seeds are drawn
STATE = {kind: FATE_STATES[kind][0] for kind in ("broken", "crack", "wear")}


def life_history(h, seed: int, spec: HistorySpec, fleet_pool: bool = False) -> LifeHistory:
    """A synthetic history (:func:`draw_history`) as :func:`rvdiag.prognostics.metrics.life_metrics` scores it
    (``fleet_pool``: without its commissioning scores, as the fleet ranks a joint's records)."""
    return LifeHistory(days=h.days, score=h.health_index, fate=h.kind, onset_days=h.onset_day,
                       failure_days=h.failure_day, state=STATE.get(h.kind),
                       baseline_scores=() if fleet_pool else h.baseline,
                       threshold=h.threshold_index, reference_level=spec.reference_level, seed=seed,
                       name=f"{h.kind}-{h.seed}")


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


def horizons(h, seed: int, delta: float, model: str, spec: HistorySpec) -> dict:
    """The prognostic horizon of ``model`` and of linear extrapolation as a share of alarm-to-failure (0 if never
    met), from a prediction at every record from the martingale's alarm to the last before failure; {} when the
    history does not alarm before failure."""
    m = ConformalMartingale(h.baseline, delta=delta, seed=seed).run(h.health_index)
    if m.alarm_index is None or h.days[m.alarm_index] >= h.failure_day:
        return {}
    profiles = {mm: ([], []) for mm in (model, "linear")}
    for kk in range(m.alarm_index, int(np.searchsorted(h.days, h.failure_day, side="left"))):
        pk = joint_prognosis(h.days[:kk + 1], health_index=h.health_index[:kk + 1], baseline_scores=h.baseline,
                             threshold=h.threshold_index, delta=delta, seed=seed, model=model,
                             reference_level=spec.reference_level)
        for mm, r in ((model, pk.rul), ("linear", pk.rul_baseline)):
            if r.estimated:
                profiles[mm][0].append(h.days[kk])
                profiles[mm][1].append(h.days[kk] + r.samples_days[::10])
    t_p = h.days[m.alarm_index]
    out = {}
    for mm, (tt, toe) in profiles.items():
        ph = horizon_progpy(tt, toe, h.failure_day) if tt else None
        out[mm] = 0.0 if ph is None else ph / (h.failure_day - t_p)
    return out


def _q(v) -> str:
    return "inf" if v is None else f"{v:.0f}"


def _f(v, fmt: str) -> str:
    return "nan" if v is None else format(v, fmt)


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
    ap.add_argument("--fleet-pool", action="store_true",
                    help="rank each record among the joint's earlier monitored records only, as rvdiag fleet and "
                         "evaluate --life do (its commissioning records have no index); no CUSUM / Page-Hinkley")
    ap.add_argument("--log", action="store_true")
    args = ap.parse_args()
    params = ReducerParams.default()
    spec = HistorySpec(n_baseline=args.baseline, n_records=args.records, scale_spread=args.scale_spread)
    t0 = time.perf_counter()
    lines = [f"histories: {args.healthy} healthy x {args.records} records, {args.faults} per fault; "
             f"{args.baseline} commissioning records" + (" (not ranked: the fleet's pool)" if args.fleet_pool else "")
             + f"; delta = {args.delta}; record every {spec.interval_days} days; "
             f"reducer scale spread {spec.scale_spread}; "
             f"index threshold at failure {spec.threshold_index:.2f}"]

    # every history scored by the product's detector and remaining-life models (rvdiag.prognostics.metrics)
    models = args.models.split(",")
    hists, synthetic, index_gt_1 = [], [], 0
    for s in range(args.healthy):
        h = draw_history("healthy", 10_000 + s, params, spec)
        hists.append(life_history(h, s, spec, args.fleet_pool))
        index_gt_1 += bool(np.any(h.health_index > 1.0))
    for kind in STATE:
        for s in range(args.faults):
            h = draw_history(kind, 20_000 + 1000 * list(STATE).index(kind) + s, params, spec)
            hists.append(life_history(h, s, spec, args.fleet_pool))
            synthetic.append((h, s))
    classical = not args.fleet_pool
    outcomes = score_histories(hists, delta=args.delta, models=models, classical=classical)
    res = summarise(outcomes, delta=args.delta, models=models, classical=classical)
    dets = {"martingale": res}
    if classical:
        dets.update(cusum=res["baseline"]["cusum"], page_hinkley=res["baseline"]["page_hinkley"])

    lines.append("healthy histories ever alarming (share, CI95):")
    for name, d in dets.items():
        fa = d["lifetime_false_alarm"]
        bound = f"  (stated bound {args.delta})" if name == "martingale" else ""
        lines.append(f"  {name:24s} {fa['rate']:.4f} [{fa['ci95'][0]:.4f}, {fa['ci95'][1]:.4f}]{bound}")
    lo, hi = binomial_interval(index_gt_1, args.healthy)
    lines.append(f"  {'per_record_index_gt_1':24s} {index_gt_1 / args.healthy:.4f} [{lo:.4f}, {hi:.4f}]")

    for kind, state in STATE.items():
        lines.append(f"{kind}: detection delay in records after onset (median, p90, within 3, before failure):")
        for name, d in dets.items():
            dl, w3 = d["detection_delay_records"][state], d["detected_within_3"][state]
            lines.append(f"  {name:24s} {_q(dl['median'])}, {_q(dl['p90'])}, "
                         f"{w3['share']:.3f}, {dl['detected_before_failure']:.3f}")
        if kind == "broken":
            continue
        kind_res = summarise([o for o in outcomes if o["fate"] == kind], delta=args.delta, models=models,
                             classical=False)["rul_models"]
        n_rul = kind_res["linear"]["rul_coverage_80"]["n"]
        if n_rul:
            lines.append(f"{kind}: remaining life at lambda = 0.5, {n_rul} histories alarmed before failure:")
            for model, r in kind_res.items():
                cov, al = r["rul_coverage_80"], r["alpha_lambda"]
                lines.append(f"  {model:12s} estimated {r['estimated']:.3f}, 80 % interval coverage "
                             f"{cov['rate']:.3f} [{cov['ci95'][0]:.3f}, {cov['ci95'][1]:.3f}], alpha-lambda (0.2, "
                             f"beta 0.5) {al['rate']:.3f}; median |error| of the median "
                             f"{_f(r['median_relative_error'], '.2f')}, median within 20 % "
                             f"{_f(r['median_within_20'], '.2f')}, "
                             f"80 % interval width {_f(r['interval_width'], '.2f')} of the true life")
            if args.horizon:
                ph = [horizons(h, s, args.delta, models[0], spec) for h, s in synthetic if h.kind == kind]
                for mm in (models[0], "linear"):
                    v = np.array([p[mm] for p in ph if p])
                    if len(v):
                        lines.append(f"  prognostic horizon ({mm}, alpha 0.2, beta 0.5) as a share of "
                                     f"alarm-to-failure: median {np.median(v):.2f}, met in {np.mean(v > 0):.2f}")
    lines.append(f"wall time {time.perf_counter() - t0:.0f} s")
    text = "\n".join(lines)
    print(text)
    if args.log:
        cmd = ".venv/bin/python bench/prognostics.py " + " ".join(
            f"--{k.replace('_', '-')}" + ("" if isinstance(v, bool) else f" {v}")
            for k, v in vars(args).items() if k != "log" and v is not False)
        with open(ROOT / "bench" / "HISTORY.md", "a") as f:
            f.write(f"\n## {dt.date.today()} prognostics on synthetic life histories (bench/prognostics.py)\n"
                    f"Command: `{cmd}`\n\n```\n{text}\n```\n")


if __name__ == "__main__":
    main()
