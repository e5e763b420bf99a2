"""A joint's records as CSV: the service record a plant keeps or sends on (``rvdiag fleet history JOINT --csv``,
``GET /api/joints/{joint}/history?format=csv``).

One row a record, in the order :meth:`rvdiag.fleet.Fleet.history` gives (time order), with the columns of
:data:`COLUMNS`; nested results are flattened: the operating point into ``output_speed_deg_s`` and ``load_Nm``,
what changed joined by ``"; "``, and, for a joint commissioned with a twin, the crack detector's ``crack_index``,
``crack_joint_p_value`` and ``crack_joint_alarm`` (empty otherwise, and ``crack_error`` when it could not judge).
Empty cells stand for none; booleans are ``true``/``false``; numbers are written in full (``repr``), so a value
read back is the value stored.
"""

from __future__ import annotations

import csv
import io

#: The CSV's columns, in order.
COLUMNS = ("time", "checksum", "filename", "epoch", "output_speed_deg_s", "load_Nm", "health_index", "p_value",
           "joint_p_value", "record_alarm", "monitor_alarm", "joint_state", "learning", "fault_state", "probability",
           "recognised", "reason", "changes", "rejected", "crack_index", "crack_joint_p_value", "crack_joint_alarm",
           "crack_error")


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def history_rows(history: list[dict]) -> list[dict]:
    """The records of :meth:`rvdiag.fleet.Fleet.history` flattened to :data:`COLUMNS` (values as stored)."""
    out = []
    for h in history:
        op = h.get("operating_point") or {}
        crack = h.get("crack") if isinstance(h.get("crack"), dict) else {}
        row = {c: h.get(c) for c in COLUMNS}
        row.update(output_speed_deg_s=op.get("output_speed_deg_s"), load_Nm=op.get("load_Nm"),
                   changes="; ".join(h.get("changes") or []) or None,
                   crack_index=crack.get("index"), crack_joint_p_value=crack.get("joint_p_value"),
                   crack_joint_alarm=crack.get("joint_alarm"), crack_error=crack.get("error"))
        out.append(row)
    return out


def history_csv(history: list[dict]) -> str:
    """The records of :meth:`rvdiag.fleet.Fleet.history` as CSV text (a header, then one row a record).

    >>> print(history_csv([{"time": "2026-01-01T06:00:00+00:00", "health_index": 0.25, "record_alarm": False,
    ...                     "changes": ["tooth pulse up 3 dB", "floor up 1 dB"]}]).splitlines()[1])
    2026-01-01T06:00:00+00:00,,,,,,0.25,,,false,,,,,,,,tooth pulse up 3 dB; floor up 1 dB,,,,,
    """
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in history_rows(history):
        w.writerow({c: _cell(v) for c, v in row.items()})
    return buf.getvalue()


__all__ = ["COLUMNS", "history_csv", "history_rows"]
