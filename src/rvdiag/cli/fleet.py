"""``rvdiag fleet ...``: watch a fleet of robot joints over their life (docs/fleet.md).

Every command parses its options, calls :class:`rvdiag.fleet.Fleet` and prints; the store is ``--db URL``, else
``$RVDIAG_FLEET_DB``, else ``sqlite:///fleet.db``.  Bad input (an unknown joint, a joint without a baseline, a file
that cannot be read, a database of a newer schema, a bad time) is one ``error:`` line and exit code 2.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import List, Optional

import typer

from rvdiag.cli import _options as opt
from rvdiag.errors import FleetError


def _db() -> Optional[str]:
    return typer.Option(None, "--db", metavar="URL",
                        help="The fleet database: a SQLAlchemy URL (sqlite:///fleet.db, postgresql+psycopg://...) or "
                             "a SQLite file (default: $RVDIAG_FLEET_DB, else fleet.db).")


def _reading(channel, fs, angle_channel, output_speed, load, meta_regex, time_regex=None):
    from rvdiag.fleet import Reading

    if output_speed is not None and meta_regex is not None and load is not None:
        raise FleetError("give the operating point by --output-speed/--load or by --meta-regex, not both")
    return Reading(channel=channel, fs=fs, angle_channel=angle_channel, output_speed=output_speed, load=load,
                   meta_regex=meta_regex, time_regex=time_regex)


def _meta_regex():
    return typer.Option(None, "--meta-regex", metavar="RE",
                        help="Regular expression on the file name with groups output_speed_deg_s (or speed_dps) and "
                             "load_Nm, e.g. '_(?P<load_Nm>[\\d.]+)Nm'.")


def _angle_channel():
    return typer.Option(None, "--angle-channel", metavar="RE", help="The input shaft's encoder angle channel (rad).")


def _fs():
    return opt.fs("Sampling rate in Hz (overrides the file's).")


def _failure_index():
    return typer.Option(None, "--failure-index", metavar="INDEX",
                        help="The health index at which the joint counts as failed: its remaining life is counted to "
                             "it (default: none, the remaining life is not estimated).")


def _print_json(obj) -> None:
    typer.echo(json.dumps(obj, indent=2, default=str))


def _fmt(v, spec=".3g") -> str:
    return "-" if v is None else format(v, spec) if isinstance(v, float) else str(v)


def register(app: typer.Typer) -> None:
    fleet_app = typer.Typer(help="Watch a fleet of robot joints over their life: a history store, joint states with "
                                 "a stated false-alarm rate, ingest by CLI, folder watcher and HTTP (docs/fleet.md).",
                            no_args_is_help=True)
    app.add_typer(fleet_app, name="fleet")
    token_app = typer.Typer(help="API tokens (stored hashed).", no_args_is_help=True)
    fleet_app.add_typer(token_app, name="token")

    @fleet_app.command("init")
    def init(db: str = _db()) -> None:
        """Create the fleet store (or migrate it to this rvdiag's schema)."""
        from rvdiag.fleet import Fleet

        f = Fleet.init(db)
        typer.echo(f"fleet store ready at {f.url} (raw records in {f.blobs.root})")

    @fleet_app.command("add")
    def add(joint: str = typer.Argument(..., help="site/robot/joint, e.g. plant/r1/j3."),
            monitor: Path = typer.Option(..., "--monitor", metavar="MODEL_DIR",
                                         help="The baseline monitor that judges the joint's records."),
            params: Path = opt.params("The reducer's parameter TOML (default: built-in RV-20E)."),
            persistence: str = typer.Option("3/3", "--persistence", metavar="K/N",
                                            help="Alarm when K of the last N records alarm."),
            clear_after: int = typer.Option(3, "--clear-after", metavar="M",
                                            help="An alert, or an acknowledged alarm, clears after M normal records."),
            learning: Optional[int] = typer.Option(None, "--learning", metavar="RECORDS",
                                                   help="The learning period in records (default: 1/alpha - 1)."),
            alpha: Optional[float] = typer.Option(None, "--alpha",
                                                  help="The per-record alarm rate (default: the monitor's)."),
            records_per_day: float = typer.Option(4.0, "--records-per-day",
                                                  help="Expected records a day (for the stated rate)."),
            failure_index: Optional[float] = _failure_index(),
            db: str = _db()) -> None:
        """Add a joint, watched by a baseline monitor."""
        from rvdiag.fleet import Fleet

        k, sep, n = persistence.partition("/")
        try:
            k, n = int(k), int(n)
        except ValueError:
            raise FleetError(f"--persistence {persistence!r}: expected K/N, e.g. 3/3") from None
        rules = {"k": k, "n": n, "m": clear_after, "learning": learning, "alpha": alpha,
                 "records_per_day": records_per_day, "failure_index": failure_index}
        f = Fleet.open(db)
        res = f.add_joint(joint, monitor, params=params, rules=rules)
        stated = f.stated_false_alarms_per_year(joint)
        r = f.rules(joint)
        typer.echo(f"added {res['joint']} ({res['signal']}), monitor {res['monitor']}; alarm when {r.k} of the last "
                   f"{r.n} records alarm at {100 * r.alpha:g} % each, clear after {r.m} normal; learning "
                   f"{r.learning} records; stated {stated:.3g} false alarms per joint-year at {r.records_per_day:g} "
                   "records/day")

    @fleet_app.command("commission")
    def commission(joint: str = typer.Argument(...),
                   files: List[Path] = typer.Argument(..., help="The joint's healthy commissioning records."),
                   output_speed: float = opt.output_speed(), load: float = opt.load("Output load torque, N m."),
                   meta_regex: str = _meta_regex(), channel: str = opt.channel(),
                   angle_channel: str = _angle_channel(), fs: float = _fs(),
                   time: Optional[str] = typer.Option(None, "--time", metavar="ISO",
                                                      help="When the baseline starts (default: now)."),
                   twin: Optional[Path] = typer.Option(None, "--twin", metavar="DIR",
                                                       help="The joint's twin folder (rvdiag update --specimen ... "
                                                            "--out DIR): its crack references are copied to the "
                                                            "epoch and every record is also judged by its crack "
                                                            "detector (result key 'crack'; docs/twin.md)."),
                   db: str = _db()) -> None:
        """Make the joint's baseline from its commissioning records (a new epoch; earlier ones are kept)."""
        from rvdiag.fleet import Fleet
        from rvdiag.fleet.store import parse_time

        t = parse_time(time) if time else None
        res = Fleet.open(db).commission(joint, files, _reading(channel, fs, angle_channel, output_speed, load,
                                                               meta_regex), time=t, twin=twin)
        ops = sorted({(o["output_speed_deg_s"], o["load_Nm"]) for o in res["operating_points"]}, key=str)
        typer.echo(f"commissioned {joint}: epoch {res['epoch']} from {res['n_records']} records at "
                   f"{len(ops)} operating point(s), starting {res['started']}"
                   + (f"; with the crack detector of the twin {twin}" if res.get("twin") else ""))

    @fleet_app.command("ingest")
    def ingest(joint: str = typer.Argument(...), files: List[Path] = typer.Argument(...),
               time: Optional[str] = typer.Option(None, "--time", metavar="ISO", help="The record's time."),
               time_regex: Optional[str] = typer.Option(None, "--time-regex", metavar="RE",
                                                        help="The time in the file name: group 'time' (or the "
                                                             "match), ISO 8601."),
               output_speed: float = opt.output_speed(), load: float = opt.load("Output load torque, N m."),
               meta_regex: str = _meta_regex(), channel: str = opt.channel(),
               angle_channel: str = _angle_channel(), fs: float = _fs(),
               json_out: bool = opt.json_flag("Print the results as JSON."),
               db: str = _db()) -> None:
        """Ingest record files of a joint (time: --time, --time-regex, else the file's modification time)."""
        from rvdiag.fleet import Fleet
        from rvdiag.fleet.store import parse_time

        if time and time_regex:
            raise FleetError("give --time or --time-regex, not both")
        t = parse_time(time) if time else None
        if t is not None and len(files) > 1:
            raise FleetError("--time names one record's time; give one file, or --time-regex")
        f = Fleet.open(db)
        reading = _reading(channel, fs, angle_channel, output_speed, load, meta_regex, time_regex)
        out, bad = [], []
        for p in files:
            res = f.ingest(joint, p, filename=p.name, reading=reading, time=t)
            res["file"] = str(p)
            out.append(res)
            if res["rejected"]:
                bad.append(f"{p.name}: {res['rejected']}")
            elif not json_out:
                r = res["result"] or {}
                what = "duplicate of record %d" % res["record_id"] if res["duplicate"] else \
                    f"health index {_fmt(r.get('health_index'))} (p {_fmt(r.get('p_value'))})" \
                    + ("" if r.get("recognised", True) else f", not recognised: {r.get('reason')}")
                typer.echo(f"{joint} {p.name} {res['time']}: {what}; joint {res['joint_state']}")
        if json_out:
            _print_json(out)
        if bad:
            raise FleetError(f"{len(bad)} of {len(files)} file(s) rejected (kept with the reason, nothing else "
                             "changed): " + "; ".join(bad))

    @fleet_app.command("status")
    def status(json_out: bool = opt.json_flag("Print the rows as JSON."), db: str = _db()) -> None:
        """Every joint's state, last health index, last record time and time in state."""
        from rvdiag.fleet import Fleet

        rows = Fleet.open(db).status()
        if json_out:
            _print_json(rows)
            return
        from rich.console import Console
        from rich.table import Table

        t = Table(title="fleet")
        for c in ("joint", "state", "since", "last index", "threshold", "last record", "records", "state guess"):
            t.add_column(c)
        for r in rows:
            state = r["state"] + (" (unacknowledged)" if r["open_alarm"] else "") \
                + (f" ({r['learning_left']} to learn)" if r["state"] == "learning" and r["learning_left"] else "")
            guess = "-" if r["last_fault_state"] is None else f"{r['last_fault_state']} ({r['last_probability']:.2f})"
            t.add_row(r["joint"], state, _fmt(r["state_since"]), _fmt(r["last_index"]), _fmt(r["threshold"]),
                      _fmt(r["last_record_time"]), str(r["n_records"]), guess)
        Console(width=160).print(t)

    @fleet_app.command("history")
    def history(joint: str = typer.Argument(...),
                limit: Optional[int] = typer.Option(None, "--limit", help="Only the last N records."),
                json_out: bool = opt.json_flag("Print the records as JSON."),
                csv_out: bool = typer.Option(False, "--csv", help="Print the records as CSV, one row a record "
                                                                  "(a service record to keep or send on)."),
                db: str = _db()) -> None:
        """The joint's records in time order, with the state each left it in."""
        from rvdiag.fleet import Fleet, history_csv

        if json_out and csv_out:
            raise FleetError("give --json or --csv, not both")
        rows = Fleet.open(db).history(joint, limit=limit)
        if json_out:
            _print_json(rows)
            return
        if csv_out:
            typer.echo(history_csv(rows), nl=False)
            return
        from rich.console import Console
        from rich.table import Table

        t = Table(title=joint)
        for c in ("time", "checksum", "epoch", "index", "p", "joint p", "alarm", "joint state", "state guess",
                  "recognised"):
            t.add_column(c)
        for r in rows:
            if r["rejected"]:
                t.add_row(r["time"], r["checksum"][:10], _fmt(r["epoch"]), "", "", "", "", "rejected",
                          r["rejected"][:60], "")
                continue
            guess = "-" if r["fault_state"] is None else f"{r['fault_state']} ({_fmt(r['probability'], '.2f')})"
            t.add_row(r["time"], r["checksum"][:10], _fmt(r["epoch"]), _fmt(r["health_index"]), _fmt(r["p_value"]),
                      _fmt(r["joint_p_value"]), "yes" if r["record_alarm"] else "",
                      _fmt(r["joint_state"]) + (" (learning)" if r["learning"] else ""), guess,
                      "yes" if r["recognised"] else f"no: {r['reason']}")
        Console(width=200).print(t)

    @fleet_app.command("events")
    def events(joint: Optional[str] = typer.Argument(None),
               kind: Optional[str] = typer.Option(None, "--kind", help="raised, acknowledged, cleared, maintenance, "
                                                                       "commissioned"),
               json_out: bool = opt.json_flag("Print the events as JSON."), db: str = _db()) -> None:
        """Alarms raised, acknowledged and cleared, maintenance and commissioning, in time order."""
        from rvdiag.fleet import Fleet

        rows = Fleet.open(db).events(joint, kind)
        if json_out:
            _print_json(rows)
            return
        for e in rows:
            by = f" by {e['by']}" if e["by"] else ""
            typer.echo(f"{e['time']} {e['joint']} {e['kind']}{by}" + (f": {e['note']}" if e["note"] else ""))

    @fleet_app.command("ack")
    def ack(joint: str = typer.Argument(...), note: str = typer.Option(..., "--note", help="What was seen or done."),
            by: Optional[str] = typer.Option(None, "--by", help="Who (default: $USER)."), db: str = _db()) -> None:
        """Acknowledge the joint's open alarm."""
        from rvdiag.fleet import Fleet

        res = Fleet.open(db).acknowledge(joint, by, note)
        typer.echo(f"acknowledged the alarm of {joint} by {res['by']}; joint {res['joint_state']}")

    @fleet_app.command("set")
    def set_(joint: str = typer.Argument(...),
             failure_index: Optional[str] = typer.Option(
                 ..., "--failure-index", metavar="INDEX|none",
                 help="The health index the joint's remaining life is counted to ('none' removes it)."),
             note: str = typer.Option("", "--note", help="Why (kept with the change)."),
             by: Optional[str] = typer.Option(None, "--by", help="Who (default: $USER)."), db: str = _db()) -> None:
        """Change a joint's setting (today its failure index), recorded as an event with who and why."""
        from rvdiag.fleet import Fleet

        value = None
        if failure_index.strip().lower() != "none":
            try:
                value = float(failure_index)
            except ValueError:
                raise FleetError(f"--failure-index {failure_index!r}: expected a number > 0 or 'none'") from None
        res = Fleet.open(db).set_failure_index(joint, value, by, note)
        typer.echo(f"{joint}: {res['note']} (by {res['by']})")

    @fleet_app.command("maintenance")
    def maintenance(joint: str = typer.Argument(...), note: str = typer.Option(..., "--note", help="What was done."),
                    by: Optional[str] = typer.Option(None, "--by", help="Who (default: $USER)."),
                    db: str = _db()) -> None:
        """Record maintenance: the joint awaits a new baseline ('rvdiag fleet commission')."""
        from rvdiag.fleet import Fleet

        res = Fleet.open(db).maintenance(joint, by, note)
        typer.echo(f"maintenance of {joint} recorded by {res['by']}; joint {res['joint_state']} until it is "
                   "commissioned again")

    @token_app.command("create")
    def token_create(read_only: bool = typer.Option(False, "--read-only", help="A token that can only read."),
                     name: Optional[str] = typer.Option(None, "--name", help="The token's name (default: token-N)."),
                     db: str = _db()) -> None:
        """Create an API token; it is printed once (the store keeps its hash)."""
        import secrets

        from rvdiag.fleet import Fleet

        name = name or f"token-{secrets.token_hex(3)}"
        tok = Fleet.open(db).create_token(name, read_only)
        typer.echo(tok)
        typer.echo(f"{'read-only' if read_only else 'read-write'} token {name!r}: shown once, keep it", err=True)

    @fleet_app.command("serve")
    def serve(host: str = typer.Option("127.0.0.1", "--host", help="Address to bind (default: this machine only)."),
              port: int = typer.Option(8000, "--port"),
              max_upload_mb: Optional[float] = typer.Option(
                  None, "--max-upload-mb", help="Largest upload accepted, MiB (default: env "
                                                "RVDIAG_FLEET_MAX_UPLOAD_MB, else 64)."),
              read_token: Optional[bool] = typer.Option(
                  None, "--read-token/--open-reads", help="Whether reading the API and the pages needs a token too "
                                                         "(default: env RVDIAG_FLEET_READ_TOKEN=1, else open reads; "
                                                         "writes always need a read-write token)."),
              db: str = _db()) -> None:
        """Serve the HTTP API and the dashboard (docs/fleet-api.md)."""
        from rvdiag.fleet import Fleet

        try:
            from rvdiag.fleet.api import create_app
        except ImportError:
            raise FleetError("this rvdiag has no fleet HTTP API (rvdiag.fleet.api)") from None
        import uvicorn

        if max_upload_mb is not None and not (math.isfinite(max_upload_mb) and max_upload_mb > 0):
            raise FleetError(f"--max-upload-mb must be a positive number, got {max_upload_mb:g}")
        app = create_app(Fleet.open(db), read_needs_token=read_token,
                         max_upload=None if max_upload_mb is None else int(max_upload_mb * 2 ** 20))
        uvicorn.run(app, host=host, port=port)

    @fleet_app.command("snapshot")
    def snapshot(out: Path = typer.Argument(..., help="A new or empty folder, or an earlier snapshot (replaced "
                                                      "whole); any other folder is refused."),
                 db: str = _db()) -> None:
        """Write the dashboard as static HTML (fleet, joints, alarms) that opens in a browser with no server."""
        from rvdiag.fleet import Fleet

        try:
            from rvdiag.fleet.web import snapshot as write_snapshot
        except ImportError:
            raise FleetError("this rvdiag has no fleet dashboard (rvdiag.fleet.web)") from None
        index = write_snapshot(Fleet.open(db), out)
        typer.echo(f"wrote the dashboard's snapshot: {index}")

    @fleet_app.command("watch")
    def watch(folder: Path = typer.Argument(..., help="Folder tree DIR/site/robot/joint/FILE."),
              once: bool = typer.Option(False, "--once", help="Ingest what is there now and exit."),
              time_regex: Optional[str] = typer.Option(None, "--time-regex", metavar="RE",
                                                       help="The time in the file name (else its modification "
                                                            "time)."),
              output_speed: float = opt.output_speed(), load: float = opt.load("Output load torque, N m."),
              meta_regex: str = _meta_regex(), channel: str = opt.channel(),
              angle_channel: str = _angle_channel(), fs: float = _fs(),
              db: str = _db()) -> None:
        """Ingest new record files in a folder tree named by joint (DIR/plant/r1/j3/*.csv)."""
        from rvdiag.fleet import Fleet
        from rvdiag.fleet.watch import watch as run

        f = Fleet.open(db)
        counts = run(f, folder, _reading(channel, fs, angle_channel, output_speed, load, meta_regex, time_regex),
                     once=once, report=lambda line, error: typer.echo(line, err=error))
        typer.echo(", ".join(f"{v} {k}" for k, v in counts.items()))
