"""The fleet's alarms on simulated joints the monitor never saw (issue 34, "Goals"; docs/fleet.md).

Two paired libraries (``rvdiag library build``), both vibration at a 20 dB floor, 48 kHz, 0.5 s records of two
12000-point windows, commissioning twice at 45 deg/s x 50 and 130 N m (configs/demo-monitoring.toml's design):

- ``train``: 8 reducers (6 train, 2 test), 8 healthy + one T2 and one T3 record each: the monitor
  (``rvdiag train --alpha 0.05``, CV+ over the 6 training reducers' 48 healthy records);
- ``unseen``, ``unseen2`` (:data:`UNSEEN`): 6 other reducers each (other seeds), each commissioned, then 34 (60)
  healthy records and 3 records with a broken tooth of 0.5-1.0 of the tooth (in that order: the tooth breaks after
  the healthy life).

Each unseen reducer becomes a joint of a fleet store (:class:`rvdiag.fleet.Fleet`, the default rules: alpha the
monitor's 5 %, alarm on 3 of 3, clear after 3, learning 19 records); its records are ingested in order, 6 h apart
(4 a day).  Among its healthy records (after the learning period) three are replaced, each at a distinct time, by
a dead (constant), a clipped (at a fifth of its peak) and a disconnected (noise at 1 % of its RMS) version of
themselves.  Measured:

- false alarms per joint-year on the healthy records after learning (and including the learning period), with the
  joint-years covered and the 95 % Poisson interval, beside the stated figure
  (:meth:`Fleet.stated_false_alarms_per_year`); the per-record alarm rates with their Clopper-Pearson intervals: the
  joint's own rank (its record alarm) against the monitor's own cross-reducer alarm on the same records (the
  baseline: the same rules fed the monitor's alarm instead of the joint's rank, replayed by
  :func:`rvdiag.fleet.rules.replay`);
- the broken tooth: the share of joints whose alarm is raised within 3 records of its appearance;
- the sensor faults: the share of dead / clipped / disconnected records shown ``sensor-fault``, and whether any
  counted as a gear fault;
- the healthy records the monitor does not recognise (shown ``sensor-fault``; they count neither way);
- the ingest time per record through :meth:`Fleet.ingest` (one process, models cached).

``--signal current``: the same on the servo motor's phase current (configs/monitoring-current.toml's design: i_a
at 1 kHz, 2.048 s records, 45 deg/s and 20 N m with the arm): a monitor on 8 reducers (alarm at 10 %, its 36
calibration records allow no lower), 6 unseen reducers with 30 healthy records and 3 with the whole tooth broken;
the joints rank their records at 5 % (:data:`CURRENT`).

``--years``: long healthy histories, to measure a rate of about one false alarm per joint-year at all.  The unseen
reducers come from life-history libraries (docs/library.md, ``[history]``; :func:`life_config`, :data:`LIFE`) of
the same record design as the monitor's: ``--reducers`` reducers each, commissioned, then ``--records`` records 6 h
apart, healthy (the fate ``broken`` with its onset at the last :data:`BROKEN_RECORDS` records), then a broken tooth
(vibration 0.5-1.0 of the tooth, current the whole tooth): every joint counts for the false alarms and for the
broken tooth.  Each set (``--sets`` of :data:`LIFE`) is built, ingested into a fleet store of its own and judged
in turn; its figures are kept (``OUT/NAME.json``) and reused, so a run resumes and a longer one adds to a shorter
one.  The broken tooth is judged with every alarm acknowledged when raised, as the stated rate assumes (the store
never acknowledges here, so a false alarm would otherwise hold the joint in alarm through the tooth).

Usage (a library or monitor that exists is reused; the libraries are 112 + 246 + 402 simulations, 10-30 min on 2
shared cores, the rest about 4 min; ``--years``: 9 x 179 simulations a set, about 25 min a set with 2 workers on
the shared machine, and 0.1-0.4 s a record to ingest)::

    PYTHONPATH=src nice python bench/fleet_alarms.py --out out/bench-fleet [--sets 2] [--json FILE]
    PYTHONPATH=src nice python bench/fleet_alarms.py --signal current --out out/bench-fleet-current [--json FILE]
    PYTHONPATH=src nice python bench/fleet_alarms.py --years --out out/years --reducers 9 --records 175 --sets 3
    PYTHONPATH=src nice python bench/fleet_alarms.py --years --signal current --out out/years-current \
        --reducers 6 --records 100 --sets 1 --workers 1
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DEMO_MONITORING = HERE.parent / "src" / "rvdiag" / "configs" / "demo-monitoring.toml"
ALPHA = 0.05
RECORDS_PER_DAY = 4
T0 = datetime(2026, 1, 1, tzinfo=timezone.utc)


#: the unseen libraries: (name, seed, healthy monitored records per reducer)
UNSEEN = [("unseen", 35, 34), ("unseen2", 36, 60)]
MONITORING_CURRENT = HERE.parent / "src" / "rvdiag" / "configs" / "monitoring-current.toml"
#: motor current (``--signal current``): the monitor's alarm at 10 % per record (its 36 calibration records), the
#: joints' own rank at 5 % (the default rules at 10 % state 4.1 false alarms per joint-year)
CURRENT = {"monitor_alpha": 0.1, "rules": {"alpha": 0.05}, "unseen": ("unseen", 38, 30)}


def current_configs(out: Path) -> dict[str, Path]:
    """``--signal current``: configs/monitoring-current.toml with 8 reducers (2 held out) to train the monitor, and 6
    other reducers with 30 healthy records and 3 with a broken tooth (the whole tooth, as that config) each."""
    import re

    text = MONITORING_CURRENT.read_text()
    body = text[text.index('name = "monitoring-current"'):]
    train = body.replace('name = "monitoring-current"', 'name = "bench-fleet-current-train"') \
        .replace("seed = 31", "seed = 37") \
        .replace("reducers = 12\ntest_reducers = 6", "reducers = 8\ntest_reducers = 2")
    _, seed, healthy = CURRENT["unseen"]
    unseen = body.replace('name = "monitoring-current"', 'name = "bench-fleet-current-unseen"') \
        .replace("seed = 31", f"seed = {seed}").replace("reducers = 12\ntest_reducers = 6",
                                                         "reducers = 6\ntest_reducers = 3")
    unseen = re.sub(r"monitored_healthy = 6\s*\n", f"monitored_healthy = {healthy}\n", unseen)
    i = unseen.index("[states.T8]")
    unseen = unseen[:i] + unseen[unseen.index("\n", unseen.index("spall_width_fraction")) + 1:]
    paths = {}
    for name, t in (("train", train), ("unseen", unseen)):
        p = out / f"{name}.toml"
        if not p.exists() or p.read_text() != t:
            p.write_text(t)
        paths[name] = p
    return paths


def configs(out: Path, reducers: int, sets: int) -> dict[str, Path]:
    """The library configs, derived from configs/demo-monitoring.toml (module docstring): ``train`` and the first
    ``sets`` of :data:`UNSEEN`."""
    import re

    text = DEMO_MONITORING.read_text()
    body = text[text.index('name = "demo-monitoring"'):]
    common = [("noise_snr_db = 30.0", "noise_snr_db = 20.0")]
    edits = {
        "train": common + [('name = "demo-monitoring"', 'name = "bench-fleet-train"'), ("seed = 27", "seed = 34"),
                           ("reducers = 12\ntest_reducers = 6", "reducers = 8\ntest_reducers = 2")],
    }
    for name, seed, healthy in UNSEEN[:sets]:
        edits[name] = common + [
            ('name = "demo-monitoring"', f'name = "bench-fleet-{name}"'), ("seed = 27", f"seed = {seed}"),
            ("reducers = 12\ntest_reducers = 6", f"reducers = {reducers}\ntest_reducers = {reducers // 2}"),
            ("monitored_healthy = 8\nmonitored_per_state = 1",
             f"monitored_healthy = {healthy}\nmonitored_per_state = 3"),
            # T2 only, from half the tooth up (the wear state T3 and its depths, whatever they are, dropped)
            (re.compile(r"broken_fraction = \{min = 0\.3, max = 1\.0\}\n\[states\.T3\]\nwear_depth = \{[^}]*\}\n"),
             "broken_fraction = {min = 0.5, max = 1.0}\n")]
    paths = {}
    for name, subs in edits.items():
        t = body
        for a, b in subs:
            if isinstance(a, re.Pattern):
                assert a.search(t), (name, a.pattern)
                t = a.sub(b, t)
                continue
            assert a in t, (name, a)
            t = t.replace(a, b)
        p = out / f"{name}.toml"
        if not p.exists() or p.read_text() != t:
            p.write_text(t)
        paths[name] = p
    return paths


#: ``--years``: the life-history libraries of long healthy histories (name, seed), built and judged one after the
#: other (``--sets``): vibration, motor current
LIFE = {"vibration": [("life1", 39), ("life2", 41), ("life3", 42), ("life4", 43), ("life5", 47), ("life6", 48),
                      ("life7", 49)],
        "current": [("life1", 44), ("life2", 45), ("life3", 46)]}
#: ``--years``: records a day (``[history] interval_days`` = 1 / this) and the broken-tooth records ending a history
BROKEN_RECORDS = 3


def life_config(out: Path, signal: str, name: str, seed: int, reducers: int, records: int) -> Path:
    """``--years``: a life-history library (docs/library.md, ``[history]``) of ``reducers`` reducers with the record
    design of the monitor it is judged by (vibration: configs/demo-monitoring.toml at a 20 dB floor, as
    :func:`configs`; current: configs/monitoring-current.toml, as :func:`current_configs`), each commissioned, then
    ``records`` records 6 h apart: healthy, and from the last :data:`BROKEN_RECORDS` on a broken tooth of 0.5-1.0 of
    the tooth (the fate ``broken`` with its onset at that record's time; vibration 0.5-1.0, current the whole tooth
    as its monitor's library).  Each record has its own operating point and run-to-run variation, each reducer its
    own specimen, path and noise floor."""
    if signal == "current":
        text = MONITORING_CURRENT.read_text()
        body = text[text.index('name = "monitoring-current"'):]
        subs = [('name = "monitoring-current"', f'name = "bench-fleet-current-{name}"'),
                ("seed = 31", f"seed = {seed}"),
                ("monitored_healthy = 6", ""), ("monitored_per_state = 3", "")]
        broken = "broken_fraction = 1.0"
    else:
        text = DEMO_MONITORING.read_text()
        body = text[text.index('name = "demo-monitoring"'):]
        subs = [("noise_snr_db = 30.0", "noise_snr_db = 20.0"),
                ('name = "demo-monitoring"', f'name = "bench-fleet-{name}"'),
                ("seed = 27", f"seed = {seed}"), ("monitored_healthy = 8\nmonitored_per_state = 1\n", "")]
        broken = "broken_fraction = {min = 0.5, max = 1.0}"
    subs.append(("reducers = 12\ntest_reducers = 6", f"reducers = {reducers}\ntest_reducers = {reducers // 2}"))
    for a, b in subs:
        assert a in body, (signal, a)
        body = body.replace(a, b)
    onset = (records - BROKEN_RECORDS + 1) / RECORDS_PER_DAY  # the k-th record lies at k / RECORDS_PER_DAY days
    body = body[:body.index("[states.T1]")] + (
        f"[history]\nrecords = {records}\ninterval_days = {1 / RECORDS_PER_DAY}\nfates = {{broken = 1.0}}\n"
        f"onset_days = {onset}\n{broken}\n")
    p = out / f"{name}.toml"
    if not p.exists() or p.read_text() != body:
        p.write_text(body)
    return p


def run(args: list, log: Path | None = None) -> None:
    cmd = [sys.executable, "-m", "rvdiag", *map(str, args)]
    print("$ rvdiag " + " ".join(map(str, args)), flush=True)
    t0 = time.perf_counter()
    with open(log, "w") if log else open(Path("/dev/null"), "w") as f:
        proc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT)
    if proc.returncode:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}" + (f"; see {log}" if log else ""))
    print(f"   ({time.perf_counter() - t0:.0f} s)", flush=True)


def records_of(store, index=None):
    """Each record of a paired store (its windows joined, in order): ``[{"reducer", "role", "state", "speed",
    "load", "x"}]`` in the store's order; ``index``: of these samples only (all of them by default)."""
    s = store.load(index=np.arange(store.n_samples) if index is None else index)
    unit = np.asarray(s.meta["unit"])
    out, seen = [], {}
    for i in range(len(unit)):
        u = int(unit[i])
        if u not in seen:
            seen[u] = len(out)
            out.append({"reducer": int(s.meta["reducer"][i]), "role": str(s.meta["role"][i]), "state": str(s.y[i]),
                        "speed": float(s.meta["output_speed_deg_s"][i]), "load": float(s.meta["load_Nm"][i]),
                        "record": int(s.meta["life.record"][i]) if "life.record" in s.meta else len(out),
                        "parts": []})
        out[seen[u]]["parts"].append(np.asarray(s.X[i], dtype=np.float64))
    for r in out:
        r["x"] = np.concatenate(r.pop("parts"))
    return out


def sensor_faults(x: np.ndarray, rng) -> dict[str, np.ndarray]:
    """A dead, a clipped and a disconnected version of a healthy record (rvdiag.library.life.apply_sensor_fault)."""
    from rvdiag.library.life import SENSOR_FAULTS, apply_sensor_fault

    return {kind: apply_sensor_fault(x, kind, rng) for kind in SENSOR_FAULTS}


def poisson_interval(k: int, exposure: float) -> list[float]:
    """The exact (Garwood) 95 % interval of a Poisson rate of ``k`` events in ``exposure``."""
    from scipy.stats import chi2

    lo = 0.0 if k == 0 else chi2.ppf(0.025, 2 * k) / 2
    hi = chi2.ppf(0.975, 2 * k + 2) / 2
    return [float(lo / exposure), float(hi / exposure)]


def clopper_pearson(k: int, n: int) -> list[float]:
    from scipy.stats import binomtest

    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=0.95, method="exact")
    return [float(ci.low), float(ci.high)]


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/bench-fleet"))
    ap.add_argument("--reducers", type=int, default=6, help="unseen reducers per library")
    ap.add_argument("--sets", type=int, default=2, help="unseen libraries (UNSEEN)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--signal", choices=("vibration", "current"), default="vibration",
                    help="vibration at a 20 dB floor, or the motor's phase current (CURRENT)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--years", action="store_true",
                    help="long histories: the life-history libraries LIFE (--sets of them, --reducers each, "
                         "--records records each, the last BROKEN_RECORDS a broken tooth)")
    ap.add_argument("--records", type=int, default=175, help="--years: records per reducer after commissioning")
    a = ap.parse_args(argv)
    out = a.out
    out.mkdir(parents=True, exist_ok=True)
    if a.years:
        return years(a, argv)
    t_start = time.perf_counter()
    current = a.signal == "current"
    cfg = current_configs(out) if current else configs(out, a.reducers, a.sets)
    unseen = [CURRENT["unseen"]] if current else UNSEEN[:a.sets]
    for name in cfg:
        if name != "train":
            run(["library", "build", cfg[name], "--out", out / f"{name}.zarr", "--workers", a.workers],
                out / f"{name}.log")
    monitor = _monitor(out, current, a.workers, cfg["train"])

    from rvdiag.datasets import SampleStore
    from rvdiag.fleet import Fleet

    recs, fs = [], None
    for k, (name, _, _) in enumerate(unseen):
        store = SampleStore.open(out / f"{name}.zarr")
        fs = float(store.fs)
        for r in records_of(store):
            r["reducer"] += 100 * k  # reducers of each library apart
            recs.append(r)
    db = out / "fleet.db"
    _fresh_db(db)
    fleet = Fleet.init(f"sqlite:///{db}")
    files = out / "records"
    files.mkdir(exist_ok=True)
    rng = np.random.default_rng(0)
    per_joint, ingest_s, n_ingested = [], 0.0, 0
    for red in sorted({r["reducer"] for r in recs}):
        pj, dt, n = _ingest_joint(fleet, f"bench/unseen/r{red}", [r for r in recs if r["reducer"] == red], monitor,
                                  fs, files, rng, CURRENT["rules"] if current else None)
        per_joint.append(pj)
        ingest_s, n_ingested = ingest_s + dt, n_ingested + n
    res = _summary(per_joint, fleet.stated_false_alarms_per_year(per_joint[0]["joint"]),
                   fleet.rules(per_joint[0]["joint"]).to_dict(), ingest_s / max(n_ingested, 1),
                   time.perf_counter() - t_start)
    return _report(res, a, argv)


def _report(res: dict, a, argv) -> dict:
    res["command"] = "PYTHONPATH=src nice python bench/fleet_alarms.py " + " ".join(map(str, argv or sys.argv[1:]))
    print(json.dumps({k: v for k, v in res.items() if k != "joints"}, indent=2))
    if a.json:
        a.json.write_text(json.dumps(res, indent=2))
    return res


def _monitor(out: Path, current: bool, workers: int, train_config: Path) -> Path:
    """The monitor of the bench (``rvdiag train`` on the ``train`` library), built and trained unless it exists."""
    run(["library", "build", train_config, "--out", out / "train.zarr", "--workers", workers], out / "train.log")
    monitor = out / "monitor"
    if not (monitor / "card.json").exists():
        run(["train", out / "train.zarr", "-o", monitor, "--alpha", CURRENT["monitor_alpha"] if current else ALPHA,
             "--seed", 0], out / "monitor.log")
    return monitor


def years(a, argv) -> dict:
    """``--years``: the first ``a.sets`` life-history libraries of :data:`LIFE` (:func:`life_config`), each built,
    then its reducers ingested as the joints of a fleet store of its own (``OUT/NAME.db``) and judged; a set's
    figures are kept in ``OUT/NAME.json`` and reused while its config and the monitor are unchanged, so a run
    resumes and a longer run (more ``--sets``) adds to a shorter one."""
    from rvdiag.datasets import SampleStore
    from rvdiag.fleet import Fleet

    out, t_start, current = a.out, time.perf_counter(), a.signal == "current"
    monitor = _monitor(out, current, a.workers,
                       current_configs(out)["train"] if current else configs(out, a.reducers, 0)["train"])
    card = (monitor / "card.json").read_text()
    per_joint, ingest_s, n_ingested, stated, rules = [], 0.0, 0, None, None
    for name, seed in LIFE[a.signal][:a.sets]:
        cfg = life_config(out, a.signal, name, seed, a.reducers, a.records)
        run(["library", "build", cfg, "--out", out / f"{name}.zarr", "--workers", a.workers], out / f"{name}.log")
        done = out / f"{name}.json"
        key = {"config": cfg.read_text(), "monitor": card}
        kept = json.loads(done.read_text()) if done.exists() else {}
        if kept.get("key") != key:
            store = SampleStore.open(out / f"{name}.zarr")
            db = out / f"{name}.db"
            _fresh_db(db)
            fleet = Fleet.init(f"sqlite:///{db}")
            files = out / "records"
            files.mkdir(exist_ok=True)
            rng = np.random.default_rng(seed)
            joints, dt_all, n_all = [], 0.0, 0
            reducer = np.asarray(store.meta["reducer"])
            for red in np.unique(reducer):
                pj, dt, n = _ingest_joint(fleet, f"bench/{name}/r{int(red)}",
                                          records_of(store, np.flatnonzero(reducer == red)), monitor,
                                          float(store.fs), files, rng, CURRENT["rules"] if current else None)
                joints.append(pj)
                dt_all, n_all = dt_all + dt, n_all + n
            j0 = joints[0]["joint"]
            kept = {"key": key, "joints": joints, "ingest_s": dt_all, "ingested": n_all,
                    "stated": fleet.stated_false_alarms_per_year(j0), "rules": fleet.rules(j0).to_dict()}
            done.write_text(json.dumps(kept))
        per_joint += _with_operating_points(kept["joints"], SampleStore.open(out / f"{name}.zarr"))
        ingest_s, n_ingested = ingest_s + kept["ingest_s"], n_ingested + kept["ingested"]
        stated, rules = kept["stated"], kept["rules"]
    res = _summary(per_joint, stated, rules, ingest_s / max(n_ingested, 1), time.perf_counter() - t_start)
    return _report(res, a, argv)


def _by_operating_point(per_joint, n_cal: int) -> dict:
    """:func:`_exchangeability`'s ``by_operating_point``."""
    from scipy.stats import norm

    out = {"above_own_point": 0, "expected": 0.0, "variance": 0.0, "alarms_at_point": {}}
    for pj in per_joint:
        n_later = len(pj["health_index"]) - len(pj["t2_states"])
        kept = [(h, p) for h, p in zip(pj["health_index"][:n_later], pj["operating_points"][:n_later])
                if h is not None]
        cal, later = kept[:n_cal], kept[n_cal:]
        top = max(h for h, _ in cal) if cal else None
        for point in sorted({p for _, p in kept}):
            c = [h for h, p in cal if p == point]
            mine = [h for h, p in later if p == point]
            if not c or not mine:
                continue
            n, m = len(c), len(mine)
            out["above_own_point"] += sum(h > max(c) for h in mine)
            out["expected"] += m / (n + 1)
            out["variance"] += m * (1 / (n + 1)) * (n / (n + 1)) * (n + 1 + m) / (n + 2)
            key = str(point)
            out["alarms_at_point"][key] = out["alarms_at_point"].get(key, 0) + sum(h > top for h in mine)
    if out["variance"] > 0:
        out["z"] = (out["above_own_point"] - out["expected"]) / math.sqrt(out["variance"])
        out["p_above"] = float(norm.sf(out["z"]))
    return out


def _with_operating_points(joints: list, store) -> list:
    """The joints' figures with each one's later records' operating points (``operating_points``, the index into
    the config's ``[baseline] operating_points``, in record order) from its life store, for :func:`_exchangeability`."""
    meta = store.meta
    first = np.asarray(meta["segment"]) == 0
    role, reducer = np.asarray(meta["role"]).astype(str), np.asarray(meta["reducer"])
    out = []
    for pj in joints:
        sel = first & (role == "monitored") & (reducer == pj["reducer"])
        order = np.argsort(np.asarray(meta["life.record"])[sel])
        out.append({**pj, "operating_points": np.asarray(meta["operating_point"])[sel][order].tolist()})
    return out


def _fresh_db(db: Path) -> None:
    """Remove a fleet store's SQLite file, its WAL files and its raw records."""
    import shutil

    for p in (db, Path(str(db) + "-wal"), Path(str(db) + "-shm")):
        p.unlink(missing_ok=True)
    shutil.rmtree(Path(str(db) + ".blobs"), ignore_errors=True)


def _ingest_joint(fleet, joint, mine, monitor, fs, files, rng, rules=None) -> tuple[dict, float, int]:
    """One reducer as the joint ``joint`` of ``fleet``: commissioned on its baseline records, then its later records
    ingested in order 6 h apart, three healthy ones after learning replaced by a dead, a clipped and a disconnected
    version of themselves; ``(figures of _judge_joint, ingest seconds, records ingested)``."""
    from rvdiag.fleet import Reading
    from rvdiag.fleet.rules import Item, Rules, replay

    fleet.add_joint(joint, monitor, rules=rules)
    rules = fleet.rules(joint)
    base = [r for r in mine if r["role"] == "baseline"]
    later = sorted((r for r in mine if r["role"] == "monitored"), key=lambda r: r["record"])
    red = joint.rsplit("/", 1)[1]
    cfiles = []
    for i, r in enumerate(base):
        p = files / f"{red}_c{i}.npy"
        np.save(p, r["x"])
        cfiles.append(p)
    fleet.commission(joint, cfiles, Reading(fs=fs), time=T0,
                     operating_points=[{"output_speed_deg_s": r["speed"], "load_Nm": r["load"]} for r in base])
    for p in cfiles:
        p.unlink()  # the store keeps the raw records
    healthy_idx = [i for i, r in enumerate(later) if r["state"] == "T1"]
    # the sensor faults replace three healthy records after learning, at distinct times
    spots = healthy_idx[rules.learning + 1::4][:3]
    kinds = dict(zip(spots, ("dead", "clipped", "disconnected")))
    history, ingest_s = [], 0.0
    for i, r in enumerate(later):
        x, kind = r["x"], kinds.get(i)
        if kind is not None:
            x = sensor_faults(x, rng)[kind]
        p = files / f"{red}_m{i}.npy"
        np.save(p, x)
        t0 = time.perf_counter()
        res = fleet.ingest(joint, p, reading=Reading(fs=fs, output_speed=r["speed"], load=r["load"]),
                           time=T0 + timedelta(hours=24 / RECORDS_PER_DAY * (i + 1)))
        ingest_s += time.perf_counter() - t0
        p.unlink()
        history.append({"state": r["state"], "sensor": kind, "res": res})
    h = fleet.history(joint)
    assert len(h) == len(later)
    pj = _judge_joint(joint, h, history, rules, Item, Rules, replay)
    print(f"{joint}: {pj['healthy_records']} healthy ({pj['healthy_not_recognised']} not recognised), "
          f"{pj['healthy_judged']} judged after learning: {pj['false_alarms']} false alarm(s) after learning, "
          f"{pj['false_alarms_with_learning']} with it (the monitor's alarm alone: "
          f"{pj['baseline_false_alarms']}); record alarms {pj['record_alarms']} / monitor {pj['monitor_alarms']};"
          f" T2 alarm within 3: {pj['t2_alarm_within_3']}; sensor faults {pj['sensor_fault_shown']}", flush=True)
    return pj, ingest_s, len(later)


def _judge_joint(joint, h, history, rules, Item, Rules, replay) -> dict:
    """One joint's figures from its history (``h``: :meth:`Fleet.history`; ``history``: what each record was)."""
    healthy_all = [i for i, x in enumerate(history) if x["state"] == "T1" and x["sensor"] is None]
    judged = [i for i in healthy_all if not h[i]["learning"] and h[i]["recognised"]]
    t2 = [i for i, x in enumerate(history) if x["state"] == "T2"]

    def raises(use_monitor: bool) -> tuple[int, int]:
        """Alarms raised on the healthy records, acknowledged at once (the stated figure's assumption), replayed
        from the stored results: (after the learning period, over all healthy records).  ``use_monitor``: the
        same rules fed the monitor's own alarm throughout (no learning period, no rank within the joint)."""
        items = [Item(time=datetime.fromisoformat(h[i]["time"]), key=i, health_index=h[i]["health_index"],
                      monitor_alarm=h[i]["monitor_alarm"], recognised=bool(h[i]["recognised"]))
                 for i, x in enumerate(history) if x["state"] == "T1"]
        rl = rules
        if use_monitor:  # one calibration score of 0.5, and each record's score 1 when the monitor alarms, else 0:
            # at alpha 0.5 the replay's record alarm is then the monitor's, from the first record on
            rl = Rules(alpha=0.5, k=rules.k, n=rules.n, m=rules.m, learning=1)
            first = min(it.time for it in items) - timedelta(seconds=1)
            items = [Item(time=first, key=-1, health_index=0.5, recognised=True)] + [
                Item(time=it.time, key=it.key, recognised=it.recognised,
                     health_index=float(bool(it.monitor_alarm)) if it.recognised else None) for it in items]
        steps = replay(items, rl, acknowledge_at_once=True)
        after = sum("raised" in st.events for st in steps if st.key in set(judged))
        return after, sum("raised" in st.events for st in steps)

    fa_after, fa_all = raises(False)
    _, base_all = raises(True)
    # the whole history (healthy, sensor faults, broken tooth) with every alarm acknowledged when raised, as the
    # stated rate assumes: a false alarm then holds the joint in alarm only until m normal records, not for good
    steps = replay([Item(time=datetime.fromisoformat(r["time"]), key=i, health_index=r["health_index"],
                         monitor_alarm=r["monitor_alarm"], recognised=bool(r["recognised"]))
                    for i, r in enumerate(h)], rules, acknowledge_at_once=True)
    state = {st.key: st.state for st in steps}
    sensors = [i for i, x in enumerate(history) if x["sensor"]]
    return {"joint": joint, "reducer": int(joint.rsplit("r", 1)[1]),
            "healthy_records": len(healthy_all), "learning": int(sum(bool(h[i]["learning"]) for i in healthy_all)),
            "healthy_judged": len(judged),
            "healthy_not_recognised": int(sum(not h[i]["recognised"] for i in healthy_all)),
            "not_recognised_reasons": sorted({(h[i]["reason"] or "")[:60] for i in healthy_all
                                              if not h[i]["recognised"]}),
            "false_alarms": fa_after, "false_alarms_with_learning": fa_all, "baseline_false_alarms": base_all,
            "record_alarms": int(sum(bool(h[i]["record_alarm"]) for i in judged)),
            "monitor_alarms": int(sum(bool(h[i]["monitor_alarm"]) for i in judged)),
            "monitor_alarms_all": int(sum(bool(h[i]["monitor_alarm"]) for i in healthy_all if h[i]["recognised"])),
            "healthy_recognised": int(sum(bool(h[i]["recognised"]) for i in healthy_all)),
            "t2_alarm_within_3": "alarm" in [h[i]["joint_state"] for i in t2[:3]] if t2 else None,
            "t2_states": [h[i]["joint_state"] for i in t2], "t2_indices": [h[i]["health_index"] for i in t2],
            "in_alarm_before_t2": bool(t2) and t2[0] > 0 and h[t2[0] - 1]["joint_state"] == "alarm",
            "t2_alarm_within_3_acknowledged": "alarm" in [state[i] for i in t2[:3]] if t2 else None,
            "t2_raised_within_3_acknowledged": any("raised" in st.events for st in steps if st.key in t2[:3]),
            "in_alarm_before_t2_acknowledged": bool(t2) and t2[0] > 0 and state[t2[0] - 1] == "alarm",
            "t2_record_alarms": [bool(h[i]["record_alarm"]) for i in t2],
            "false_alarms_at": [st.key for st in steps if "raised" in st.events and st.key in set(judged)],
            # the index series of the gear's records: None where not recognised or a sensor fault
            "health_index": [h[i]["health_index"] if h[i]["recognised"] and not history[i]["sensor"] else None
                             for i in range(len(h))],
            "joint_p_value": [h[i].get("joint_p_value") for i in range(len(h))],
            "sensor_fault_shown": {history[i]["sensor"]: h[i]["joint_state"] == "sensor-fault" for i in sensors},
            "sensor_as_gear_fault": int(sum(bool(h[i]["record_alarm"]) or h[i]["fault_state"] is not None
                                            for i in sensors)),
            "sensor_reasons": {history[i]["sensor"]: h[i]["reason"] for i in sensors}}


def _summary(per_joint, stated, rules, ingest_per_record, wall) -> dict:
    tot = (lambda key: sum(j[key] for j in per_joint))
    healthy, allh = tot("healthy_judged"), tot("healthy_records")
    years, years_all = healthy / RECORDS_PER_DAY / 365.25, allh / RECORDS_PER_DAY / 365.25
    fa, fa_all, fb = tot("false_alarms"), tot("false_alarms_with_learning"), tot("baseline_false_alarms")
    ra, ma, ma_all, rec_all = tot("record_alarms"), tot("monitor_alarms"), tot("monitor_alarms_all"), \
        tot("healthy_recognised")
    t2 = [j["t2_alarm_within_3"] for j in per_joint if j["t2_alarm_within_3"] is not None]
    t2a = [j["t2_alarm_within_3_acknowledged"] for j in per_joint
           if j.get("t2_alarm_within_3_acknowledged") is not None]
    t2r = [j["t2_raised_within_3_acknowledged"] for j in per_joint if j.get("t2_alarm_within_3") is not None]
    sens = [v for j in per_joint for v in j["sensor_fault_shown"].values()]
    return {
        "joints": per_joint, "n_joints": len(per_joint), "rules": rules,
        "stated_false_alarms_per_joint_year": stated,
        "healthy_records_judged_after_learning": healthy, "joint_years_after_learning": years,
        "false_alarms_after_learning": fa, "false_alarms_per_joint_year": fa / years if years else None,
        "false_alarms_per_joint_year_ci95": poisson_interval(fa, years) if years else None,
        "healthy_records": allh, "joint_years": years_all,
        "false_alarms_with_learning": fa_all, "false_alarms_with_learning_ci95": poisson_interval(fa_all, years_all),
        "baseline_monitor_alarm_false_alarms": fb, "baseline_ci95": poisson_interval(fb, years_all),
        "record_alarm_rate_after_learning": ra / healthy if healthy else None,
        "record_alarm_ci95": clopper_pearson(ra, healthy),
        "monitor_alarm_rate_same_records": ma / healthy if healthy else None,
        "monitor_alarm_ci95": clopper_pearson(ma, healthy),
        "monitor_alarm_rate_all_recognised_healthy": ma_all / rec_all if rec_all else None,
        "monitor_alarm_all_ci95": clopper_pearson(ma_all, rec_all),
        "healthy_not_recognised": f"{tot('healthy_not_recognised')} of {allh}",
        "broken_tooth_alarm_within_3": f"{sum(t2)} of {len(t2)}",
        "broken_tooth_alarm_within_3_acknowledged": f"{sum(t2a)} of {len(t2a)}",
        "broken_tooth_acknowledged_ci95": clopper_pearson(sum(t2a), len(t2a)) if t2a else None,
        "broken_tooth_raised_within_3_acknowledged": f"{sum(t2r)} of {len(t2r)}",
        "in_alarm_before_broken_tooth_acknowledged": sum(bool(j.get("in_alarm_before_t2_acknowledged"))
                                                         for j in per_joint),
        "sensor_fault_shown": f"{sum(sens)} of {len(sens)}",
        "sensor_as_gear_fault": tot("sensor_as_gear_fault"),
        "ingest_s_per_record": ingest_per_record, "wall_s": wall,
        # where the false alarms fall: the joints that raised any (record positions after commissioning)
        "false_alarm_joints": {j["joint"]: j.get("false_alarms_at", j["false_alarms"]) for j in per_joint
                               if j["false_alarms"]},
        **_exchangeability(per_joint, rules),
    }


def _exchangeability(per_joint, rules) -> dict:
    """Are a joint's later healthy records exchangeable with its learning records, as the stated rate assumes?

    - ``record_alarm_rate_per_joint``: each joint's record alarms after learning; given its ``N`` learning records
      a joint alarms at a rate ``F ~ Beta(j, N - j + 1)``, ``j = floor(alpha (N + 1))``
      (:func:`rvdiag.fleet.rules.false_alarms_per_year`), so a rate well above alpha is expected of some joints;
      ``joints_rate_beyond_calibration`` names those above that law's 99th percentile; ``record_alarms_pooled``:
      the joints' record alarms together against what that law implies (each joint's count beta-binomial with
      ``n`` its judged records: mean ``n j / (N + 1)``, variance ``n a b (a + b + n) / ((a + b)^2 (a + b + 1))``,
      ``a = j``, ``b = N - j + 1``), as a z-score: the per-record rate's test that allows for the joints' shared
      calibrations, which a binomial interval on the pooled records does not;
    - ``joints_later_above_learning``: the joints whose later health indices stand above their learning ones (a
      one-sided Mann-Whitney U test, p < 0.01; Mann & Whitney 1947), as a drift or a learning period unlike the
      joint's life would; ``later_above_learning_pooled``: the joints' tests pooled (Stouffer's z, the sum of the
      joints' normal scores over the square root of their number; Stouffer et al. 1949), which sees a shift that
      each joint's 19 learning records alone cannot.

    - ``by_operating_point`` (with each joint's ``operating_points``): the index may depend on the operating point,
      and then a joint's rank is in effect its rank among its learning records at the later record's point; the
      later records above every learning record of their own point, against ``m / (n_p + 1)`` expected of ``m``
      exchangeable records over ``n_p`` learning records at that point (its variance beta-binomial as above).

    Needs each joint's ``health_index`` series (``--years``); the learning records are its first ``learning``
    recognised ones, the later ones those up to the broken tooth."""
    from scipy.stats import beta, mannwhitneyu, norm

    if not per_joint or "health_index" not in per_joint[0]:
        return {}
    n_cal = int(rules["learning"])
    j = math.floor(rules["alpha"] * (n_cal + 1) + 1e-9)
    top = float(beta.ppf(0.99, j, n_cal - j + 1))
    rates, beyond, drift, z = {}, {}, {}, []
    a, b = j, n_cal - j + 1
    pooled = {"alarms": 0, "expected": 0.0, "variance": 0.0}
    for pj in per_joint:
        hi = [v for v in pj["health_index"][:len(pj["health_index"]) - len(pj["t2_states"])] if v is not None]
        learn, later = hi[:n_cal], hi[n_cal:]
        rate = pj["record_alarms"] / pj["healthy_judged"] if pj["healthy_judged"] else None
        rates[pj["joint"]] = rate
        n = pj["healthy_judged"]
        pooled["alarms"] += pj["record_alarms"]
        pooled["expected"] += n * a / (a + b)
        pooled["variance"] += n * a * b * (a + b + n) / ((a + b) ** 2 * (a + b + 1))
        if rate is not None and rate > top:
            beyond[pj["joint"]] = f"{pj['record_alarms']} of {pj['healthy_judged']}"
        if learn and later:
            p = float(mannwhitneyu(learn, later, alternative="less").pvalue)
            z.append(float(norm.isf(p)))
            if p < 0.01:
                drift[pj["joint"]] = p
    by_point = _by_operating_point(per_joint, n_cal) if "operating_points" in per_joint[0] else None
    if pooled["variance"] > 0:
        pooled["z"] = (pooled["alarms"] - pooled["expected"]) / math.sqrt(pooled["variance"])
        pooled["p_above"] = float(norm.sf(pooled["z"]))
    return {"record_alarm_rate_per_joint": rates, "calibration_rate_99th_percentile": top,
            "record_alarms_pooled": pooled, "by_operating_point": by_point,
            "joints_rate_beyond_calibration": beyond, "joints_later_above_learning": drift,
            "later_above_learning_pooled": {"z": sum(z) / math.sqrt(len(z)), "p": float(norm.sf(sum(z) / math.sqrt(
                len(z))))} if z else None}


if __name__ == "__main__":
    main()
