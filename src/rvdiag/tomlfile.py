"""Reading a TOML file with errors a user can act on (shared by parameter sets and library configs)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from rvdiag.errors import ConfigError


def read_toml(path: str | Path, what: str) -> dict[str, Any]:
    """Parse the TOML file at ``path``; ``what`` names it in errors ("parameter file", "library config").

    Raises :class:`ConfigError` (one line naming the file) when it is missing, a directory, unreadable
    or not valid TOML.
    """
    path = Path(path)
    try:
        text = path.read_text("utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{what} not found: {path}") from None
    except IsADirectoryError:
        raise ConfigError(f"{what} {path} is a directory, expected a TOML file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML ({exc})") from None
