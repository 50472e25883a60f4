#!/usr/bin/env bash
# What a P-core machine allows a run split P ways, measured with whole processes: the
# whole case on 1 rank and on P ranks, against P jobs of 1/P the size run side by side
# (each on 1 rank) and one of them alone. The P small jobs together are what a P-rank
# run that split its work into independent pieces, with no start, interface or exchange
# of its own, could do on this machine; copies of the whole 1-rank run overstate how
# much the cores slow each other, since each touches the whole run's memory.
#
#   bash run-scripts/halves.sh --whole WHOLE.toml --part PART.toml [--ranks 2] [--runs 5]
#                              [--bin PATH] [--out DIR]
#
# PART.toml is the same problem on a mesh of 1/P the nodes, e.g. for P = 2:
#   python3 run-scripts/make_meshes.py --case block --nodes 1000000 --out W
#   python3 run-scripts/make_meshes.py --case block --nodes 499000 --out H   # about half
#   bash run-scripts/halves.sh --whole W/block.toml --part H/block.toml --out halves
# Every run is `contact-par CASE --threads 1 --quiet` under `mpirun --bind-to none`,
# timed by /usr/bin/time; the four kinds run in turn in each repetition, so that a drift
# of the machine's load spreads over all of them. Writes DIR/halves.csv (one row per run:
# wall, user and system seconds, peak KB of the largest process) and prints the medians,
# the P-rank speed-up, the bound the small jobs give, and how much they slow each other.
set -euo pipefail
cd "$(dirname "$0")/.."
WHOLE=""
PART=""
RANKS=2
RUNS=5
OUT=halves-out
BIN=target/release/contact-par
while [ $# -gt 0 ]; do
  case "$1" in
    --whole) WHOLE="$2"; shift 2 ;;
    --part) PART="$2"; shift 2 ;;
    --ranks) RANKS="$2"; shift 2 ;;
    --runs) RUNS="$2"; shift 2 ;;
    --bin) BIN="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    *) echo "halves.sh: unknown option $1 (see the head of run-scripts/halves.sh)" >&2; exit 2 ;;
  esac
done
if [ -z "$WHOLE" ] || [ -z "$PART" ]; then
  echo "halves.sh: give --whole WHOLE.toml and --part PART.toml (the same problem on 1/P the nodes)" >&2
  exit 2
fi
for f in "$WHOLE" "$PART"; do
  [ -f "$f" ] || { echo "halves.sh: $f: no such case file" >&2; exit 2; }
done
[ -x "$BIN" ] || cargo build --release
[ -x /usr/bin/time ] || { echo "halves.sh: needs /usr/bin/time (apt-get install time)" >&2; exit 2; }
mkdir -p "$OUT"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
CSV="$OUT/halves.csv"
echo "run,kind,wall_s,user_s,sys_s,peak_kb" > "$CSV"

# contact-par on N ranks, one thread each, its wall, user and system seconds and peak
# (the largest process) written to FILE.
timed() { # FILE N CASE OUT
  /usr/bin/time -f "%e %U %S %M" -o "$1" \
    mpirun -n "$2" --bind-to none "$BIN" "$3" --threads 1 --quiet --out "$4" > /dev/null
}
record() { # RUN KIND FILE
  read -r wall user sys peak < "$3"
  echo "$1,$2,$wall,$user,$sys,$peak" >> "$CSV"
}

for run in $(seq 1 "$RUNS"); do
  timed "$TMP/time" 1 "$WHOLE" "$TMP/w1"; record "$run" whole_1 "$TMP/time"
  timed "$TMP/time" "$RANKS" "$WHOLE" "$TMP/wp"; record "$run" whole_p "$TMP/time"
  # The small jobs at once: the wall from start to the last one's end, their user and
  # system seconds summed, the largest peak.
  start=$(date +%s.%N)
  pids=()
  for k in $(seq 1 "$RANKS"); do
    timed "$TMP/time.$k" 1 "$PART" "$TMP/p$k" &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p"; done
  end=$(date +%s.%N)
  awk -v run="$run" -v start="$start" -v end="$end" \
    '{ u += $2; s += $3; if ($4 > m) m = $4 }
     END { printf "%s,parts_side_by_side,%.3f,%.2f,%.2f,%d\n", run, end - start, u, s, m }' \
    "$TMP"/time.* >> "$CSV"
  timed "$TMP/time" 1 "$PART" "$TMP/pa"; record "$run" part_alone "$TMP/time"
done

python3 - "$CSV" "$RANKS" <<'EOF'
import csv, statistics, sys
path, p = sys.argv[1], int(sys.argv[2])
rows = list(csv.DictReader(open(path)))
def med(kind, col="wall_s"):
    return statistics.median(float(r[col]) for r in rows if r["kind"] == kind)
runs = sorted({r["run"] for r in rows})
wall = {(r["run"], r["kind"]): float(r["wall_s"]) for r in rows}
def paired(a, b):
    ratios = [wall[(k, a)] / wall[(k, b)] for k in runs]
    return statistics.median(ratios), min(ratios), max(ratios)
print(f"{'kind':20s} {'wall s':>8s} {'user s':>8s} {'sys s':>8s}   (medians of {len(runs)} runs)")
for kind in ["whole_1", "whole_p", "parts_side_by_side", "part_alone"]:
    print(f"{kind:20s} {med(kind):8.2f} {med(kind, 'user_s'):8.2f} {med(kind, 'sys_s'):8.2f}")
s = paired("whole_1", "whole_p")
b = paired("whole_1", "parts_side_by_side")
c = paired("parts_side_by_side", "part_alone")
print(f"speed-up 1 -> {p} ranks: {s[0]:.2f} ({s[1]:.2f}-{s[2]:.2f}), paired")
print(f"bound of {p} independent jobs of 1/{p} the size: {b[0]:.2f} ({b[1]:.2f}-{b[2]:.2f})")
print(f"those jobs side by side against one alone: {c[0]:.3f} ({c[1]:.3f}-{c[2]:.3f})")
EOF
