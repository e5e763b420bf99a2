"""Write an updated parameter set as TOML with every changed value commented (tomli_w writes no comments).

The text of the base file is kept (its comments carry the sources of the values) and only the changed lines are
rewritten; a key or section the base file lacks (an optional section such as ``[mounting]``) is added.  The result
is parsed again and compared with the updated set; should the line edit not reproduce it (an unusual layout of the
base file: inline tables, dotted keys), the plain ``tomli_w`` text of the updated set is annotated instead.
"""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path

import tomli_w

from rvdiag.params import ReducerParams
from rvdiag.params.schema import DEFAULT_PARAMS_NAME

_SECTION = re.compile(r"^\s*\[\s*([A-Za-z0-9_]+)\s*\]\s*(#.*)?$")


def _value_text(value) -> str:
    """TOML text of one value, a list of scalars on one line."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value_text(v) for v in value) + "]"
    return tomli_w.dumps({"v": value}).split("=", 1)[1].strip()


def changed_values(before: ReducerParams, after: ReducerParams) -> list[tuple[str, str, object, object]]:
    """(section, key, old, new) of every value that differs between two parameter sets, in file order."""
    a, b = before.to_dict(), after.to_dict()
    out = []
    for section, values in b.items():
        if not isinstance(values, dict):
            continue
        for key, new in values.items():
            old = a.get(section, {}).get(key)
            if old != new:
                out.append((section, key, old, new))
    return out


def base_text(params: ReducerParams, path: str | Path | None) -> str:
    """TOML text the base set was read from: the file, or the built-in set's resource."""
    if path is not None:
        return Path(path).read_text("utf-8")
    return resources.files("rvdiag.params").joinpath(DEFAULT_PARAMS_NAME).read_text("utf-8")


def annotated_toml(before: ReducerParams, after: ReducerParams, base: str, comment: str) -> str:
    """TOML text of ``after``, edited from the base text ``base``, with ``# comment (was X)`` on changed lines.

    ``comment`` may hold ``{was}``, replaced by the old value of each line.
    """
    changes = changed_values(before, after)
    text = _edit_lines(base, changes, comment)
    if _parses_to(text, after):
        return text
    text = _edit_lines(after.to_toml(), changes, comment)
    if not _parses_to(text, after):  # pragma: no cover - the plain text always parses back
        raise RuntimeError("the annotated parameter file does not round-trip")
    return text


def _parses_to(text: str, params: ReducerParams) -> bool:
    try:
        return ReducerParams.from_dict(tomllib.loads(text)) == params
    except Exception:  # noqa: BLE001 - any failure means "use the fallback"
        return False


def _edit_lines(text: str, changes, comment: str) -> str:
    lines = text.splitlines()
    for section, key, old, new in changes:
        note = comment.format(was=_value_text(old) if old is not None else "unset")
        line = f"{key} = {_value_text(new)}"
        start, end = _section_span(lines, section)
        if start is None:
            if lines and lines[-1].strip():
                lines.append("")
            lines.append(f"[{section}]")
            lines.append(f"{line}  # {note}")
            continue
        pat = re.compile(rf"^\s*{re.escape(key)}\s*=")
        hit = next((i for i in range(start + 1, end) if pat.match(lines[i])), None)
        if hit is None:
            last = max((i for i in range(start + 1, end) if lines[i].strip() and not lines[i].lstrip().startswith("#")),
                       default=start)
            lines.insert(last + 1, f"{line}  # {note}")
        else:
            lines[hit] = f"{line}  # {note}"
    return "\n".join(lines) + "\n"


def _section_span(lines: list[str], section: str) -> tuple[int | None, int]:
    """Index of ``[section]``'s header line and of the next header (or the end)."""
    start = None
    for i, ln in enumerate(lines):
        m = _SECTION.match(ln)
        if m and start is not None:
            return start, i
        if m and m.group(1) == section:
            start = i
    return start, len(lines)
