#!/usr/bin/env bash
# A room of 100 players: serves bench/scenes/crowd.json (1,000 bodies, 10 sensors) as room
# "crowd", runs 100 load clients against it for 30 s (each hears the players, subscribes to
# every event and sends a command a second), then prints the room's tick figures from
# /metrics and the load's totals. Extra arguments go to the server, e.g. the same room
# without its sensors: bench/crowd_room.sh 8090 --set 'crowd:sensors=[]'
# Usage: bench/crowd_room.sh PORT [server arguments...]   (after script/build release)
set -euo pipefail
cd "$(dirname "$0")/.."
port=$1
shift
build/release/server/kugel-server --port "$port" --room crowd=bench/scenes/crowd.json --log-level warn "$@" &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null || true' EXIT
sleep 2
report=$(mktemp)
build/release/client/kugel-client load --url "ws://127.0.0.1:$port/ws/crowd" --clients 100 --duration 30 \
  --commands-per-second 1 --players --events >"$report" 2>&1 || true
curl -s "http://127.0.0.1:$port/metrics" |
  grep -E '^kugel_(tick_duration_seconds_(sum|count)|ticks_behind_total|late_ticks_total|tick_lateness_max_seconds|events_(sent|dropped)_total)\{'
grep -E '^server|^ *total|^events|^connections' "$report"
rm -f "$report"
