"""The public monitoring API (rvdiag.monitoring: make_baseline, open_baseline, monitor_record -> MonitorResult) on the
small synthetic paired store of tests/test_monitoring_cli.py: the same answer as ``rvdiag diagnose --baseline
--json``, its one-line errors, a baseline written from records, and a monitor saved before BaselineMonitor moved
to rvdiag.monitoring loading as before."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from conftest import run_cli
from rvdiag.errors import ParameterError, StoreError
from rvdiag.io.readers import MeasuredSignal
from rvdiag.monitoring import (Baseline, MonitorResult, make_baseline, monitor_record, open_baseline,
                               train_monitor)
from rvdiag.workflows import load_model, read_record
from test_monitoring_cli import FS, L, OPS, baseline_store, params_attrs, record, record_file
from test_monitoring_cli import paired  # noqa: F401  (the module-scoped paired store)

#: the keys of ``rvdiag diagnose --baseline --json`` that MonitorResult must carry
CONTRACT = ("health_index", "p_value", "alarm", "false_alarm_rate", "threshold", "state", "state_name",
            "probability", "probabilities", "changes", "recognised", "reason", "operating_point", "warnings",
            "n_windows", "windows")


@pytest.fixture(scope="module")
def monitor(paired):  # noqa: F811
    from rvdiag.datasets import SampleStore

    out = paired["dir"] / "api-monitor"
    train_monitor(SampleStore.open(paired["store"]), paired["store"], out, features=None, alpha=None, seed=0,
                  echo=lambda msg: None)
    return out


@pytest.fixture(scope="module")
def loaded(monitor):
    return load_model(monitor)


@pytest.fixture(scope="module")
def base(paired, loaded, tmp_path_factory):  # noqa: F811
    return open_baseline(baseline_store(paired, tmp_path_factory.mktemp("b") / "base.zarr"), loaded)


def test_monitor_record_gives_what_the_cli_prints(paired, monitor, loaded, base, tmp_path, capsys):  # noqa: F811
    f = record_file(paired, tmp_path / "t2.npy", "T2", speed=30.2, load=51.0)
    res = monitor_record(loaded, read_record(f, fs=FS), base, output_speed=30.2, load=51.0)
    assert isinstance(res, MonitorResult)
    d = res.to_dict()
    assert set(CONTRACT) <= set(d) and json.loads(json.dumps(d)) == d
    assert d["recognised"] is True and d["alarm"] is True and d["health_index"] > d["threshold"] == 1.0
    assert d["state"] == "T2" and d["probabilities"]["T2"] == pytest.approx(d["probability"])
    assert sum(d["probabilities"].values()) == pytest.approx(1.0)
    assert [w["start"] for w in d["windows"]] == [0, L] and d["n_windows"] == 2
    code, out, err = run_cli(["diagnose", monitor, f, "--baseline", base.path, "--fs", FS, "--output-speed", 30.2,
                              "--load", 51, "--json"], capsys)
    assert code == 0, err
    assert json.loads(out) == json.loads(json.dumps(d))  # the CLI prints MonitorResult.to_dict()


def test_a_healthy_record_raises_no_alarm_and_plots_against_the_threshold(paired, loaded, base, tmp_path):  # noqa: F811
    import matplotlib

    matplotlib.use("Agg")
    f = record_file(paired, tmp_path / "t1.npy", "T1", speed=59.6, load=128.0)
    res = monitor_record(loaded, read_record(f, fs=FS), base, output_speed=59.6, load=128.0)
    assert res.recognised and res.alarm is False and res.health_index <= 1.0 and res.p_value > res.false_alarm_rate
    ax = res.plot()
    assert len(ax.lines) == 3 and ax.lines[2].get_ydata()[0] == 1.0  # windows, record, threshold


def test_a_flat_record_is_not_recognised_and_names_no_state(loaded, base):
    rec = MeasuredSignal(data=np.full(2 * L, 0.5), fs=FS, channel="x", path=__import__("pathlib").Path("flat.npy"))
    res = monitor_record(loaded, rec, base, output_speed=30.0, load=50.0)
    assert not res.recognised and "constant" in res.reason
    assert res.state is None and res.alarm is None and res.probabilities == {} and res.windows == []


def test_bad_input_is_one_line_errors(paired, loaded, base, tmp_path):  # noqa: F811
    f = record_file(paired, tmp_path / "r.npy", "T1")
    rec = read_record(f, fs=FS)
    with pytest.raises(ParameterError, match="give --load"):
        monitor_record(loaded, rec, base, output_speed=30.0)
    with pytest.raises(ParameterError, match="no baseline within 5 % of speed"):
        monitor_record(loaded, rec, base, output_speed=45.0, load=50.0)
    with pytest.raises(ParameterError, match="sampled at 16000 Hz"):
        monitor_record(loaded, read_record(f, fs=2 * FS), base, output_speed=30.0, load=50.0)
    with pytest.raises(ParameterError, match="needs a Baseline"):
        monitor_record(loaded, rec, str(base.path), output_speed=30.0, load=50.0)
    with pytest.raises(ParameterError, match="another reducer type"):
        open_baseline(baseline_store(paired, tmp_path / "o.zarr", attrs=params_attrs(sun_teeth=13)), loaded)
    with pytest.raises(ParameterError, match="is sampled at 16000 Hz, the model at 8000 Hz"):
        open_baseline(baseline_store(paired, tmp_path / "f.zarr", fs=2 * FS), loaded)


def _answers(paired, tmp_path, *pairs):
    """``to_dict()`` of one broken-tooth record judged by each (model, baseline) of ``pairs``."""
    rec = read_record(record_file(paired, tmp_path / "t2.npy", "T2", speed=30.2, load=51.0), fs=FS)
    return [monitor_record(m, rec, b, output_speed=30.2, load=51.0).to_dict() for m, b in pairs]


def test_make_baseline_writes_a_store_that_judges_as_the_built_one(paired, loaded, base, tmp_path):  # noqa: F811
    """Records of reducer 8's baseline, written by make_baseline, give the same answer as its store."""
    m = paired["meta"]
    keep = np.flatnonzero((m["reducer"] == 8) & (m["role"] == "baseline"))
    recs = [MeasuredSignal(data=paired["X"][i].astype(np.float32).astype(np.float64), fs=FS, channel="x",
                           path=tmp_path / f"c{i}.npy") for i in keep]
    ops = [{"output_speed_deg_s": float(m["output_speed_deg_s"][i]), "load_Nm": float(m["load_Nm"][i])} for i in keep]
    made = make_baseline(recs, model=loaded, operating_points=ops, out=tmp_path / "made.zarr")
    assert isinstance(made, Baseline) and made.n_records == len(keep) and made.fs == FS
    assert len(made.operating_points) == len(keep)
    a, b = _answers(paired, tmp_path, (loaded, made), (loaded, base))
    a.pop("baseline"), b.pop("baseline")
    assert a == b
    with pytest.raises(StoreError, match="already exists"):
        make_baseline(recs, model=loaded, operating_points=ops, out=tmp_path / "made.zarr")
    with pytest.raises(ParameterError, match="one each"):
        make_baseline(recs, model=loaded, operating_points=ops[:-1], out=tmp_path / "m2.zarr")
    with pytest.raises(ParameterError, match="load_Nm > 0"):
        make_baseline(recs[:1], model=loaded, operating_points=[{"output_speed_deg_s": 30.0}], out=tmp_path / "m3")
    assert not (tmp_path / "m2.zarr").exists() and not (tmp_path / "m3").exists()


def test_read_record_reads_the_load_and_speed_from_the_name_in_one_spelling(paired, loaded, base,  # noqa: F811
                                                                            tmp_path):
    """``--meta-regex`` groups ``load`` and ``load_Nm`` both give ``load_Nm``; ``speed_dps`` gives the speed."""
    rng = np.random.default_rng(5)
    x = np.concatenate([record(rng, paired["fps"][8], 30.0, 50.0, "T2") for _ in range(2)])
    f = tmp_path / "run_30dps_50Nm.npy"
    np.save(f, x)
    for group in ("load", "load_Nm"):
        rec = read_record(f, fs=FS, meta_regex=rf"_(?P<speed_dps>\d+)dps_(?P<{group}>\d+)Nm")
        assert rec.metadata == {"speed_dps": 30.0, "load_Nm": 50.0}
        res = monitor_record(loaded, rec, base)
        assert res.operating_point["load_Nm"] == 50.0
        assert res.operating_point["output_speed_deg_s"] == pytest.approx(30.0)
        assert "from the file name" in res.operating_point["speed_source"]
    with pytest.raises(ParameterError, match="both give 'load_Nm'"):
        read_record(f, fs=FS, meta_regex=r"_(?P<load>\d+)dps_(?P<load_Nm>\d+)Nm")


def test_a_monitor_saved_before_the_move_loads_as_before(monitor, loaded, base, paired, tmp_path):  # noqa: F811
    """A model.skops that names ``rvdiag.models.monitoring.BaselineMonitor`` (saved before the monitor moved to
    rvdiag.monitoring) loads and answers bit for bit as the same monitor saved now."""
    import shutil

    old = tmp_path / "old-monitor"
    shutil.copytree(monitor, old)
    p = old / "model.skops"
    with zipfile.ZipFile(p) as z:
        members = {i: z.read(i) for i in z.infolist()}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for info, body in members.items():
            if info.filename == "schema.json":
                assert b'"rvdiag.monitoring.detector"' in body
                body = body.replace(b'"rvdiag.monitoring.detector"', b'"rvdiag.models.monitoring"')
            z.writestr(info, body)
    p.write_bytes(buf.getvalue())
    again = load_model(old)
    assert type(again.estimator) is type(loaded.estimator)
    a, b = _answers(paired, tmp_path, (again, base), (loaded, base))
    a.pop("model"), b.pop("model")
    assert a == b


def test_operating_points_are_listed(base):
    """The baseline store holds 3 records at each of OPS, each at its own speed and load (within 1 % and 3 %)."""
    assert base.n_records == 12 and len(base.operating_points) == 12
    for p in base.operating_points:
        assert any(abs(p["output_speed_deg_s"] / v - 1) <= 0.01 and abs(p["load_Nm"] / ld - 1) <= 0.03 for v, ld in OPS)


def test_diagnose_reads_the_record_as_dataset_from_files(paired, monitor, loaded, base, tmp_path, capsys):  # noqa: F811
    """``diagnose --angle-channel --meta-regex``: the speed from the encoder angle, the load from the file
    name's group ``load``, as ``dataset from-files`` reads them; the same answer as the API."""
    from rvdiag.params import ReducerParams

    rng = np.random.default_rng(21)
    v, ld = 30.0, 50.0
    t = np.arange(2 * L) / FS
    x = np.concatenate([record(rng, paired["fps"][8], v, ld, "T2") for _ in range(2)])
    angle = 2 * np.pi * v * ReducerParams.default().ratio / 360.0 * t
    f = tmp_path / "joint_50Nm.csv"
    np.savetxt(f, np.column_stack([t, x, angle]), delimiter=",", header="time_s,acc,angle_in", comments="")
    reading = ["--channel", "^acc$", "--angle-channel", "angle_in", "--meta-regex", r"_(?P<load>\d+)Nm"]
    code, out, err = run_cli(["diagnose", monitor, f, "--baseline", base.path, *reading, "--json"], capsys)
    assert code == 0, err
    got = json.loads(out)
    assert got["operating_point"]["load_Nm"] == 50.0
    assert got["operating_point"]["output_speed_deg_s"] == pytest.approx(v, rel=1e-3)
    assert "angle" in got["operating_point"]["speed_source"]
    rec = read_record(f, channel="^acc$", angle_channel="angle_in", meta_regex=r"_(?P<load>\d+)Nm")
    assert got == json.loads(json.dumps(monitor_record(loaded, rec, base).to_dict()))
