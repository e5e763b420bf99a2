"""Observability of a reducer's own errors from a commissioning record (issue 36 step 1; docs/twin.md).

    PYTHONPATH=src nice python research/twin_observability.py --out out/twin_obs.npz            # simulate + report
    PYTHONPATH=src nice python research/twin_observability.py --out out/twin_obs.npz --report   # report only
    PYTHONPATH=src nice python research/twin_observability.py --out out/twin_long.npz --revolutions 15 \\
        --only "sun tooth 0,sun tooth 3,sun tooth 7,planet 0 runout A,bearings.sun_support" --draws 0   # the check

The nominal RV-20E (default manufacturing errors, seed 0) with a sensor path resonance at 4 kHz (damping ratio
0.08, inside configs/monitoring.toml's ranges), at 45 deg/s and 90 N m (configs/monitoring.toml's noise reference).
The Jacobian of :mod:`rvdiag.updating.observability` by central differences (and at twice the step, for linearity)
of 3 whole sun revolutions (0.2 s) after 0.1 s of run-in, 4 sub-steps; the run-to-run variation linearised (5
columns) and, beside it, ``--draws`` records drawn as the paired library draws them.  The report: the singular
values of the whitened Jacobian per signal and for all together, the parameters identifiable at 1 record of 1 s and
at 12 records (6 operating points x 2, configs/monitoring.toml's commissioning) of 1 s, the sun teeth's Cramér–Rao
and posterior spreads against the issue's 20 % goal, and where each tooth-error harmonic lies in each signal.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rvdiag.params import ReducerParams
from rvdiag.updating import observability as ob


def base_params() -> ReducerParams:
    return ReducerParams.default().replace(mounting={"path_resonance_hz": 4000.0, "path_damping_ratio": 0.08})


def simulate(a) -> None:
    base = base_params()
    op = ob.OperatingPoint(revolutions=a.revolutions, substeps=a.substeps, period_revs=a.period)
    pars = ob.reducer_parameters(base)
    if a.only:
        keep = set(a.only.split(","))
        pars = [p for p in pars if p.name in keep]
    t0 = time.perf_counter()

    def prog(i, n, name):
        print(f"  {i}/{n} {name} {time.perf_counter() - t0:.0f} s", flush=True)

    J = ob.jacobian(base, op, pars, progress=prog, check_linearity=not a.no_linearity)
    print(f"parameters: {len(pars)} in {time.perf_counter() - t0:.0f} s", flush=True)
    nuis = ob.run_to_run_parameters()
    G = ob.jacobian(base, op, nuis, progress=prog, check_linearity=not a.no_linearity)
    print(f"run-to-run columns in {time.perf_counter() - t0:.0f} s", flush=True)
    D = ob.run_to_run_draws(base, op, a.draws, seed=0) if a.draws else {s: np.zeros((0, 0)) for s in ob.OBSERVATIONS}
    print(f"{a.draws} draws in {time.perf_counter() - t0:.0f} s", flush=True)
    save = {"names": json.dumps([p.name for p in pars]), "nuisance": json.dumps([p.name for p in nuis]),
            "vibration_power": J.vibration_power,
            "seconds": time.perf_counter() - t0, "revolutions": a.revolutions, "substeps": a.substeps,
            "period": a.period}
    for s in ob.OBSERVATIONS:
        save[f"lin_{s}"] = J.linearity[s]
        save[f"nuisance_lin_{s}"] = G.linearity[s]
        save[f"J_{s}"] = J.columns[s]
        save[f"G_{s}"] = G.columns[s]
        save[f"D_{s}"] = D[s]
        save[f"nominal_{s}"] = J.nominal[s]
    os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
    np.savez(a.out, **save)
    print(f"wrote {a.out}: {time.perf_counter() - t0:.0f} s", flush=True)


def load(path: str):
    z = np.load(path)
    base = base_params()
    by = {p.name: p for p in ob.reducer_parameters(base)}
    pars = [by[n] for n in json.loads(str(z["names"]))]
    nb = {p.name: p for p in ob.run_to_run_parameters()}
    nuis = [nb[n] for n in json.loads(str(z["nuisance"]))]
    vp = float(z["vibration_power"])
    J = ob.Jacobian(pars, {s: z[f"J_{s}"] for s in ob.OBSERVATIONS}, {s: z[f"nominal_{s}"] for s in ob.OBSERVATIONS},
                    {s: z[f"lin_{s}"] for s in ob.OBSERVATIONS}, vp)
    G = ob.Jacobian(nuis, {s: z[f"G_{s}"] for s in ob.OBSERVATIONS}, J.nominal,
                    {s: z[f"nuisance_lin_{s}"] for s in ob.OBSERVATIONS}, vp)
    D = {s: z[f"D_{s}"] for s in ob.OBSERVATIONS} if z["D_vibration"].size else None
    return base, J, G, D, z


SETS = (("vibration",), ("te",), ("current",), ("te", "current"), ("vibration", "te", "current"))


def report(a) -> None:
    base, J, G, D, z = load(a.out)
    prior = ob.sun_tooth_prior(base)
    period = int(z["period"]) if "period" in z else 1
    op = ob.OperatingPoint(revolutions=int(z["revolutions"]), period_revs=period)
    print(f"# {a.out}: {len(J.parameters)} parameters, simulated in {float(z['seconds']):.0f} s; vibration RMS "
          f"{np.sqrt(J.vibration_power):.3f} m/s^2 (floor 20 dB below: {np.sqrt(J.vibration_power) / 10:.3f})")
    print("\n## linearity: ||J_h - J_2h|| / ||J_h|| per signal (vibration / te / current; nan: a zero column)")
    for jac in (J, G):
        for j, p in enumerate(jac.parameters):
            print(f"  {p.name:34s} " + " / ".join(f"{jac.linearity[s][j]:.3f}" for s in ob.OBSERVATIONS))
    cases = [("1 record of 1 s, linearised run-to-run", 1.0, 1, None),
             ("1 record of 1 s, linearised + drawn run-to-run", 1.0, 1, D),
             ("12 records of 1 s, linearised + drawn run-to-run", 1.0, 12, D)]
    for title, T, n, draws in cases:
        if draws is None and "drawn" in title:
            continue
        print(f"\n## {title}")
        for sig in SETS:
            r = ob.analyse(J, G, sig, record_s=T, records=n, tooth_prior=prior, draws=draws)
            above = int(np.sum(r.singular_values > 1))
            sv = ", ".join(f"{v:.3g}" for v in r.singular_values)
            print(f"### {'+'.join(sig)}: {above} of {len(r.names)} singular values > 1")
            print(f"  singular values: {sv}")
            print("  CRB sd / prior sd: " + "; ".join(f"{nm} {v:.3g}" for nm, v in zip(r.names, r.crb_sd)))
            rel = r.tooth_crb_m / r.tooth_prior_m
            relp = r.tooth_posterior_m / r.tooth_prior_m
            print(f"  sun teeth: prior RMS {np.sqrt(np.mean(r.tooth_prior_m ** 2)) * 1e6:.3f} um; CRB sd / prior "
                  f"{np.sqrt(np.mean(rel ** 2)):.3g} (RMS over teeth; max {rel.max():.3g}); posterior / prior "
                  f"{np.sqrt(np.mean(relp ** 2)):.3g}; 20 % goal {'met' if np.sqrt(np.mean(rel ** 2)) <= 0.2 else 'NOT met'}")
    harmonics(J, base, op, prior)


def groups_of(J: ob.Jacobian, names: list[str]) -> dict[str, list[int]]:
    """Columns of L (prior_square_root's names) by parameter group."""
    group = {p.name: p.group for p in J.parameters}
    out: dict[str, list[int]] = {}
    for k, nm in enumerate(names):
        out.setdefault("sun teeth" if nm.startswith("sun tooth harmonic") else group[nm], []).append(k)
    return out


def summary(a) -> None:
    """The tables of docs/twin.md: per signal set and case, the singular values above 1 and, per parameter group,
    how many columns the record bounds below their prior spread (CRB sd / prior sd < 1) and the median of that
    ratio; the sun teeth's RMS ratio against the issue's 20 %."""
    base, J, G, D, z = load(a.out)
    prior = ob.sun_tooth_prior(base)
    quant = ob.NoiseModel()
    cases = [("1 record of 1 s", 1.0, 1, quant), ("12 records of 1 s", 1.0, 12, quant),
             ("1 record of 1 s; TE noise 1 arcsec, floor 10 dB", 1.0, 1,
              ob.NoiseModel(snr_db=10.0, te_sd_rad=np.radians(1.0 / 3600.0)))]
    for title, T, n, noise in cases:
        print(f"\n## {title} (run-to-run: linearised + {0 if D is None else len(D['vibration'])} drawn)")
        first = True
        for sig in SETS:
            r = ob.analyse(J, G, sig, record_s=T, records=n, noise=noise, tooth_prior=prior, draws=D)
            g = groups_of(J, r.names)
            if first:
                print("| signals | singular values > 1 | " + " | ".join(g) + " |")
                print("|---" * (len(g) + 2) + "|")
                first = False
            cells = []
            for k in g.values():
                v = r.crb_sd[k]
                cells.append(f"{int(np.sum(v < 1))} of {len(k)} ({np.median(v):.2g})")
            rel = np.sqrt(np.mean((r.tooth_crb_m / r.tooth_prior_m) ** 2))
            print(f"| {' + '.join(sig)} | {int(np.sum(r.singular_values > 1))} of {r.singular_values.size} | "
                  + " | ".join(cells) + f" |  teeth CRB {rel:.2g} of prior RMS")
    print("\n## the sun teeth against record length and count (CRB sd / prior RMS, RMS over teeth; 20 % goal)")
    print("| signals | " + " | ".join(f"{n} x {T:g} s" for n in (1, 12) for T in (0.2, 1.0, 5.0)) + " |")
    print("|---" * 7 + "|")
    for sig in SETS:
        row = []
        for n in (1, 12):
            for T in (0.2, 1.0, 5.0):
                r = ob.analyse(J, G, sig, record_s=T, records=n, tooth_prior=prior, draws=D)
                row.append(f"{np.sqrt(np.mean((r.tooth_crb_m / r.tooth_prior_m) ** 2)):.2g}")
        print(f"| {' + '.join(sig)} | " + " | ".join(row) + " |")
    print("\n## each sun tooth, one record of 1 s: posterior sd of its position error / of its single pitch deviation "
          "(um); prior RMS 1.52 / 1.52 um")
    print("| signals | " + " | ".join(f"tooth {j}" for j in range(base.stage1.sun_teeth)) + " | RMS over teeth |")
    print("|---" * (base.stage1.sun_teeth + 2) + "|")
    for sig in SETS:
        r = ob.analyse(J, G, sig, record_s=1.0, records=1, tooth_prior=prior, draws=D)
        pos, pitch = r.tooth_posterior_m * 1e6, r.pitch_posterior_m() * 1e6
        print(f"| {' + '.join(sig)} | " + " | ".join(f"{u:.3g} / {v:.3g}" for u, v in zip(pos, pitch))
              + f" | {np.sqrt(np.mean(pos ** 2)):.3g} / {np.sqrt(np.mean(pitch ** 2)):.3g} |")
    if a.plot:
        plot(J, G, D, prior, a.plot)


def plot(J, G, D, prior, path: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for sig, mk in zip(SETS, "osd^v"):
        r = ob.analyse(J, G, sig, record_s=1.0, records=1, tooth_prior=prior, draws=D)
        sv = np.maximum(r.singular_values, 1e-4)
        ax.semilogy(np.arange(1, sv.size + 1), sv, marker=mk, ms=4, lw=1, label=" + ".join(sig))
    ax.axhline(1.0, color="k", lw=0.8, ls="--")
    ax.set_xlabel("singular value index")
    ax.set_ylabel("singular value (whitened, prior-spread units)")
    ax.set_title("RV-20E at 45 deg/s, 90 N m: one 1 s record, 20 dB floor, run-to-run variation")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def compare(a) -> None:
    """The Jacobian of --out against that of --against (a longer record, more sub-steps) on their common
    parameters: ||J_a - J_b|| / ||J_b|| per signal, and the singular values of the common parameters from each."""
    base, Ja, Ga, _, _ = load(a.out)
    prior = ob.sun_tooth_prior(base)
    _, Jb, Gb, _, _ = load(a.against)
    nb = [p.name for p in Jb.parameters]
    ia = [[p.name for p in Ja.parameters].index(n) for n in nb]
    print(f"\n## {a.out} against {a.against}: relative difference of each column")
    for j, n in enumerate(nb):
        print(f"  {n:28s} " + " / ".join(
            f"{np.linalg.norm(Ja.columns[s][:, ia[j]] - Jb.columns[s][:, j]) / max(np.linalg.norm(Jb.columns[s][:, j]), 1e-300):.3f}"
            for s in ob.OBSERVATIONS) + "   (vibration / te / current)")
    for jac, g, tag in ((Ja, Ga, a.out), (Jb, Gb, a.against)):
        sub = ob.Jacobian([jac.parameters[k] for k in (ia if jac is Ja else range(len(nb)))],
                          {s: jac.columns[s][:, ia if jac is Ja else slice(None)] for s in ob.OBSERVATIONS},
                          jac.nominal, {}, jac.vibration_power)
        for sig in SETS:
            r = ob.analyse(sub, g, sig, tooth_prior=prior)
            print(f"  {tag} {'+'.join(sig):24s} singular values " + ", ".join(f"{v:.3g}" for v in r.singular_values))


def scale_check(a) -> None:
    """How far the linearisation holds: tooth patterns drawn as specimens' (seeds 100..), scaled by 0.03-1, simulated,
    and ``||y(d) - y(0) - J d|| / ||y(d) - y(0)||`` per signal (the Jacobian of --out, at its own record length)."""
    base, J, G, D, z = load(a.out)
    period = int(z["period"]) if "period" in z else 1
    op = ob.OperatingPoint(revolutions=int(z["revolutions"]), substeps=int(z["substeps"]), period_revs=period)
    teeth = [j for j, p in enumerate(J.parameters) if p.kind == "tooth"]
    t0 = ob.nominal_tooth_errors(base)
    y0 = ob.observe(base, op, None, t0)
    from rvdiag.gears.modification import iso1328_tolerances, tooth_position_errors

    s1 = base.stage1
    tol = iso1328_tolerances(s1.module, s1.module * s1.sun_teeth, base.modification.iso1328_grade)
    print(f"\n## linearity at the prior's scale ({a.out}): ||y(d) - y(0) - J d|| / ||y(d) - y(0)||, "
          "vibration / te / current")
    for k in range(a.scale_check):
        d = tooth_position_errors(s1.sun_teeth, tol, 100 + k)          # a pattern drawn as a specimen's (seed 100+k)
        for scale in (0.03, 0.1, 0.3, 1.0):
            dd = scale * d
            y = ob.observe(base, op, None, t0 + dd)
            err = []
            for s in ob.OBSERVATIONS:
                dy = y[s] - y0[s]
                pred = J.columns[s][:, teeth] @ dd
                err.append(np.linalg.norm(dy - pred) / max(np.linalg.norm(dy), 1e-300))
            print(f"  pattern {k}, {scale:4.2f} x prior ({np.sqrt(np.mean(dd ** 2)) * 1e6:.3f} um RMS): "
                  + " / ".join(f"{e:.3f}" for e in err), flush=True)


def gauss_newton_check(a) -> None:
    """Can the tooth pattern be found from the prior's mean?  A specimen with the pattern of seed 100 (drawn as a
    specimen's) and, with ``--gn-factors``, its stiffness and damping factors drawn from their prior (uniform
    +-10 %, seed 100) and estimated too (else nominal and known); its lines of ``--gn-signal`` as the data, with
    ``--gn-noise`` the white noise of one 1 s record added (seed 7).  Gauss-Newton with the prior as regulariser
    (the MAP step of the linearised model at each iterate), a fresh Jacobian (central differences) at each iterate,
    from a zero pattern and nominal factors.  Prints the RMS error of the positions after each iteration."""
    from rvdiag.gears.modification import iso1328_tolerances, tooth_position_errors

    base = base_params()
    s1 = base.stage1
    op = ob.OperatingPoint(revolutions=a.revolutions, substeps=a.substeps)
    tol = iso1328_tolerances(s1.module, s1.module * s1.sun_teeth, base.modification.iso1328_grade)
    truth = tooth_position_errors(s1.sun_teeth, tol, 100)
    sig = tuple(a.gn_signal.split("+"))
    pars = ob.reducer_parameters(base, planets=False, path=False, stiffness=a.gn_factors, damping=a.gn_factors,
                                 encoder=False)
    teeth = [j for j, p in enumerate(pars) if p.kind == "tooth"]
    facs = [j for j, p in enumerate(pars) if p.kind == "factor"]
    rng = np.random.default_rng(100)
    f_true = {pars[j]: float(rng.uniform(-0.1, 0.1)) for j in facs}
    y_true = ob.observe(base, op, ob.Perturbation(dict(f_true)), truth)
    noise = ob.NoiseModel()
    if a.gn_noise:
        nrng = np.random.default_rng(7)
        for s in sig:
            y_true[s] = y_true[s] + np.sqrt(noise.line_variance(s, 1.0, y_true["_vibration_power"])) * \
                nrng.standard_normal(y_true[s].size)
    P = ob.sun_tooth_prior(base)
    w, V = np.linalg.eigh(P)
    keep = w > 1e-9 * w.max()
    n = len(pars)
    Pinv = np.zeros((n, n))
    Pinv[np.ix_(teeth, teeth)] = (V[:, keep] / w[keep]) @ V[:, keep].T   # the teeth's mean is held at 0
    for j in facs:
        Pinv[j, j] = 1.0 / pars[j].prior_sd ** 2
    theta = np.zeros(n)                                               # teeth (m), then factors (1 + v)
    t_start = time.perf_counter()
    print(f"\n## Gauss-Newton from a zero pattern on {'+'.join(sig)} ({a.revolutions} revolutions, "
          f"{'noise of a 1 s record' if a.gn_noise else 'noise-free data'}, weights of a 1 s record; "
          f"{len(facs)} factors estimated too); truth RMS {np.sqrt(np.mean(truth ** 2)) * 1e6:.3f} um")
    for it in range(a.gn_iterations + 1):
        err = np.sqrt(np.mean((theta[teeth] - truth) ** 2))
        ferr = (np.sqrt(np.mean([(theta[j] - f_true[pars[j]]) ** 2 for j in facs])) if facs else 0.0)
        print(f"  iteration {it}: teeth RMS error {err * 1e6:.4f} um ({err / np.sqrt(np.mean(np.diag(P))):.4f} of the "
              f"prior RMS); factors RMS error {ferr:.4f}; {time.perf_counter() - t_start:.0f} s", flush=True)
        if it == a.gn_iterations:
            break
        here = ob._split(ob.Perturbation({pars[j]: theta[j] for j in facs}), base, theta[teeth])[0]
        J = ob.jacobian(here, op, pars, check_linearity=False, teeth0=theta[teeth])
        A = np.zeros((n, n))
        g = np.zeros(n)
        for s in sig:
            wgt = 1.0 / noise.line_variance(s, 1.0, J.vibration_power)
            Js = J.columns[s].copy()
            Js[:, facs] /= 1.0 + theta[facs]                          # d/dv of (1 + v_k)(1 + u): per unit of v
            A += wgt * Js.T @ Js
            g += wgt * Js.T @ (y_true[s] - J.nominal[s])
        move = teeth if it < a.gn_teeth_first else list(range(n))    # the first steps hold the factors
        M = np.ix_(move, move)
        step = np.zeros(n)
        step[move] = np.linalg.lstsq((A + Pinv)[M], (g - Pinv @ theta)[move], rcond=None)[0]
        if a.gn_trust > 0 and facs:                                   # a trust region on the factors: the step
            big = np.max(np.abs(step[facs])) / a.gn_trust            # scaled so that none moves by more
            step = step / max(big, 1.0)
        theta = theta + step
        theta[teeth] -= theta[teeth].mean()


def harmonics(J, base, op, prior) -> None:
    """Where each tooth-error harmonic's sensitivity lies: its share at sun orders that N divides."""
    N = base.stage1.n_planets * op.period_revs                # lines in orders of the period: sun order n is n k
    L, names = ob.prior_square_root(J.parameters, prior)
    print(f"\n## tooth-error harmonics: share of each column's energy (at its prior spread) at orders divisible by "
          f"N = {N}, and its norm")
    for s in ob.OBSERVATIONS:
        K = J.columns[s].shape[0] // 2
        orders = np.arange(1, K + 1)
        even = np.concatenate([orders % N == 0, orders % N == 0])
        low = np.concatenate([orders <= 5 * op.period_revs, orders <= 5 * op.period_revs])
        Jz = J.columns[s] @ L
        for j, nm in enumerate(names):
            if not nm.startswith("sun tooth"):
                continue
            c = Jz[:, j]
            e = float(np.sum(c ** 2))
            per = c[:K] ** 2 + c[K:] ** 2
            top = np.argsort(per)[::-1][:4]
            tops = ", ".join(f"{orders[t] / op.period_revs:g} ({per[t] / e:.2f})" for t in top)
            print(f"  {s:9s} {nm:24s} |J L| {np.sqrt(e):.3e}; share at orders N divides {np.sum(c[even] ** 2) / e:.3f}"
                  f"; at orders 1-5: {np.sum(c[low] ** 2) / e:.3f}, of which odd {np.sum(c[low & ~even] ** 2) / e:.3f}"
                  f"; largest sun orders (share): {tops}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/twin_obs.npz")
    ap.add_argument("--report", action="store_true", help="report from --out without simulating")
    ap.add_argument("--revolutions", type=int, default=3)
    ap.add_argument("--substeps", type=int, default=4)
    ap.add_argument("--period", type=int, default=1, help="averaging period in sun revolutions (3: the cranks' too)")
    ap.add_argument("--draws", type=int, default=16)
    ap.add_argument("--no-linearity", action="store_true", help="skip the +-2h differences (half the simulations)")
    ap.add_argument("--only", default="", help="comma-separated parameter names (default: all)")
    ap.add_argument("--summary", action="store_true", help="the tables of docs/twin.md (implies --report)")
    ap.add_argument("--plot", default="", help="with --summary: write the singular values' figure here")
    ap.add_argument("--against", default="", help="compare --out's Jacobian with this file's (implies --report)")
    ap.add_argument("--scale-check", type=int, default=0, metavar="K",
                    help="simulate K prior-drawn tooth patterns at 0.03-1 x and compare with J d (implies --report)")
    ap.add_argument("--gn-check", action="store_true", help="Gauss-Newton for the tooth pattern of a specimen")
    ap.add_argument("--gn-signal", default="te", help="signals for --gn-check, joined by + (e.g. vibration+te)")
    ap.add_argument("--gn-iterations", type=int, default=5)
    ap.add_argument("--gn-factors", action="store_true", help="--gn-check: the stiffness and damping factors unknown")
    ap.add_argument("--gn-noise", action="store_true", help="--gn-check: the noise of one 1 s record on the data")
    ap.add_argument("--gn-teeth-first", type=int, default=0, metavar="K",
                    help="--gn-check: the first K iterations move the teeth only (the factors held)")
    ap.add_argument("--gn-trust", type=float, default=0.0,
                    help="--gn-check: largest factor change per iteration (the whole step scaled to it; 0: none)")
    a = ap.parse_args()
    if a.gn_check:
        gauss_newton_check(a)
        return
    if a.scale_check:
        scale_check(a)
        return
    if a.against:
        compare(a)
        return
    if a.summary:
        summary(a)
        return
    if not a.report:
        simulate(a)
    report(a)


if __name__ == "__main__":
    main()
