"""Reducer parameter sets: the built-in RV-20E (``rv20e.toml``), the typed schema and derived masses."""

from rvdiag.params.derived import Body, BodyProperties, body_properties
from rvdiag.params.schema import ReducerParams

__all__ = ["Body", "BodyProperties", "ReducerParams", "body_properties"]
