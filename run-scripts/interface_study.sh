#!/usr/bin/env bash
# The interface system on the first rank (--interface rank0) against MUMPS across the
# ranks (--interface mumps): oversubscribed runs at several rank counts, one thread and
# one subdomain per rank, with per-rank work and memory from summary.json.
#   bash run-scripts/interface_study.sh [--case hertz] [--level 4] [--ranks "4 8 16 32"] [--out DIR]
# Writes OUT/interface.csv and prints it as a table. Flops and memory do not depend on
# the machine's load; the times do (on an oversubscribed machine they are the sum of the
# ranks' work more than its critical path).
set -euo pipefail
cd "$(dirname "$0")/.."
CASE=hertz
LEVEL=4
RANKS="4 8 16 32"
OUT=interface-study
while [ $# -gt 0 ]; do
  case "$1" in
    --case) CASE="$2"; shift 2 ;;
    --level) LEVEL="$2"; shift 2 ;;
    --ranks) RANKS="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    *) echo "interface_study.sh: unknown option $1 (expected --case, --level, --ranks or --out)" >&2; exit 2 ;;
  esac
done
BIN=$(realpath target/release/contact-par)
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1 PMIX_MCA_gds=hash
echo "ranks,interface,interface_dofs,sweeps,interface_gflop_total,interface_gflop_max_rank,subdomain_gflop_max,rank0_peak_mb,median_peak_mb,max_peak_mb,loop_s,total_s" > "$OUT/interface.csv"
for p in $RANKS; do
  for itf in rank0 mumps; do
    run="$OUT/run-$p-$itf"
    mpirun -n "$p" "$BIN" --builtin "$CASE" --level "$LEVEL" --threads 1 \
      --subdomains-per-rank 1 --interface "$itf" --out "$run" --quiet
    python3 - "$run/summary.json" "$p" "$itf" >> "$OUT/interface.csv" <<'PY'
import json, statistics, sys
s = json.load(open(sys.argv[1]))
per = s["per_subdomain"]
peaks = [b / 1e6 for b in s["peak_memory_bytes_per_rank"]]
t = s["timings_s"]
print(",".join(str(v) for v in [
    sys.argv[2], sys.argv[3], s["interface_dofs"], s["iterations"],
    round(s["interface_gflop"], 4), round(max(p["interface_gflop"] for p in per), 4),
    round(max(p["factor_gflop"] for p in per), 4), round(peaks[0]), round(statistics.median(peaks)),
    round(max(peaks)), round(t["loop"], 3), round(t["total"], 3)]))
PY
    rm -rf "$run"
  done
done
column -s, -t "$OUT/interface.csv"
