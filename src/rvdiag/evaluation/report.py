"""The evaluation report: ONE self-contained HTML file (figures embedded as base64 PNG, inline CSS,
no script, no external resource), readable from disk without a server.

Sections: summary metrics; per-class precision / recall / F1 and the confusion matrix; what the model cannot do
(:func:`limits_section`: its weak classes and confusions on its held-out test, the conditions it was not trained
on); a t-SNE map of
the model's learned features (CNN: last hidden layer; classical: the standardised features); the
training curve (CNN); one example waveform and spectrum per state with the characteristic frequencies
of ``rvdiag freqs`` marked; the gear condition indicators (sun shaft) per state, median and quartiles of at
most 50 samples of each (when the store gives a sampling rate and a speed column); caveats (a default used in place of unreadable store data, a formula used
outside its fitted range); the library config and the model card.
"""

from __future__ import annotations

import html
import json
import warnings
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from rvdiag import __version__
from rvdiag.atomic import atomic_write
from rvdiag.errors import FallbackWarning, RvdiagError
from rvdiag.evaluation import plots

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2em auto;max-width:1150px;
color:#222;line-height:1.4;padding:0 1em}
h1{font-size:1.6em;margin-bottom:.2em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .7em;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}
.big td{font-size:1.15em}.muted{color:#666;font-size:.9em}
pre{background:#f7f7f7;border:1px solid #e3e3e3;padding:.7em;overflow:auto;max-height:420px;font-size:.82em}
img{max-width:100%;height:auto;border:1px solid #eee}
.flex{display:flex;flex-wrap:wrap;gap:1.5em;align-items:flex-start}
.bad{background:#fde2e2}.ok{background:#e3f5e1}
"""


def _img(b64: str, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{b64}">'


def _pct(x: float) -> str:
    return f"{100.0 * x:.2f} %"


def store_reducer_params(store_attrs: Mapping[str, Any]):
    """The reducer parameters a store records, and the caveats of reading them.

    Returns ``(params, notes)``.  ``params`` is the store's :class:`~rvdiag.params.ReducerParams`, or None when
    the store records none (measured data) or its record cannot be read; the latter is never silent: it adds
    a note and issues a :class:`rvdiag.errors.FallbackWarning`.  The notes also hold the caveats of the
    sun-planet mesh stiffness of those parameters (:func:`rvdiag.gears.tvms.foundation_range_notes`).
    """
    from rvdiag.gears import GearPair
    from rvdiag.gears.tvms import foundation_range_notes
    from rvdiag.params import ReducerParams

    raw = store_attrs.get("params")
    if not raw:
        return None, []
    try:
        params = ReducerParams.from_dict(raw)
    except (RvdiagError, TypeError, ValueError, KeyError, AttributeError) as exc:
        msg = f"the store's reducer parameters cannot be read ({type(exc).__name__}: {exc})"
        warnings.warn(msg, FallbackWarning, stacklevel=2)
        return None, [msg]
    try:
        pair = GearPair.sun_planet(params)
    except RvdiagError as exc:  # parameters that load but give no valid gear pair: say so
        return params, [f"sun-planet mesh stiffness not checked: {exc}"]
    return params, [f"sun-planet mesh stiffness (TVMS): {note}" for note in foundation_range_notes(pair)]


_FROM_STORE = object()


def characteristic_frequencies_for(store_attrs: Mapping[str, Any], meta: Mapping[str, np.ndarray],
                                   index: np.ndarray | None = None, *, params: Any = _FROM_STORE,
                                   notes: list[str] | None = None) -> dict[str, float] | None:
    """Characteristic frequencies (Hz) of the store's reducer at the median speed of the given samples.

    Parameters
    ----------
    store_attrs, meta : the store's attributes and metadata columns (``input_speed_rpm`` or
        ``output_speed_deg_s`` give the speed)
    index : rows of ``meta`` to take the median speed over (default: all)
    params : ReducerParams or None
        Default: read from ``store_attrs`` with :func:`store_reducer_params` (its notes go to ``notes``).
        None, or parameters the store lacks or cannot give, means the default RV-20E, and ``notes`` says so.
    notes : list, appended to with the caveats

    Returns None when the store records no speed, or when the frequencies cannot be computed (the reason is
    appended to ``notes``).
    """
    from rvdiag.kinematics import characteristic_frequencies
    from rvdiag.params import ReducerParams

    notes = [] if notes is None else notes
    for key in ("input_speed_rpm", "output_speed_deg_s"):
        if key in meta:
            v = np.asarray(meta[key], dtype=float)
            if index is not None:
                v = v[index]
            v = v[np.isfinite(v)]
            if v.size:
                if params is _FROM_STORE:
                    params, param_notes = store_reducer_params(store_attrs)
                    notes.extend(param_notes)
                if params is None:
                    notes.append("characteristic frequencies: the store gives no reducer parameters, those of the "
                                 "default RV-20E are marked")
                    params = ReducerParams.default()
                try:
                    return characteristic_frequencies(params, **{key: float(np.median(v))}).as_dict()
                except RvdiagError as exc:
                    notes.append(f"characteristic frequencies not marked: {exc}")
                    return None
    return None


def sets_section(sets: Mapping[str, Any] | None, note: str | None) -> str:
    """The section "Prediction sets": per state, the stated coverage, the share of its samples whose set holds it
    and the mean set size (:mod:`rvdiag.models.conformal`); or why there are none."""
    head = "<h2>Prediction sets</h2>"
    if sets is None:
        return head + f"<p class='muted'>{html.escape(note or 'no prediction sets')}</p>"
    rows = "".join(
        f"<tr class='{'bad' if v['coverage'] < v['stated_coverage'] - 0.03 else ''}'><td>{html.escape(c)}</td>"
        f"<td>{_pct(v['stated_coverage'])}</td><td>{_pct(v['coverage'])}</td><td>{v['mean_size']:.2f}</td>"
        f"<td>{v['n']}</td></tr>" for c, v in sets["per_state"].items())
    return (head + "<table><tr><th>state</th><th>stated coverage</th><th>coverage</th><th>mean set size</th>"
            f"<th>samples</th></tr>{rows}<tr><td><b>all</b></td><td>{_pct(sets['stated_coverage'])}</td>"
            f"<td>{_pct(sets['coverage'])}</td><td>{sets['mean_size']:.2f}</td><td>{sets['n']}</td></tr></table>"
            "<p class='muted'>Each sample gets the set of states the model cannot rule out (class-conditional "
            "split-conformal, calibrated on training reducers held out of the fit). Coverage: the share of a "
            "state's samples whose set holds that state; red: more than 3 points below the stated coverage. "
            f"{_pct(sets['singletons'])} of the sets name one state.</p>")


def render_report(*, title: str, metrics: Mapping[str, Any], card: Mapping[str, Any],
                  store_info: Mapping[str, Any], examples: Mapping[str, np.ndarray] | None = None,
                  fs: float | None = None, frequencies: Mapping[str, float] | None = None,
                  embedding: np.ndarray | None = None, embedding_labels=None, notes: Sequence[str] = (),
                  indicators: Mapping[str, Any] | None = None, sets: Mapping[str, Any] | None = None,
                  sets_note: str | None = None) -> str:
    """The report as an HTML string.

    Parameters
    ----------
    title : str
    metrics : dict from :func:`rvdiag.evaluation.metrics.classification_metrics`
    card : the model card (:func:`rvdiag.models.persistence.read_card`)
    store_info : {"path", "split", "kind", "config", "config_hash", "n_samples"} of the evaluated store
    examples : {state: 1-D signal}, one example per state
    fs : sampling rate of the examples (Hz) or None
    frequencies : characteristic frequencies to mark (Hz)
    embedding : (n, 2) t-SNE coordinates, with ``embedding_labels`` (true classes)
    notes : caveats to show (a default used in place of unreadable data, a formula outside its fitted range),
        listed in the "Caveats" section before the library config and announced under the title
    indicators : the gear condition indicators per class, from
        :func:`rvdiag.evaluation.evaluate.indicators_by_class` (section "Gear condition indicators")
    sets, sets_note : the prediction sets' coverage and size (:func:`rvdiag.evaluation.evaluate.set_metrics_of`),
        or None and the reason there are none (section "Prediction sets")
    """
    labels = metrics["labels"]
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
             f"<style>{_CSS}</style></head><body>", f"<h1>{html.escape(title)}</h1>"]
    parts.append(
        f"<p class='muted'>model <b>{html.escape(str(card.get('model')))}</b> ({html.escape(str(card.get('kind')))}"
        f"{', features ' + html.escape(str(card['features'])) if card.get('features') else ''}), "
        f"evaluated on <b>{html.escape(str(store_info.get('path')))}</b>, split <b>{html.escape(str(store_info.get('split')))}</b> "
        f"({metrics['n_samples']} samples, store kind {html.escape(str(store_info.get('kind')))}); rvdiag {__version__}"
        + (f"; <b>{len(notes)} caveat(s)</b>, see Caveats" if notes else "") + "</p>")
    # summary
    h = metrics.get("healthy_class")
    h_recall, fa = metrics.get("healthy_recall"), metrics.get("false_alarm_rate")
    parts.append("<h2>Summary</h2><table class='big summary'><tr><th>accuracy</th>"
                 f"<th>healthy recall{' (' + html.escape(str(h)) + ')' if h else ''}</th>"
                 "<th>false-alarm rate</th><th>precision (macro)</th>"
                 "<th>recall (macro)</th><th>F1 (macro)</th><th>Cohen's kappa</th></tr><tr>"
                 f"<td>{_pct(metrics['accuracy'])}</td>"
                 f"<td>{'n/a' if h_recall is None else _pct(h_recall)}</td>"
                 f"<td>{'n/a' if fa is None else _pct(fa)}</td><td>{_pct(metrics['precision_macro'])}</td>"
                 f"<td>{_pct(metrics['recall_macro'])}</td><td>{_pct(metrics['f1_macro'])}</td>"
                 f"<td>{metrics['kappa']:.4f}</td></tr></table>"
                 "<p class='muted'>False-alarm rate: the share of the healthy samples diagnosed as a fault "
                 "(1 - healthy recall)" + ("" if h else "; n/a: the model has no healthy class") + ".</p>")
    # per class + confusion
    rows = "".join(
        f"<tr class='{'ok' if v['recall'] >= 0.99 else ('bad' if v['recall'] < 0.9 else '')}'>"
        f"<td>{html.escape(c)}</td><td>{_pct(v['precision'])}</td><td>{_pct(v['recall'])}</td>"
        f"<td>{_pct(v['f1'])}</td><td>{v['support']}</td></tr>"
        for c, v in metrics["per_class"].items())
    cm_png = plots.figure_to_base64(plots.plot_confusion(metrics["confusion"], labels))
    parts.append("<h2>Per class</h2><div class='flex'><div><table><tr><th>class</th><th>precision</th>"
                 f"<th>recall (class accuracy)</th><th>F1</th><th>support</th></tr>{rows}</table>"
                 "<p class='muted'>Recall of a class = share of its samples diagnosed correctly (the seed "
                 "papers' per-state accuracy). Rows: green &ge; 99 %, red &lt; 90 %.</p></div>"
                 f"<div>{_img(cm_png, 'confusion matrix')}<p class='muted'>Rows: true state; columns: "
                 "diagnosis; shading: share of the row.</p></div></div>")
    parts.append(sets_section(sets, sets_note))
    parts.append(limits_section(card, metrics, store_info))
    if embedding is not None and len(embedding):
        png = plots.figure_to_base64(plots.plot_tsne(embedding, embedding_labels))
        parts.append("<h2>t-SNE map of the learned features</h2><div class='flex'>"
                     f"<div>{_img(png, 't-SNE map')}</div><p class='muted' style='max-width:420px'>Each point is one "
                     "evaluated sample, placed by t-SNE (van der Maaten &amp; Hinton 2008) from the model's "
                     "internal features (CNN: last hidden layer; classical: standardised features), coloured by "
                     "its TRUE state. Well separated clusters mean the features distinguish the states; "
                     "points inside another colour's cluster are the confusions.</p></div>")
    if card.get("history"):
        png = plots.figure_to_base64(plots.plot_history(card["history"]))
        parts.append(f"<h2>Training</h2>{_img(png, 'training curve')}<p class='muted'>"
                     f"{card.get('n_epochs')} epochs, weights of epoch {card.get('best_epoch')} kept "
                     "(lowest validation loss).</p>")
    if examples:
        png = plots.figure_to_base64(plots.plot_examples(examples, fs, frequencies))
        if frequencies:
            ftab = "".join(f"<tr><td>{html.escape(k)}</td><td>{v:.3f}</td></tr>" for k, v in frequencies.items())
            ftab = ("<table><tr><th>characteristic frequency</th><th>Hz</th></tr>" + ftab + "</table>")
        else:
            ftab = "<p class='muted'>No speed recorded in the store: frequencies not marked.</p>"
        parts.append("<h2>Example signals per state</h2>" + _img(png, "waveforms and spectra") +
                     "<p class='muted'>One sample per state from the evaluated split. Dashed lines: "
                     "characteristic frequencies (as <code>rvdiag freqs</code>) at the samples' speed.</p>" + ftab)
    if indicators:
        parts.append(_indicator_section(indicators))
    if notes:
        items = "".join(f"<li>{html.escape(str(n))}</li>" for n in notes)
        parts.append(f"<h2>Caveats</h2><ul class='caveats'>{items}</ul>")
    cfg = store_info.get("config")
    parts.append("<h2>Library config</h2><p class='muted'>config hash "
                 f"{html.escape(str(store_info.get('config_hash')))}</p>"
                 f"<pre>{html.escape(json.dumps(cfg, indent=2, default=str))}</pre>")
    card_view = {k: v for k, v in card.items() if k != "history"}
    parts.append(f"<h2>Model card</h2><pre>{html.escape(json.dumps(card_view, indent=2, default=str))}</pre>")
    parts.append("</body></html>")
    return "\n".join(parts)


def limits_section(card: Mapping[str, Any], metrics: Mapping[str, Any], store_info: Mapping[str, Any]) -> str:
    """The "What this model cannot do" section: the model's recall of each class on its held-out test (the card's
    ``metrics``; the evaluated split's when the card has none), its weak classes and confusions by the rule that
    ``rvdiag diagnose`` warns with (:func:`rvdiag.models.conditions.class_limits`), and the conditions it was not
    trained on (:func:`rvdiag.models.conditions.untrained_conditions`: the card's ``operating_range``, and what
    the training library held fixed when the evaluated store is that library)."""
    from rvdiag.models.conditions import class_limits, untrained_conditions

    held_out = card.get("metrics") or {}
    source = "its held-out test split (the model card)"
    if "per_class" not in held_out:
        held_out, source = metrics, "the evaluated split (the card holds no held-out test)"
    lim = class_limits(held_out)
    esc = html.escape
    if lim:
        confused = {}
        for c in lim["confused"]:
            confused.setdefault(c["true"], []).append(f"{esc(c['predicted'])} ({100 * c['share']:.0f} %)")
        rows = "".join(
            f"<tr class='{'bad' if c in lim['weak'] else ''}'><td>{esc(c)}</td><td>{_pct(r)}</td>"
            f"<td>{'weak' if c in lim['weak'] else ''}</td><td>{', '.join(confused.get(c, [])) or '-'}</td></tr>"
            for c, r in lim["recall"].items())
        items = [f"<li>weak: <b>{esc(c)}</b>, recall {_pct(lim['recall'][c])}</li>" for c in lim["weak"]]
        items += [f"<li>confused: {100 * c['share']:.0f} % of the <b>{esc(c['true'])}</b> samples diagnosed as "
                  f"<b>{esc(c['predicted'])}</b>: an answer {esc(c['predicted'])} may be {esc(c['true'])}</li>"
                  for c in lim["confused"]]
        found = (f"<ul class='weak'>{''.join(items)}</ul>" if items else
                 "<p class='none-weak'>None: every class is recognised in at least 90 % of its held-out samples "
                 "and no class is diagnosed as another in 10 % or more of them.</p>")
        classes = (f"<p>Per-class recall on {esc(source)}; rule: {esc(lim['rule'])}.</p>{found}"
                   "<table class='limits'><tr><th>class</th><th>recall</th><th></th><th>diagnosed as (share of the "
                   f"class)</th></tr>{rows}</table>")
    else:
        classes = "<p>The model card holds no held-out test: its weak classes are not known.</p>"
    trained = card.get("training_store") or {}
    same = trained.get("config_hash") and trained.get("config_hash") == store_info.get("config_hash")
    config = store_info.get("config") if same else None
    untrained = untrained_conditions(card.get("operating_range"), config)
    cond = "" if card.get("operating_range") else ("<p>The model card states no operating range (a model "
                                                  "trained before rvdiag recorded one).</p>")
    if untrained:
        cond += "<ul class='untrained'>" + "".join(f"<li>{esc(u)}</li>" for u in untrained) + "</ul>"
    if not same:
        cond += ("<p class='muted'>The evaluated store is not the training library: what that library held fixed "
                 "is not listed.</p>")
    return ("<h2 id='limits'>What this model cannot do</h2>" + classes +
            "<h3>Conditions it was not trained on</h3>" + cond +
            "<p class='muted'><code>rvdiag diagnose</code> warns when an answer is a weak or confused class, and "
            "when a record lies outside the training range.</p>")


def _indicator_section(ind: Mapping[str, Any]) -> str:
    """The "Gear condition indicators" section: per state, the median [quartiles] of each indicator."""
    pc = ind["per_class"]
    head = "".join(f"<th>{html.escape(c)} (n={v['n']})</th>" for c, v in pc.items())
    rows = "".join(
        f"<tr><td>{html.escape(k)}</td>" + "".join(
            f"<td>{v['median'][k]:.4g} <span class='muted'>[{v['q25'][k]:.3g}, {v['q75'][k]:.3g}]</span></td>"
            for v in pc.values()) + "</tr>" for k in ind["names"])
    return ("<h2 id='indicators'>Gear condition indicators</h2>"
            f"<table class='indicators'><tr><th>indicator</th>{head}</tr>{rows}</table>"
            "<p class='muted'>Median [first, third quartile] per true state of the indicators of each sample's TSA "
            "on the sun shaft (relative to the carrier), at the speed of the store's column "
            f"<code>{html.escape(str(ind['speed_column']))}</code>; at most 50 samples per state. FM4 = 3, "
            "M6A = 15, M8A = 105 for a Gaussian difference signal; formulas and sources in docs/orders.md.</p>")


def write_report(path: str | Path, html_text: str) -> Path:
    """Write the report atomically (:func:`rvdiag.atomic.atomic_write`: temporary file + rename)."""
    return atomic_write(path, html_text)
