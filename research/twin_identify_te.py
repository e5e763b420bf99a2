"""Identify a specimen's sun tooth errors from a noisy commissioning record's transmission error (issue 36, a
measurement toward step 2; docs/twin.md, "Identifying the sun's tooth errors from the transmission error
(measured)").

    PYTHONPATH=src nice python research/twin_identify_te.py --out out/twin_identify_te.json

Held-out specimens: the RV-20E of research/twin_observability.py (path at 4 kHz) with ``[modification] error_seed``
= 300, 301, ... (ISO 1328 grade 5; step 1 used seeds 0 and 100-102), each with its own sun tooth pattern and planet
table, and its nine stiffness factors (:data:`rvdiag.library.config.STIFFNESS_KEYS`) drawn uniform in +-10 % as the
monitoring library draws them (``numpy.random.default_rng([seed, 1])``).

The measured records: 3 records per specimen at 45 deg/s, 90 N m, each with its own run-to-run variation
(:func:`rvdiag.library.paired.draw_variation`, ``default_rng([seed, 2])``), simulated noise-free over 3 sun
revolutions after the run-in (:func:`rvdiag.updating.observability.observe`), and the TE's synchronous lines given the
white noise of a 1 s record with the 23-bit output encoder (:class:`~rvdiag.updating.observability.NoiseModel`,
``default_rng([seed, 3])``).  The TE's lines do not depend on the record's length (docs/twin.md, "Record length"),
so a 3-revolution simulation with the noise of 1 s stands for a 1 s record.

The estimator: maximum a posteriori on the whitened TE lines, ``||C^-1/2 (y - f(theta))||^2 + ||z||^2`` with
``theta = L z`` (the prior square root of :func:`~rvdiag.updating.observability.prior_square_root`, so the teeth's
mean stays 0) and ``C = G Sigma_u G^T + D_draws + diag(sigma^2)`` for the mean of ``n`` records divided by ``n``
(the run-to-run variation linearised plus ``--draws`` drawn, as :func:`~rvdiag.updating.observability.analyse`
has it).  Levenberg-Marquardt (Nocedal & Wright, *Numerical Optimization*, 2nd ed., sec. 10.3) with one
Jacobian: central differences at the nominal reducer (seed 0, zero pattern, nominal stiffness), reused at every
iterate and for every specimen (a chord, or simplified, Gauss-Newton), so an iteration costs one simulation; a
step that does not lower the cost is refused and the damping raised.

Cases:

- ``oracle``: the specimen's stiffness factors and planet table known; the 11 teeth identified;
- ``nominal``: the stiffness factors left at nominal (the specimen's are +-10 % off), the teeth identified;
- ``joint``: the teeth and the 9 stiffness factors identified together: from the ``nominal`` case's teeth (the
  teeth first, as docs/twin.md's ``--gn-teeth-first``), a fresh Jacobian there (40 simulations), then
  Levenberg-Marquardt on both with the factors' step held within ``--trust`` (as docs/twin.md's ``--gn-trust``);
- ``oracle_nuisance``, ``nominal_nuisance``: the oracle and nominal cases with the record's five run-to-run
  factors fitted beside the teeth (their prior the draw's spread; the chord Jacobian's columns from the same
  nominal point), the covariance the white floor only;
- ``oracle_refresh``, ``nominal_refresh``: the case's fit, then a fresh teeth Jacobian at its estimate (22
  simulations) and the fit again from there (the chord's fixed point is biased where the Jacobian at the
  nominal reducer differs from the one at the specimen; the refreshed one removes most of that).

Each with 1 record and with the mean of 3.  The planet table (runouts, crank holes and phases) is the specimen's
own in every case: unknown ones are not measured here.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import time

import numpy as np

from rvdiag.errors import RvdiagError
from rvdiag.library.paired import draw_variation
from rvdiag.params import ReducerParams
from rvdiag.updating import observability as ob
from rvdiag.updating.specimen import levenberg_marquardt, te_covariance

CASES = ("oracle", "nominal", "joint", "oracle_refresh", "nominal_refresh", "oracle_nuisance", "nominal_nuisance")


def base_params() -> ReducerParams:
    return ReducerParams.default().replace(mounting={"path_resonance_hz": 4000.0, "path_damping_ratio": 0.08})


def setup(op: ob.OperatingPoint, draws: int):
    """The chord Jacobian (teeth and stiffness factors), the run-to-run columns and draws, at the nominal reducer."""
    base = base_params()
    pars = ob.reducer_parameters(base, planets=False, path=False, stiffness=True, damping=False, encoder=False)
    zero = np.zeros(base.stage1.sun_teeth)
    J = ob.jacobian(base, op, pars, check_linearity=False, teeth0=zero)
    G = ob.jacobian(base, op, ob.run_to_run_parameters(), check_linearity=False, teeth0=zero)
    D = ob.run_to_run_draws(base, op, draws, seed=0, teeth0=zero) if draws else None
    return base, pars, J, G, D


def covariance(G: ob.Jacobian, D, noise: ob.NoiseModel, records: int) -> np.ndarray:
    """The TE lines' covariance of the mean of ``records`` records of 1 s each
    (:func:`rvdiag.updating.specimen.te_covariance`)."""
    return te_covariance(G.columns["te"], [p.prior_sd ** 2 for p in G.parameters],
                         None if D is None else D["te"], noise.line_variance("te", 1.0, G.vibration_power)) / records


def measure(spec: ReducerParams, pars, f_true: dict, truth: np.ndarray, op, noise, seed: int, n: int,
            variation: bool = True, white: bool = True):
    """``n`` noisy records of the specimen: its TE lines, each with its own run-to-run draw and white noise
    (either left out for the diagnosis, the draws still made)."""
    keys = {p.name.replace(" ", "_"): p for p in ob.run_to_run_parameters()}
    vrng = np.random.default_rng([seed, 2])
    nrng = np.random.default_rng([seed, 3])
    out = []
    for _ in range(n):
        v = draw_variation(vrng)
        pert = ob.Perturbation(dict(f_true))
        for k, f in v.items():
            pert = pert.add(keys[k], (f - 1.0) * variation)
        y = ob.observe(spec, op, pert, truth)["te"]
        sd = np.sqrt(noise.line_variance("te", 1.0, 1.0))
        out.append(y + white * sd * nrng.standard_normal(y.size))
    return np.array(out)


def identify(spec, pars, J, Ci, y, case: str, f_true: dict, op, trust: float, iterations: int, truth, start=None):
    """Levenberg-Marquardt (:func:`rvdiag.updating.specimen.levenberg_marquardt`) with the chord Jacobian ``J`` from
    the teeth ``start`` (default zero) and nominal factors; returns the teeth (m), the factors, the history and the count of simulations."""
    teeth = [j for j, p in enumerate(pars) if p.kind == "tooth"]
    facs = [j for j, p in enumerate(pars) if p.kind == "factor"]
    nuis = [j for j, p in enumerate(pars) if p.group == "run-to-run"]
    est = teeth + (facs if case == "joint" else []) + (nuis if case.endswith("_nuisance") else [])
    L, _ = ob.prior_square_root([pars[j] for j in est], ob.sun_tooth_prior(spec))
    Jl = J.columns["te"][:, est] @ L                             # per unit of z
    m = L.shape[1]

    def predict(z):
        th = L @ z
        fac = dict(f_true) if case.startswith("oracle") else {}
        for k, j in enumerate(est):
            if pars[j].kind != "tooth":
                fac[pars[j]] = th[k]
        return ob.observe(spec, op, ob.Perturbation(fac), th[:len(teeth)])["te"], th

    Wt = np.linalg.cholesky(Ci).T                               # r^T Ci r = ||Wt r||^2
    z = np.zeros(m)
    if start is not None:
        th0 = np.zeros(len(est))
        th0[:len(teeth)] = start
        z = np.linalg.lstsq(L, th0, rcond=None)[0]

    def residual(zz):
        return Wt @ (y - predict(zz)[0])

    def step(zz, dz):                                           # joint: the factors' step within the trust region
        if case == "joint" and trust > 0:
            dth = L @ dz
            dz = dz / max(np.max(np.abs(dth[len(teeth):])) / trust, 1.0)
        return dz

    hist = [float(np.sqrt(np.mean(((L @ z)[:len(teeth)] - truth) ** 2)))]
    lm = levenberg_marquardt(residual, Wt @ Jl, z, iterations, step=step,
                             on_iteration=lambda it, zz, c: hist.append(
                                 float(np.sqrt(np.mean(((L @ zz)[:len(teeth)] - truth) ** 2)))))
    th = L @ lm.z
    facs_est = th[len(teeth):len(teeth) + len(facs)] if case == "joint" else None
    return th[:len(teeth)], facs_est, hist, lm.evaluations


def crb(J, G, D, pars, spec, records: int, case: str) -> float:
    """The Cramér–Rao bound of the teeth (RMS over teeth, m) from ``records`` records of 1 s (the TE only)."""
    est = [p for p in pars if p.kind == "tooth" or (case == "joint" and p.kind == "factor")]
    idx = [pars.index(p) for p in est]
    sub = ob.Jacobian(est, {s: J.columns[s][:, idx] for s in ob.OBSERVATIONS}, J.nominal, {}, J.vibration_power)
    r = ob.analyse(sub, G, ("te",), record_s=1.0, records=records, tooth_prior=ob.sun_tooth_prior(spec), draws=D)
    return float(np.sqrt(np.mean(r.tooth_crb_m ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/twin_identify_te.json")
    ap.add_argument("--seeds", default="300,301,302,303,304", help="the specimens' error_seed values")
    ap.add_argument("--cases", default=",".join(CASES[:3]), help=f"of {', '.join(CASES)}")
    ap.add_argument("--records", default="1,3", help="numbers of records averaged")
    ap.add_argument("--draws", type=int, default=8, help="run-to-run draws in the whitening (seed 0)")
    ap.add_argument("--cache", default="", help="keep the Jacobian, columns and draws in this pickle (reused if there)")
    ap.add_argument("--no-variation", action="store_true", help="diagnosis: records without run-to-run variation")
    ap.add_argument("--no-white", action="store_true", help="diagnosis: records without the white noise")
    ap.add_argument("--iterations", type=int, default=12)
    ap.add_argument("--trust", type=float, default=0.05, help="joint: largest factor change per step")
    a = ap.parse_args()
    from rvdiag.gears.modification import iso1328_tolerances, tooth_position_errors

    op = ob.OperatingPoint()
    noise = ob.NoiseModel()
    t0 = time.perf_counter()
    if a.cache and os.path.exists(a.cache):
        with open(a.cache, "rb") as fh:
            base, pars, J, G, D = pickle.load(fh)
    else:
        base, pars, J, G, D = setup(op, a.draws)
        if a.cache:
            os.makedirs(os.path.dirname(a.cache) or ".", exist_ok=True)
            with open(a.cache, "wb") as fh:
                pickle.dump((base, pars, J, G, D), fh)
    print(f"chord Jacobian, run-to-run columns and {a.draws} draws: {time.perf_counter() - t0:.0f} s", flush=True)
    recs = [int(k) for k in a.records.split(",")]
    rr = list(G.parameters)                                 # the run-to-run factors, as nuisance parameters
    Jx = ob.Jacobian(pars + rr, {s: np.hstack([J.columns[s], G.columns[s]]) for s in ob.OBSERVATIONS}, J.nominal,
                     {}, J.vibration_power)
    cases = a.cases.split(",")
    facs = [p for p in pars if p.kind == "factor"]
    s1 = base.stage1
    tol = iso1328_tolerances(s1.module, s1.module * s1.sun_teeth, 5)
    rows = []
    for seed in (int(s) for s in a.seeds.split(",")):
        spec = base.replace(modification={"error_seed": seed, "iso1328_grade": 5})
        truth = tooth_position_errors(s1.sun_teeth, tol, seed)
        assert np.allclose(truth, ob.nominal_tooth_errors(spec))
        frng = np.random.default_rng([seed, 1])
        f_true = {p: float(frng.uniform(-0.1, 0.1)) for p in facs}
        ts = time.perf_counter()
        Y = measure(spec, pars, f_true, truth, op, noise, seed, max(recs), not a.no_variation, not a.no_white)
        t_rms = float(np.sqrt(np.mean(truth ** 2)))
        f_rms = float(np.sqrt(np.mean(np.array(list(f_true.values())) ** 2)))
        print(f"\n# specimen {seed}: pattern {t_rms * 1e6:.3f} um RMS, stiffness factors {100 * f_rms:.1f} % RMS "
              f"off; {max(recs)} records in {time.perf_counter() - ts:.0f} s", flush=True)
        for n in recs:
            Ci = np.linalg.inv(covariance(G, D, noise, n))
            Cw = np.eye(Ci.shape[0]) * n / noise.line_variance("te", 1.0, 1.0)
            y = Y[:n].mean(axis=0)
            done = {}
            for case in cases:
                ts = time.perf_counter()
                if case == "joint":                  # the teeth first (the nominal case), then a Jacobian there
                    if "nominal" not in done:
                        done["nominal"] = identify(spec, pars, J, Ci, y, "nominal", f_true, op, a.trust,
                                                   a.iterations, truth) + (time.perf_counter() - ts,)
                    t1, _, h1, s1_, sec1 = done["nominal"]
                    J1 = ob.jacobian(spec, op, pars, check_linearity=False, teeth0=t1)
                    est, fe, hist, sims = identify(spec, pars, J1, Ci, y, case, f_true, op, a.trust, a.iterations,
                                                   truth, start=t1)
                    hist, sims = h1 + hist[1:], s1_ + sims + 2 * len(pars)
                    ts -= sec1 if "nominal" in cases and cases.index("nominal") < cases.index("joint") else 0.0
                elif case.endswith("_refresh"):      # the case's chord fit, then a teeth Jacobian there, again
                    first = case[:-len("_refresh")]
                    if first not in done:
                        done[first] = identify(spec, pars, J, Ci, y, first, f_true, op, a.trust, a.iterations,
                                               truth) + (time.perf_counter() - ts,)
                    t1, _, h1, s1_, sec1 = done[first]
                    tp = [p for p in pars if p.kind == "tooth"]
                    here = ob._split(ob.Perturbation(dict(f_true) if first == "oracle" else {}), spec, t1)[0]
                    Jt = ob.jacobian(here, op, tp, check_linearity=False, teeth0=t1)
                    cols = {s: np.hstack([Jt.columns[s], np.zeros((Jt.columns[s].shape[0], len(pars) - len(tp)))])
                            for s in ob.OBSERVATIONS}
                    J1 = ob.Jacobian(pars, cols, Jt.nominal, {}, Jt.vibration_power)
                    est, fe, hist, sims = identify(spec, pars, J1, Ci, y, first, f_true, op, a.trust, a.iterations,
                                                   truth, start=t1)
                    hist, sims = h1 + hist[1:], s1_ + sims + 2 * len(tp)
                    ts -= sec1 if first in cases and cases.index(first) < cases.index(case) else 0.0
                elif case.endswith("_nuisance"):     # the record's run-to-run factors fitted, white floor only
                    est, fe, hist, sims = identify(spec, pars + rr, Jx, Cw, y, case, f_true, op, a.trust,
                                                   a.iterations, truth)
                else:
                    est, fe, hist, sims = identify(spec, pars, J, Ci, y, case, f_true, op, a.trust, a.iterations,
                                                   truth)
                    done[case] = (est, fe, hist, sims, time.perf_counter() - ts)
                err = float(np.sqrt(np.mean((est - truth) ** 2)))
                bound = crb(J, G, D, pars, spec, n, case)               # at the nominal reducer's Jacobian
                row = {"seed": seed, "records": n, "case": case, "truth_rms_um": t_rms * 1e6,
                       "stiffness_rms_off": f_rms, "error_rms_um": err * 1e6, "error_rel": err / t_rms,
                       "crb_rms_um": bound * 1e6, "crb_rel": bound / t_rms, "iterations": len(hist) - 1,
                       "simulations": sims, "seconds": time.perf_counter() - ts,
                       "history_um": [h * 1e6 for h in hist]}
                if fe is not None:
                    row["factor_error_rms"] = float(np.sqrt(np.mean((fe - np.array(list(f_true.values()))) ** 2)))
                rows.append(row)
                print(f"  {n} record(s), {case:8s}: error {err * 1e6:.4f} um = {err / t_rms:.4f} of the pattern "
                      f"(CRB {bound / t_rms:.4f}); {len(hist) - 1} iterations, {sims} simulations, "
                      f"{row['seconds']:.0f} s; history " + " ".join(f"{h * 1e6:.3f}" for h in hist)
                      + (f"; factors off {row['factor_error_rms']:.4f} RMS" if fe is not None else ""), flush=True)
        os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
        with open(a.out, "w") as fh:
            json.dump({"rows": rows, "args": vars(a)}, fh, indent=1)
    print("\n| case | records | error / pattern RMS, per specimen | pooled RMS | CRB / pattern RMS (pooled) | "
          "iterations | seconds per identification |")
    print("|---|---|---|---|---|---|---|")
    for case in cases:
        for n in recs:
            sel = [r for r in rows if r["case"] == case and r["records"] == n]
            if not sel:
                continue
            per = ", ".join(f"{r['error_rel']:.3g}" for r in sel)
            pooled = np.sqrt(np.mean([r["error_rms_um"] ** 2 for r in sel]) / np.mean([r["truth_rms_um"] ** 2
                                                                                       for r in sel]))
            pcrb = np.sqrt(np.mean([r["crb_rms_um"] ** 2 for r in sel]) / np.mean([r["truth_rms_um"] ** 2 for r in sel]))
            its = f"{min(r['iterations'] for r in sel)}-{max(r['iterations'] for r in sel)}"
            secs = f"{min(r['seconds'] for r in sel):.0f}-{max(r['seconds'] for r in sel):.0f}"
            print(f"| {case} | {n} | {per} | {pooled:.3g} | {pcrb:.3g} | {its} | {secs} |")
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
