"""rvdiag.validation: the one home of the number checks, each failing with one message that names the value."""

import functools
import math

import numpy as np
import pytest

from rvdiag import validation as v
from rvdiag.errors import ConfigError, ParameterError


@pytest.mark.parametrize("call, error, message", [
    (lambda: v.number("1", "pit radius"), ParameterError, "pit radius must be a number, got '1'"),
    (lambda: v.number(True, "pit radius"), ParameterError, "pit radius must be a number, got True"),
    (lambda: v.number(math.nan, "pit radius"), ParameterError, "pit radius must be finite, got nan"),
    (lambda: v.positive(0.0, "pit radius", unit=" m"), ParameterError, "pit radius must be > 0, got 0.0 m"),
    (lambda: v.at_least(-1, "x", 0), ParameterError, "x must be >= 0, got -1"),
    (lambda: v.at_least(2.0, "x", 2, strict=True), ParameterError, "x must be > 2, got 2.0"),
    (lambda: v.whole_number(2.5, "teeth"), ParameterError, "teeth must be a whole number, got 2.5"),
    (lambda: v.whole_number(1.0, "teeth", minimum=3), ParameterError, "teeth must be >= 3, got 1"),
    # a key of a file: the ConfigError form, "key: expected ..."
    (lambda: v.number("x", "a.toml: [signal] hop", error=ConfigError), ConfigError,
     "a.toml: [signal] hop: expected a number, got 'x'"),
    (lambda: v.number(math.inf, "[signal] fs", error=ConfigError), ConfigError, "[signal] fs: must be finite, got inf"),
    (lambda: v.positive(-1, "[signal] fs", error=ConfigError), ConfigError, "[signal] fs: must be > 0, got -1"),
    (lambda: v.whole_number(2.5, "[split] reducers", minimum=1, error=ConfigError), ConfigError,
     "[split] reducers: expected a whole number, got 2.5"),
    (lambda: v.whole_number(math.nan, "k", error=ConfigError), ConfigError, "k: must be finite, got nan"),
    # in one phrase
    (lambda: v.finite_number(None, "jerk", 0, strict=True, type_first=True), ParameterError,
     "jerk must be a number, got None"),
    (lambda: v.finite_number("3", "J", 0), ParameterError, "J must be a finite number >= 0, got '3'"),
    (lambda: v.finite_number(0.0, "jerk", 0, strict=True), ParameterError, "jerk must be a finite number > 0, got 0.0"),
    (lambda: v.finite_number(math.nan, "J", 0), ParameterError, "J must be a finite number >= 0, got nan"),
    (lambda: v.finite_number(-1.0, "--fs", 0, strict=True, noun="a number"), ParameterError,
     "--fs must be a number > 0, got -1.0"),
    (lambda: v.integer(1, "cv", 2), ParameterError, "cv must be an integer >= 2, got 1"),
    (lambda: v.integer(2.0, "cv", 2), ParameterError, "cv must be an integer >= 2, got 2.0"),
    (lambda: v.integer(True, "cv", 0), ParameterError, "cv must be an integer >= 0, got True"),
    (lambda: v.finite_array([1.0, math.nan], "scores"), ParameterError, "scores must be finite numbers"),
    (lambda: v.finite_array(["a"], "scores"), ParameterError, "scores must be finite numbers"),
])
def test_each_failure_is_one_message_naming_the_value(call, error, message):
    with pytest.raises(error) as exc:
        call()
    assert str(exc.value) == message and type(exc.value) is error


def test_good_values_come_back_converted():
    assert v.number(np.float32(1.5), "x") == 1.5 and type(v.number(np.int64(3), "x")) is float
    assert v.positive(2, "x") == 2.0
    assert v.whole_number(3.0, "x", minimum=3) == 3 and type(v.whole_number(np.int16(3), "x")) is int
    assert v.integer(np.int64(5), "x", 1) == 5 and type(v.integer(np.int64(5), "x", 1)) is int
    assert v.finite_number(-4, "x") == -4.0 and v.at_least(0, "x", 0) == 0.0
    assert v.finite_array([[1, 2], [3, 4]], "x").tolist() == [1.0, 2.0, 3.0, 4.0]


def test_error_may_be_any_callable_making_the_exception():
    class HttpError(Exception):
        def __init__(self, status, message):
            super().__init__(message)
            self.status = status

    with pytest.raises(HttpError, match="^limit must be a finite number, got nan$") as exc:
        v.finite_number(math.nan, "limit", error=functools.partial(HttpError, 400))
    assert exc.value.status == 400
