#!/usr/bin/env bash
# A two-node Ray cluster on loopback, for trying `deepphy run --address` on one machine.
#   cluster/local-cluster.sh start   # head on 127.0.0.2, a worker node on 127.0.0.3
#   cluster/local-cluster.sh stop    # stops only this cluster's processes (never `ray stop`)
# Prints the address to pass to `deepphy run --address`. On a real cluster, run the same
# `ray start` lines on each machine with its own address instead of 127.0.0.x.
set -euo pipefail
RAY=${RAY:-$(dirname "$0")/../.venv/bin/ray}
DIR=${DEEPPHY_CLUSTER_DIR:-/tmp/deepphy-cluster}
PORT=${DEEPPHY_CLUSTER_PORT:-6390}
HEAD_CPUS=${HEAD_CPUS:-1}
WORKER_CPUS=${WORKER_CPUS:-1}
export RAY_USAGE_STATS_ENABLED=0
# Token auth is Ray's default; the driver and every node must share the token.
export RAY_AUTH_MODE=${RAY_AUTH_MODE:-token}

case "${1:-}" in
start)
  mkdir -p "$DIR"
  "$RAY" start --head --node-ip-address=127.0.0.2 --port="$PORT" --num-cpus="$HEAD_CPUS" \
    --include-dashboard=false --temp-dir="$DIR" --disable-usage-stats >"$DIR/head.log" 2>&1
  "$RAY" start --address="127.0.0.2:$PORT" --node-ip-address=127.0.0.3 --num-cpus="$WORKER_CPUS" \
    --resources='{"physics": 1}' --disable-usage-stats >"$DIR/worker.log" 2>&1
  echo "127.0.0.2:$PORT"
  ;;
stop)
  # Every process that names this cluster's directory or its head's address (the Ray
  # client server, left behind by `ray start`), and all their descendants: Ray's agents
  # rename themselves (neither on their command line) and ignore SIGTERM.
  family() {
    local all frontier next p
    all=$(pgrep -f -- "$DIR|--address=127\.0\.0\.2:$PORT( |\$)" || true)
    frontier=$all
    while [ -n "$frontier" ]; do
      next=""
      for p in $frontier; do next="$next $(pgrep -P "$p" || true)"; done
      frontier=$(echo $next)
      all="$all $frontier"
    done
    echo $all
  }
  pids=$(family)
  [ -n "$pids" ] && kill $pids 2>/dev/null || true
  sleep 2
  pids="$pids $(family)"
  [ -n "${pids// /}" ] && kill -9 $pids 2>/dev/null || true
  echo stopped
  ;;
*)
  echo "usage: $0 start|stop" >&2
  exit 2
  ;;
esac
