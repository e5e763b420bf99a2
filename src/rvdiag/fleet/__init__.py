"""PLACEHOLDER until branch ``fleet`` lands: the names of INTERFACES.md B that ``rvdiag.fleet.api`` imports.

Replaced wholesale by the fleet branch's package at merge (take theirs)."""

from __future__ import annotations

from dataclasses import dataclass

from rvdiag.errors import RvdiagError


class FleetError(RvdiagError):
    """A fleet operation refused (unknown joint, bad record, newer schema...)."""


class AuthError(FleetError):
    """A missing, unknown or read-only token for the operation asked."""


@dataclass(frozen=True)
class Reading:
    """How to read a joint's record files."""

    channel: str | None = None
    fs: float | None = None
    angle_channel: str | None = None
    output_speed: float | None = None
    load: float | None = None
    meta_regex: str | None = None
    time_regex: str | None = None


__all__ = ["AuthError", "FleetError", "Reading"]
