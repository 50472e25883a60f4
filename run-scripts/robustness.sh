#!/usr/bin/env bash
# Sweeps of the default loop (automatic r, Anderson, tol 1e-8; one thread, since the
# counts move by a few sweeps with the round-off of other thread counts) on cases unlike the
# built-in ones against the built-in cases of similar size: the unstructured Gmsh cases
# of tests/data/tolerance (made by its make_cases.py), their frictionless variants, and
# hertz, block and block_flat at levels 1-3. Iteration counts only: the result does not
# depend on the machine's load.
#   bash run-scripts/robustness.sh [--bin target/release/contact-par] [--out DIR] [--beams DIR] [--cases DIR]...
# --beams DIR also runs the clamped beams that
#   python3 tests/data/tolerance/make_cases.py --beams --out DIR
# writes (needs the Gmsh SDK: pip install gmsh); --cases DIR (repeatable) every case
# file of DIR, e.g. the held-out and slender cases of make_cases.py --heldout / --slender.
# Writes OUT/robustness.csv (case, nodes, iterations, refused, retunes, converged,
# warnings, vs_block: iterations over the built-in block's at the same size).
set -euo pipefail
# Paths given on the command line are the caller's; the defaults are the repository's.
ROOT=$(realpath "$(dirname "$0")/..")
BIN=$ROOT/target/release/contact-par
OUT=$ROOT/robustness
BEAMS=
CASES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$(realpath "$2"); shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --beams) BEAMS=$(realpath "$2"); shift 2 ;;
    --cases) CASES+=("$(realpath "$2")"); shift 2 ;;
    *) echo "robustness.sh: unknown option $1 (expected --bin FILE, --out DIR, --beams DIR or --cases DIR)" >&2; exit 2 ;;
  esac
done
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
cd "$ROOT"
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cp tests/data/tolerance/*.msh tests/data/tolerance/*.toml "$WORK/"
for c in cantilever wedge; do
  sed -e 's/^friction = .*/friction = "none"/' -e '/^coefficient/d' "$WORK/$c.toml" > "$WORK/${c}_frictionless.toml"
done
row() { # name, then the run's arguments
  local name=$1; shift
  "$BIN" "$@" --threads 1 --out "$WORK/out" --quiet > /dev/null 2>&1 || true
  python3 - "$name" "$WORK/out/summary.json" <<'PY' >> "$OUT/robustness.csv"
import json, sys
s = json.load(open(sys.argv[2]))
print(",".join(str(v) for v in [sys.argv[1], s["nodes"], s["iterations"],
      s["refused_accelerations"], s["r_retunes"], str(s["converged"]).lower(),
      len(s.get("warnings", []))]))
PY
  rm -rf "$WORK/out"
}
echo "case,nodes,iterations,refused,retunes,converged,warnings" > "$OUT/robustness.csv"
for c in cantilever cantilever_frictionless wall disc wedge wedge_frictionless; do
  row "$c" "$WORK/$c.toml"
done
if [ -n "$BEAMS" ]; then
  for f in "$BEAMS"/beam_*.toml; do row "$(basename "$f" .toml)" "$f"; done
fi
for d in "${CASES[@]}"; do
  for f in "$d"/*.toml; do row "$(basename "$d")/$(basename "$f" .toml)" "$f"; done
done
for b in hertz block block_flat; do
  for l in 1 2 3; do row "$b-$l" --builtin "$b" --level "$l"; done
done
# Each case against the built-in block at the same size (what issue 24 asks to stay
# within 2x): the block's sweeps interpolated in log(nodes) between levels 1-3, held at
# the end levels outside them.
python3 - "$OUT/robustness.csv" <<'PY'
import csv, math, sys
path = sys.argv[1]
rows = list(csv.DictReader(open(path)))
block = sorted((int(r["nodes"]), int(r["iterations"])) for r in rows if r["case"].startswith("block-"))
def reference(n):
    if n <= block[0][0]:
        return block[0][1]
    for (n0, s0), (n1, s1) in zip(block, block[1:]):
        if n <= n1:
            t = (math.log(n) - math.log(n0)) / (math.log(n1) - math.log(n0))
            return s0 + t * (s1 - s0)
    return block[-1][1]
for r in rows:
    r["vs_block"] = f'{int(r["iterations"]) / reference(int(r["nodes"])):.2f}'
with open(path, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
    w.writeheader()
    w.writerows(rows)
cases = [r for r in rows if not r["case"].startswith(("hertz-", "block-", "block_flat-"))]
done = [r for r in cases if r["converged"] == "true"]
worst = max(done, key=lambda r: float(r["vs_block"]))
over = sum(float(r["vs_block"]) > 2.0 for r in done)
print(f"largest vs_block of the converged cases: {worst['vs_block']} ({worst['case']});"
      f" {over} of {len(done)} above 2; not converged: "
      + (", ".join(r["case"] for r in cases if r not in done) or "none"), file=sys.stderr)
PY
column -s, -t "$OUT/robustness.csv"
