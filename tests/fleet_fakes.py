"""A stand-in for the fleet's judge (:class:`rvdiag.fleet.judge.Judge`) in the fleet's unit tests, and the
PostgreSQL database they run against.

:class:`FakeJudge` reads ``.npy`` records; a record's health index is its mean, the monitor's alarm is ``mean >
ALARM_AT``, a record without variation is not recognised, and an empty array is a file the monitor cannot read.
So a test writes ``np.full(8, 0.1) + noise`` for a healthy record and a mean of 10 for a broken tooth.

:func:`postgres_url` makes a fresh database on the server named by ``RVDIAG_TEST_POSTGRES`` (a random name, dropped
at the end), skips when the variable is unset, and fails instead under ``CI=true``."""

from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from rvdiag.errors import DataFileError

ALARM_AT = 3.0


class FakeJudge:
    alpha = 0.05

    def __init__(self):
        self.judged = 0

    def describe(self, monitor):
        if not Path(monitor).is_dir():
            from rvdiag.errors import ModelFileError

            raise ModelFileError(f"no model at {monitor}")
        return {"alpha": self.alpha, "signal": "vibration"}

    def read(self, path, reading, monitor):
        try:
            x = np.load(path)
        except Exception as exc:  # noqa: BLE001 - the real reader says DataFileError too
            raise DataFileError(f"{Path(path).name}: not a record ({type(exc).__name__})") from None
        if x.size == 0:
            raise DataFileError(f"{Path(path).name}: the file holds no samples")
        return x

    def make_baseline(self, monitor, records, operating_points, out):
        Path(out).mkdir(parents=True)
        (Path(out) / "n").write_text(str(len(records)))
        return {"n_records": len(records), "operating_points": operating_points}

    def judge(self, monitor, baseline, x, reading, operating_point):
        self.judged += 1
        flat = bool(np.ptp(x) == 0)
        h = None if flat else float(np.mean(x))
        return {"health_index": h, "p_value": None if flat else float(np.exp(-max(h, 0))),
                "alarm": None if flat else h > ALARM_AT, "false_alarm_rate": self.alpha, "state": None if flat
                else ("T2" if h > ALARM_AT else "T1"), "probability": None if flat else 0.9,
                "changes": [] if flat else ["tooth pulse up 3 dB"], "recognised": not flat,
                "reason": "the signal is constant: a dead or disconnected sensor?" if flat else None,
                "operating_point": operating_point, "warnings": [], "n_windows": 1, "windows": []}


def write_record(path: Path, mean: float, seed: int = 0, flat: bool = False) -> Path:
    x = np.full(16, float(mean)) if flat else mean + 0.1 * np.random.default_rng(seed).standard_normal(16)
    np.save(path, x)
    return path


@contextmanager
def postgres_database():
    """A fresh PostgreSQL database (URL) on the test server, dropped afterwards (module docstring)."""
    admin = os.environ.get("RVDIAG_TEST_POSTGRES")
    if not admin:
        if os.environ.get("CI") == "true":
            pytest.fail("CI=true but RVDIAG_TEST_POSTGRES is unset: tests/services/start.sh did not start PostgreSQL")
        pytest.skip("RVDIAG_TEST_POSTGRES is unset (eval \"$(bash tests/services/start.sh)\" starts PostgreSQL)")
    from sqlalchemy import create_engine, text
    from sqlalchemy.engine import make_url

    name = f"rvdiag_fleet_{secrets.token_hex(6)}"
    eng = create_engine(admin, isolation_level="AUTOCOMMIT")
    with eng.connect() as c:
        c.execute(text(f'CREATE DATABASE "{name}"'))
    try:
        yield make_url(admin).set(database=name).render_as_string(hide_password=False)
    finally:
        with eng.connect() as c:
            c.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        eng.dispose()
