"""The Markdown of ``mcsa.md``: one table speed x feature set per protocol, and the held-out store's figures."""

from __future__ import annotations

from rvdiag.evaluation.motor_current_study.protocol import protocols_run
from rvdiag.evaluation.motor_current_study.settings import FEATURE_SETS, PROTOCOL_KEYS


def _recall_text(recalls: dict) -> str:
    return " / ".join(f"{c} {'-' if r is None else f'{100 * r:.0f}'}" for c, r in recalls.items())


def _pct(v: float) -> str:
    return f"{100 * v:.2f}"


def markdown(report_: dict) -> str:
    """The Markdown of ``mcsa.md``: one table speed x feature set (split protocol), and one of the held-out
    figures when the run had a test store."""
    unit = report_["speed_unit"]
    st = report_["settings"]
    protocol = st.get("protocol", "windows")
    if protocol != "windows":
        lines = ["# Motor-current study protocol (rvdiag mcsa)", ""] + protocol_markdown(report_)
        return _markdown_tail(report_, lines + _test_store_lines(report_))
    lines = [
        "# Motor-current study protocol (rvdiag mcsa)",
        "",
        f"Store `{report_['store']['path']}`, channel `{report_['store']['channel']}`, "
        f"speeds from `{report_['speed_column']}`.  {st['repeats']} stratified "
        f"{round(100 * (1 - st['test_size']))}/{round(100 * st['test_size'])} splits per speed and feature set, "
        f"seed {st['seed']}; StandardScaler + RBF SVC (C = {st['svm_c']:g}, gamma = {st['svm_gamma']}) for every "
        "feature set.  Accuracy as mean ± std over the splits (%); precision, recall and F1 are macro averages "
        "(%), kappa is Cohen's; all means over the splits.",
        "",
        f"| speed ({unit or report_['speed_column']}) | features | accuracy | precision | recall | F1 | kappa | "
        "recall per class (all splits) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for speed, sets in report_["results"].items():
        for name, e in sets.items():
            s = e["split"]
            lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(s['accuracy']['mean'])} ± "
                         f"{_pct(s['accuracy']['std'])} | {_pct(s['precision_macro']['mean'])} | "
                         f"{_pct(s['recall_macro']['mean'])} | {_pct(s['f1_macro']['mean'])} | "
                         f"{s['kappa']['mean']:.3f} | {_recall_text(s['recall_per_class'])} |")
    return _markdown_tail(report_, lines + _test_store_lines(report_))


def _test_store_lines(report_: dict) -> list[str]:
    """The table of the figures on a held-out store (``--test``), or nothing without one."""
    unit = report_["speed_unit"]
    lines: list[str] = []
    if report_.get("test_store"):
        lines += ["", f"Held out: fitted on every sample of the store at each speed, scored on "
                      f"`{report_['test_store']['path']}` (channel `{report_['test_store']['channel']}`).", "",
                  f"| speed ({unit or report_['speed_column']}) | features | accuracy | precision | recall | F1 | "
                  "kappa | test samples | recall per class |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                h = e["held_out"]
                if h is None:
                    continue
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(h['accuracy'])} | "
                             f"{_pct(h['precision_macro'])} | {_pct(h['recall_macro'])} | {_pct(h['f1_macro'])} | "
                             f"{h['kappa']:.3f} | {h['n_test']} | {_recall_text(h['recall_per_class'])} |")
    return lines


def _markdown_tail(report_: dict, lines: list[str]) -> str:
    st = report_["settings"]
    if "cnn" in report_["feature_sets"]:
        lines += ["", f"The CNN sees each window as `{st.get('cnn_representation', 'waveform')}` "
                      "(waveform: the z-scored window, the study's input; logspec: its log spectrum; residual: the "
                      "window minus its fitted supply line)."]
    study = "; ".join(f"{FEATURE_SETS[k]} {v}" for k, v in report_["study"].items())
    lines += ["", f"The study (Li, Zhao et al. 2024, measured motor current, 4 states) reports: {study}."]
    if report_["notes"]:
        lines += [""] + [f"Note: {n}." for n in report_["notes"]]
    return "\n".join(lines) + "\n"


def _recalls(e: dict) -> str:
    return " / ".join("-" if v is None else f"{100 * v:.0f}" for v in e["recall_per_class"].values())


def _fa(e: dict) -> str:
    return "-" if e["false_alarm_rate"] is None else f"{100 * e['false_alarm_rate']:.1f}"


def protocol_markdown(report_: dict) -> list[str]:
    """The lines of the study / held-out tables (``--protocol study|held-out|both``): per speed and feature set
    the accuracy (mean ± std over the splits), the per-class recall and the false-alarm rate (of the summed
    confusion), and with ``both`` the two protocols side by side and their gap (the protocol's leak)."""
    unit = report_["speed_unit"] or report_["speed_column"]
    st = report_["settings"]
    runs = protocols_run(st["protocol"])
    split = f"{round(100 * (1 - st['test_size']))}/{round(100 * st['test_size'])}"
    first = next(iter(next(iter(report_["results"].values())).values()))
    labels = first[PROTOCOL_KEYS[runs[0]]]["labels"]
    lines = [f"Store `{report_['store']['path']}`, channel `{report_['store']['channel']}`, speeds from "
             f"`{report_['speed_column']}`; {st['repeats']} splits per speed, feature set and protocol, seed "
             f"{st['seed']}; StandardScaler + RBF SVC (C = {st['svm_c']:g}, gamma = {st['svm_gamma']}).", ""]
    if "study" in runs:
        lines.append(f"- study: per state one simulated reducer (drawn per split), its windows split {split} at "
                     "random (the study's protocol: each state a different physical gear);")
    if "held-out" in runs:
        lines.append(f"- held-out: per state about {round(100 * st['test_size'])} % of the simulated reducers, "
                     "with all their windows, on the test side: every test reducer is unseen by the fit;")
    lines += ["- accuracy: mean ± std over the splits (%); recall per class "
              f"({' / '.join(labels)}) and false alarms (healthy windows called faulty) from the confusion summed "
              "over the splits (%).", ""]
    if len(runs) == 2:
        lines += [f"| speed ({unit}) | features | study accuracy | held-out accuracy | leak (points) | "
                  "study recall | held-out recall | study false alarms | held-out false alarms |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                a, b = e[PROTOCOL_KEYS["study"]], e[PROTOCOL_KEYS["held-out"]]
                gap = 100 * (a["accuracy"]["mean"] - b["accuracy"]["mean"])
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(a['accuracy']['mean'])} ± "
                             f"{_pct(a['accuracy']['std'])} | {_pct(b['accuracy']['mean'])} ± "
                             f"{_pct(b['accuracy']['std'])} | {gap:+.1f} | {_recalls(a)} | {_recalls(b)} | "
                             f"{_fa(a)} | {_fa(b)} |")
    else:
        key = PROTOCOL_KEYS[runs[0]]
        lines += [f"| speed ({unit}) | features | {runs[0]} accuracy | kappa | recall | false alarms |",
                  "|---|---|---|---|---|---|"]
        for speed, sets in report_["results"].items():
            for name, e in sets.items():
                a = e[key]
                lines.append(f"| {speed} | {FEATURE_SETS[name]} | {_pct(a['accuracy']['mean'])} ± "
                             f"{_pct(a['accuracy']['std'])} | {a['kappa']['mean']:.3f} | {_recalls(a)} | {_fa(a)} |")
    return lines
