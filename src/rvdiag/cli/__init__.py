"""The ``rvdiag`` command.

Every module in this package other than ``__init__`` and names starting with ``_`` defines
``register(app: typer.Typer) -> None`` that adds its command(s) to the main app.  Modules are found
by :func:`pkgutil.iter_modules`, so adding a command never means editing this file.

Errors: an :class:`rvdiag.errors.RvdiagError` (and a missing or unreadable file) becomes one line
``error: <message>`` on stderr and exit code 2, never a traceback.  Warnings (:mod:`warnings`) become one line
``warning: <message>`` on stderr, each distinct message once per command (:func:`_show_warning`).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
import warnings

import typer

try:  # typer >= 0.20 vendors click as typer._click
    from typer._click import exceptions as _click_exc
except ImportError:  # pragma: no cover - older typer on plain click
    from click import exceptions as _click_exc

from rvdiag import __version__
from rvdiag.errors import RvdiagError


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"rvdiag {__version__}")
        raise typer.Exit()


def build_app() -> typer.Typer:
    """Create the Typer app with every command module of :mod:`rvdiag.cli` registered."""
    app = typer.Typer(
        name="rvdiag",
        help="Physics-based fault diagnosis of RV reducers: mesh stiffness, dynamics, "
        "simulated fault libraries, classifiers and diagnosis of measured signals.",
        no_args_is_help=True,
        pretty_exceptions_enable=False,
        add_completion=False,
    )

    @app.callback()
    def _root(
        version: bool = typer.Option(
            False, "--version", callback=_version_callback, is_eager=True, help="Print the version."
        ),
    ) -> None:
        """rvdiag: diagnose RV-reducer gear faults by physics."""

    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(app)
    return app


#: the warning lines already printed by this command (each distinct message once per command)
_shown: set[str] = set()


def _show_warning(message, category, filename, lineno, file=None, line=None):  # noqa: ANN001
    """Every warning as one line ``warning: ...`` on stderr, each distinct one once per command, without the
    source path and line Python prints (those say where rvdiag noticed, not what the user can do).  rvdiag's own
    warnings (:class:`rvdiag.errors.RvdiagWarning`) are their message; others (numpy, a library) keep their
    category's name in front.  Warnings raised in Dask worker processes come back here through
    :mod:`rvdiag.library.worker_warnings`."""
    from rvdiag.errors import RvdiagWarning

    text = " ".join(str(message).split())
    if not issubclass(category, RvdiagWarning):
        text = f"{category.__name__}: {text}"
    if text in _shown:
        return
    _shown.add(text)
    typer.echo(f"warning: {text}", err=True)


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``rvdiag`` console script."""
    warnings.showwarning = _show_warning
    _shown.clear()
    app = build_app()
    try:
        code = app(args=argv, prog_name="rvdiag", standalone_mode=False)
    except RvdiagError as exc:
        _fail(str(exc), exc.exit_code)
    except (FileNotFoundError, PermissionError, IsADirectoryError, NotADirectoryError) as exc:
        _fail(f"{exc.strerror or exc}: {exc.filename}" if getattr(exc, "filename", None) else str(exc))
    except _click_exc.ClickException as exc:  # usage errors, bad parameters, unreadable --option files
        _fail(exc.format_message())
    except typer.Abort:
        typer.echo("aborted", err=True)
        sys.exit(130)
    except typer.Exit as exc:
        sys.exit(exc.exit_code)
    except BrokenPipeError:  # `rvdiag ... | head`: the reader went away; not an error of ours
        sys.stderr.close()
        sys.exit(0)
    # with standalone_mode=False, typer.Exit(n) and Ctrl-C come back as a return value
    if isinstance(code, int) and not isinstance(code, bool) and code != 0:
        sys.exit(code)


def _fail(message: str, code: int = 2) -> None:
    """Print one line ``error: message`` on stderr and exit with ``code`` (2, or the error's ``exit_code``)."""
    first_line = " ".join(str(message).split())
    typer.echo(f"error: {first_line}", err=True)
    sys.exit(code)
