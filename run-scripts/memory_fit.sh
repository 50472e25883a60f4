#!/usr/bin/env bash
# Peak memory per rank against mesh size, and a linear fit of it, for sizing cluster jobs
# (run-scripts/slurm/contact-par.sbatch quotes the result).
#
#   bash run-scripts/memory_fit.sh                              # block levels 3 4 5 on 1 and 2 ranks
#   bash run-scripts/memory_fit.sh --levels "3 4 5 6" --ranks "1 2 4" --out DIR
#
# One run per (level, ranks), 1 thread per rank (memory does not depend on the thread
# count beyond a few MB of stacks). Peak memory is each rank's VmHWM as reported in
# summary.json ("per_subdomain"[].peak_memory_bytes; one subdomain per rank here). Writes DIR/memory.csv (one row per rank
# of every run) and DIR/memory.md (the table and the fits), and prints memory.md.
#
# Options: --case NAME (default block), --levels "L ..." (default "3 4 5"),
# --ranks "P ..." (default "1 2"), --out DIR (default memory-out), --bin PATH,
# --no-run (only redo the table and the fits from DIR/runs).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
CASE=block
LEVELS="3 4 5"
RANKS="1 2"
OUT=memory-out
BIN="$ROOT/target/release/contact-par"
RUN=1
die() { echo "memory_fit.sh: $*" >&2; exit 2; }
while [[ $# -gt 0 ]]; do
  [[ $# -ge 2 || $1 == -h || $1 == --help || $1 == --no-run ]] || die "$1 needs a value"
  case "$1" in
    --case) CASE="$2"; shift 2 ;;
    --levels) LEVELS="$2"; shift 2 ;;
    --ranks) RANKS="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --bin) BIN="$2"; shift 2 ;;
    --no-run) RUN=0; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
[[ $RUN == 0 || -x "$BIN" ]] || die "$BIN is not an executable; build with cargo build --release or pass --bin"
if [[ $(id -u) == 0 ]]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
export OMPI_MCA_rmaps_base_oversubscribe=1
mkdir -p "$OUT/runs"
OUT="$(cd "$OUT" && pwd)"
for level in $LEVELS; do
  [[ $RUN == 1 ]] || break
  for p in $RANKS; do
    dir="$OUT/runs/L${level}_P${p}"
    rm -rf "$dir"
    echo "level $level, $p rank(s)"
    mpirun -n "$p" --oversubscribe --bind-to none "$BIN" --builtin "$CASE" --level "$level" \
      --threads 1 --quiet --out "$dir" || [[ $? == 3 ]] || die "the run failed (level $level, $p ranks)"
    rm -f "$dir"/*.vtu "$dir"/*.pvtu
  done
done

python3 - "$OUT" "$CASE" <<'PY'
import csv, glob, json, os, sys

out, case = sys.argv[1], sys.argv[2]
rows = []
for path in sorted(glob.glob(os.path.join(out, "runs", "*", "summary.json"))):
    with open(path) as f:
        s = json.load(f)
    level = int(os.path.basename(os.path.dirname(path)).split("_")[0][1:])
    for r in s.get("per_subdomain", s.get("per_rank")):
        rows.append({
            "level": level, "nodes": s["nodes"], "ranks": s["ranks"], "rank": r["rank"],
            "rank_nodes": r["nodes"], "interface_dofs": s.get("interface_dofs", 0),
            "rank_boundary_dofs": r["boundary_dofs"],
            "factor_nnz": r["factor_nnz"], "peak_memory_bytes": r["peak_memory_bytes"],
        })
rows.sort(key=lambda r: (r["level"], r["ranks"], r["rank"]))
with open(os.path.join(out, "memory.csv"), "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)


def fit(xs, ys):
    """Least squares y = a + b x."""
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    if n < 2 or sxx == 0:
        return 0.0, my / mx if mx else 0.0
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return my - b * mx, b


MB = 2**20
L = [f"Peak memory per rank, built-in case `{case}`, 1 thread per rank (VmHWM from summary.json).",
     "", "| level | nodes | ranks | n_G | rank 0 MB | other ranks, max MB | bytes/node (largest other rank, or rank 0 alone) |",
     "| --- | --- | --- | --- | --- | --- | --- |"]
for (level, ranks) in sorted({(r["level"], r["ranks"]) for r in rows}):
    run = [r for r in rows if r["level"] == level and r["ranks"] == ranks]
    root = next(r for r in run if r["rank"] == 0)
    others = [r for r in run if r["rank"] > 0]
    big = max(others, key=lambda r: r["peak_memory_bytes"]) if others else root
    L.append(f"| {level} | {root['nodes']} | {ranks} | {root['interface_dofs']} | "
             f"{root['peak_memory_bytes'] / MB:.0f} | "
             + (f"{big['peak_memory_bytes'] / MB:.0f}" if others else "-")
             + f" | {big['peak_memory_bytes'] / big['rank_nodes']:.0f} |")
L += ["", "Every rank:", "",
      "| level | nodes | ranks | rank | nodes on rank | boundary dofs b_s | factor nnz | peak MB | bytes/node on rank |",
      "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
for r in rows:
    L.append(f"| {r['level']} | {r['nodes']} | {r['ranks']} | {r['rank']} | {r['rank_nodes']} | "
             f"{r['rank_boundary_dofs']} | {r['factor_nnz']} | {r['peak_memory_bytes'] / MB:.0f} | "
             f"{r['peak_memory_bytes'] / r['rank_nodes']:.0f} |")
L.append("")
groups = {
    "1 rank (x = nodes)": [(r["nodes"], r["peak_memory_bytes"]) for r in rows if r["ranks"] == 1],
    "other ranks (x = nodes on the rank)":
        [(r["rank_nodes"], r["peak_memory_bytes"]) for r in rows if r["ranks"] > 1 and r["rank"] > 0],
}
# What rank 0 holds beyond a subdomain like the others': the whole mesh while it reads,
# partitions and distributes it, and the dense interface system on the interface dofs
# (n_G = "interface_dofs"). Its peak minus the mean peak of the other ranks of the same
# run is fitted as x N + y 8 n_G^2 (N nodes of the whole mesh; y counts the dense copies).
# (Every rank also holds its dense trailing factor block, 8 b_s^2 bytes, inside its
# per-node figure.)
extra = []
for (level, ranks) in sorted({(r["level"], r["ranks"]) for r in rows if r["ranks"] > 1}):
    run = [r for r in rows if r["level"] == level and r["ranks"] == ranks]
    others = [r["peak_memory_bytes"] for r in run if r["rank"] > 0]
    root = next(r for r in run if r["rank"] == 0)
    extra.append((root["nodes"], 8.0 * root["interface_dofs"] ** 2,
                  root["peak_memory_bytes"] - sum(others) / len(others)))
L.append("Least-squares fits peak = a + b x:")
L.append("")
for name, pts in groups.items():
    if len(pts) < 2:
        continue
    a, b = fit([p[0] for p in pts], [p[1] for p in pts])
    L.append(f"* {name}: a = {a / MB:.0f} MB, b = {b:.0f} bytes per node ({len(pts)} points)")
if len(extra) >= 2:
    # Least squares without intercept on two regressors: the 2 x 2 normal equations.
    s11 = sum(n * n for n, _, _ in extra)
    s12 = sum(n * d for n, d, _ in extra)
    s22 = sum(d * d for _, d, _ in extra)
    t1 = sum(n * e for n, _, e in extra)
    t2 = sum(d * e for _, d, e in extra)
    det = s11 * s22 - s12 * s12
    if abs(det) > 1e-12 * s11 * s22:
        x = (t1 * s22 - t2 * s12) / det
        y = (s11 * t2 - s12 * t1) / det
        L.append(f"* rank 0 minus the mean of the other ranks of its run: {x:.0f} bytes per node "
                 f"of the whole mesh + {y:.2f} x 8 n_G^2 bytes (n_G = interface dofs; "
                 f"{len(extra)} runs):")
        L.append("")
        L.append("  | nodes | ranks | n_G | rank 0 extra MB | fit MB |")
        L.append("  | --- | --- | --- | --- | --- |")
        runs = sorted({(r["level"], r["ranks"]) for r in rows if r["ranks"] > 1})
        for (level, ranks), (n, d, e) in zip(runs, extra):
            nb = round((d / 8.0) ** 0.5)
            L.append(f"  | {n} | {ranks} | {nb} | {e / MB:.0f} | {(x * n + y * d) / MB:.0f} |")
with open(os.path.join(out, "memory.md"), "w") as f:
    f.write("\n".join(L) + "\n")
print("\n".join(L))
PY
