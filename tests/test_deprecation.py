"""Old public names renamed in the refactors keep working, each with a DeprecationWarning naming the new one."""

import importlib

import pytest

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
