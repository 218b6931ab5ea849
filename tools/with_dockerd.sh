#!/usr/bin/env bash
# Run a command with a Docker engine: the one already running, else a dockerd started here for
# the command's duration (installed from Debian first when missing and we are root). The engine
# runs without iptables and bridge (containers use --network host), so it changes nothing in the
# machine's networking. When no engine can start, the command runs anyway and the docker tests
# skip, saying why.
set -uo pipefail
if docker info >/dev/null 2>&1; then
    exec "$@"
fi
if ! command -v dockerd >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "with_dockerd: installing docker.io and debootstrap" >&2
    apt-get update -qq >/dev/null 2>&1
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq docker.io debootstrap >/dev/null 2>&1
fi
pid=""
if command -v dockerd >/dev/null 2>&1; then
    state="${MOMLOC_DOCKER_STATE:-/tmp/momloc-dockerd}"  # kept: the next run reuses the images
    mkdir -p "$state"
    dockerd --iptables=false --ip6tables=false --bridge=none --data-root "$state/root" \
        --exec-root "$state/exec" --pidfile "$state/dockerd.pid" -H "unix://$state/docker.sock" \
        >"$state/dockerd.log" 2>&1 &
    pid=$!
    export DOCKER_HOST="unix://$state/docker.sock"
    for _ in $(seq 60); do
        docker info >/dev/null 2>&1 && break
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.5
    done
fi
"$@"
rc=$?
if [ -n "$pid" ]; then
    kill "$pid" 2>/dev/null
    wait "$pid" 2>/dev/null
fi
exit "$rc"
