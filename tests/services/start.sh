#!/usr/bin/env bash
# Starts what the tests need beyond Python: PostgreSQL 15 (the fleet store's PostgreSQL tests) and Debian's
# chromium (the dashboard's browser test).  Called by `make test` and `.ci/run`; best effort on a developer's
# machine (a test whose service is missing skips there), but CI (CI=true) must have both, and the tests that need
# them fail there instead of skipping.  Prints the environment to export: RVDIAG_TEST_POSTGRES, RVDIAG_TEST_CHROMIUM.
set -uo pipefail
log() { echo "services: $*" >&2; }

if [ "$(id -u)" = 0 ] && ! command -v chromium >/dev/null 2>&1 && command -v apt-get >/dev/null 2>&1; then
    log "installing Debian's chromium"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium) >/dev/null 2>&1 \
        || log "chromium could not be installed"
fi
if command -v chromium >/dev/null 2>&1; then
    echo "export RVDIAG_TEST_CHROMIUM=$(command -v chromium)"
fi

if command -v pg_ctlcluster >/dev/null 2>&1 && [ "$(id -u)" = 0 ]; then
    ver=$(ls /etc/postgresql 2>/dev/null | sort -n | tail -1)
    if [ -n "$ver" ]; then
        pg_ctlcluster "$ver" main start >/dev/null 2>&1 || true
        for _ in $(seq 1 30); do
            su postgres -c "psql -qAtc 'select 1'" >/dev/null 2>&1 && break
            sleep 0.5
        done
        su postgres -c "psql -qAtc \"select 1 from pg_roles where rolname='rvdiag_test'\"" 2>/dev/null | grep -q 1 \
            || su postgres -c "psql -qc \"create role rvdiag_test login createdb password 'rvdiag_test'\"" >/dev/null 2>&1
        su postgres -c "psql -qAtc \"select 1 from pg_database where datname='rvdiag_test'\"" 2>/dev/null | grep -q 1 \
            || su postgres -c "createdb -O rvdiag_test rvdiag_test" >/dev/null 2>&1
        if su postgres -c "psql -qAtc \"select 1 from pg_database where datname='rvdiag_test'\"" 2>/dev/null | grep -q 1; then
            port=$(su postgres -c "psql -qAtc 'show port'" 2>/dev/null)
            echo "export RVDIAG_TEST_POSTGRES=postgresql+psycopg://rvdiag_test:rvdiag_test@127.0.0.1:${port:-5432}/rvdiag_test"
        else
            log "PostgreSQL could not be started"
        fi
    fi
fi
