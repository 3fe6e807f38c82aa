#!/usr/bin/env bash
# The live viewer's cost: `mcslam run` on one sequence without the viewer, with --viewer and one
# client that reads everything, and with --viewer and one client that never reads, interleaved,
# N runs each; prints each run's frames_per_second and the medians' ratios.
# Usage: scripts/viewer_fps.sh SEQ_DIR OUT_DIR [N] [-- extra mcslam run options]
# The clients are small Python WebSocket clients (no browser: its rendering would compete for
# the CPU with SLAM on the same machine, which is not the viewer's cost).
set -euo pipefail
seq_dir="$1"; out="$2"; n="${3:-3}"
shift $(( $# >= 3 ? 3 : $# )); [ "${1:-}" = "--" ] && shift
exe="$(cd "$(dirname "$0")/.." && pwd)/build/mcslam"
port=18765
mkdir -p "$out"
client() {  # client PORT read|stall: connects when the server is up, until it closes
  exec python3 - "$@" << 'PY'
import socket, sys, time
port, mode = int(sys.argv[1]), sys.argv[2]
for _ in range(600):
    try:
        s = socket.create_connection(("127.0.0.1", port)); break
    except OSError:
        time.sleep(0.1)
else:
    sys.exit("no server")
# The server answers only a Host naming this machine (docs/viewer.md).
s.sendall(f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n".encode() +
          b"Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
          b"Sec-WebSocket-Version: 13\r\n\r\n")
if mode == "stall":
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    while True:
        time.sleep(1)
# Reads everything; says something every 5 s, as a browser answers pings (the server closes a
# connection it hears nothing from for 30 s).
s.settimeout(1.0)
total, last = 0, time.time()
while True:
    if time.time() - last > 5:
        s.sendall(bytes([0x81, 0x80 | 2, 0, 0, 0, 0]) + b"{}")  # a masked text frame: {}
        last = time.time()
    try:
        data = s.recv(1 << 16)
    except socket.timeout:
        continue
    except OSError:
        break
    if not data: break
    total += len(data)
print(f"client read {total / 1e6:.1f} MB", file=sys.stderr)
PY
}
run() {  # run NAME MODE K
  local name="$1" mode="$2" k="$3" dir="$out/$1_$3" cpid=""
  local args=()
  if [ "$mode" != none ]; then
    args=(--viewer "$port")
    client "$port" "$mode" & cpid=$!
  fi
  "$exe" run "$seq_dir" --output "$dir" -q "${args[@]}" "${EXTRA[@]}" 2> "$dir.err" || { cat "$dir.err"; exit 1; }
  [ -n "$cpid" ] && { kill "$cpid" 2> /dev/null || true; wait "$cpid" 2> /dev/null || true; }
  python3 -c "import json,sys; s=json.load(open('$dir/summary.json')); print('$name', $k, round(s['frames_per_second'], 2), s.get('viewer', {}).get('clients_dropped', '-'))"
}
EXTRA=("$@")
# ORDER: the order of the three runs within a round (to check for position effects).
order="${ORDER:-none viewer stalled}"
for k in $(seq 1 "$n"); do
  for m in $order; do
    case "$m" in
      none) run none none "$k" ;;
      viewer) run viewer read "$k" ;;
      stalled) run stalled stall "$k" ;;
    esac
  done
done | tee "$out/fps.txt"
python3 - "$out/fps.txt" << 'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
med = {m: statistics.median(float(r[2]) for r in rows if r[0] == m)
       for m in ("none", "viewer", "stalled") if any(r[0] == m for r in rows)}
names = {"viewer": "viewer + reading client", "stalled": "viewer + client that never reads"}
print(f"median fps: without {med['none']:.2f}" + "".join(
    f", {names[m]} {med[m]:.2f} (ratio {med[m] / med['none']:.3f})" for m in names if m in med))
PY
