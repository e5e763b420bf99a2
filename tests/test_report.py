"""The HTML report is one self-contained file; figures render; frequencies come from the store."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

from rvdiag.evaluation import plots
from rvdiag.evaluation.metrics import classification_metrics
from rvdiag.evaluation.report import characteristic_frequencies_for, render_report, write_report


@pytest.fixture(scope="module")
def html_text():
    rng = np.random.default_rng(0)
    y = np.array(["T1", "T2", "T3"] * 10)
    p = y.copy()
    p[:2] = "T3"
    m = classification_metrics(y, p, labels=["T1", "T2", "T3"])
    emb = rng.standard_normal((30, 2))
    ex = {c: rng.standard_normal(1024) for c in ("T1", "T2", "T3")}
    freqs = characteristic_frequencies_for({}, {"output_speed_deg_s": np.full(30, 45.0)})
    card = {"model": "cnn1d-lean", "kind": "cnn", "classes": ["T1", "T2", "T3"], "input_length": 1024,
            "history": [{"epoch": 1, "loss": 1.0, "val_loss": 1.1, "val_accuracy": 0.5},
                        {"epoch": 2, "loss": 0.5, "val_loss": 0.6, "val_accuracy": 0.9}],
            "n_epochs": 2, "best_epoch": 2}
    store = {"path": "lib.zarr", "split": "test", "kind": "simulated",
             "config": {"name": "<script>alert(1)</script>"}, "config_hash": "deadbeef"}
    return render_report(title="t", metrics=m, card=card, store_info=store, examples=ex, fs=48000.0,
                         frequencies=freqs, embedding=emb, embedding_labels=y)


def test_report_is_self_contained(html_text):
    assert html_text.startswith("<!DOCTYPE html>")
    # no external resource of any kind: every src is an embedded data URI, no script, no link
    srcs = re.findall(r'src="([^"]+)"', html_text)
    assert len(srcs) == 4  # confusion, t-SNE, training curve, examples; nothing else
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert "<script" not in html_text and "<link" not in html_text and "http://" not in html_text
    for s in srcs:
        assert base64.b64decode(s.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"


def test_report_sections_and_escaping(html_text):
    for section in ("Summary", "Per class", "t-SNE", "Training", "Example signals per state",
                    "Library config", "Model card"):
        assert f">{section}" in html_text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in html_text  # config is escaped
    assert "93.33 %" in html_text  # accuracy 28/30


def test_write_report_atomic(tmp_path, html_text):
    p = write_report(tmp_path / "sub" / "r.html", html_text)
    assert p.read_text(encoding="utf-8") == html_text
    assert [q.name for q in p.parent.iterdir()] == ["r.html"]
    assert p.stat().st_mode & 0o044  # readable by others (a browser run as another user)


def test_characteristic_frequencies_from_store_speed():
    f = characteristic_frequencies_for({}, {"output_speed_deg_s": np.array([45.0, 45.0])})
    assert f["fsp"] == pytest.approx(165.0, rel=1e-3)  # Li, Zhao et al. 2024, Table 3 at 45 deg/s
    assert f["fcs"] == pytest.approx(195.0, rel=1e-3)
    assert characteristic_frequencies_for({}, {"load_Nm": np.ones(2)}) is None


def test_amplitude_spectrum_finds_a_tone():
    fs = 1000.0
    x = 2.0 * np.sin(2 * np.pi * 125.0 * np.arange(1000) / fs)
    f, a = plots.amplitude_spectrum(x, fs)
    assert f[np.argmax(a)] == pytest.approx(125.0)
    assert a.max() == pytest.approx(2.0, rel=0.02)
    f2, _ = plots.amplitude_spectrum(x)
    assert f2[-1] == pytest.approx(0.5)  # cycles per sample without fs


def test_example_plot_marks_frequencies():
    fig = plots.plot_examples({"T1": np.random.default_rng(1).standard_normal(2048)}, 48000.0,
                              {"fsp": 165.0, "fcs": 195.0, "f1": 15.1})
    spec_ax = fig.axes[1]
    xs = sorted(round(float(line.get_xdata()[0]), 1) for line in spec_ax.get_lines()[1:])
    assert xs == [15.1, 165.0, 195.0]
    plots.figure_to_base64(fig)


def _limits_report(y_pred, **card_extra):
    """A report whose model card's held-out test gave ``y_pred`` for ten samples of each of T1, T2, T3."""
    y = np.repeat(["T1", "T2", "T3"], 10)
    m = classification_metrics(y, np.asarray(y_pred), labels=["T1", "T2", "T3"])
    card = {"model": "cnn1d-lean", "kind": "cnn", "classes": ["T1", "T2", "T3"], "metrics": m,
            "training_store": {"config_hash": "abc"}, **card_extra}
    store = {"path": "lib.zarr", "split": "test", "kind": "simulated", "config_hash": "abc",
             "config": {"operation": {"output_speed_deg_s": 45.0, "load_Nm": 75.0, "noise_snr_db": 40.0},
                        "randomise": {"stiffness_pct": 0.0, "damping_pct": 0.0}, "params": "",
                        "states": {"T1": {}, "T2": {"broken_fraction": 1.0},
                                   "T3": {"wear_depth": {"min": 5e-6, "max": 1.5e-5}}}}}
    full = render_report(title="t", metrics=m, card=card, store_info=store)
    return full[full.index("What this model cannot do"):full.index("Library config")]


def test_the_limits_section_names_a_weak_class_and_its_confusion():
    """4 of the 10 held-out T3 samples called T1: T3 is weak (60 %) and confused with T1, by the
    rule diagnose warns with; the card's operating range and the library's fixed conditions are listed."""
    pred = ["T1"] * 10 + ["T2"] * 10 + ["T1"] * 4 + ["T3"] * 6
    rng = {"output_speed_deg_s": {"min": 45.0, "max": 45.0, "unit": "deg/s"},
           "load_Nm": {"min": 75.0, "max": 75.0, "unit": "N m"}, "fs": 48000.0,
           "level": {"rms_p01": 0.5, "rms_median": 1.0, "rms_p99": 2.0, "unit": "m/s^2", "note": "z-scored"}}
    text = _limits_report(pred, operating_range=rng)
    assert "weak: <b>T3</b>, recall 60.00 %" in text
    assert "40 % of the <b>T3</b> samples diagnosed as <b>T1</b>" in text
    assert "weak: held-out recall &lt; 0.9" in text and "None: every class" not in text
    assert "<td>T1</td><td>100.00 %</td>" in text  # every class's recall
    for condition in ("output_speed_deg_s: trained on 45 deg/s only", "load_Nm: trained on 75 N m only",
                      "trained at 48000 Hz only", "RMS 0.5-2 m/s^2", "held load_Nm fixed at 75 N m",
                      "added white noise fixed at 40 dB SNR", "did not vary the damping", "one specimen",
                      "only the states T1, T2, T3", "T3 wear_depth 5e-06-1.5e-05 m"):
        assert condition in text, condition


def test_the_limits_section_of_a_model_without_weak_classes_says_so():
    text = _limits_report(["T1"] * 10 + ["T2"] * 10 + ["T3"] * 10)
    assert "None: every class is recognised in at least 90 %" in text and "weak: <b>" not in text
    assert "no operating range" in text  # a card from before rvdiag recorded one
