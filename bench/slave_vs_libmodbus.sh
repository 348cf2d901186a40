#!/usr/bin/env bash
# Requests per second over TCP loopback: `mbscope slave` against libmodbus's own server, driven by the same
# libmodbus clients (bench/slave_load.c), one client and 16 concurrent clients, side by side in one run.
# Also the slave's resident memory before and after the load (it must stay flat).
#
#   bench/slave_vs_libmodbus.sh [BUILD_DIR] [SECONDS]     (default build/release, 5 s per measurement)
set -euo pipefail
case "${1:-}" in -h|--help) sed -n '2,/^set /{/^set /d;s/^# \{0,1\}//;p}' "$0"; exit 0 ;; esac
build=${1:-build/release}
seconds=${2:-5}
mbscope="$build/cli/mbscope"
for b in "$mbscope" "$build/bench/libmodbus_server" "$build/bench/slave_load"; do
  [ -x "$b" ] || { echo "slave_vs_libmodbus: $b not built (cmake --build $build)" >&2; exit 2; }
done

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

start() {  # start COMMAND...; sets $port and $pid from the first stdout line (tcp://HOST:PORT)
  local out
  out=$(mktemp)
  "$@" >"$out" 2>/dev/null &
  pid=$!
  pids+=("$pid")
  for _ in $(seq 100); do [ -s "$out" ] && break; sleep 0.05; done
  port=$(head -1 "$out" | sed 's/.*://')
  rm -f "$out"
  [ -n "$port" ] || { echo "slave_vs_libmodbus: $1 did not start" >&2; exit 2; }
}
rss_kib() { awk '/^VmRSS/ {print $2}' "/proc/$1/status"; }

start "$mbscope" slave --profile modbus --listen tcp://127.0.0.1:0 --quiet
slave_port=$port slave_pid=$pid
start "$build/bench/libmodbus_server" 0
lib_port=$port

rss_before=$(rss_kib "$slave_pid")
printf '%-10s %14s %14s %8s\n' clients "mbscope req/s" "libmodbus req/s" ratio
for clients in 1 16; do
  # Alternate the two servers so drift on the machine (other load, frequency) hits both alike.
  read -r s_req s_err < <("$build/bench/slave_load" 127.0.0.1 "$slave_port" "$clients" "$seconds")
  read -r l_req l_err < <("$build/bench/slave_load" 127.0.0.1 "$lib_port" "$clients" "$seconds")
  [ "$s_err" = 0 ] && [ "$l_err" = 0 ] || echo "slave_vs_libmodbus: errors: mbscope $s_err, libmodbus $l_err" >&2
  awk -v c="$clients" -v s="$s_req" -v l="$l_req" -v t="$seconds" \
    'BEGIN { printf "%-10s %14.0f %14.0f %8.2f\n", c, s / t, l / t, s / l }'
done
rss_after=$(rss_kib "$slave_pid")
echo "mbscope slave resident memory: ${rss_before} KiB before the load, ${rss_after} KiB after"
