#!/bin/sh
# Runs the command (make test's pytest) in a new network namespace with only the loopback interface up, when
# this machine can make one (root, unshare and ip): whatever a test starts then listens and talks on the
# loopback only, Ray included (it listens on every interface). Otherwise the command runs as it is, and the
# tests that would listen beyond the loopback skip, saying why (tests/conftest.py).
if [ "$(id -u)" = 0 ] && command -v unshare >/dev/null 2>&1 && command -v ip >/dev/null 2>&1 \
    && unshare --net true 2>/dev/null; then
    exec unshare --net sh -c 'ip link set lo up && exec "$@"' sh "$@"
fi
exec "$@"
