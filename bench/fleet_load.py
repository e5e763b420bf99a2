"""The fleet service under load and faults, against real ``uvicorn`` servers on 127.0.0.1.

Scenarios (each prints one line and appends nothing by itself; ``--history`` appends the run to bench/HISTORY.md):

- ``load``: ``--clients`` concurrent clients (threads) each send ``--records`` distinct records of its own joint;
  afterwards every record is in the store exactly once (none lost, none doubled).
- ``kill``: the same, while the server is killed with SIGKILL ``--kills`` times mid-run and restarted; each client
  resends every record whose answer it did not get (the same bytes and the same ``Idempotency-Key``): none lost,
  none doubled, and the store consistent (every record's kept raw file present and of its checksum; every joint's
  state replays).
- ``two``: two server processes on one database (PostgreSQL), the clients split between them.
- ``scaling``: the store's cost per ingested record as a joint's history grows (in-process, ``--records N``),
  and the time of ``status()``, ``history()`` and of the dashboard's pages at the end.
- ``throughput``: records/s sustained and p95 latency for 1 s 48 kHz vibration records judged by the default
  monitor (``--monitor MODEL_DIR`` and its commissioning files), against the CLI's one-process-per-record path
  (``rvdiag diagnose MODEL FILE --baseline BASE``) in the same run.

The load and fault scenarios judge with :class:`TinyJudge` (a stand-in of :class:`rvdiag.fleet.judge.Judge` that
judges a record in microseconds), so that they measure the service, its store and its idempotence, not the monitor;
the throughput scenario judges with the real monitor.

Usage::

    PYTHONPATH=src python bench/fleet_load.py load --db sqlite:////tmp/f.db --clients 8 --records 200
    PYTHONPATH=src python bench/fleet_load.py kill --db sqlite:////tmp/f.db --clients 8 --records 200 --kills 2
    eval "$(bash tests/services/start.sh)"   # RVDIAG_TEST_POSTGRES
    PYTHONPATH=src python bench/fleet_load.py kill --db postgres --clients 8 --records 200
    PYTHONPATH=src python bench/fleet_load.py two --db postgres --clients 8 --records 200
    PYTHONPATH=src python bench/fleet_load.py scaling --records 1000
    PYTHONPATH=src python bench/fleet_load.py throughput --monitor out/demo-monitor --store out/demo-monitoring.zarr \\
        --records 40 --clients 4 --servers 2 --cli-records 3   # or --commission FILE... --files FILE... [--fs HZ]

``--db postgres`` creates a database of a random name on the server of ``$RVDIAG_TEST_POSTGRES`` and drops it
afterwards.  ``serve`` (used by the scenarios, and by tests/test_fleet_browser.py) runs one server:
``python bench/fleet_load.py serve --db URL --port P [--tiny-judge]``.
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import math
import os
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from datetime import datetime, timedelta, timezone
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
FS = 2000.0
ALPHA = 0.2


class TinyJudge:
    """A stand-in of :class:`rvdiag.fleet.judge.Judge` (the same four methods) that judges in microseconds: the
    health index is a record's RMS over its baseline's, its p-value ``exp(-10 (index - 1))`` (capped at 1), the
    monitor's alarm ``p <= alpha`` (alpha 0.2).  It reads files with :func:`rvdiag.io.read_signal`, so a bad file
    is refused as the real judge refuses it; a record at another sampling rate than its baseline's is refused; a
    flat record is "not recognised"."""

    alpha = ALPHA

    def describe(self, monitor):
        return {"alpha": self.alpha, "signal": "vibration"}

    def read(self, path, reading, monitor):
        from rvdiag.io import read_signal

        return read_signal(path, channel_regex=reading.channel, fs=reading.fs)

    def make_baseline(self, monitor, records, operating_points, out):
        out = Path(out)
        out.mkdir(parents=True)
        rms = float(np.mean([np.sqrt(np.mean(r.data ** 2)) for r in records]))
        (out / "tiny.json").write_text(json.dumps({"rms": rms, "fs": records[0].fs}))
        return {"n_records": len(records), "operating_points": operating_points}

    def judge(self, monitor, baseline, signal, reading, operating_point):
        from rvdiag.errors import ParameterError

        base = json.loads((Path(baseline) / "tiny.json").read_text())
        if signal.fs != base["fs"]:
            raise ParameterError(f"the record's sampling rate {signal.fs} Hz is not its baseline's {base['fs']} Hz")
        x = np.asarray(signal.data, dtype=float)
        flat = float(np.std(x)) == 0.0
        hi = float(np.sqrt(np.mean(x ** 2)) / base["rms"])
        p = min(1.0, math.exp(-10 * (hi - 1)))
        alarm = (not flat) and p <= self.alpha
        return {"health_index": hi, "p_value": p, "alarm": alarm, "false_alarm_rate": self.alpha, "threshold": None,
                "state": "T1" if alarm else "healthy", "state_name": "broken tooth" if alarm else "healthy",
                "probability": 0.9, "probabilities": {"healthy": 0.1 if alarm else 0.9, "T1": 0.9 if alarm else 0.1},
                "changes": [f"vibration RMS x{hi:.2f}"] if alarm else [], "recognised": not flat,
                "reason": "flat signal (dead sensor?)" if flat else None, "operating_point": operating_point,
                "warnings": [], "n_windows": 1, "windows": []}


def record_bytes(rng, scale: float = 1.0, n: int = 400, fs: float = FS, flat: bool = False) -> bytes:
    """One record as NPZ bytes: channel ``vib`` (``n`` samples, RMS ~ ``scale``) and the scalar ``fs``."""
    x = np.zeros(n) if flat else rng.normal(size=n) * scale
    buf = io.BytesIO()
    np.savez(buf, vib=x, fs=np.array(fs))
    return buf.getvalue()


def make_fleet(url: str, workdir: Path, joints: list[str], seed: int = 0, judge=None, commission: int = 3,
               rules: dict | None = None):
    """A fleet store at ``url`` with ``joints`` watched by :class:`TinyJudge` and commissioned on ``commission``
    healthy records each (at 2024-01-01); returns the open :class:`rvdiag.fleet.Fleet`."""
    from rvdiag.fleet import Fleet, Reading

    fleet = Fleet.init(url, judge=judge or TinyJudge())
    monitor = workdir / "tiny-monitor"
    monitor.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for j in joints:
        fleet.add_joint(j, monitor=monitor, rules=rules)
        files = []
        for i in range(commission):
            f = workdir / f"commission-{j.replace('/', '_')}-{i}.npz"
            f.write_bytes(record_bytes(rng))
            files.append(f)
        fleet.commission(j, files, Reading(load=50.0), time=datetime(2024, 1, 1, tzinfo=timezone.utc))
    return fleet


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve(url: str, port: int, tiny: bool, host: str = "127.0.0.1") -> None:
    """Run one server (uvicorn) on the fleet store at ``url``."""
    import uvicorn

    from rvdiag.fleet import Fleet
    from rvdiag.fleet.api import create_app

    fleet = Fleet.open(url, judge=TinyJudge() if tiny else None)
    uvicorn.run(create_app(fleet), host=host, port=port, log_level="warning")


def start_server(url: str, port: int, tiny: bool = True, log: Path | None = None) -> subprocess.Popen:
    """Start a server process (:func:`serve` with :class:`TinyJudge` if ``tiny``, else ``rvdiag fleet serve``) and
    wait until it answers ``/api/health`` (60 s at most)."""
    import httpx

    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if tiny:
        cmd = [sys.executable, str(Path(__file__).resolve()), "serve", "--db", url, "--port", str(port), "--tiny-judge"]
    else:  # the service as users start it
        cmd = [sys.executable, "-m", "rvdiag", "fleet", "serve", "--db", url, "--port", str(port)]
    out = open(log, "ab") if log else subprocess.DEVNULL
    proc = subprocess.Popen(cmd, env=env, stdout=out, stderr=out)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"the server exited with {proc.returncode} ({' '.join(cmd)})")
        try:
            if httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            pass
        time.sleep(0.1)
    proc.kill()
    raise RuntimeError("the server did not answer within 60 s")


def stop(proc: subprocess.Popen, sig=signal.SIGTERM) -> None:
    if proc.poll() is None:
        proc.send_signal(sig)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


class Client(threading.Thread):
    """Sends ``records`` (bytes) of ``joint``, one at a time, each until the server answers it (a lost connection
    or a 5xx: sent again, the same bytes and Idempotency-Key, after a pause).  ``urls``: the servers to use, the
    next one tried after a failure."""

    def __init__(self, urls: list[str], token: str, joint: str, records: list[bytes], t0: datetime):
        super().__init__(daemon=True)
        self.urls, self.token, self.joint, self.records, self.t0 = urls, token, joint, records, t0
        self.answers: list[dict] = []
        self.latencies: list[float] = []
        self.resent = 0
        self.error: str | None = None

    def run(self):
        import httpx

        which = 0
        with httpx.Client(timeout=30) as http:
            for i, data in enumerate(self.records):
                key = f"{self.joint}#{i}"
                when = (self.t0 + timedelta(minutes=i)).isoformat()
                tries = 0
                while True:
                    tries += 1
                    start = time.perf_counter()
                    try:
                        r = http.post(f"{self.urls[which]}/api/joints/{self.joint}/records",
                                      headers={"Authorization": f"Bearer {self.token}", "Idempotency-Key": key},
                                      files={"file": (f"r{i:05d}.npz", data)}, data={"time": when, "load": "50"})
                        if r.status_code < 500:
                            break
                    except httpx.HTTPError:
                        pass
                    self.resent += 1
                    which = (which + 1) % len(self.urls)
                    if tries > 600:
                        self.error = f"record {i} not answered after {tries} tries"
                        return
                    time.sleep(0.1)
                self.latencies.append(time.perf_counter() - start)
                if r.status_code not in (200, 201):
                    self.error = f"record {i}: {r.status_code} {r.text[:200]}"
                    return
                self.answers.append(r.json())


def check_store(url: str, sent: dict[str, list[bytes]]) -> dict:
    """Every record sent is in the store once (by checksum), nothing else is; the kept raw files are there and of
    their checksum; every joint's state replays.  Returns counts; raises AssertionError on the first breach."""
    from rvdiag.fleet import Fleet
    from rvdiag.fleet.blobs import checksum

    fleet = Fleet.open(url, judge=TinyJudge())
    try:
        n = dups = 0
        for joint, records in sent.items():
            hist = fleet.history(joint)
            got = [h["checksum"] for h in hist]
            want = {checksum(b) for b in records}
            dups += len(got) - len(set(got))
            lost = want - set(got)
            extra = set(got) - want
            assert not lost, f"{joint}: {len(lost)} records lost"
            assert not extra, f"{joint}: {len(extra)} records never sent"
            assert len(got) == len(set(got)), f"{joint}: {len(got) - len(set(got))} records doubled"
            assert not any(h["rejected"] for h in hist), f"{joint}: a record rejected"
            for h in hist[-3:]:
                path = fleet.blobs.find(h["checksum"])
                assert checksum(Path(path).read_bytes()) == h["checksum"], f"{joint}: kept file differs"
            n += len(got)
        rows = {r["joint"]: r for r in fleet.status()}
        for joint, records in sent.items():
            assert rows[joint]["n_records"] == len(records), f"{joint}: status counts {rows[joint]['n_records']}"
        return {"records": n, "doubled": dups, "lost": 0}
    finally:
        fleet.close()


@contextmanager
def database(spec: str, workdir: Path):
    """A fresh store URL: ``postgres`` -> a new database on ``$RVDIAG_TEST_POSTGRES``'s server (dropped at the
    end; raw records in ``workdir/blobs`` unless ``$RVDIAG_FLEET_BLOBS`` says); ``sqlite`` -> a file in
    ``workdir``; else ``spec`` itself."""
    if spec == "sqlite":
        yield f"sqlite:///{workdir / 'fleet.db'}"
        return
    if spec != "postgres":
        yield spec
        return
    import sqlalchemy as sa

    base = os.environ.get("RVDIAG_TEST_POSTGRES")
    if not base:
        raise SystemExit('error: RVDIAG_TEST_POSTGRES is not set: eval "$(bash tests/services/start.sh)"')
    blobs = os.environ.get("RVDIAG_FLEET_BLOBS")
    os.environ["RVDIAG_FLEET_BLOBS"] = blobs or str(workdir / "blobs")  # raw records (the servers inherit it)
    name = "rvdiag_load_" + secrets.token_hex(4)
    admin = sa.create_engine(base, isolation_level="AUTOCOMMIT")
    with admin.connect() as c:
        c.execute(sa.text(f'CREATE DATABASE "{name}"'))
    try:
        yield sa.engine.make_url(base).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as c:
            c.execute(sa.text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        admin.dispose()
        if blobs is None:
            del os.environ["RVDIAG_FLEET_BLOBS"]


def run_clients(urls_of, token, sent, t0):
    clients = [Client(urls_of(i), token, joint, recs, t0) for i, (joint, recs) in enumerate(sent.items())]
    for c in clients:
        c.start()
    return clients


def scenario(kind: str, db_spec: str, n_clients: int, n_records: int, kills: int, workdir: Path, seed: int = 0):
    """Run one load / fault scenario; returns its summary dict."""
    workdir.mkdir(parents=True, exist_ok=True)
    joints = [f"plant/r{i // 4 + 1}/j{i % 4 + 1}" for i in range(n_clients)]
    rng = np.random.default_rng(seed)
    sent = {j: [record_bytes(rng) for _ in range(n_records)] for j in joints}
    with database(db_spec, workdir) as url:
        fleet = make_fleet(url, workdir, joints, seed=seed)
        token = fleet.create_token("load", read_only=False)
        fleet.close()
        n_servers = 2 if kind == "two" else 1
        ports = [free_port() for _ in range(n_servers)]
        log = workdir / "server.log"
        procs = []
        try:
            procs += [start_server(url, p, log=log) for p in ports]
            bases = [f"http://127.0.0.1:{p}" for p in ports]
            t0 = datetime(2024, 2, 1, tzinfo=timezone.utc)
            start = time.perf_counter()
            clients = run_clients(lambda i: bases[i % n_servers:] + bases[:i % n_servers], token, sent, t0)
            killed = 0
            if kind == "kill":
                total = n_clients * n_records
                for k in range(kills):
                    target = total * (k + 1) / (kills + 1)
                    while sum(len(c.answers) for c in clients) < target and any(c.is_alive() for c in clients):
                        time.sleep(0.02)
                    procs[0].send_signal(signal.SIGKILL)
                    procs[0].wait()
                    killed += 1
                    time.sleep(0.5)
                    procs[0] = start_server(url, ports[0], log=log)
            for c in clients:
                c.join()
            wall = time.perf_counter() - start
        finally:
            for p in procs:
                stop(p)
        errors = [c.error for c in clients if c.error]
        assert not errors, errors
        counts = check_store(url, sent)
        answered_dup = sum(a["duplicate"] for c in clients for a in c.answers)
        lat = np.array([x for c in clients for x in c.latencies])
    return {"scenario": kind, "db": db_spec, "servers": n_servers, "clients": n_clients, "records_each": n_records,
            "kills": killed, "resent": sum(c.resent for c in clients), "answered_duplicate": int(answered_dup),
            "stored": counts["records"], "lost": counts["lost"], "doubled": counts["doubled"],
            "wall_s": round(wall, 1), "records_per_s": round(n_clients * n_records / wall, 1),
            "p95_ms": round(float(np.percentile(lat, 95)) * 1000, 1)}


def variants(files: list[Path], n: int, seed: int = 0) -> list[tuple[str, bytes]]:
    """``n`` distinct records from ``files`` (NPZ or NPY): the files themselves, then copies with noise of 1e-6 of
    each channel's RMS added (distinct bytes, so the store does not take them for the same record; the judging work
    is the same)."""
    rng = np.random.default_rng(seed)
    out = [(f.name, f.read_bytes()) for f in files[:n]]
    i = 0
    while len(out) < n:
        f = files[i % len(files)]
        i += 1
        if f.suffix == ".npy":
            x = np.load(f, allow_pickle=False)
            buf = io.BytesIO()
            np.save(buf, x + rng.normal(size=x.shape) * 1e-6 * np.sqrt(np.mean(x ** 2)))
        else:
            with np.load(f, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            for k, v in arrays.items():
                if v.ndim >= 1 and v.dtype.kind == "f" and v.size > 1000:
                    arrays[k] = v + rng.normal(size=v.shape) * 1e-6 * np.sqrt(np.mean(v ** 2))
            buf = io.BytesIO()
            np.savez(buf, **arrays)
        out.append((f"v{len(out):04d}-{f.name}", buf.getvalue()))
    return out


def export_joint(store_path: Path, out: Path) -> tuple[list[Path], list[Path]]:
    """A joint's files from a paired library (``make demo``'s out/demo-monitoring.zarr): the first held-out
    reducer's commissioning records (one NPY each) and 1 s monitored records, each two 0.5 s records of one load
    group end to end (as bench/monitor_record_speed.py makes them); the operating point in each name
    (``_s<deg/s>_l<N m>.npy``).  Returns (commissioning files, record files)."""
    from rvdiag.datasets import SampleStore

    store = SampleStore.open(store_path)
    s = store.load(index=np.arange(store.n_samples))
    meta = {k: np.asarray(v) for k, v in s.meta.items()}
    test = np.flatnonzero(meta["split"].astype(str) == "test")
    mine = meta["reducer"] == meta["reducer"][test[0]]
    role = meta["role"].astype(str)
    fs = int(store.fs)
    out.mkdir(parents=True, exist_ok=True)

    def rows(u):
        return np.flatnonzero(meta["unit"] == u)

    def point(units):
        return (float(np.mean([meta["output_speed_deg_s"][rows(u)[0]] for u in units])),
                float(np.mean([meta["load_Nm"][rows(u)[0]] for u in units])))

    base, recs = [], []
    for u in dict.fromkeys(meta["unit"][mine & (role == "baseline")].tolist()):
        sp, ld = point([u])
        base.append(out / f"base_u{u}_s{sp:.3f}_l{ld:.3f}.npy")
        np.save(base[-1], np.concatenate([s.X[i] for i in rows(u)]).astype(np.float64))
    groups: dict = {}
    loads = meta["load_Nm"][mine]
    for u in dict.fromkeys(meta["unit"][mine & (role == "monitored")].tolist()):
        groups.setdefault(point([u])[1] > (loads.min() + loads.max()) / 2, []).append(u)
    for units in groups.values():
        for a, b in zip(units[::2], units[1::2]):
            x = np.concatenate([s.X[i] for u in (a, b) for i in rows(u)]).astype(np.float64)[:fs]
            if len(x) == fs:
                sp, ld = point([a, b])
                recs.append(out / f"rec{len(recs):02d}_s{sp:.3f}_l{ld:.3f}.npy")
                np.save(recs[-1], x)
    return base, recs


def throughput(monitor: Path, commission: list[Path], records: list[Path], *, n: int, clients: int, servers: int,
               n_cli: int, meta_regex: str, fs: float | None, workdir: Path) -> dict:
    """Records/s sustained and latency through the HTTP API of ``servers`` ``rvdiag fleet serve`` processes on one
    store with the real monitor (after one warm-up record per server), ``clients`` clients at a time, against
    ``rvdiag diagnose MODEL FILE --baseline BASE`` run as one process per record.  Each file's operating point
    comes from its name by ``meta_regex`` (groups ``output_speed_deg_s``, ``load_Nm``)."""
    import httpx

    from rvdiag.fleet import Fleet, Reading

    workdir.mkdir(parents=True, exist_ok=True)
    url = f"sqlite:///{workdir / 'fleet.db'}"
    joint = "plant/r1/j1"
    fleet = Fleet.init(url)
    fleet.add_joint(joint, monitor=monitor)
    reading = Reading(meta_regex=meta_regex, fs=fs)
    info = fleet.commission(joint, commission, reading, time=datetime(2024, 1, 1, tzinfo=timezone.utc))
    token = fleet.create_token("bench", read_only=False)
    fleet.close()
    recs = variants(records, n + servers)
    ports = [free_port() for _ in range(servers)]
    procs = [start_server(url, p, tiny=False, log=workdir / "server.log") for p in ports]
    bases = [f"http://127.0.0.1:{p}" for p in ports]
    form = {"meta_regex": meta_regex} | ({"fs": str(fs)} if fs else {})
    try:
        for k, b in enumerate(bases):  # warm-up: the model and baseline loaded once per server process
            r = httpx.post(f"{b}/api/joints/{joint}/records", headers={"Authorization": f"Bearer {token}"},
                           files={"file": recs[k]}, data=form | {"time": "2024-02-01T00:00:00Z"}, timeout=300)
            assert r.status_code == 201, r.text
        queue = list(enumerate(recs[servers:]))
        lock = threading.Lock()
        lat, errors = [], []

        def worker(w):
            with httpx.Client(timeout=300) as http:
                while True:
                    with lock:
                        if not queue:
                            return
                        i, (name, data) = queue.pop(0)
                    t = time.perf_counter()
                    r = http.post(f"{bases[w % servers]}/api/joints/{joint}/records",
                                  headers={"Authorization": f"Bearer {token}"}, files={"file": (name, data)},
                                  data=form | {"time": (datetime(2024, 2, 2, tzinfo=timezone.utc)
                                                        + timedelta(minutes=i)).isoformat()})
                    with lock:
                        lat.append(time.perf_counter() - t)
                        if r.status_code != 201:
                            errors.append(f"{r.status_code} {r.text[:200]}")

        t0 = time.perf_counter()
        threads = [threading.Thread(target=worker, args=(w,)) for w in range(clients)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        wall = time.perf_counter() - t0
    finally:
        for p in procs:
            stop(p)
    assert not errors, errors[:3]
    env = dict(os.environ, PYTHONPATH=str(REPO / "src") + os.pathsep + os.environ.get("PYTHONPATH", ""))
    cli = []
    for f in records[:n_cli]:
        op = reading.operating_point(f.name)
        cmd = [sys.executable, "-m", "rvdiag", "diagnose", str(monitor), str(f), "--baseline", info["baseline"],
               "--load", str(op["load_Nm"]), "--output-speed", str(op["output_speed_deg_s"]), "--json"] \
            + (["--fs", str(fs)] if fs else [])
        t = time.perf_counter()
        subprocess.run(cmd, env=env, check=True, capture_output=True)
        cli.append(time.perf_counter() - t)
    lat = np.array(lat)
    return {"scenario": "throughput", "servers": servers, "clients": clients, "records": len(lat),
            "records_per_s": round(len(lat) / wall, 2), "p50_s": round(float(np.median(lat)), 3),
            "p95_s": round(float(np.percentile(lat, 95)), 3),
            "cli_s_per_record": round(float(np.mean(cli)), 2), "cli_records_per_s": round(1 / float(np.mean(cli)), 3),
            "speedup": round(len(lat) / wall * float(np.mean(cli)), 1)}


def scaling(n: int, workdir: Path, checkpoints=(10, 100, 300, 1000, 3000)) -> dict:
    """How the store's per-record cost grows with a joint's history: one joint, ``n`` records ingested in-process
    with :class:`TinyJudge` (so the time is the store's), the mean ingest time of the 10 records before each
    checkpoint, and at the end the time of ``status()``, ``history()`` and of rendering the fleet and joint pages."""
    from rvdiag.fleet import Reading
    from rvdiag.fleet import web

    workdir.mkdir(parents=True, exist_ok=True)
    joint = "plant/r1/j1"
    fleet = make_fleet(f"sqlite:///{workdir / 'fleet.db'}", workdir, [joint])
    rng = np.random.default_rng(0)
    t0 = datetime(2024, 2, 1, tzinfo=timezone.utc)
    times, out = [], {"scenario": "scaling", "ingest_ms": {}}
    for i in range(n):
        data = record_bytes(rng)
        t = time.perf_counter()
        fleet.ingest(joint, data, filename="r.npz", reading=Reading(load=50.0), time=t0 + timedelta(hours=i))
        times.append(time.perf_counter() - t)
        if i + 1 in checkpoints:
            out["ingest_ms"][i + 1] = round(1000 * float(np.mean(times[-10:])), 1)
    for name, call in (("status_ms", fleet.status), ("history_ms", lambda: fleet.history(joint)),
                       ("fleet_page_ms", lambda: web.fleet_page(fleet)),
                       ("joint_page_ms", lambda: web.joint_page(fleet, joint))):
        t = time.perf_counter()
        call()
        out[name] = round(1000 * (time.perf_counter() - t), 1)
    fleet.close()
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", choices=["load", "kill", "two", "serve", "throughput", "scaling"])
    ap.add_argument("--db", default="sqlite", help="sqlite (a file in --workdir), postgres, or a URL")
    ap.add_argument("--clients", type=int, default=8)
    ap.add_argument("--records", type=int, default=200)
    ap.add_argument("--kills", type=int, default=2)
    ap.add_argument("--port", type=int, default=8000)
    ap.add_argument("--tiny-judge", action="store_true")
    ap.add_argument("--workdir", type=Path, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--monitor", type=Path, help="throughput: the monitor model directory")
    ap.add_argument("--store", type=Path, help="throughput: a paired library to take the joint's files from")
    ap.add_argument("--commission", type=Path, nargs="+", help="throughput: the joint's commissioning files")
    ap.add_argument("--files", type=Path, nargs="+", help="throughput: record files (NPZ/NPY; varied to --records)")
    ap.add_argument("--servers", type=int, default=1, help="throughput: server processes on the one store")
    ap.add_argument("--cli-records", type=int, default=5, help="throughput: records diagnosed by the CLI path")
    ap.add_argument("--meta-regex", default=r"_s(?P<output_speed_deg_s>[0-9.]+)_l(?P<load_Nm>[0-9.]+)\.",
                    help="throughput: the operating point in the file names")
    ap.add_argument("--fs", type=float, default=None, help="throughput: the files' sampling rate, Hz")
    args = ap.parse_args(argv)
    if args.scenario == "serve":
        serve(args.db, args.port, args.tiny_judge)
        return
    import tempfile

    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="fleet-load-"))
    if args.scenario == "throughput":
        if args.store:
            args.commission, args.files = export_joint(args.store, workdir / "files")
            args.fs = args.fs or float(__import__("rvdiag.datasets", fromlist=["SampleStore"])
                                       .SampleStore.open(args.store).fs)
        if not (args.monitor and args.commission and args.files):
            raise SystemExit("error: throughput needs --monitor MODEL_DIR and --store PAIRED.zarr or "
                             "--commission FILE... --files FILE...")
        out = throughput(args.monitor, args.commission, args.files, n=args.records, clients=args.clients,
                         servers=args.servers, n_cli=args.cli_records, meta_regex=args.meta_regex, fs=args.fs,
                         workdir=workdir)
        print(json.dumps(out))
        return
    if args.scenario == "scaling":
        print(json.dumps(scaling(args.records, workdir)))
        return
    out = scenario(args.scenario, args.db, args.clients, args.records, args.kills, workdir, args.seed)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
