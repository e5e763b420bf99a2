"""Old public names renamed in the refactors, and old paths of moved modules, keep working, each with a
DeprecationWarning naming the new one."""

import ast
import importlib
import pickle
import re
import sys
import warnings
from pathlib import Path

import pytest
from test_import_layers import imported_names, python_files

from rvdiag.registry import MOVED_TYPES, TRUSTED_TYPES

#: (module, old name, new name)
RENAMED = [
    ("rvdiag.motor", "estimate_output_speed", "output_speed_from_current"),
    ("rvdiag.motor.lines", "estimate_output_speed", "output_speed_from_current"),
    ("rvdiag.datasets", "parse_condition", "parse_where"),
    ("rvdiag.datasets.store", "parse_condition", "parse_where"),
]


@pytest.mark.parametrize("module, old, new", RENAMED)
def test_an_old_name_warns_naming_the_new_one_and_is_the_new_object(module, old, new):
    mod = importlib.import_module(module)
    with pytest.warns(DeprecationWarning, match=rf"^{module}\.{old} is deprecated; use {module}\.{new}$"):
        obj = getattr(mod, old)
    assert obj is getattr(mod, new)
    assert old not in getattr(mod, "__all__", ())
    assert old not in dir(mod)


@pytest.mark.parametrize("module, old, new", RENAMED)
def test_from_import_of_an_old_name_warns_at_the_users_line(module, old, new):
    namespace = {}
    with pytest.warns(DeprecationWarning, match=new) as record:
        exec(compile(f"from {module} import {old}", "users_script.py", "exec"), namespace)
    assert namespace[old] is getattr(importlib.import_module(module), new)
    assert record[0].filename == "users_script.py"  # the warning points at the user's import, not at rvdiag


def test_the_old_names_still_compute():
    import numpy as np

    from rvdiag.datasets import parse_where
    from rvdiag.params import ReducerParams

    with pytest.warns(DeprecationWarning):
        from rvdiag.datasets import parse_condition
    assert parse_condition("state = T4") == parse_where("state = T4") == ("state", "==", "T4")
    p = ReducerParams.load(None)
    fs, f_e = 2000.0, 37.0
    t = np.arange(4000) / fs
    x = np.sin(2 * np.pi * f_e * t)
    from rvdiag.motor import output_speed_from_current

    with pytest.warns(DeprecationWarning):
        from rvdiag.motor import estimate_output_speed
    assert estimate_output_speed(x, fs, p) == output_speed_from_current(x, fs, p)


def test_an_unknown_name_is_still_an_attribute_error():
    import rvdiag.motor

    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        rvdiag.motor.no_such_name  # noqa: B018
    assert not hasattr(rvdiag.motor, "no_such_name")


# --- moved modules: the old path is a thin alias of the new module (rvdiag.deprecation.moved_module) ---

#: (old path, new module, a class or function of it, whether it is built without arguments)
MOVED = [
    ("rvdiag.features.baseline", "rvdiag.features.zscore", "HealthyBaselineFeatures", True),
    ("rvdiag.features.cnn", "rvdiag.models.cnn_features", "CNNFeatures", True),
    ("rvdiag.library.units", "rvdiag.library.work_units", "run_unit", False),
    ("rvdiag.models.monitoring", "rvdiag.monitoring.detector", "BaselineMonitor", True),
    ("rvdiag.evaluation.mcsa", "rvdiag.evaluation.motor_current_study", "McsaSettings", True),
]
OLD_PATHS = [m[0] for m in MOVED]
SRC = Path(__file__).resolve().parents[1] / "src" / "rvdiag"


def _forget(old):
    """Undo an import of ``old``: the next import runs its body (and warns) again."""
    sys.modules.pop(old, None)
    parent, _, child = old.rpartition(".")
    if parent in sys.modules:
        vars(sys.modules[parent]).pop(child, None)


@pytest.fixture
def first_import():
    """Each old path imports as for the first time in the test (it warns once, at its first import), and is
    forgotten after it."""
    for old in OLD_PATHS:
        _forget(old)
    yield
    for old in OLD_PATHS:
        _forget(old)


def _own(record, old):
    return [w for w in record if issubclass(w.category, DeprecationWarning) and str(w.message).startswith(old + " ")]


@pytest.mark.parametrize("old, new, name, _", MOVED)
def test_an_old_module_path_warns_once_naming_the_new_one_and_serves_its_objects(old, new, name, _, first_import):
    target = importlib.import_module(new)
    with pytest.warns(DeprecationWarning, match=rf"^{re.escape(old)} is deprecated; use {re.escape(new)}$") as rec:
        mod = importlib.import_module(old)
        public = getattr(target, "__all__", None) or [n for n in vars(target) if not n.startswith("_")]
        assert all(getattr(mod, n) is getattr(target, n) for n in public)
        assert getattr(mod, name) is getattr(target, name) and mod.__all__ == list(public)
        assert dir(mod) == sorted(public)
        star = {}
        exec(f"from {old} import *", star)  # noqa: S102
        assert {k: v for k, v in star.items() if k != "__builtins__"} == {n: getattr(target, n) for n in public}
        assert importlib.import_module(old) is mod
    assert len(_own(rec, old)) == 1  # once, at the first import
    for missing in ("no_such_name", "_private", "__path__"):
        with pytest.raises(AttributeError, match=rf"module '{re.escape(old)}' has no attribute '{missing}'"):
            getattr(mod, missing)


@pytest.mark.parametrize("old, new, name, _", MOVED)
def test_the_warning_points_at_the_users_import(old, new, name, _, first_import):
    namespace = {}
    with pytest.warns(DeprecationWarning, match=re.escape(new)) as rec:
        exec(compile(f"from {old} import {name}", "users_script.py", "exec"), namespace)  # noqa: S102
    assert namespace[name] is getattr(importlib.import_module(new), name)
    assert [w.filename for w in _own(rec, old)] == ["users_script.py"]


@pytest.mark.parametrize("old, new, name, build", MOVED)
def test_an_object_pickled_under_the_old_path_unpickles_to_the_new_class(old, new, name, build, first_import,
                                                                          monkeypatch):
    """Pickled when the class lived at ``old`` (its ``__module__`` then), the pickle names ``old`` and loads the
    class itself, in an interpreter that had not imported ``old``."""
    obj = getattr(importlib.import_module(new), name)
    with monkeypatch.context() as m, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        m.setattr(obj, "__module__", old)
        data = pickle.dumps([obj, obj() if build else None])
    assert old.encode() in data and new.encode() not in data
    _forget(old)
    with pytest.warns(DeprecationWarning, match=re.escape(new)):
        cls, instance = pickle.loads(data)
    assert cls is obj
    assert instance is None or type(instance) is obj


def test_each_type_a_model_file_holds_from_a_moved_module_is_mapped_from_its_old_path():
    """A saved model may name a trusted type of a moved module by the module's old path (it was saved before the
    move): :data:`rvdiag.registry.MOVED_TYPES` maps each such old name to the type now."""
    expected = {old + t[len(new):]: t for old, new, _, _ in MOVED for t in TRUSTED_TYPES if t.startswith(new + ".")}
    assert expected == {k: v for k, v in MOVED_TYPES.items() if k.rsplit(".", 1)[0] in OLD_PATHS}
    assert "rvdiag.features.cnn.CNNFeatures" in expected  # the feature set "cnn" of classical pipelines


@pytest.mark.parametrize("old, new", sorted(MOVED_TYPES.items()))
def test_a_model_file_that_names_a_moved_type_loads_the_new_type(old, new, tmp_path):
    """A ``model.skops`` that names a type by its module's old path (as models saved before the move do) loads
    through :data:`rvdiag.registry.MOVED_TYPES`, without the deprecated alias: the old name is not trusted."""
    import skops.io as sio
    from conftest import as_saved_before_a_move

    from rvdiag.models.pipelines import load_classical, save_classical

    old_module, new_module = old.rsplit(".", 1)[0], new.rsplit(".", 1)[0]
    cls = getattr(importlib.import_module(new_module), new.rsplit(".", 1)[1])
    save_classical(cls(), tmp_path / "m", {"classes": ["T1", "T2"], "input_length": 1})
    as_saved_before_a_move(tmp_path / "m", new_module, old_module)
    data = (tmp_path / "m" / "model.skops").read_bytes()
    assert old in sio.get_untrusted_types(data=data) and old not in TRUSTED_TYPES and new in TRUSTED_TYPES
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        assert type(load_classical(tmp_path / "m")) is cls
    assert not _own(rec, old_module)


@pytest.mark.parametrize("old, new, name, _", MOVED)
def test_importing_an_old_path_does_not_import_the_new_module(old, new, name, _, first_import, monkeypatch):
    """The new module is imported at the first name looked up, not with the old path.  The old path's file imports
    only :mod:`rvdiag.deprecation` (layer 0; see the test below), so importing ``rvdiag.features.cnn`` loads
    nothing of the models layer, nor ``rvdiag.models.monitoring`` anything of the monitoring layer: the aliases
    keep the layering of tests/test_import_layers.py."""
    monkeypatch.setitem(sys.modules, new, None)  # any import of the new module fails from here on
    with pytest.warns(DeprecationWarning, match=re.escape(new)):
        mod = importlib.import_module(old)
    with pytest.raises(ImportError, match=re.escape(new)):
        getattr(mod, name)


def _calls_moved_module(path):
    text = path.read_text()
    return "moved_module(" in text and any(isinstance(n, ast.Call) and getattr(n.func, "id", None) == "moved_module"
                                           for n in ast.walk(ast.parse(text)))


def test_each_old_path_is_a_thin_alias_and_every_alias_is_tested():
    aliases = {".".join(f.relative_to(SRC.parent).with_suffix("").parts) for f in SRC.rglob("*.py")
               if _calls_moved_module(f)}
    assert aliases == set(OLD_PATHS)
    for old, new, _, _ in MOVED:
        body = ast.parse((SRC.parent / (old.replace(".", "/") + ".py")).read_text()).body
        assert [type(n) for n in body] == [ast.Expr, ast.ImportFrom, ast.Assign]
        assert ast.unparse(body[1]) == "from rvdiag.deprecation import moved_module"
        assert ast.unparse(body[2]) == f"__getattr__, __dir__ = moved_module(__name__, {new!r})"


def test_nothing_but_this_test_imports_an_old_path():
    here = Path(__file__).resolve()
    parents = "|".join(sorted({re.escape(old.rsplit(".", 1)[0]) for old in OLD_PATHS}))
    bad = [f"{where}: {name}" for f in python_files(parents) if f != here for where, name in imported_names(f)
           if any(name == old or name.startswith(old + ".") for old in OLD_PATHS)]
    assert not bad, "\n".join(bad)
