#!/usr/bin/env bash
# A Redis Cluster of its own on loopback, for the fleet's tests (docs/fleet.md
# "Redis Cluster"): N masters (3 by default), no replicas, each with an AOF
# (appendfsync everysec) in DIR/nodeK.
#   scripts/redis_cluster.sh start DIR [N]   starts it; prints the first node's URL
#   scripts/redis_cluster.sh stop DIR        takes it down (SIGTERM, waits)
set -euo pipefail
usage() { echo "usage: $0 start DIR [MASTERS] | stop DIR" >&2; exit 2; }
[ $# -ge 2 ] || usage
cmd=$1; dir=$2

stop() {
  local f pid pids=()
  for f in "$dir"/node*/redis.pid; do
    [ -f "$f" ] || continue
    pid=$(cat "$f"); rm -f "$f"
    kill "$pid" 2>/dev/null && pids+=("$pid")
  done
  for pid in "${pids[@]}"; do
    for _ in $(seq 200); do kill -0 "$pid" 2>/dev/null || break; sleep 0.05; done
  done
}

case $cmd in
start)
  n=${3:-3}
  [[ $n =~ ^[0-9]+$ ]] && [ "$n" -ge 3 ] || { echo "$0: a cluster needs 3 or more masters, got '$n'" >&2; exit 2; }
  command -v redis-server >/dev/null || { echo "$0: redis-server not found (scripts/setup.sh installs it)" >&2; exit 2; }
  mkdir -p "$dir"
  # 2N free loopback ports at once: each node's client port and its cluster bus port.
  read -r -a ports <<<"$(python3 -c '
import socket, sys
socks = [socket.socket() for _ in range(2 * int(sys.argv[1]))]
for s in socks: s.bind(("127.0.0.1", 0))
print(" ".join(str(s.getsockname()[1]) for s in socks))
for s in socks: s.close()' "$n")"
  trap 'stop' ERR
  endpoints=()
  for ((k = 0; k < n; k++)); do
    p=${ports[$((2 * k))]}; bus=${ports[$((2 * k + 1))]}
    mkdir -p "$dir/node$k"
    redis-server --port "$p" --cluster-port "$bus" --bind 127.0.0.1 --cluster-enabled yes \
      --cluster-config-file nodes.conf --cluster-node-timeout 5000 --save "" --appendonly yes \
      --appendfsync everysec --dir "$dir/node$k" --logfile redis.log --daemonize yes \
      --pidfile "$dir/node$k/redis.pid"
    endpoints+=("127.0.0.1:$p")
  done
  for e in "${endpoints[@]}"; do
    for i in $(seq 100); do
      [ "$(redis-cli -p "${e#*:}" PING 2>/dev/null)" = PONG ] && break
      [ "$i" = 100 ] && { echo "$0: the node on $e did not start (see $dir/node*/redis.log)" >&2; false; }
      sleep 0.05
    done
  done
  redis-cli --cluster create "${endpoints[@]}" --cluster-replicas 0 --cluster-yes >"$dir/create.log" 2>&1 ||
    { echo "$0: redis-cli --cluster create failed (see $dir/create.log)" >&2; false; }
  for e in "${endpoints[@]}"; do
    for i in $(seq 200); do
      redis-cli -p "${e#*:}" CLUSTER INFO 2>/dev/null | grep -q '^cluster_state:ok' && break
      [ "$i" = 200 ] && { echo "$0: the cluster did not reach state ok on $e" >&2; false; }
      sleep 0.05
    done
  done
  echo "redis://${endpoints[0]}"
  ;;
stop) stop ;;
*) usage ;;
esac
