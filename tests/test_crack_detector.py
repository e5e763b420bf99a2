"""The crack detector with a joint's twin (:mod:`rvdiag.monitoring.crack`; docs/twin.md, "The crack detector in use"):
its reference file, the model threshold against a Monte Carlo, the noise floor's estimate, resumable commissioning,
and the detector on records simulated with the twin's own parameters.  The CLI's ``diagnose --twin`` is tested in
tests/test_monitoring_cli.py, beside the monitor it runs with."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from rvdiag.errors import DataFileError, ParameterError
from rvdiag.features.gmf import GeneralisedMatchedFilter
from rvdiag.monitoring import crack as ck
from rvdiag.params import ReducerParams


def synthetic_reference(n=400, K=8, speed=45.0, load=90.0, fs=48000.0, seed=0, digest="d" * 64,
                        noise_var=0.5, n_baseline=3) -> ck.CrackReference:
    """A reference of random arrays (no simulation): for the file format and the folder's logic."""
    rng = np.random.default_rng(seed)
    return ck.CrackReference(output_speed_deg_s=speed, load_Nm=load, fs=fs, duration_s=n / fs, n_points=n,
                             template=rng.standard_normal(n).astype(np.float32),
                             draws=rng.standard_normal((K, n)).astype(np.float32), seed=seed,
                             severity=dict(ck.CRACK_SEVERITY), params_digest=digest, seconds=1.5,
                             simulation={"transient_s": 0.2, "substeps": 4, "ranges": {"load": 0.03},
                                         "channel": 0},
                             baseline_mean=rng.standard_normal(n), n_baseline=n_baseline, noise_var=noise_var,
                             noise_var_source="given", baseline_records=["a.csv", "b.csv", "c.csv"])


# --------------------------------------------------------------------------- the reference file
def test_reference_round_trip_without_pickle(tmp_path):
    ref = synthetic_reference()
    path = ref.save(tmp_path / "op0.npz")
    with np.load(path, allow_pickle=False) as z:             # plain arrays and a JSON string: no object arrays
        assert set(z.files) == {"template", "draws", "baseline_mean", "meta"}
        assert z["template"].dtype == np.float32 and z["draws"].dtype == np.float32
    back = ck.CrackReference.load(path)
    assert np.array_equal(back.template, ref.template) and np.array_equal(back.draws, ref.draws)
    assert np.array_equal(back.baseline_mean, ref.baseline_mean)
    assert back.meta() == ref.meta() and back.simulation_key() == ref.simulation_key()
    assert not list(tmp_path.glob(".*tmp"))                   # written through a temporary sibling
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(DataFileError, match="is not a crack reference"):
        ck.CrackReference.load(tmp_path / "other.npz")


# --------------------------------------------------------------------------- the threshold
@pytest.mark.parametrize("noise_var, exact", [
    # run-to-run dominated: index / its estimated spread is Student t with m - 1 degrees of freedom, so the bound's
    # false-alarm rate is P(t_{m-1} > t_{m-1}(1 - alpha) sqrt(1 + 1/m))
    (1e-9, "t"),
    # noise dominated (its variance known): the spread is known, the rate P(Z > t_{m-1}(1 - alpha) sqrt(1 + 1/m))
    (50.0, "normal"),
])
def test_model_threshold_false_alarm_rate_matches_a_monte_carlo(noise_var, exact):
    """Healthy records of a Gaussian model (run-to-run variation of rank 4 plus white noise), a filter fitted on 4
    draws, the threshold from m = 8 fresh draws at alpha = 5 %, 20000 trials (each with its own fresh draws, baseline
    and record): the alarms' share within 5 binomial standard deviations of the exact rate, and at most alpha."""
    from scipy.stats import norm, t as student

    rng = np.random.default_rng(36)
    n, r, m, n_b, alpha, trials = 40, 4, 8, 3, 0.05, 20000
    U = rng.standard_normal((r, n)) * 2.0                      # Sigma_rr = U^T U
    delta = rng.standard_normal(n)

    def healthy(k):
        return rng.standard_normal((k, r)) @ U

    g = GeneralisedMatchedFilter(delta, healthy(4), noise_var, n_b).fit()
    alarms = 0
    for _ in range(trials):
        fresh = healthy(m)
        thr = ck.model_threshold(g, fresh, noise_var, n_b, (alpha,))[alpha]
        base = healthy(n_b) + math.sqrt(noise_var) * rng.standard_normal((n_b, n))
        y = healthy(1) + math.sqrt(noise_var) * rng.standard_normal((1, n))
        alarms += int(g.statistic(y, base)[0] > thr)
    q = student.ppf(1 - alpha, m - 1) * math.sqrt(1 + 1 / m)
    want = student.sf(q, m - 1) if exact == "t" else norm.sf(q)
    rate = alarms / trials
    assert abs(rate - want) < 5 * math.sqrt(want * (1 - want) / trials), (rate, want)
    assert rate < alpha
    # the p-value is the same bound inverted: at the threshold it is alpha
    assert ck.model_p_value(thr, g, fresh, noise_var, n_b) == pytest.approx(alpha, rel=1e-9)


# --------------------------------------------------------------------------- the noise floor
def test_noise_variance_is_what_the_draws_do_not_span():
    """Records = run-to-run variation of rank 5 (0.5 per point) + white noise (0.5), 20 records, 40 draws: the
    projection's estimate has (19)(n - 39) degrees of freedom (within 3 %), the difference's ~0.1 spread; variation
    the draws do not span raises the projection's estimate (conservative); records that spread less than the draws
    fall to the floor."""
    rng = np.random.default_rng(7)
    n, r, sigma2 = 2000, 5, 0.5
    U = rng.standard_normal((r, n)) * math.sqrt(0.1)
    B = rng.standard_normal((20, r)) @ U + math.sqrt(sigma2) * rng.standard_normal((20, n))
    H = rng.standard_normal((40, r)) @ U
    assert ck.estimate_noise_var(B, H) == pytest.approx(sigma2, rel=0.03)
    assert ck.estimate_noise_var(B[:2], H) == pytest.approx(sigma2, rel=0.15)          # 2 records: 1961 dof
    assert ck.estimate_noise_var(B, H, method="difference") == pytest.approx(sigma2, abs=0.1)
    extra = B + rng.standard_normal((20, 1)) * rng.standard_normal(n)                 # one direction more
    assert ck.estimate_noise_var(extra, H) > 1.2 * sigma2
    quiet = 0.1 * (rng.standard_normal((3, r)) @ U) + 1.0
    assert ck.estimate_noise_var(quiet, H, method="difference") == pytest.approx(1e-6 * np.mean(quiet ** 2))
    with pytest.raises(ParameterError, match="at least 2 baseline records"):
        ck.estimate_noise_var(B[:1], H)
    with pytest.raises(ParameterError, match="projection, difference"):
        ck.estimate_noise_var(B, H, method="median")


# --------------------------------------------------------------------------- commissioning, resumable
def _records(speeds_loads, n=24000, fs=48000.0):
    rng = np.random.default_rng(3)
    return [ck.CommissioningRecord(rng.standard_normal(n), fs, v, L, f"r{i}.csv")
            for i, (v, L) in enumerate(speeds_loads)]


def fake_simulation(calls: list, fail: list | None = None):
    """A stand-in for :func:`rvdiag.monitoring.crack.simulate_reference`: random arrays of the right size and
    settings; each call is appended to ``calls``; the second raises KeyboardInterrupt while ``fail[0]``."""
    from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT

    def fake(params, v, L, fs, duration_s, draws, seed, **kw):
        calls.append((round(v, 3), L))
        if fail is not None and len(calls) == 2 and fail[0]:
            raise KeyboardInterrupt
        ref = synthetic_reference(n=int((duration_s * fs - 3) * 0.99), K=draws, speed=v, load=L, fs=fs, seed=seed,
                                  digest=ck.params_digest(params))
        ref.duration_s = duration_s
        ref.simulation = {"transient_s": kw["transient_s"], "substeps": kw["substeps"],
                          "ranges": dict(RUN_TO_RUN_DEFAULT), "channel": 0, "planet_tables": kw["planet_tables"]}
        return ref

    return fake


def test_commissioning_is_resumable_and_refuses_other_parameters(tmp_path, monkeypatch):
    """Two operating points; the simulation replaced by random arrays (the real one is tested below).  An interrupted
    run keeps its finished point; the next run simulates only the other; a third simulates nothing; another
    parameter set is refused without overwrite."""
    calls, fail = [], [True]
    fake = fake_simulation(calls, fail)
    monkeypatch.setattr(ck, "simulate_reference", fake)
    p = ReducerParams.default()
    recs = _records([(45.0, 90.0), (45.3, 90.0), (30.0, 50.0), (30.1, 50.0)])
    with pytest.raises(KeyboardInterrupt):
        ck.commission_crack_references(tmp_path, p, recs, draws=6, duration_s=0.25, planet_tables=0)
    assert (tmp_path / "crack" / "op0.npz").exists() and not (tmp_path / "crack" / "op1.npz").exists()
    with pytest.raises(ParameterError, match="unfinished"):
        ck.load_twin(tmp_path)
    fail[0] = False
    calls.clear()
    man = ck.commission_crack_references(tmp_path, p, recs, draws=6, duration_s=0.25, planet_tables=0)
    assert calls == [(30.05, 50.0)] and man["complete"] and man["ops"][0]["kept"] and man["ops"][1]["simulated"]
    assert man["ops"][0]["output_speed_deg_s"] == pytest.approx(45.15) and man["simulations_per_point"] == 8
    assert json.loads((tmp_path / "crack" / "manifest.json").read_text()) == man
    calls.clear()
    man = ck.commission_crack_references(tmp_path, p, recs, draws=6, duration_s=0.25, planet_tables=0)
    assert calls == [] and all(op["kept"] for op in man["ops"])
    twin = ck.load_twin(tmp_path)
    assert len(twin.detectors) == 2
    other = p.replace(damping={"mesh_damping_ratio": 1.1 * p.damping.mesh_damping_ratio})
    with pytest.raises(ParameterError, match="params_digest differ.*--overwrite"):
        ck.commission_crack_references(tmp_path, other, recs, draws=6, duration_s=0.25, planet_tables=0)
    assert calls == []
    ck.commission_crack_references(tmp_path, other, recs, draws=6, duration_s=0.25, planet_tables=0, overwrite=True)
    assert len(calls) == 2
    # one record at a point: the noise floor cannot be estimated, unless it is given
    with pytest.raises(ParameterError, match="has one commissioning record"):
        ck.commission_crack_references(tmp_path / "b", p, recs[:1], draws=6, duration_s=0.25, planet_tables=0)
    with pytest.raises(ParameterError, match="at least 4 run-to-run draws"):
        ck.commission_crack_references(tmp_path / "b", p, recs, draws=3, planet_tables=0)
    with pytest.raises(ParameterError, match=r"multiple of the planet tables \(4\)"):
        ck.commission_crack_references(tmp_path / "b", p, recs, draws=6, planet_tables=4)


def test_twin_picks_the_operating_point_and_names_the_others(tmp_path):
    crack = tmp_path / "crack"
    crack.mkdir()
    ops = []
    for k, (v, L) in enumerate([(45.0, 90.0), (30.0, 50.0)]):
        synthetic_reference(speed=v, load=L, seed=k).save(crack / f"op{k}.npz")
        ops.append({"file": f"op{k}.npz"})
    (crack / "manifest.json").write_text(json.dumps({"complete": True, "alpha": 0.05, "ops": ops}))
    twin = ck.load_twin(tmp_path)
    assert twin.detector(46.0, 90.0).reference.output_speed_deg_s == 45.0
    assert twin.detector(29.5, 50.0).reference.load_Nm == 50.0
    with pytest.raises(ParameterError, match=r"no crack reference at 47 deg/s 90 N m .* it has 45 deg/s 90 N m, "
                                             r"30 deg/s 50 N m"):
        twin.detector(47.0, 90.0)
    x = np.random.default_rng(9).standard_normal(500)
    res = twin.judge(x, 48000.0, 45.0, 90.0)
    assert res.alpha == 0.05 and res.to_dict()["reference"]["file"].endswith("op0.npz")
    # the statistic and the threshold written out: the filter from the first 4 of 8 draws, the bound from the others
    from scipy.stats import t as student

    r = synthetic_reference(speed=45.0, load=90.0, seed=0)
    g = GeneralisedMatchedFilter(r.template.astype(float), r.draws[:4].astype(float), 0.5, 3).fit()
    w, d = g.weights_, g.deflection_
    assert res.index == pytest.approx(float((x[:400] - r.baseline_mean) @ w) / d, rel=1e-9, abs=1e-12)
    h = r.draws[4:].astype(float) @ w
    thr = student.ppf(0.95, 3) * math.sqrt(1.25 * (4 / 3) * (np.var(h, ddof=1) + 0.5 * (w @ w))) / d
    assert res.threshold == pytest.approx(thr, rel=1e-12) and res.alarm == (res.index > thr)
    with pytest.raises(ParameterError, match="needs 0.008375 s"):
        twin.judge(np.zeros(300), 48000.0, 45.0, 90.0)
    with pytest.raises(ParameterError, match="sampled at 8000 Hz"):
        twin.judge(np.zeros(500), 8000.0, 45.0, 90.0)
    with pytest.raises(ParameterError, match="does not exist"):
        ck.load_twin(tmp_path / "nothing")
    with pytest.raises(ParameterError, match="holds no crack references"):
        ck.load_twin(crack)


# --------------------------------------------------------------------------- the detector on simulated records
def test_a_cracked_record_scores_above_healthy_ones_of_the_same_twin(tmp_path):
    """The twin is the built-in RV-20E; its records are simulated with the same parameters (each with its own
    run-to-run variation, ``draw_variation``, and white noise 20 dB below the first record's power; seed 36): 3
    commissioning records, 3 healthy and one cracked (1.8 mm at 45 deg on sun tooth 0) monitored ones, 0.25 s at
    48 kHz after a 0.05 s run-in; the references (0.243 s) with 12 draws (the filter from 6).  The cracked index lies
    above every healthy one (measured: 4.03 against -0.49 to 0.04; with 6 draws, the filter from 3, the ordering is
    lost: -5.11 against -6.67 to 2.3).  So short a reference does not alarm at 1 % (threshold 4.48)."""
    from rvdiag.dynamics import ModelSettings, simulate
    from rvdiag.library.paired import apply_variation, draw_variation
    from rvdiag.library.states import tooth_faults

    p = ReducerParams.default()
    fs, dur, tr, v0, L0 = 48000.0, 0.25, 0.05, 45.0, 90.0
    rng = np.random.default_rng(36)
    sigma = None
    recs = []
    for k, state in enumerate(["T1"] * 6 + ["T4"]):
        d = draw_variation(rng)
        v = v0 * d["speed"]
        res = simulate(apply_variation(p, d), tooth_faults(state, **(ck.CRACK_SEVERITY if state == "T4" else {})),
                       output_speed_deg_s=v, load_Nm=L0 * d["load"], duration_s=dur, fs=fs, seed=k,
                       settings=ModelSettings(transient_s=tr, substeps=4))
        x = d["gain"] * np.asarray(res.signal[0], dtype=float)
        sigma = sigma or math.sqrt(np.mean(x ** 2) / 100)
        recs.append(ck.CommissioningRecord(x + sigma * rng.standard_normal(x.size), fs, v, L0, f"rec{k}"))
    man = ck.commission_crack_references(tmp_path, p, recs[:3], draws=12, duration_s=dur, transient_s=tr,
                                         planet_tables=0)
    assert len(man["ops"]) == 1 and man["ops"][0]["simulated"] and man["ops"][0]["seed"] == 0
    twin = ck.load_twin(tmp_path)
    ref = twin.detectors[0].reference
    assert ref.n_baseline == 3 and ref.noise_var_source == "estimated (projection) from 3 baseline records"
    # the floor on the axis: the stretch's interpolation lowers it a little (measured 0.85 of sigma^2; the difference
    # of variances gives several times it here, run-to-run dominated: bench/HISTORY.md)
    assert 0.6 * sigma ** 2 < ref.noise_var < 1.05 * sigma ** 2
    scores = [twin.judge(r.data, fs, r.output_speed_deg_s, L0) for r in recs[3:]]
    healthy, cracked = scores[:3], scores[3]
    assert cracked.index > max(h.index for h in healthy), [s.index for s in scores]
    assert cracked.p_value < min(h.p_value for h in healthy)
    assert all(s.threshold == healthy[0].threshold and s.deflection > 0 for s in scores)


# --------------------------------------------------------------------------- update --specimen --channel
def _fake_identification(monkeypatch):
    """``identify_specimen`` replaced by a zero pattern (the identification is tested in tests/test_specimen.py)."""
    from rvdiag.updating import specimen as sp

    def fake(params, records, settings=None, **kw):
        z = np.zeros(params.stage1.sun_teeth)
        return sp.SpecimenResult(z, z + 1e-7, np.eye(z.size) * 1e-14, z + 1e-7, z + 1e-6,
                                 [{"name": r.name, "output_speed_deg_s": r.output_speed_deg_s} for r in records],
                                 1.0, 1.0, 10, 1e-7, 1e-6, 0, 0, 0.0, settings or sp.SpecimenSettings())

    monkeypatch.setattr(sp, "identify_specimen", fake)


def _commissioning_files(d, n=4000, fs=8000.0):
    """Two CSV records of 0.5 s at 8 kHz: both encoders turning at 45 deg/s at the RV-20E's ratio, and a vibration
    channel ``acc`` at the same rate."""
    ratio = ReducerParams.default().ratio
    t = np.arange(n) / fs
    a_out = np.radians(45.0) * t
    files = []
    for k in range(2):
        acc = np.random.default_rng(k).standard_normal(n)
        path = d / f"rec{k}.csv"
        np.savetxt(path, np.column_stack([t, ratio * a_out, a_out, acc]), delimiter=",",
                   header="time_s,theta_in,theta_out,acc", comments="", fmt="%.17g")
        files.append(path)
    return files


def test_update_specimen_commissions_the_crack_references_from_the_vibration_channel(tmp_path, monkeypatch, capsys):
    from conftest import run_cli

    _fake_identification(monkeypatch)
    calls = []
    monkeypatch.setattr(ck, "simulate_reference", fake_simulation(calls))
    files = _commissioning_files(tmp_path)
    out = tmp_path / "twin"
    argv = ["update", "--specimen", *files, "--angle-channel", "theta_in", "--output-angle-channel", "theta_out",
            "--load", "90", "--out", out, "-q"]
    code, stdout, err = run_cli(argv + ["--channel", "acc", "--crack-draws", "4", "--crack-planet-tables", "2"],
                                capsys)
    assert code == 0, err
    assert calls == [(45.0, 90.0)]
    assert ("crack reference op0.npz at 45 deg/s 90 N m, 2 baseline record(s), 0.487 s: simulated: 8 simulations"
            in stdout)
    man = json.loads((out / "crack" / "manifest.json").read_text())
    assert man["complete"] and man["draws"] == 4 and man["ops"][0]["records"] == [str(f) for f in files]
    ref = ck.CrackReference.load(out / "crack" / "op0.npz")
    assert ref.params_digest == ck.params_digest(ReducerParams.load(out / "params.toml")) and ref.n_baseline == 2
    # again, with --overwrite (the identification is repeated): the reference is kept, not simulated
    code, stdout, err = run_cli(argv + ["--channel", "acc", "--crack-draws", "4", "--crack-planet-tables", "2",
                                        "--overwrite"], capsys)
    assert code == 0 and len(calls) == 1 and "kept (simulated before" in stdout, err
    # without --channel: a note, no references; the encoder's channel as --channel: one error line
    code, stdout, err = run_cli(argv[:-3] + ["--out", tmp_path / "t2", "-q"], capsys)
    assert code == 0 and "note: without --channel the crack detector's references" in err
    assert not (tmp_path / "t2" / "crack").exists()
    code, _, err = run_cli(argv[:-3] + ["--out", tmp_path / "t3", "-q", "--channel", "theta_in"], capsys)
    assert code == 2 and err.count("\n") == 1 and "picks the encoder channel 'theta_in'" in err
    code, _, err = run_cli(argv[:-3] + ["--out", tmp_path / "t4", "-q", "--channel", "acc", "--crack-draws", "3"],
                           capsys)
    assert code == 2 and "--crack-draws must be >= 4" in err
    code, _, err = run_cli(argv[:-3] + ["--out", tmp_path / "t5", "-q", "--channel", "acc", "--crack-draws", "4"],
                           capsys)
    assert code == 2 and err.count("\n") == 1 and "multiple of --crack-planet-tables (8)" in err
    code, _, err = run_cli(["update", files[0], "--output-speed", "45", "--load", "90", "--out", tmp_path / "u.toml",
                            "--no-crack-references"], capsys)
    assert code == 2 and "--no-crack-references applies to --specimen" in err


# --------------------------------------------------------------------------- evaluate: the records of a store
def test_evaluate_crack_joins_each_record_and_counts_its_alarms(tmp_path):
    """Records of two windows (``start`` 0 and 250, the second row first for one of them) on a twin of random
    arrays: healthy ones are its baseline mean plus a little noise, cracked ones add 3 times the template."""
    from rvdiag.datasets.store import Samples

    crack = tmp_path / "crack"
    crack.mkdir()
    ref = synthetic_reference(n=400, K=8, noise_var=0.01)
    ref.save(crack / "op0.npz")
    (crack / "manifest.json").write_text(json.dumps({"complete": True, "alpha": 0.01, "ops": [{"file": "op0.npz"}]}))
    twin = ck.load_twin(tmp_path)
    rng = np.random.default_rng(5)
    X, y, unit, start = [], [], [], []
    for u, state in enumerate(["T1", "T1", "T1", "T4", "T4", "T2"]):
        x = np.r_[ref.baseline_mean, np.zeros(100)] + 0.01 * rng.standard_normal(500)
        if state != "T1":
            x[:400] += 3 * ref.template
        rows = [(x[:250], 0), (x[250:], 250)]
        for w, s0 in (rows[::-1] if u == 1 else rows):
            X.append(w)
            y.append(state)
            unit.append(u)
            start.append(s0)
    n = len(y)
    meta = {"unit": np.array(unit), "start": np.array(start), "output_speed_deg_s": np.full(n, 45.2),
            "load": np.full(n, 91.0)}
    s = Samples(X=np.array(X, dtype=np.float32), y=np.array(y), meta=meta, index=np.arange(n))
    res = ck.evaluate_crack(twin, s, 48000.0)
    assert res["crack_detection"] == 1.0 and res["crack_false_alarm_rate"] == 0.0 and res["crack_alpha"] == 0.01
    assert res["crack_n_records"] == {"T1": 3, "T4": 2, "T2": 1} and len(res["crack_records"]) == 6
    # the same record's index as judged whole
    x1 = np.r_[s.X[3], s.X[2]].astype(float)
    assert res["crack_records"][1]["index"] == pytest.approx(twin.judge(x1, 48000.0, 45.2, 91.0).index, rel=1e-12)
    with pytest.raises(ParameterError, match="cannot be joined"):
        ck.whole_records(s.X, {"unit": meta["unit"]}, hop=125)


# --------------------------------------------------------------------------- the fleet
def test_fleet_commission_with_a_twin_adds_the_crack_detector_to_each_record(tmp_path):
    """A joint commissioned with a twin (random references at 45 deg/s 90 N m): its references are copied to the
    epoch, each record's result holds the crack detector's, and a record at a point the twin lacks holds the
    reason instead (the record itself is judged by the monitor as ever).  The fleet's stand-in judge with the real
    crack detector (its records carry no rate: 48 kHz)."""
    from datetime import datetime, timedelta, timezone
    from pathlib import Path
    from types import SimpleNamespace

    from fleet_fakes import FakeJudge

    from rvdiag.errors import FleetError
    from rvdiag.fleet import Fleet, Reading
    from rvdiag.fleet.judge import Judge

    class TwinJudge(FakeJudge):
        real = Judge()

        def twin(self, folder):
            return self.real.twin(folder)

        def crack(self, folder, x, op):
            return self.real.crack(folder, SimpleNamespace(data=x, fs=48000.0), op)

    twin = tmp_path / "twin"
    (twin / "crack").mkdir(parents=True)
    synthetic_reference().save(twin / "crack" / "op0.npz")
    (twin / "crack" / "manifest.json").write_text(json.dumps({"complete": True, "alpha": 0.01,
                                                              "ops": [{"file": "op0.npz"}]}))
    t0, joint, reading = datetime(2026, 1, 1, tzinfo=timezone.utc), "plant/r1/j3", Reading(output_speed=45.0, load=90.0)
    rng = np.random.default_rng(2)
    files = []
    for i in range(5):
        files.append(tmp_path / f"r{i}.npy")
        np.save(files[-1], 0.1 + 0.1 * rng.standard_normal(500))
    f = Fleet.init(f"sqlite:///{tmp_path / 'fleet.db'}", judge=TwinJudge())
    try:
        (tmp_path / "monitor").mkdir()
        f.add_joint(joint, tmp_path / "monitor")
        with pytest.raises(FleetError, match="--twin .*none: the twin folder .* does not exist"):
            f.commission(joint, files[:3], reading, time=t0, twin=tmp_path / "none")
        res = f.commission(joint, files[:3], reading, time=t0, twin=twin)
        assert (Path(res["twin"]) / "crack" / "op0.npz").is_file() and Path(res["twin"]).parent != twin.parent
        a = f.ingest(joint, files[3], reading=reading, time=t0 + timedelta(hours=1))
        crack = a["result"]["crack"]
        want = ck.load_twin(twin).judge(np.load(files[3]), 48000.0, 45.0, 90.0)
        assert crack["index"] == pytest.approx(want.index, rel=1e-12) and crack["alarm"] == want.alarm
        assert crack["reference"]["file"].startswith(res["twin"])
        b = f.ingest(joint, files[4], reading=Reading(output_speed=45.0, load=50.0), time=t0 + timedelta(hours=2))
        assert b["rejected"] is None and "no crack reference at 45 deg/s 50 N m" in b["result"]["crack"]["error"]
    finally:
        f.close()


@pytest.mark.parametrize("database", ["sqlite", "postgresql"])
def test_fleet_ranks_the_crack_index_among_the_joints_own_learning_records(database, tmp_path, monkeypatch, capsys):
    """A joint with a twin: each record after its learning period gets ``crack["joint_p_value"]``, the conformal
    rank of its crack index among the crack indices of the replay's learning records, ``(1 + #{c_i >= c}) /
    (N + 1)``, and ``joint_alarm`` at the rules' alpha; learning records carry None and ``learning``; a crack error
    and a record not recognised are no calibration scores.  A record ingested late but earlier in time moves the
    learning period as it moves the health index's.  ``fleet status --json`` has ``crack`` for that joint only.
    A stand-in judge whose crack index is the record's first sample (an error where it is negative)."""
    from contextlib import ExitStack
    from datetime import datetime, timedelta, timezone

    from conftest import run_cli
    from fleet_fakes import FakeJudge, postgres_database

    from rvdiag.fleet import Fleet, Reading

    class CrackJudge(FakeJudge):
        def twin(self, folder):
            if not (folder / "crack").is_dir():
                raise ParameterError(f"no twin at {folder}")

        def crack(self, folder, x, op):
            if x[0] < 0:
                raise ParameterError("no crack reference at this point")
            return {"index": float(x[0]), "threshold": 0.7, "alarm": bool(x[0] > 0.7), "alpha": 0.01}

    monkeypatch.setattr("rvdiag.fleet.store.Judge", CrackJudge)
    stack = ExitStack()
    if database == "sqlite":
        db_url = f"sqlite:///{tmp_path / 'fleet.db'}"
    else:
        monkeypatch.setenv("RVDIAG_FLEET_BLOBS", str(tmp_path / "blobs"))
        db_url = stack.enter_context(postgres_database())
    monkeypatch.setenv("RVDIAG_FLEET_DB", db_url)
    (tmp_path / "twin" / "crack").mkdir(parents=True)
    (tmp_path / "monitor").mkdir()
    rng = np.random.default_rng(4)

    def record(name, crack_index, flat=False):
        x = np.full(16, crack_index) if flat else np.r_[crack_index, 0.1 + 0.1 * rng.standard_normal(15)]
        np.save(tmp_path / name, x)
        return tmp_path / name

    t0, joint, reading = datetime(2026, 1, 1, tzinfo=timezone.utc), "plant/r1/j3", Reading(output_speed=45.0, load=90.0)
    f = Fleet.init(db_url, judge=CrackJudge())
    stack.callback(f.close)
    with stack:
        for name in (joint, "plant/r1/j4"):
            f.add_joint(name, tmp_path / "monitor", rules={"alpha": 0.25, "learning": 5})
            f.commission(name, [record(f"c{name[-1]}.npy", 0.1)], reading, time=t0,
                         twin=tmp_path / "twin" if name == joint else None)
        # (hours after t0, crack index, flat): the flat record is not recognised; -1 is a crack error
        plan = [(1, 0.5, False), (2, 0.05, True), (3, 0.2, False), (4, -1.0, False), (5, 0.9, False), (6, 0.4, False),
                (7, 0.3, False), (8, 1.0, False), (9, 0.45, False), (2.5, 0.35, False)]  # the last: late, early
        answers = []
        for i, (h, c, flat) in enumerate(plan):
            answers.append(f.ingest(joint, record(f"r{i}.npy", c, flat), reading=reading,
                                    time=t0 + timedelta(hours=h)))
        assert answers[0]["result"]["crack"] == {"index": 0.5, "threshold": 0.7, "alarm": False, "alpha": 0.01,
                                                 "joint_p_value": None, "joint_alarm": None, "learning": True}
        # before the late record, the learning records were 0.5, 0.2, (error), 0.9, 0.4: N = 4 scores
        assert answers[6]["result"]["crack"]["joint_p_value"] == pytest.approx(4 / 5)  # 0.3
        assert answers[7]["result"]["crack"]["joint_p_value"] == pytest.approx(1 / 5)  # 1.0
        assert answers[7]["result"]["crack"]["joint_alarm"] is True
        # brute force over the records as they stand: the first 5 recognised in time order learn
        hist = f.history(joint)
        recog = [r for r in hist if r["recognised"]]
        learn = recog[:5]
        calib = [r["crack"]["index"] for r in learn if "error" not in r["crack"]]
        assert sorted(calib) == [0.2, 0.35, 0.5, 0.9]  # the late record learns; the 0.4 record no longer does
        for r in hist:
            cr = r["crack"]
            assert cr["learning"] == bool(r["learning"])
            if r in learn or not r["recognised"] or "error" in cr:
                assert cr["joint_p_value"] is None and cr["joint_alarm"] is None
            else:
                want = (1 + sum(c >= cr["index"] for c in calib)) / (len(calib) + 1)
                assert cr["joint_p_value"] == pytest.approx(want, abs=1e-15)
                assert cr["joint_alarm"] is (want <= 0.25)
        assert [r["crack"]["joint_p_value"] for r in recog[5:]] == pytest.approx([3 / 5, 4 / 5, 1 / 5, 3 / 5])
        assert answers[-1]["result"]["crack"]["learning"] is True
        # an error result stays an error, a record not recognised keeps its crack result unranked
        assert "error" in hist[4]["crack"] and hist[1]["recognised"] is False
        code, out, err = run_cli(["fleet", "status", "--json"], capsys)
        assert code == 0, err
        rows = {r["joint"]: r for r in json.loads(out)}
        assert rows[joint]["crack"] == {"last_index": 0.45, "joint_alarm": False, "learning_left": 0}
        assert "crack" not in rows["plant/r1/j4"]
        # the dashboard shows what status and history give: the joint page's crack fact, its figure and column
        import re

        from rvdiag.fleet import web

        page = web.joint_page(f, joint)
        assert re.search(r'class="crack-index" data-value="0\.45"', page) and 'crack-alarm" data-value="false"' in page
        fig = json.loads(re.search(r'data-plot="crack-plot">(.*?)</script>', page, re.S).group(1))
        shown = {tr["name"]: tr["y"] for tr in fig["data"]}
        ranked = [r for r in recog if "error" not in r["crack"]]
        assert sorted(shown["learning"]) == sorted(r["crack"]["index"] for r in ranked if r["crack"]["learning"])
        assert shown["crack alarm"] == [r["crack"]["index"] for r in ranked if r["crack"]["joint_alarm"]] == [1.0]
        cells = re.findall(r'<td class="num crack-index[^"]*" data-value="([^"]*)"', page)
        assert len(cells) == len(hist) and sorted(c for c in cells if c) == sorted(
            repr(r["crack"]["index"]) for r in hist if "error" not in r["crack"])
        assert "crack-plot" not in web.joint_page(f, "plant/r1/j4")
        fleet_html = web.fleet_page(f)
        assert fleet_html.count('<td class="num crack-index"') == 2 and 'data-value="0.45"' in fleet_html


def test_a_reference_over_planet_tables_pools_each_tables_own_variation():
    """``planet_tables`` J: the template is the mean of the J tables' templates and the draws are each table's own
    draws less their mean, times sqrt((K - 1) / (K - J)), interleaved; checked against ``gmf_reference`` called
    per table in the same run (short records: 0.1 s after a 0.05 s run-in)."""
    from rvdiag.evaluation.separability import RUN_TO_RUN_DEFAULT, gmf_reference

    p = ReducerParams.default()
    kw = dict(output_speed_deg_s=45.0, load_Nm=90.0, duration_s=0.1, fs=48000.0)
    ref = ck.simulate_reference(p, draws=4, seed=3, transient_s=0.05, planet_tables=2, **kw)
    per_table = [gmf_reference("T4", ranges=RUN_TO_RUN_DEFAULT, draws=2, transient_s=0.05, model={"substeps": 4},
                               severities=ck.CRACK_SEVERITY, seed=3 + 100 * (j + 1),
                               params=p.replace(modification={"error_seed": 1 + j}), **kw) for j in range(2)]
    np.testing.assert_allclose(ref.template, (per_table[0]["template"] + per_table[1]["template"]) / 2, rtol=1e-6,
                               atol=1e-6 * np.abs(ref.template).max())
    scale = math.sqrt(3 / 2)
    want = [scale * (t["draws"][i] - t["draws"].mean(axis=0)) for i in range(2) for t in per_table]  # interleaved
    np.testing.assert_allclose(ref.draws, np.array(want), rtol=1e-5, atol=1e-5 * np.abs(ref.draws).max())
    assert ref.simulation["planet_tables"] == 2 and ref.draws.shape == (4, ref.n_points)
    # the two tables differ (else the test could not tell them apart), and each half of the draws holds both
    assert not np.allclose(per_table[0]["template"], per_table[1]["template"])
    with pytest.raises(ParameterError, match="multiple of the planet tables"):
        ck.simulate_reference(p, draws=6, planet_tables=4, **kw)
