#!/usr/bin/env bash
# Strong scaling study for the cluster-scale design: a case split once per rank count
# (contact-par split), then run from the split on P ranks, one subdomain and one thread
# each, with the default --interface (MUMPS from 16 subdomains on); per-rank figures from
# summary.json, and each answer against the P = 1 run's.
#   bash run-scripts/scale_study.sh [--case hertz] [--level 5] [--ranks "1 2 4 8 16 32 64"] [--out DIR]
# Writes OUT/scale.csv (one row per P) and OUT/summary-P.json (for run-scripts/cost_model.py),
# and prints the table. On a machine with fewer
# cores than ranks (oversubscribed) flops, memory and bytes are what a cluster would see;
# times are the sum of the ranks' work more than its critical path.
#
# Columns: ranks, interface (rank0's dense/sparse or mumps), interface_dofs, sweeps;
# rank0/median/max peak memory (MB); the largest subdomain factor and interface share
# (Gflop); critical = max over ranks of factor + interface share; critical_fraction =
# critical / the P = 1 factor's work; bytes sent per sweep (median and max rank);
# split_s (the serial split), loop_s, total_s; rel_diff: the largest difference of u_n,
# u_t, p_n, p_t from the P = 1 run over the largest of each.
set -euo pipefail
cd "$(dirname "$0")/.."
CASE=hertz
LEVEL=5
RANKS="1 2 4 8 16 32 64"
OUT=scale-study
while [ $# -gt 0 ]; do
  case "$1" in
    --case) CASE="$2"; shift 2 ;;
    --level) LEVEL="$2"; shift 2 ;;
    --ranks) RANKS="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    *) echo "scale_study.sh: unknown option $1 (expected --case, --level, --ranks or --out)" >&2; exit 2 ;;
  esac
done
BIN=$(realpath target/release/contact-par)
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1 PMIX_MCA_gds=hash
CSV="$OUT/scale.csv"
echo "ranks,interface,interface_dofs,sweeps,rank0_peak_mb,median_peak_mb,max_peak_mb,factor_gflop_max,interface_gflop_max,critical_gflop,critical_fraction,sent_kb_median,sent_kb_max,split_s,loop_s,total_s,rel_diff" > "$CSV"
REF=""
for p in $RANKS; do
  parts="$OUT/parts-$p"
  run="$OUT/run-$p"
  start=$EPOCHREALTIME
  "$BIN" split --builtin "$CASE" --level "$LEVEL" --parts "$p" --out "$parts" > /dev/null
  split_s=$(python3 -c "print($EPOCHREALTIME - $start)")
  mpirun -n "$p" "$BIN" --builtin "$CASE" --level "$LEVEL" --mesh-split "$parts" \
    --threads 1 --out "$run" --quiet
  [ -z "$REF" ] && REF="$run"
  python3 - "$run" "$REF" "$p" "$split_s" >> "$CSV" <<'PY'
import csv, json, statistics, sys
run, ref, p, split_s = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
s = json.load(open(f"{run}/summary.json"))
r1 = json.load(open(f"{ref}/summary.json"))
per = s["per_subdomain"]
peaks = [b / 1e6 for b in s["peak_memory_bytes_per_rank"]]
work = [q["factor_gflop"] + q["interface_gflop"] for q in per]
one = sum(q["factor_gflop"] for q in r1["per_subdomain"])
sent = [q["sent_bytes_per_sweep"] / 1e3 for q in per]
def rows(d):
    with open(f"{d}/contact.csv") as f:
        return {(r["x"], r["y"]): r for r in csv.DictReader(f)}
a, b = rows(run), rows(ref)
diff = 0.0
for col in ["u_n", "u_t", "p_n", "p_t"]:
    scale = max(abs(float(r[col])) for r in b.values()) or 1.0
    diff = max(diff, max(abs(float(a[k][col]) - float(b[k][col])) for k in b) / scale)
t = s["timings_s"]
print(",".join(str(v) for v in [
    p, s["interface_factor"], s["interface_dofs"], s["iterations"],
    round(peaks[0]), round(statistics.median(peaks)), round(max(peaks)),
    round(max(q["factor_gflop"] for q in per), 3), round(max(q["interface_gflop"] for q in per), 3),
    round(max(work), 3), round(max(work) / one, 4),
    round(statistics.median(sent), 1), round(max(sent), 1),
    round(split_s, 2), round(t["loop"], 2), round(t["total"], 2), f"{diff:.2e}"]))
PY
  cp "$run/summary.json" "$OUT/summary-$p.json"
  # Keep the P = 1 run as the reference; the others' files are large.
  [ "$run" != "$REF" ] && rm -rf "$run"
  rm -rf "$parts"
done
column -s, -t "$CSV"
