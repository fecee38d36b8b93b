#!/bin/sh
# Runs a command in a network namespace of its own where the machine allows one (only a
# loopback interface exists there, so no DDS packet can leave the machine), else as it is;
# the test's DDS configurations keep every participant on 127.0.0.1 either way.
if unshare -rn true 2>/dev/null && command -v ip >/dev/null 2>&1; then
  exec unshare -rn sh -c 'ip link set lo up multicast on && MOBMAP_NETNS=1 exec "$@"' sh "$@"
fi
exec "$@"
