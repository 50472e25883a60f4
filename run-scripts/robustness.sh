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
# warnings).
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=target/release/contact-par
OUT=robustness
BEAMS=
CASES=()
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN="$2"; shift 2 ;;
    --out) OUT="$2"; shift 2 ;;
    --beams) BEAMS=$(realpath "$2"); shift 2 ;;
    --cases) CASES+=("$(realpath "$2")"); shift 2 ;;
    *) echo "robustness.sh: unknown option $1 (expected --bin FILE, --out DIR, --beams DIR or --cases DIR)" >&2; exit 2 ;;
  esac
done
BIN=$(realpath "$BIN")
mkdir -p "$OUT"
OUT=$(realpath "$OUT")
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
column -s, -t "$OUT/robustness.csv"
