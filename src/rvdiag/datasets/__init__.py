"""Sample stores (Zarr): the one format shared by simulated libraries and measured datasets."""

from rvdiag.datasets.store import (PAIRED_COLUMNS, ROLES, SampleStore, Samples, StoreBuilder, config_hash,
                                   parse_where, write_store)

__all__ = ["PAIRED_COLUMNS", "ROLES", "SampleStore", "Samples", "StoreBuilder", "config_hash",
           "parse_where", "write_store"]
