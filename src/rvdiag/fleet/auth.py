"""API tokens of the fleet: created at random, shown once, stored hashed.

A token is 32 random bytes (:func:`secrets.token_urlsafe`, 43 characters); the store keeps only its SHA-256, so a
copy of the database gives no token away.  A token is read-write or read-only; writing (ingest, acknowledge,
maintenance) needs a read-write one (:func:`check`)."""

from __future__ import annotations

import hashlib
import hmac
import secrets
from datetime import datetime, timezone

from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from rvdiag.errors import AuthError, FleetError
from rvdiag.fleet.db import Token


def token_hash(token: str) -> str:
    """The SHA-256 (hex) that the store keeps of ``token``."""
    return hashlib.sha256(token.encode("utf-8")).hexdigest()


def create(session, name: str, read_only: bool) -> str:
    """Store a new token named ``name``; returns the token (the only time it is seen)."""
    name = str(name).strip()
    if not name or len(name) > 200:
        raise FleetError("a token needs a name of 1-200 characters")
    token = secrets.token_urlsafe(32)
    session.add(Token(name=name, hash=token_hash(token), read_only=bool(read_only),
                      created=datetime.now(timezone.utc)))
    try:
        session.flush()
    except IntegrityError:
        session.rollback()
        raise FleetError(f"a token named {name!r} exists already; choose another name") from None
    return token


def check(session, token: str | None, write: bool) -> str:
    """The name of ``token``; :class:`AuthError` when it is missing or unknown (401), or read-only for a write
    (403)."""
    if not token:
        raise AuthError("a token is needed: send 'Authorization: Bearer TOKEN' (create one with 'rvdiag fleet token "
                        "create')", 401)
    digest = token_hash(token)
    row = session.scalar(select(Token).where(Token.hash == digest))
    if row is None or not hmac.compare_digest(row.hash, digest):
        raise AuthError("unknown token", 401)
    if write and row.read_only:
        raise AuthError(f"the token {row.name!r} is read-only; writing needs a read-write token", 403)
    return row.name
