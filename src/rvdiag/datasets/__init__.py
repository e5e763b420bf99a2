"""Sample stores (Zarr): the one format shared by simulated libraries and measured datasets."""

from rvdiag.datasets.store import (PAIRED_COLUMNS, ROLES, SampleStore, Samples, StoreBuilder, config_hash,
                                   parse_where, write_store)
from rvdiag.deprecation import renamed_names

__all__ = ["PAIRED_COLUMNS", "ROLES", "SampleStore", "Samples", "StoreBuilder", "config_hash",
           "parse_where", "write_store"]

#: old names, served with a DeprecationWarning naming the new one
__getattr__ = renamed_names(__name__, {"parse_condition": "parse_where"})
