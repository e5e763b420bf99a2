"""The crack detector with an identified twin (issue 36, step 3; docs/twin.md, "The crack detector with the
identified twin"): the generalised matched filter's AUC and detection when its template and covariance come from a
model whose sun tooth errors were identified from the joint's own commissioning records (``rvdiag update
--specimen``), between the nominal model and the reducer's exact one (the oracle).

    PYTHONPATH=src nice python research/twin_gmf.py --prepare --out out/twin_gmf           # linearisation, nominal refs
    PYTHONPATH=src nice python research/twin_gmf.py --only 0 2 4 6 8 10 --out out/twin_gmf &   # one process each
    PYTHONPATH=src nice python research/twin_gmf.py --only 1 3 5 7 9 11 --out out/twin_gmf
    PYTHONPATH=src nice python research/twin_gmf.py --reidentify --out out/twin_gmf        # (and --marginal)
    PYTHONPATH=src python research/twin_gmf.py --evaluate --out out/twin_gmf [--extra-db 10] [--estimate-noise]

Reducers (``--reducers``, 12; reducer r seeded by ``SeedSequence(--seed).spawn(reducers)[r]``, seed 36, drawn apart
from every earlier study's): as research/monitoring_pairs.py draws them, a specimen of the built-in RV-20E with every
stiffness and damping factor in 1 +- 10 %, its own sensor path (resonance 1.5-9 kHz, damping ratio 0.02-0.15, 0-15 kg
on the housing) and its own ``error_seed`` (its sun teeth and its planet table: runouts, crank holes, phases), at the
built-in ISO 1328 grade 5.

Per reducer and operating point (45 deg/s 90 N m, 30 deg/s 50 N m, 60 deg/s 130 N m): 3 commissioning vibration
records, then ``--healthy`` (8) healthy and ``--cracked`` (8) cracked monitored ones (root crack on sun tooth 0,
depth U(1.4, 2.2) mm, angle U(30, 60) deg), each 1 s at 48 kHz after a 0.2 s run-in (channel 0), each with its own
run-to-run variation (:func:`rvdiag.library.paired.draw_variation`: load 3 %, speed 1 %, temperature 2 %, mesh damping
10 %, gain 3 %).  The noise floor is fixed per reducer, 20 dB below the power of its first commissioning record; the
records are stored noise-free and the noise is drawn at evaluation (``default_rng([r, i, 7])`` for record i), so that
``--extra-db`` lowers the floor on the same records.

The twin's teeth: 3 commissioning records of the two encoders (1 s, 8 kHz, 23 bits, each with its own variation;
:func:`rvdiag.updating.specimen.simulated_record`) at 45 deg/s 90 N m, identified by
:func:`~rvdiag.updating.specimen.identify_specimen` with the command's defaults on the built-in set (its stiffnesses
nominal, its planet table ``error_seed`` 0's): the linearisation is shared (``--prepare``).

Models for the filter (each :func:`reference` at each operating point: the T1/T4 change of a 1.8 mm crack at 45 deg,
noise-free, and ``--draws`` (32) healthy draws with the run-to-run variation (``--use-draws`` evaluates with the first ones); seed ``5000 + 10 r + op``, the same for every
model of a reducer, so that the models differ only in their parameters):

- ``oracle``: the specimen's own parameters (its path, stiffnesses, sun teeth and planet table);
- ``twin``: the specimen's global parameters (path, stiffnesses and damping: a perfect global update) with the
  identified sun teeth and the built-in planet table;
- ``true teeth``: the same with the specimen's true sun teeth (what a perfect identification gives, the planet
  table still unknown);
- ``twin x3``: the same with the true teeth plus 3 times the identification's error (the error's dose);
- ``global only``: the specimen's global parameters, the built-in teeth and planet table (no ``--specimen``);
- ``twin, nominal global``: the built-in global parameters with the identified teeth (no global update);
- ``nominal``: the built-in set;
- with ``--marginal``: ``twin, planets marginalised`` and ``true teeth, planets marginalised``, the references over
  ``--tables`` (8) planet tables the twin does not know (:func:`rvdiag.monitoring.crack.simulate_reference` with
  ``planet_tables``);
- with ``--reidentify``: the teeth identified again on the specimen's global parameters (a perfect global update
  first, as docs/twin.md recommends), ``twin, global updated`` and ``twin, global updated, planets marginalised``
  (the product's default twin).

Evaluation (:class:`rvdiag.features.gmf.GeneralisedMatchedFilter`, as research/monitoring_gmf.py): every record on
the nominal angle axis by its speed ratio; ``T / d`` against the mean of the reducer's 3 commissioning records at the
same operating point, ``C = (1 + 1/3)(Sigma_rr + sigma^2 I)``, Ledoit-Wolf shrinkage; thresholds the split-conformal
quantile of the other reducers' healthy monitored scores (leave-3-reducers-out, 4 folds) at 1 % and 5 %.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import time

import numpy as np

from rvdiag.dynamics import ModelSettings, simulate
from rvdiag.features.gmf import GeneralisedMatchedFilter, on_angle_axis
from rvdiag.library.config import DAMPING_KEYS, STIFFNESS_KEYS
from rvdiag.library.paired import apply_variation, draw_variation
from rvdiag.library.states import tooth_faults
from rvdiag.monitoring.crack import estimate_noise_var, model_threshold, simulate_reference  # the product's
from rvdiag.params import ReducerParams
from rvdiag.updating import specimen as sp
from rvdiag.updating.observability import nominal_tooth_errors

FS = 48000.0
FS_TE = 8000.0
OPS = [(45.0, 90.0), (30.0, 50.0), (60.0, 130.0)]
CRACK = {"crack_depth": 1.8e-3, "crack_angle_deg": 45.0}
SETTINGS = ModelSettings(transient_s=0.2, substeps=4)
MODELS = ["oracle", "twin", "true teeth", "twin x3", "global only", "twin, nominal global", "nominal"]
MARGINAL = ["twin, planets marginalised", "true teeth, planets marginalised", "twin, global updated",
            "twin, global updated, planets marginalised"]


def draw_specimen(rng, base: ReducerParams) -> tuple[ReducerParams, dict]:
    """A specimen as research/monitoring_pairs.py draws one, at the built-in grade."""
    scales = {f"{s}.{k}": float(1 + 0.10 * rng.uniform(-1, 1)) for s, k in STIFFNESS_KEYS + DAMPING_KEYS}
    mounting = {"path_resonance_hz": float(rng.uniform(1500, 9000)),
                "path_damping_ratio": float(rng.uniform(0.02, 0.15)),
                "housing_added_mass": float(rng.uniform(0, 15))}
    mod = {"error_seed": int(rng.integers(0, 2**31))}
    changes: dict[str, dict] = {}
    for name, f in scales.items():
        s, k = name.split(".")
        changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * f
    return base.replace(**changes).replace(mounting=mounting, modification=mod), \
        {"scales": scales, "mounting": mounting, "modification": mod}


def model_params(name: str, spec: ReducerParams, base: ReducerParams, truth, ident) -> ReducerParams:
    glob = spec.replace(modification={"error_seed": base.modification.error_seed})
    um = lambda t: [float(v) * 1e6 for v in t]          # noqa: E731
    return {"oracle": lambda: spec,
            "twin": lambda: glob.replace(modification={"sun_tooth_errors_um": um(ident)}),
            "true teeth": lambda: glob.replace(modification={"sun_tooth_errors_um": um(truth)}),
            "twin x3": lambda: glob.replace(modification={"sun_tooth_errors_um": um(truth + 3 * (ident - truth))}),
            "global only": lambda: glob,
            "twin, nominal global": lambda: base.replace(modification={"sun_tooth_errors_um": um(ident)}),
            "nominal": lambda: base}[name]()


def reference(p: ReducerParams, op: int, seed: int, draws: int, tables: int = 0) -> dict:
    """The filter's reference at operating point ``op`` with ``p``: the product's
    :func:`rvdiag.monitoring.crack.simulate_reference` (1 s at 48 kHz after a 0.2 s run-in, 4 sub-steps, the
    1.8 mm crack), with the twin's own planet table (``tables`` 0, ``draws + 2`` simulations) or over ``tables``
    planet tables (``error_seed`` of ``p`` plus 1..tables, ``tables (draws / tables + 2)`` simulations)."""
    v, L = OPS[op]
    ref = simulate_reference(p, v, L, FS, 1.0, draws, seed, severity=CRACK, transient_s=0.2, substeps=4,
                             planet_tables=tables)
    return {"template": ref.template, "draws": ref.draws, "seconds": ref.seconds}


def save(path: str, obj) -> None:
    tmp = path + ".part"
    with open(tmp, "wb") as fh:
        pickle.dump(obj, fh, protocol=5)
    os.replace(tmp, path)


def load(path: str):
    with open(path, "rb") as fh:
        return pickle.load(fh)


def prepare(a) -> None:
    base = ReducerParams.default()
    os.makedirs(a.out, exist_ok=True)
    lin = os.path.join(a.out, "linearisation.pkl")
    if not os.path.exists(lin):
        t = time.perf_counter()
        pm = sp.linearise(base, OPS[0][0], OPS[0][1], FS_TE, sp.SpecimenSettings())
        save(lin, {"pm": pm, "seconds": time.perf_counter() - t})
        print(f"linearisation: {pm.simulations} simulations, {time.perf_counter() - t:.0f} s", flush=True)
    for o in range(len(OPS)):
        path = os.path.join(a.out, f"nominal_op{o}.pkl")
        if not os.path.exists(path):
            save(path, reference(base, o, 2000 + o, a.draws))
            print(f"nominal op {o} done", flush=True)


def run_marginal(r: int, ss, a) -> None:
    """Add the models ``twin, planets marginalised`` and ``true teeth, planets marginalised`` to reducer ``r``'s file."""
    path = os.path.join(a.out, f"r{r}.pkl")
    rec = load(path)
    base = ReducerParams.default()
    spec, _ = draw_specimen(np.random.default_rng(ss), base)
    glob = spec.replace(modification={"error_seed": base.modification.error_seed})   # tables 1..J, as the product's
    t0 = time.perf_counter()
    for name, teeth in (("twin, planets marginalised", rec["ident"]), ("true teeth, planets marginalised",
                                                                       rec["truth"])):
        if name in rec["refs"]:
            continue
        p = glob.replace(modification={"sun_tooth_errors_um": [float(v) * 1e6 for v in teeth]})
        rec["refs"][name] = [reference(p, o, 7000 + 10 * r + o, a.tables * a.per_table, a.tables)
                             for o in range(len(OPS))]
        save(path, rec)
    print(f"reducer {r}: marginal references done ({time.perf_counter() - t0:.0f} s)", flush=True)


def run_reidentify(r: int, ss, a) -> None:
    """Identify reducer ``r``'s teeth again on its global parameters (a perfect global update: stiffnesses, damping
    and path known, the planet table not), and add the models ``twin, global updated`` and ``twin, global updated,
    planets marginalised``."""
    path = os.path.join(a.out, f"r{r}.pkl")
    rec = load(path)
    if "twin, global updated, planets marginalised" in rec["refs"]:
        return
    base = ReducerParams.default()
    spec, _ = draw_specimen(np.random.default_rng(ss), base)
    glob = spec.replace(modification={"error_seed": base.modification.error_seed})
    t0 = time.perf_counter()
    if "ident_g" not in rec:
        te_rng = np.random.default_rng([r, 36])
        angles = [sp.simulated_record(spec, OPS[0][0], OPS[0][1], 1.0, FS_TE, variation=draw_variation(te_rng),
                                      rng=np.random.default_rng([r, 36, i])) for i in range(a.te_records)]
        recs = [sp.te_record(x, y, FS_TE, glob, load_Nm=OPS[0][1], name=f"r{r}-{i}") for i, (x, y) in
                enumerate(angles)]
        res = sp.identify_specimen(glob, recs)
        truth = rec["truth"]
        rec["ident_g"] = res.teeth_m
        rec["ident_g_error"] = float(np.sqrt(np.mean((res.teeth_m - truth) ** 2)) / np.sqrt(np.mean(truth ** 2)))
        rec["ident_g_seconds"] = time.perf_counter() - t0
        save(path, rec)
        print(f"reducer {r}: teeth on the global parameters identified to {rec['ident_g_error']:.3f} of the pattern "
              f"({rec['ident_g_seconds']:.0f} s, linearisation included)", flush=True)
    p = glob.replace(modification={"sun_tooth_errors_um": [float(v) * 1e6 for v in rec["ident_g"]]})
    if "twin, global updated" not in rec["refs"]:
        rec["refs"]["twin, global updated"] = [reference(p, o, 5000 + 10 * r + o, a.draws) for o in range(len(OPS))]
        save(path, rec)
    rec["refs"]["twin, global updated, planets marginalised"] = [
        reference(p, o, 7000 + 10 * r + o, a.tables * a.per_table, a.tables) for o in range(len(OPS))]
    save(path, rec)
    print(f"reducer {r}: re-identified twin's references done ({time.perf_counter() - t0:.0f} s)", flush=True)


def run_reducer(r: int, ss, a) -> None:
    path = os.path.join(a.out, f"r{r}.pkl")
    part = os.path.join(a.out, f"r{r}_records.pkl")
    base = ReducerParams.default()
    rng = np.random.default_rng(ss)
    spec, spec_dict = draw_specimen(rng, base)
    truth = nominal_tooth_errors(spec)
    t0 = time.perf_counter()
    if os.path.exists(part):
        rec = load(part)
    else:
        plan = [("baseline", "T1", o) for o in range(len(OPS)) for _ in range(3)]
        plan += [("monitored", "T1", o) for o in range(len(OPS)) for _ in range(a.healthy)]
        plan += [("monitored", "T4", o) for o in range(len(OPS)) for _ in range(a.cracked)]
        X, meta, sigma = [], [], None
        for k, (role, state, o) in enumerate(plan):
            d = draw_variation(rng)
            sev = ({"crack_depth": float(rng.uniform(1.4e-3, 2.2e-3)), "crack_angle_deg": float(rng.uniform(30, 60))}
                   if state == "T4" else {})
            v, L = OPS[o][0] * d["speed"], OPS[o][1] * d["load"]
            res = simulate(apply_variation(spec, d), tooth_faults(state, **sev), output_speed_deg_s=v, load_Nm=L,
                           duration_s=1.0, fs=FS, seed=int(rng.integers(0, 2**31)), settings=SETTINGS)
            x = d["gain"] * np.asarray(res.signal[0], dtype=float)
            if sigma is None:
                sigma = float(np.sqrt(np.mean(x ** 2) * 10 ** (-a.floor_db / 10)))
            X.append(x.astype(np.float32))
            meta.append({"reducer": r, "role": role, "state": state, "op": o, "output_speed_deg_s": v, "load_Nm": L,
                         **sev})
        # the twin's teeth, from 3 records of the two encoders at the first operating point
        te_rng = np.random.default_rng([r, 36])
        ts = time.perf_counter()
        angles = [sp.simulated_record(spec, OPS[0][0], OPS[0][1], 1.0, FS_TE, variation=draw_variation(te_rng),
                                      rng=np.random.default_rng([r, 36, i])) for i in range(a.te_records)]
        t_te = time.perf_counter() - ts
        pm = load(os.path.join(a.out, "linearisation.pkl"))["pm"]
        recs = [sp.te_record(x, y, FS_TE, base, load_Nm=OPS[0][1], name=f"r{r}-{i}") for i, (x, y) in
                enumerate(angles)]
        res = sp.identify_specimen(base, recs, points=[pm])
        ident = res.teeth_m
        err = float(np.sqrt(np.mean((ident - truth) ** 2)) / np.sqrt(np.mean(truth ** 2)))
        rec = {"X": np.stack(X), "meta": meta, "sigma": sigma, "specimen": spec_dict, "truth": truth, "ident": ident,
               "ident_error": err, "ident_seconds": res.seconds, "te_seconds": t_te, "iterations": res.iterations}
        save(part, rec)
        print(f"reducer {r}: {len(X)} records; teeth identified to {err:.3f} of the pattern in {res.seconds:.0f} s "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    refs = {}
    for name in MODELS[:-1]:
        p = model_params(name, spec, base, rec["truth"], rec["ident"])
        refs[name] = [reference(p, o, 5000 + 10 * r + o, a.draws) for o in range(len(OPS))]
    rec["refs"] = refs
    save(path, rec)
    os.remove(part)
    print(f"reducer {r}: references done ({time.perf_counter() - t0:.0f} s)", flush=True)


def evaluate(a) -> dict:
    from scipy.stats import spearmanr
    from scipy.stats import t as student
    from sklearn.metrics import roc_auc_score

    nominal = [load(os.path.join(a.out, f"nominal_op{o}.pkl")) for o in range(len(OPS))]
    reducers = sorted(int(f[1:-4]) for f in os.listdir(a.out) if f.startswith("r") and f.endswith(".pkl")
                      and "_" not in f and (a.only is None or int(f[1:-4]) in a.only))
    extra = 10 ** (a.extra_db / 10) - 1.0
    models: list = []
    rows: dict = {}            # model -> (reducer, state, op, depth, statistic, ...)
    defl: dict = {}
    ident, ident_g = {}, {}
    noise_ratio: dict = {}
    for r in reducers:
        rec = load(os.path.join(a.out, f"r{r}.pkl"))
        if not models:
            models = MODELS + [m for m in MARGINAL if all(m in load(os.path.join(a.out, f"r{q}.pkl"))["refs"]
                                                          for q in reducers)]
            rows, defl = {m: [] for m in models}, {m: {} for m in models}
        ident[r] = rec["ident_error"]
        if "ident_g_error" in rec:
            ident_g[r] = rec["ident_g_error"]
        sig2 = sig_true = rec["sigma"] ** 2 * (1 + extra)
        meta = rec["meta"]
        n = nominal[0]["template"].size
        Y = []
        for i, m in enumerate(meta):
            x = rec["X"][i].astype(float) + np.sqrt(sig_true) * np.random.default_rng([r, i, 7]).standard_normal(
                rec["X"].shape[1])
            Y.append(x)
        for o in range(len(OPS)):
            idx = [i for i, m in enumerate(meta) if m["op"] == o]
            n = nominal[o]["template"].size
            Yo = np.array([on_angle_axis(Y[i], meta[i]["output_speed_deg_s"] / OPS[o][0], n) for i in idx])
            base_rows = [j for j, i in enumerate(idx) if meta[i]["role"] == "baseline"]
            mon_rows = [j for j, i in enumerate(idx) if meta[i]["role"] == "monitored"]
            mu = Yo[base_rows].mean(axis=0)
            for name in models:
                ref = nominal[o] if name == "nominal" else rec["refs"][name][o]
                if a.estimate_noise:        # the floor as the product estimates it from the commissioning records
                    sig2 = estimate_noise_var(Yo[base_rows], ref["draws"].astype(float))
                    noise_ratio.setdefault(name, []).append(sig2 / (rec["sigma"] ** 2 * (1 + extra)))
                H = ref["draws"][: a.use_draws or None].astype(float)
                g = GeneralisedMatchedFilter(ref["template"].astype(float), H, sig2, len(base_rows)).fit()
                t = g.statistic(Yo[mon_rows], mu)
                defl[name].setdefault(r, []).append(g.deflection_)
                # the model's own threshold: the filter from the first half of the draws, the healthy statistic's
                # spread from the other half (fresh to the filter), a Student-t prediction bound
                half = ref["draws"].shape[0] // 2
                gh = GeneralisedMatchedFilter(ref["template"].astype(float), ref["draws"][:half].astype(float), sig2,
                                              len(base_rows)).fit()
                th = model_threshold(gh, ref["draws"][half:].astype(float), sig2, len(base_rows))
                t_half = gh.statistic(Yo[mon_rows], mu)
                for j, s, sh in zip(mon_rows, t, t_half):
                    m = meta[idx[j]]
                    rows[name].append((r, m["state"], o, m.get("crack_depth", np.nan), float(s), float(sh),
                                       th[0.01], th[0.05]))
    folds = [reducers[k::4] for k in range(4)]
    out = {"floor_db": 20 - a.extra_db, "draws": a.use_draws or "all", "reducers": reducers, "identification_error": ident,
           "identification_error_global_updated": ident_g, "models": {}}
    print(f"floor {20 - a.extra_db:.0f} dB; draws {a.use_draws or 'all'}; {len(reducers)} reducers; identification "
          "error / pattern RMS (nominal global): " + ", ".join(f"{ident[r]:.3f}" for r in reducers)
          + "; (global updated): " + ", ".join(f"{ident_g[r]:.3f}" for r in reducers if r in ident_g))
    print("\n| model | AUC T4 | detection at 1 % / 5 % | false alarms at 1 % / 5 % | Spearman(depth) | median d | "
          "model threshold: detection at 1 % / 5 % | its false alarms | learning threshold: detection | its false "
          "alarms |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name in models:
        arr = rows[name]
        red = np.array([x[0] for x in arr])
        st = np.array([x[1] for x in arr])
        depth = np.array([x[3] for x in arr])
        v = np.array([x[4] for x in arr])
        h, c = st == "T1", st == "T4"
        auc = roc_auc_score(np.r_[np.zeros(h.sum()), np.ones(c.sum())], np.r_[v[h], v[c]])
        det, fa = {}, {}
        for alpha in (0.01, 0.05):
            hit = alarm = 0
            for f in folds:
                test = np.isin(red, f)
                thr = GeneralisedMatchedFilter.calibrate(v[h & ~test], alpha)
                hit += int(np.sum(v[c & test] > thr))
                alarm += int(np.sum(v[h & test] > thr))
            det[alpha], fa[alpha] = hit / c.sum(), alarm / h.sum()
        vh = np.array([x[5] for x in arr])
        mth = {al: np.array([x[6 if al == 0.01 else 7] for x in arr]) for al in (0.01, 0.05)}
        mdet = {al: float(np.mean(vh[c] > mth[al][c])) for al in mth}
        mfa = {al: float(np.mean(vh[h] > mth[al][h])) for al in mth}
        # the joint's own threshold: its first --learning healthy monitored records of each operating point (a
        # learning period) give the mean and spread of its statistic, a Student-t prediction bound; tested on the rest
        opn = np.array([x[2] for x in arr])
        ldet, lfa = {0.01: [0, 0], 0.05: [0, 0]}, {0.01: [0, 0], 0.05: [0, 0]}
        for r in reducers:
            learn = np.zeros(len(arr), bool)
            for o in range(len(OPS)):
                learn[np.flatnonzero((red == r) & h & (opn == o))[: a.learning]] = True
            lv = v[learn]
            for al in (0.01, 0.05):
                thr = lv.mean() + student.ppf(1 - al, lv.size - 1) * np.sqrt(1 + 1 / lv.size) * lv.std(ddof=1)
                hr, cr = (red == r) & h & ~learn, (red == r) & c
                ldet[al][0] += int(np.sum(v[cr] > thr))
                ldet[al][1] += int(cr.sum())
                lfa[al][0] += int(np.sum(v[hr] > thr))
                lfa[al][1] += int(hr.sum())
        ldet = {al: x[0] / x[1] for al, x in ldet.items()}
        lfa = {al: x[0] / x[1] for al, x in lfa.items()}
        rho, pv = spearmanr(depth[c], v[c])
        per_red = {}
        for r in reducers:
            hr, cr = h & (red == r), c & (red == r)
            per_red[r] = float(roc_auc_score(np.r_[np.zeros(hr.sum()), np.ones(cr.sum())], np.r_[v[hr], v[cr]]))
        med_d = float(np.median([d for r in reducers for d in defl[name][r]]))
        out["models"][name] = {"auc": float(auc), "detection_1": det[0.01], "detection_5": det[0.05],
                               "false_alarm_1": fa[0.01], "false_alarm_5": fa[0.05], "spearman_depth": float(rho),
                               "spearman_p": float(pv), "median_deflection": med_d, "auc_per_reducer": per_red,
                               "n_healthy": int(h.sum()), "n_cracked": int(c.sum()),
                               "learning_threshold": {"detection_1": ldet[0.01], "detection_5": ldet[0.05],
                                                      "false_alarm_1": lfa[0.01], "false_alarm_5": lfa[0.05],
                                                      "records_per_point": a.learning},
                               "model_threshold": {"detection_1": mdet[0.01], "detection_5": mdet[0.05],
                                                   "false_alarm_1": mfa[0.01], "false_alarm_5": mfa[0.05]}}
        print(f"| {name} | {auc:.3f} | {det[0.01]:.0%} / {det[0.05]:.0%} | {fa[0.01]:.1%} / {fa[0.05]:.1%} | "
              f"{rho:+.2f} (p {pv:.2g}) | {med_d:.1f} | {mdet[0.01]:.0%} / {mdet[0.05]:.0%} | "
              f"{mfa[0.01]:.1%} / {mfa[0.05]:.1%} | {ldet[0.01]:.0%} / {ldet[0.05]:.0%} | "
              f"{lfa[0.01]:.1%} / {lfa[0.05]:.1%} |")
    if noise_ratio:
        out["noise_ratio"] = {k: [float(np.min(v)), float(np.median(v)), float(np.max(v))] for k, v in noise_ratio.items()}
        print("\nestimated / true noise variance (min, median, max): " + "; ".join(
            f"{k} {v[0]:.2f} {v[1]:.2f} {v[2]:.2f}" for k, v in out["noise_ratio"].items()))
    shown = [m for m in ("twin", "true teeth", "twin x3", "oracle", "twin, global updated",
                         "twin, global updated, planets marginalised") if m in out["models"]]
    print("\nper reducer: identification error (nominal global, global updated), AUC " + " / ".join(shown))
    for r in reducers:
        print(f"  r{r}: {ident[r]:.3f} {ident_g.get(r, float('nan')):.3f}  "
              + " / ".join(f"{out['models'][m]['auc_per_reducer'][r]:.3f}" for m in shown))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/twin_gmf")
    ap.add_argument("--reducers", type=int, default=12)
    ap.add_argument("--seed", type=int, default=36)
    ap.add_argument("--only", type=int, nargs="+", default=None)
    ap.add_argument("--healthy", type=int, default=8)
    ap.add_argument("--cracked", type=int, default=8)
    ap.add_argument("--te-records", type=int, default=3)
    ap.add_argument("--draws", type=int, default=32)
    ap.add_argument("--use-draws", type=int, default=0, help="with --evaluate: the first this many draws (0: all)")
    ap.add_argument("--floor-db", type=float, default=20.0)
    ap.add_argument("--extra-db", type=float, default=0.0)
    ap.add_argument("--learning", type=int, default=4,
                    help="with --evaluate: healthy records per operating point in each joint's learning period")
    ap.add_argument("--estimate-noise", action="store_true",
                    help="with --evaluate: the floor estimated from the commissioning records as the product does "
                         "(rvdiag.monitoring.crack.estimate_noise_var), not the true one")
    ap.add_argument("--marginal", action="store_true",
                    help="add the models whose draws span --tables planet tables the twin does not know")
    ap.add_argument("--reidentify", action="store_true",
                    help="identify the teeth again on each specimen's global parameters and add its models")
    ap.add_argument("--tables", type=int, default=8)
    ap.add_argument("--per-table", type=int, default=4)
    ap.add_argument("--prepare", action="store_true")
    ap.add_argument("--evaluate", action="store_true")
    ap.add_argument("--json", default="", help="with --evaluate: write the figures here")
    a = ap.parse_args()
    if a.prepare:
        prepare(a)
        return
    if a.evaluate:
        out = evaluate(a)
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(out, fh, indent=1, default=str)
        return
    for r, ss in enumerate(np.random.SeedSequence(a.seed).spawn(a.reducers)):
        if a.reidentify:
            if (a.only is None or r in a.only) and os.path.exists(os.path.join(a.out, f"r{r}.pkl")):
                run_reidentify(r, ss, a)
            continue
        if a.marginal:
            if (a.only is None or r in a.only) and os.path.exists(os.path.join(a.out, f"r{r}.pkl")):
                run_marginal(r, ss, a)
            continue
        if (a.only is None or r in a.only) and not os.path.exists(os.path.join(a.out, f"r{r}.pkl")):
            run_reducer(r, ss, a)


if __name__ == "__main__":
    main()
