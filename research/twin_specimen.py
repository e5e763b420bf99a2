"""Measure ``rvdiag update --specimen`` (:func:`rvdiag.updating.specimen.identify_specimen`) on simulated specimens
never used to develop it: the recovered sun tooth pattern's error against the truth as the number and the length
of the commissioning records grow (issue 36, step 2; docs/twin.md, "A specimen's tooth errors").

    PYTHONPATH=src nice -n 10 python research/twin_specimen.py --out out/twin_specimen.json

Specimens: the built-in RV-20E with ``[modification] error_seed`` = 310-314 (grade 5): each its own sun tooth pattern
and its own planet table (runouts, crank holes and phases), which the twin does not know (it keeps the built-in
set's, error_seed 0).  With ``--stiffness-pct P`` the specimen's nine stiffness factors
(:data:`rvdiag.library.config.STIFFNESS_KEYS`) are drawn uniform in +-P % too (``default_rng([seed, 1])``) and left
at nominal in the twin.

Records: ``--records`` (the most, 6) records per specimen at 45 deg/s, 90 N m, each with its own run-to-run
variation (:func:`rvdiag.library.paired.draw_variation`, ``default_rng([seed, 2])``), simulated as the two encoder
angles at 8 kHz quantised to 23 bits (:func:`rvdiag.updating.specimen.simulated_record`), ``--lengths`` s long (the
shorter records are the longer ones' first seconds).  Each (number, length) is one identification from a zero
pattern on the built-in set, through the same code as the command (:func:`~rvdiag.updating.specimen.te_record`,
:func:`~rvdiag.updating.specimen.identify_specimen`); the linearisation at the operating point (the command's first
``1 + 2 Z1 + 8 + draws`` simulations) is computed once and shared, since every specimen starts from the same set.
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import time

import numpy as np

from rvdiag.library.config import STIFFNESS_KEYS
from rvdiag.library.paired import draw_variation
from rvdiag.params import ReducerParams
from rvdiag.updating import specimen as sp
from rvdiag.updating.observability import nominal_tooth_errors


def specimen_params(base: ReducerParams, seed: int, stiffness_pct: float) -> ReducerParams:
    spec = base.replace(modification={"error_seed": seed})
    if stiffness_pct > 0:
        rng = np.random.default_rng([seed, 1])
        changes: dict = {}
        for s, k in STIFFNESS_KEYS:
            changes.setdefault(s, {})[k] = getattr(getattr(base, s), k) * (1 + stiffness_pct / 100 * rng.uniform(-1, 1))
        spec = spec.replace(**changes)
    return spec


def summary(rows: list, lengths, counts) -> None:
    """The table of docs/twin.md: per (records, length) the error over the pattern's RMS per specimen and pooled
    (``sqrt(sum err^2 / sum truth^2)``), the posterior and the residual-scaled spread pooled likewise."""
    print("\n| records x length | error / pattern RMS, per specimen | pooled | posterior sd, pooled | scaled sd, "
          "pooled | iterations | seconds |")
    print("|---|---|---|---|---|---|---|")
    for T in lengths:
        for n in counts:
            sel = [r for r in rows if r["records"] == n and r["length_s"] == T]
            if not sel:
                continue
            den = np.mean([r["truth_rms_um"] ** 2 for r in sel])
            pooled = np.sqrt(np.mean([r["error_rms_um"] ** 2 for r in sel]) / den)
            ppost = np.sqrt(np.mean([r["posterior_rms_um"] ** 2 for r in sel]) / den)
            pscaled = np.sqrt(np.mean([(r["scaled_rel"] * r["truth_rms_um"]) ** 2 for r in sel]) / den)
            per = ", ".join(f"{r['error_rel']:.3g}" for r in sel)
            print(f"| {n} x {T:g} s | {per} | {pooled:.3g} | {ppost:.3g} | {pscaled:.3g} | "
                  f"{min(r['iterations'] for r in sel)}-{max(r['iterations'] for r in sel)} | "
                  f"{min(r['seconds'] for r in sel):.0f}-{max(r['seconds'] for r in sel):.0f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/twin_specimen.json")
    ap.add_argument("--seeds", default="310,311,312,313,314")
    ap.add_argument("--records", default="1,3,6")
    ap.add_argument("--lengths", default="1,4", help="record lengths, s")
    ap.add_argument("--iterations", type=int, default=15)
    ap.add_argument("--draws", type=int, default=8)
    ap.add_argument("--stiffness-pct", type=float, default=0.0)
    ap.add_argument("--broyden", action="store_true", help="Broyden updates of the chord Jacobian")
    ap.add_argument("--records-spread", action="store_true", help="add the records' own sample covariance")
    ap.add_argument("--fs", type=float, default=8000.0)
    ap.add_argument("--planets-known", action="store_true",
                    help="diagnosis: the twin starts from the specimen's own planet table (its error_seed), linearised "
                         "per specimen")
    ap.add_argument("--cache", default="", help="keep the linearisation and the records in this folder")
    ap.add_argument("--summary", action="store_true", help="print the table of --out's rows and stop")
    a = ap.parse_args()
    if a.summary:
        with open(a.out) as fh:
            rows = json.load(fh)["rows"]
        summary(rows, sorted({r["length_s"] for r in rows}), sorted({r["records"] for r in rows}))
        return
    base = ReducerParams.default()
    st = sp.SpecimenSettings(iterations=a.iterations, draws=a.draws, broyden=a.broyden,
                             records_spread=a.records_spread)
    counts = [int(x) for x in a.records.split(",")]
    lengths = [float(x) for x in a.lengths.split(",")]
    speed, load = 45.0, 90.0
    t0 = time.perf_counter()

    def linearisation(start: ReducerParams, tag: str):
        lin_file = os.path.join(a.cache, f"lin_d{a.draws}{tag}.pkl") if a.cache else ""
        if lin_file and os.path.exists(lin_file):
            with open(lin_file, "rb") as fh:
                return pickle.load(fh)
        ts = time.perf_counter()
        pm = sp.linearise(start, speed, load, a.fs, st, progress=lambda m: print("  linearise:", m, flush=True))
        if lin_file:
            os.makedirs(a.cache, exist_ok=True)
            with open(lin_file, "wb") as fh:
                pickle.dump(pm, fh)
        print(f"linearisation: {pm.simulations} simulations, {time.perf_counter() - ts:.0f} s", flush=True)
        return pm

    if not a.planets_known:
        pm = linearisation(base, "")
    rows = []
    for seed in (int(s) for s in a.seeds.split(",")):
        spec = specimen_params(base, seed, a.stiffness_pct)
        twin0 = base
        if a.planets_known:                  # the specimen's planet table (its error_seed), its teeth still unknown
            twin0 = base.replace(modification={"error_seed": seed})
            pm = linearisation(twin0, f"_planets{seed}")
        truth = nominal_tooth_errors(spec)
        rms = float(np.sqrt(np.mean(truth ** 2)))
        ts = time.perf_counter()
        rec_file = os.path.join(a.cache, f"rec_{seed}_{a.stiffness_pct:g}_{max(counts)}x{max(lengths):g}.npz") \
            if a.cache else ""
        if rec_file and os.path.exists(rec_file):
            z = np.load(rec_file)
            angles = [(z[f"in{i}"], z[f"out{i}"]) for i in range(max(counts))]
        else:
            vrng = np.random.default_rng([seed, 2])
            angles = [sp.simulated_record(spec, speed, load, max(lengths), a.fs, variation=draw_variation(vrng),
                                          rng=np.random.default_rng([seed, 3, i])) for i in range(max(counts))]
            if rec_file:
                np.savez(rec_file, **{f"in{i}": x for i, (x, _) in enumerate(angles)},
                         **{f"out{i}": y for i, (_, y) in enumerate(angles)})
        print(f"\n# specimen {seed}: pattern {rms * 1e6:.3f} um RMS; {len(angles)} records of {max(lengths):g} s in "
              f"{time.perf_counter() - ts:.0f} s", flush=True)
        for T in lengths:
            n_s = int(round(T * a.fs))
            recs = [sp.te_record(x[:n_s], y[:n_s], a.fs, twin0, load_Nm=load, name=f"{seed}-{i}", settings=st)
                    for i, (x, y) in enumerate(angles)]
            for n in counts:
                res = sp.identify_specimen(twin0, recs[:n], st, points=[pm])
                err = float(np.sqrt(np.mean((res.teeth_m - truth) ** 2)))
                post = float(np.sqrt(np.mean(res.posterior_sd_m ** 2)))
                row = {"seed": seed, "records": n, "length_s": T, "truth_rms_um": rms * 1e6, "error_rms_um": err * 1e6,
                       "error_rel": err / rms, "posterior_rms_um": post * 1e6, "posterior_rel": post / rms,
                       "scaled_rel": post * res.birge_ratio / rms,
                       "chi2_start": res.chi2_start, "chi2": res.chi2, "n_lines": res.n_lines,
                       "iterations": res.iterations, "simulations": res.simulations - pm.simulations,
                       "seconds": res.seconds, "stiffness_pct": a.stiffness_pct, "planets_known": a.planets_known,
                       "broyden": a.broyden, "records_spread": a.records_spread, "converged": res.converged}
                rows.append(row)
                print(f"  {n} x {T:g} s: error {err * 1e6:.4f} um = {err / rms:.4f} of the pattern (posterior sd "
                      f"{post / rms:.4f}, scaled {post * res.birge_ratio / rms:.4f}); chi2 {res.chi2_start:.4g} -> {res.chi2:.4g} / {res.n_lines}; "
                      f"{res.iterations} iterations{'' if res.converged else ' (not converged)'}, {res.seconds:.0f} s",
                      flush=True)
                os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
                with open(a.out, "w") as fh:
                    json.dump({"rows": rows, "args": vars(a)}, fh, indent=1)
    summary(rows, lengths, counts)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
