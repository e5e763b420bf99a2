"""How the command line prints a monitor's results (:mod:`rvdiag.monitoring`): ``rvdiag evaluate`` of a monitor
(:func:`print_evaluation`) and ``rvdiag diagnose --baseline`` (:func:`print_diagnosis`), and the "not recognised"
line that ``diagnose`` prints for both kinds of model (:func:`not_recognised_line`)."""

from __future__ import annotations


def not_recognised_line(res: dict) -> str | None:
    """The line that says a record is not recognised, with its reason (rich markup), or None when it is: one
    wording for ``diagnose`` and its baseline flow."""
    if res["recognised"]:
        return None
    return (f"{res['file']} [{res['channel']}]: [bold]not recognised[/bold]: this record does not look like the "
            f"reducer the model knows: {res['reason']}")


def print_evaluation(res: dict, loaded, data) -> None:
    from rich.console import Console
    from rich.table import Table

    from rvdiag.monitoring.training import headline

    con = Console()
    reds = "" if res.get("n_reducers") is None else f" of {res['n_reducers']} reducers"
    lo, hi = res["windows_per_record"]
    con.print(f"{loaded.card.get('model')} on {data} [{res['split']}], {res['n_records']} monitored records"
              f"{reds} ({lo if lo == hi else f'{lo}-{hi}'} window(s) each, decided on their mean change): "
              + headline(res), soft_wrap=True)
    t = Table()
    for col in ("state", "recall", "alarm raised", "support"):
        t.add_column(col, justify="left" if col == "state" else "right")
    for c, v in res["per_class"].items():
        det = res["detection_rate_per_state"].get(c)
        if det is None and c == res.get("healthy_class"):
            det = res["false_alarm_rate"]
        t.add_row(c, f"{100 * v['recall']:.1f} %", "-" if det is None else f"{100 * det:.1f} %", str(v["support"]))
    con.print(t)
    if "merged" in res:
        mg = res["merged"]
        con.print(f"merged {','.join(f'{a}={b}' for a, b in mg['merge'].items())}: accuracy "
                  f"{100 * mg['accuracy']:.2f} %; " + ", ".join(f"{c} recall {100 * v['recall']:.1f} %"
                                                              for c, v in mg["per_class"].items()), soft_wrap=True)


def print_diagnosis(res: dict) -> None:
    from rich.console import Console

    con = Console()
    if not res["recognised"]:
        con.print(not_recognised_line(res), soft_wrap=True)
        return
    b = res["baseline"]
    op = res["operating_point"]
    con.print(f"{res['file']} [{res['channel']}]: {res['n_windows']} window(s) of {res['window_length']} points at "
              f"{op['output_speed_deg_s']:.4g} deg/s, {op['load_Nm']:.4g} N m, against {b['n_records']} baseline "
              f"records at {b['output_speed_deg_s']:.4g} deg/s, {b['load_Nm']:.4g} N m", soft_wrap=True)
    con.print(f"health index {res['health_index']:.3g}: "
              + ("[bold]ALARM[/bold]" if res["alarm"] else "no alarm")
              + f" (the alarm's false-alarm rate is {100 * res['false_alarm_rate']:g} % of healthy records; p-value "
                f"{res['p_value']:.3g})", soft_wrap=True)
    con.print(f"most probable state: [bold]{res['state_name']}[/bold] (probability {res['probability']:.3f})",
              soft_wrap=True)
    if res["changes"]:
        con.print("what changed since the baseline: " + "; ".join(res["changes"]), soft_wrap=True)
