"""The sample store: one Zarr (v3) group per library or measured dataset, one reader for both.

Layout of a store ``PATH.zarr``::

    attrs     format ("rvdiag-store/1"), kind ("simulated" | "measured"), classes (list of str),
              length (points per sample), fs (Hz or null), complete (bool), config (dict),
              config_hash (str), params (dict or null), rvdiag_version, plus anything the writer adds
    signals   float32 (n_samples, length), one chunk per sample
    label     int16 (n_samples,): index into attrs["classes"]
    meta/<c>  one column per metadata field, one row per sample (float64, int64 or str).
              Always present: ``split`` ("train" | "test" | ...) and ``unit`` (the simulation or file the
              sample came from, an int).
    _units/   while a build is under way: one JSON record per committed unit (see below)

Two ways to write:

- :func:`write_store` writes a whole dataset at once into a temporary sibling folder and renames it into
  place, so a crash never leaves a half-written store (measured datasets use this).
- :class:`StoreBuilder` fills a preallocated store unit by unit (a unit = one simulation). Each unit's
  rows are written first, then its metadata record ``_units/<id>.json`` is written atomically: the record's
  existence is the commit.  Re-opening the builder after a crash lists the committed units so the caller
  skips them; :meth:`StoreBuilder.finalize` turns the records into the ``label`` and ``meta`` columns and sets
  ``complete``.  A store whose ``config_hash`` differs from the builder's is refused, never mixed.

Readers use :class:`SampleStore` only.

Paired stores (monitoring a reducer against its own baseline, docs/monitoring.md): every sample also carries
``reducer`` (int, which simulated or real reducer it was recorded on) and ``role`` (``"baseline"``: a healthy
commissioning record; ``"monitored"``: a later record in some state).  :func:`rvdiag.monitoring.pairing.is_paired`
tells one; :func:`rvdiag.monitoring.pairing.match_baseline` gives each monitored sample its reducer's baseline samples
at the nearest operating point.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, Mapping

import numpy as np
import zarr

from rvdiag import __version__
from rvdiag.atomic import atomic_file, staged_directory
from rvdiag.deprecation import renamed_names
from rvdiag.errors import ParameterError, StoreError

STORE_FORMAT = "rvdiag-store/1"
REQUIRED_META = ("split", "unit")


#: The comparison operators of a ``--where`` filter (:func:`parse_where`), longest first.
WHERE_OPERATORS = ("<=", ">=", "==", "!=", "<", ">", "=")


def parse_where(text: str) -> tuple[str, str, float | str]:
    """``(column, operator, value)`` of a ``--where`` filter on the samples' metadata, ``COLUMN OP VALUE`` (``OP`` one of ``< <= > >= == !=``,
    ``=`` meaning ``==``): the value is a number when it reads as one, else a string (``state==T1``).

    >>> parse_where("noise_snr_db>=20")
    ('noise_snr_db', '>=', 20.0)
    >>> parse_where("state = T4")
    ('state', '==', 'T4')
    """
    t = str(text)
    for op in WHERE_OPERATORS:
        if op in t:
            column, _, value = (x.strip() for x in t.partition(op))
            if column and value and not any(o in value for o in "<>=!"):
                try:
                    v: float | str = float(value)
                except ValueError:
                    v = value
                return column, ("==" if op == "=" else op), v
            break
    raise ParameterError(f"condition {text!r}: expected COLUMN OP VALUE with OP one of < <= > >= == != "
                         "(e.g. noise_snr_db>=20, simulation<10, state==T1)")


def _compare(values: np.ndarray, op: str, value: float | str, where: str) -> np.ndarray:
    """Boolean mask of ``values OP value`` (numbers compared as numbers, strings as strings)."""
    import operator

    fn = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge, "==": operator.eq,
          "!=": operator.ne}[op]
    if isinstance(value, float):
        try:
            v = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):
            raise StoreError(f"{where}: the column is not numeric") from None
        return np.asarray(fn(v, value), dtype=bool)
    if op not in ("==", "!="):
        raise StoreError(f"{where}: {op} needs a number")
    return np.asarray(fn(np.asarray(values).astype(str), value), dtype=bool)


def config_hash(config: Mapping[str, Any]) -> str:
    """SHA-256 (hex, 16 chars) of a config's canonical JSON: equal configs give equal hashes."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


@dataclass
class Samples:
    """A selection of samples loaded into memory.

    Attributes
    ----------
    X : ndarray, float32, shape (n, length)
    y : ndarray of str, shape (n,)   class names
    meta : dict of column name -> ndarray (n,)
    index : ndarray of int, the sample indices in the store
    """

    X: np.ndarray
    y: np.ndarray
    meta: dict[str, np.ndarray]
    index: np.ndarray


class SampleStore:
    """Read access to a complete sample store (simulated library or measured dataset)."""

    def __init__(self, path: str | Path, group: zarr.Group):
        self.path = Path(path)
        self._group = group
        self.attrs: dict[str, Any] = dict(group.attrs)
        self.classes: list[str] = list(self.attrs["classes"])
        self.length: int = int(self.attrs["length"])
        fs = self.attrs.get("fs")
        self.fs: float | None = None if fs is None else float(fs)
        self.signals = group["signals"]
        self.n_samples: int = int(self.signals.shape[0])
        self.labels = np.asarray(group["label"][:], dtype=np.int64)
        meta_group = group["meta"]
        self.meta: dict[str, np.ndarray] = {
            name: np.asarray(arr[:]) for name, arr in sorted(meta_group.arrays())
        }

    # ------------------------------------------------------------------ opening
    @classmethod
    def open(cls, path: str | Path) -> "SampleStore":
        """Open a store for reading; raises :class:`StoreError` if it is missing, foreign or incomplete."""
        path = Path(path)
        if not path.exists():
            raise StoreError(f"no sample store at {path}")
        try:
            group = zarr.open_group(str(path), mode="r")
        except Exception as exc:  # zarr raises several types for a folder that is not a group
            raise StoreError(f"{path} is not a Zarr sample store ({type(exc).__name__})") from None
        attrs = dict(group.attrs)
        if attrs.get("format") != STORE_FORMAT:
            raise StoreError(f"{path} is not an rvdiag sample store (format {attrs.get('format')!r})")
        if not attrs.get("complete", False):
            raise StoreError(
                f"{path} is an unfinished build: re-run the same 'rvdiag library build' command to finish it"
            )
        try:
            return cls(path, group)
        except KeyError as exc:
            raise StoreError(f"{path} is corrupt: missing {exc}") from None

    # ------------------------------------------------------------------ selection
    @property
    def label_names(self) -> np.ndarray:
        """Class name of every sample."""
        return np.asarray(self.classes, dtype=object)[self.labels]

    def splits(self) -> list[str]:
        """Split names present in the store."""
        return sorted(set(self.meta["split"].tolist()))

    def indices(self, split: str = "all", where: Iterable[str] = ()) -> np.ndarray:
        """Sample indices of a split (``"all"`` = every sample), keeping only the samples that satisfy every
        condition of ``where`` (``"noise_snr_db>=20"``, ``"simulation<10"``: :func:`parse_where`)."""
        if split == "all":
            idx = np.arange(self.n_samples)
        elif split not in self.splits():
            raise StoreError(f"{self.path}: no split {split!r} (has {', '.join(self.splits())}, or 'all')")
        else:
            idx = np.flatnonzero(self.meta["split"] == split)
        for text in where or ():
            column, op, value = parse_where(text)
            if column not in self.meta:
                raise StoreError(f"{self.path}: no metadata column {column!r} for the condition {text!r} "
                                 f"(columns: {', '.join(sorted(self.meta))})")
            idx = idx[_compare(self.meta[column][idx], op, value, f"{self.path}: condition {text!r}")]
        return idx

    def load(self, split: str = "all", index: Iterable[int] | None = None) -> Samples:
        """Load the samples of a split (or of explicit indices) into memory."""
        idx = self.indices(split) if index is None else np.asarray(list(index), dtype=np.int64)
        if idx.size == 0:
            X = np.zeros((0, self.length), dtype=np.float32)
        elif idx.size == self.n_samples:
            X = np.asarray(self.signals[:], dtype=np.float32)
        else:
            X = np.asarray(self.signals.get_orthogonal_selection((idx, slice(None))), dtype=np.float32)
        return Samples(
            X=X,
            y=self.label_names[idx],
            meta={k: v[idx] for k, v in self.meta.items()},
            index=idx,
        )

    # ------------------------------------------------------------------ description
    def summary(self) -> dict[str, Any]:
        """Counts per class and split, length, fs, kind, config: what ``rvdiag library info`` prints."""
        counts: dict[str, dict[str, int]] = {}
        pairs = Counter(zip(self.label_names.tolist(), self.meta["split"].tolist()))
        for (cls_name, split), n in sorted(pairs.items()):
            counts.setdefault(cls_name, {})[split] = n
        return {
            "path": str(self.path),
            "kind": self.attrs.get("kind"),
            "n_samples": self.n_samples,
            "length": self.length,
            "fs": self.fs,
            "classes": self.classes,
            "splits": self.splits(),
            "counts": counts,
            "meta_columns": sorted(self.meta),
            "config_hash": self.attrs.get("config_hash"),
            "rvdiag_version": self.attrs.get("rvdiag_version"),
            "config": self.attrs.get("config"),
        }


# ---------------------------------------------------------------------- writing helpers
def _base_attrs(
    kind: str, classes: list[str], length: int, fs: float | None, config: Mapping[str, Any], extra: Mapping[str, Any]
) -> dict[str, Any]:
    attrs = {
        "format": STORE_FORMAT,
        "kind": kind,
        "classes": list(classes),
        "length": int(length),
        "fs": None if fs is None else float(fs),
        "complete": False,
        "config": _jsonable(config),
        "config_hash": config_hash(config),
        "rvdiag_version": __version__,
    }
    attrs.update(_jsonable(dict(extra)))
    return attrs


def _jsonable(obj: Any) -> Any:
    """Round-trip through JSON so numpy scalars and tuples become plain types."""
    return json.loads(json.dumps(obj, default=_json_default))


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def _write_meta_columns(group: zarr.Group, meta: Mapping[str, Any], n: int) -> None:
    meta_group = group.require_group("meta")
    for name, values in meta.items():
        col = np.asarray(values)
        if col.shape != (n,):
            raise StoreError(f"metadata column {name!r} has {col.shape} rows, expected ({n},)")
        if col.dtype.kind in "biu":
            arr = meta_group.create_array(name, shape=(n,), dtype="int64", chunks=(max(n, 1),), overwrite=True)
            arr[:] = col.astype(np.int64)
        elif col.dtype.kind == "f":
            arr = meta_group.create_array(name, shape=(n,), dtype="float64", chunks=(max(n, 1),), overwrite=True)
            arr[:] = col.astype(np.float64)
        else:
            arr = meta_group.create_array(name, shape=(n,), dtype=str, chunks=(max(n, 1),), overwrite=True)
            arr[:] = np.asarray([("" if v is None else str(v)) for v in col.tolist()], dtype=object)


def _check_meta(meta: Mapping[str, Any]) -> None:
    missing = [c for c in REQUIRED_META if c not in meta]
    if missing:
        raise StoreError(f"metadata lacks required column(s): {', '.join(missing)}")


def write_store(
    path: str | Path,
    signals: np.ndarray,
    labels: Iterable[str],
    meta: Mapping[str, Any],
    *,
    kind: str,
    fs: float | None,
    config: Mapping[str, Any],
    classes: list[str] | None = None,
    overwrite: bool = False,
    extra_attrs: Mapping[str, Any] | None = None,
) -> Path:
    """Write a complete store at once, atomically (temporary folder + rename).

    Parameters
    ----------
    signals : array (n_samples, length), stored as float32
    labels : class name per sample
    meta : column name -> values per sample; must hold ``split`` and ``unit``
    classes : class order; default the sorted distinct labels
    overwrite : replace an existing store at ``path`` (only after the new one is complete)
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise StoreError(f"{path} already exists (remove it or choose another --out)")
    X = np.asarray(signals, dtype=np.float32)
    if X.ndim != 2 or X.shape[0] == 0:
        raise StoreError(f"signals must be a non-empty 2-D array (samples x length), got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise StoreError("signals contain NaN or Inf")
    names = np.asarray([str(v) for v in labels], dtype=object)
    if names.shape != (X.shape[0],):
        raise StoreError(f"{names.size} labels for {X.shape[0]} samples")
    _check_meta(meta)
    classes = sorted(set(names.tolist())) if classes is None else list(classes)
    lookup = {c: i for i, c in enumerate(classes)}
    unknown = set(names.tolist()) - set(lookup)
    if unknown:
        raise StoreError(f"labels not among classes: {sorted(unknown)}")
    with staged_directory(path) as tmp:
        group = zarr.open_group(str(tmp), mode="w")
        group.attrs.update(_base_attrs(kind, classes, X.shape[1], fs, config, extra_attrs or {}))
        sig = group.create_array("signals", shape=X.shape, dtype="float32", chunks=(1, X.shape[1]))
        sig[:] = X
        lab = group.create_array("label", shape=(X.shape[0],), dtype="int16", chunks=(X.shape[0],))
        lab[:] = np.asarray([lookup[v] for v in names.tolist()], dtype=np.int16)
        _write_meta_columns(group, meta, X.shape[0])
        group.attrs["complete"] = True
    return path


class StoreBuilder:
    """Fill a preallocated store unit by unit, with atomic per-unit commits (resumable builds).

    Parameters
    ----------
    path : store folder
    unit_rows : number of sample rows of each unit, in unit order (unit ``k`` owns a contiguous block)
    length : points per sample
    classes : class names, in label order
    config : the full build config; its hash guards against mixing stores of different configs
    fs, kind, extra_attrs : stored in the group attributes
    """

    def __init__(
        self,
        path: str | Path,
        *,
        unit_rows: list[int],
        length: int,
        classes: list[str],
        config: Mapping[str, Any],
        fs: float | None,
        kind: str = "simulated",
        extra_attrs: Mapping[str, Any] | None = None,
    ):
        self.path = Path(path)
        self.unit_rows = [int(n) for n in unit_rows]
        self.offsets = np.concatenate([[0], np.cumsum(self.unit_rows)]).astype(np.int64)
        self.n_samples = int(self.offsets[-1])
        self.length = int(length)
        self.classes = list(classes)
        self.config_hash = config_hash(config)
        self._physics_revision = config.get("physics_revision")
        self._units_dir = self.path / "_units"
        if self.path.exists():
            self._group = self._open_existing()
        else:
            self._group = self._create(config, fs, kind, extra_attrs or {})
        self._signals = self._group["signals"]

    def _create(self, config: Mapping[str, Any], fs: float | None, kind: str, extra: Mapping[str, Any]) -> zarr.Group:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        group = zarr.open_group(str(self.path), mode="w")
        attrs = _base_attrs(kind, self.classes, self.length, fs, config, extra)
        attrs["unit_rows"] = self.unit_rows
        group.create_array(
            "signals", shape=(self.n_samples, self.length), dtype="float32", chunks=(1, self.length)
        )
        self._units_dir.mkdir(exist_ok=True)
        group.attrs.update(attrs)  # attributes last: a folder without them is refused on resume
        return group

    def _open_existing(self) -> zarr.Group:
        try:
            group = zarr.open_group(str(self.path), mode="r+")
        except Exception:
            raise StoreError(f"{self.path} exists and is not a sample store; choose another --out") from None
        attrs = dict(group.attrs)
        if attrs.get("format") != STORE_FORMAT or "signals" not in group:
            raise StoreError(f"{self.path} exists and is not a resumable sample store; choose another --out")
        stored_rev = (attrs.get("config") or {}).get("physics_revision")
        this_rev = self._physics_revision
        if attrs.get("config_hash") != self.config_hash and stored_rev != this_rev:
            raise StoreError(
                f"{self.path} was simulated by the physics of {stored_rev or 'before 2026-11-25'} and this rvdiag "
                f"simulates that of {this_rev}: its samples would not match new ones; choose another --out, or "
                "--overwrite to replace it"
            )
        if attrs.get("config_hash") != self.config_hash:
            raise StoreError(
                f"{self.path} was built from a different config (hash {attrs.get('config_hash')}, "
                f"this one {self.config_hash}); refusing to mix them: choose another --out, or --overwrite to replace "
                "it"
            )
        if attrs.get("unit_rows") != self.unit_rows or int(attrs.get("length", -1)) != self.length:
            raise StoreError(f"{self.path}: layout differs from this build; choose another --out, or --overwrite "
                             "to replace it")
        self._units_dir.mkdir(exist_ok=True)
        return group

    # ------------------------------------------------------------------ state
    @property
    def attrs(self) -> dict[str, Any]:
        """The store's group attributes (config, library description, ...), as written when it was created."""
        return dict(self._group.attrs)

    @property
    def complete(self) -> bool:
        return bool(self._group.attrs.get("complete", False))

    def committed_units(self) -> set[int]:
        """Units whose records exist (their rows are fully written)."""
        if self.complete:
            return set(range(len(self.unit_rows)))
        done = set()
        for f in self._units_dir.glob("*.json"):
            try:
                done.add(int(f.stem))
            except ValueError:
                continue
        return done

    # ------------------------------------------------------------------ writing
    def write_unit(self, unit: int, signals: np.ndarray, labels: list[str], meta: Mapping[str, Any]) -> None:
        """Write one unit's rows, then commit it by writing its record atomically.

        ``meta`` maps column names to one value per row (``split`` required; ``unit`` is added).
        """
        lo, hi = int(self.offsets[unit]), int(self.offsets[unit + 1])
        X = np.asarray(signals, dtype=np.float32)
        if X.shape != (hi - lo, self.length):
            raise StoreError(f"unit {unit}: expected signals of shape {(hi - lo, self.length)}, got {X.shape}")
        if len(labels) != hi - lo:
            raise StoreError(f"unit {unit}: {len(labels)} labels for {hi - lo} rows")
        unknown = set(labels) - set(self.classes)
        if unknown:
            raise StoreError(f"unit {unit}: labels not among classes: {sorted(unknown)}")
        if "split" not in meta:
            raise StoreError(f"unit {unit}: metadata lacks 'split'")
        self._signals[lo:hi] = X
        record = {
            "unit": unit,
            "labels": list(labels),
            "meta": {k: _jsonable(np.asarray(v).tolist()) for k, v in meta.items()},
        }
        for k, v in record["meta"].items():
            if len(v) != hi - lo:
                raise StoreError(f"unit {unit}: metadata column {k!r} has {len(v)} rows, expected {hi - lo}")
        target = self._units_dir / f"{unit}.json"
        with atomic_file(target, "w", encoding="utf-8") as fh:
            json.dump(record, fh)

    def finalize(self) -> Path:
        """Turn the unit records into ``label`` and ``meta`` columns and mark the store complete.

        Two passes over the records: the first finds each column's type, the second fills typed arrays, one
        record at a time.  Memory is the columns themselves (8 bytes a value), not Python lists of every value."""
        if self.complete:
            return self.path
        n_units = len(self.unit_rows)
        missing = sorted(set(range(n_units)) - self.committed_units())
        if missing:
            raise StoreError(f"{self.path}: {len(missing)} unit(s) not built yet (first: {missing[0]})")
        kinds: dict[str, _ColumnKind] = {}
        for unit, meta in self._records():
            rows = self.unit_rows[unit]
            for key in set(kinds) | set(meta):
                kinds.setdefault(key, _ColumnKind(unit > 0)).see(meta.get(key, [None] * rows))
        lookup = {c: i for i, c in enumerate(self.classes)}
        labels = np.empty(self.n_samples, dtype=np.int16)
        columns = {key: kind.empty(self.n_samples) for key, kind in kinds.items()}
        for unit, meta, names in self._records(with_labels=True):
            lo, hi = int(self.offsets[unit]), int(self.offsets[unit + 1])
            labels[lo:hi] = [lookup[v] for v in names]
            for key, kind in kinds.items():
                kind.fill(columns[key], lo, meta.get(key, [None] * (hi - lo)))
        lab = self._group.create_array(
            "label", shape=(self.n_samples,), dtype="int16", chunks=(max(self.n_samples, 1),), overwrite=True
        )
        lab[:] = labels
        _write_meta_columns(self._group, columns, self.n_samples)
        self._group.attrs["complete"] = True
        shutil.rmtree(self._units_dir, ignore_errors=True)
        return self.path

    def _records(self, with_labels: bool = False) -> Iterator[tuple]:
        """``(unit, meta)`` (``+ labels``) of every unit record in unit order, ``unit`` added to the metadata."""
        for unit in range(len(self.unit_rows)):
            record = json.loads((self._units_dir / f"{unit}.json").read_text("utf-8"))
            meta = dict(record["meta"])
            meta["unit"] = [unit] * self.unit_rows[unit]
            yield (unit, meta, record["labels"]) if with_labels else (unit, meta)


class _ColumnKind:
    """The type of a metadata column seen value by value: int64 when every value is an int, float64 (``None`` ->
    NaN) when every present value is a number, else str (``None`` -> "")."""

    def __init__(self, missing_before: bool = False):
        self.none = missing_before  # a column that first appears in a later unit is None in the earlier ones
        self.present = False
        self.ints = self.numbers = True

    def see(self, values: list[Any]) -> None:
        for v in values:
            if v is None:
                self.none = True
                continue
            self.present = True
            if isinstance(v, bool) or not isinstance(v, (int, float, np.number)):
                self.ints = self.numbers = False
            elif not isinstance(v, (int, np.integer)):
                self.ints = False

    @property
    def dtype(self) -> Any:
        if self.present and self.ints and not self.none:
            return np.int64
        if self.present and self.numbers:
            return np.float64
        return object

    def empty(self, n: int) -> np.ndarray:
        return np.empty(n, dtype=self.dtype)

    def fill(self, out: np.ndarray, lo: int, values: list[Any]) -> None:
        if out.dtype == np.int64:
            out[lo:lo + len(values)] = values
        elif out.dtype == np.float64:
            out[lo:lo + len(values)] = [np.nan if v is None else float(v) for v in values]
        else:
            out[lo:lo + len(values)] = ["" if v is None else str(v) for v in values]


# ---------------------------------------------------------------------- paired stores
#: metadata columns of a paired store (module docstring) and the values of ``role``
PAIRED_COLUMNS = ("reducer", "role")
ROLES = ("baseline", "monitored")


#: old names, served with a DeprecationWarning naming the new one
__getattr__ = renamed_names(__name__, {"parse_condition": "parse_where"})
