#!/usr/bin/env bash
# Strong and weak scaling studies of contact-par on a built-in case, or a strong scaling
# study on a case file of yours.
#
#   bash run-scripts/scaling.sh                          # block, level 4, 3 runs, out: scaling-out
#   bash run-scripts/scaling.sh --case block --level 4 --runs 3 --out DIR
#   bash run-scripts/scaling.sh --case-file my.toml --runs 3 --out DIR   # your mesh, strong
#   bash run-scripts/scaling.sh --smoke --out DIR        # seconds: level 0, 1 run, 1 and 2 ranks
#
# Strong scaling (fixed mesh at --level): ranks x threads = 1x1, 1x2, 2x1, 2x2, then 4x1
# and 8x1 (oversubscribed when the machine has fewer cores).
# Weak scaling (the mesh grows with the ranks; each block level has 4x the nodes of the
# one below): 1 rank at --weak-level (default --level - 1), 4 ranks at one level more,
# 16 ranks at two more, ... up to --weak-max-ranks (default 4), 1 thread per rank.
# The ceiling of this machine: P independent 1-rank x 1-thread copies of the strong-scaling
# run at once (P = each strong-scaling ranks x threads from 2 up to the cores; --copies).
# Cores that share memory bandwidth, caches or (on a virtual machine) a host core run P
# copies at less than P times the throughput of one: P T1 / T(copy) is the speed-up a
# P-way run could reach without doing less work than the 1-rank run, and the report
# divides each speed-up by it (a point that would not fit in memory is skipped).
# Every point is run --runs times (median reported); the repetitions are interleaved
# (run 1 of every point, then run 2, ...) so that a drift in the machine's load spreads
# over all points instead of biasing one.
#
# Writes to DIR: runs.csv (one row per run), summary.csv (medians per point), report.md,
# speedup.png, phases.png (when matplotlib can be had), meta.json (machine, command
# line, binary), runs/ (each run's summary.json, history.csv and stdout/stderr; the
# large .vtu files are deleted). The binary is copied to DIR/bin first, so a rebuild
# during the study cannot change what is measured.
#
# Options:
#   --case NAME          built-in case (hertz, block, block_flat); default block
#   --case-file FILE     a case file (TOML, its Gmsh mesh) instead: strong scaling and
#                        ceiling only, as a weak study needs meshes that grow with the
#                        ranks; the case's name in the CSV files is FILE's name, level 0
#   --level N            strong-scaling level; default 4
#   --weak-level N       weak-scaling level of the 1-rank point; default level - 1
#   --weak-max-ranks N   largest weak-scaling rank count (a power of 4); default 4
#   --runs N             repetitions per point; default 3
#   --out DIR            output folder; default scaling-out
#   --bin PATH           the contact-par binary; default target/release/contact-par
#                        (built with `cargo build --release` when missing)
#   --study S            strong, weak or both; default both
#   --copies "P ..."     the copy counts of the ceiling points, or "none"; default every
#                        strong-scaling ranks x threads from 2 to the number of cores
#   --bind B             mpirun --bind-to value; default none (Open MPI would otherwise
#                        bind a 1- or 2-rank job to one core per rank, and then the
#                        threads of a rank share that core)
#   --mpirun-args "..."  extra mpirun arguments, e.g. "--mca mpi_yield_when_idle 1"
#   --venv DIR           Python venv for matplotlib; default DIR/.venv (created with pip
#                        when the system python3 has no matplotlib)
#   --wait-idle X        before each run, wait until other processes use less than X
#                        cores (sampled over 1 s), at most --wait-max seconds (default
#                        120); for shared machines. Default: do not wait. Every run
#                        records how many cores others kept busy during it regardless.
#   --timeout S          kill a run (mpirun and its ranks) that has not ended after S
#                        seconds and record it as failed (exit 124); default 0, no
#                        limit (--smoke: 300)
#   --no-plots           no plots, no pip
#   --smoke              level 0, 1 run, ranks 1 and 2 (1 thread) and 2 copies, strong
#                        study only, no pip (plots only when python3 already has matplotlib)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
CMDLINE="bash run-scripts/scaling.sh"
[[ $# -eq 0 ]] || CMDLINE+="$(printf ' %q' "$@")"

CASE=block
CASE_FILE=
LEVEL=4
WEAK_LEVEL=
WEAK_MAX=4
RUNS=3
OUT=scaling-out
BIN="$ROOT/target/release/contact-par"
STUDY=both
STUDY_GIVEN=0
COPIES=
BIND=none
VENV=
MPI_ARGS=
WAIT_IDLE=
WAIT_MAX=120
PLOTS=1
SMOKE=0
TIMEOUT=

die() { echo "scaling.sh: $*" >&2; exit 2; }
need_arg() { [[ $# -ge 2 && -n "$2" ]] || die "$1 needs a value"; }
while [[ $# -gt 0 ]]; do
  case "$1" in
    --case) need_arg "$@"; CASE="$2"; shift 2 ;;
    --case-file) need_arg "$@"; CASE_FILE="$2"; shift 2 ;;
    --level) need_arg "$@"; LEVEL="$2"; shift 2 ;;
    --weak-level) need_arg "$@"; WEAK_LEVEL="$2"; shift 2 ;;
    --weak-max-ranks) need_arg "$@"; WEAK_MAX="$2"; shift 2 ;;
    --runs) need_arg "$@"; RUNS="$2"; shift 2 ;;
    --out) need_arg "$@"; OUT="$2"; shift 2 ;;
    --bin) need_arg "$@"; BIN="$2"; shift 2 ;;
    --study) need_arg "$@"; STUDY="$2"; STUDY_GIVEN=1; shift 2 ;;
    --copies) need_arg "$@"; COPIES="$2"; shift 2 ;;
    --bind) need_arg "$@"; BIND="$2"; shift 2 ;;
    --venv) need_arg "$@"; VENV="$2"; shift 2 ;;
    --mpirun-args) need_arg "$@"; MPI_ARGS="$2"; shift 2 ;;
    --wait-idle) need_arg "$@"; WAIT_IDLE="$2"; shift 2 ;;
    --wait-max) need_arg "$@"; WAIT_MAX="$2"; shift 2 ;;
    --timeout) need_arg "$@"; TIMEOUT="$2"; shift 2 ;;
    --no-plots) PLOTS=0; shift ;;
    --smoke) SMOKE=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    *) die "unknown option $1 (see --help)" ;;
  esac
done
for v in LEVEL WEAK_MAX RUNS; do
  [[ "${!v}" =~ ^[0-9]+$ ]] || die "--$(echo "$v" | tr 'A-Z_' 'a-z-') must be a whole number, not '${!v}'"
done
[[ -z "$WEAK_LEVEL" || "$WEAK_LEVEL" =~ ^[0-9]+$ ]] || die "--weak-level must be a whole number"
[[ -z "$WAIT_IDLE" || "$WAIT_IDLE" =~ ^[0-9]*\.?[0-9]+$ ]] || die "--wait-idle must be a number of cores"
[[ "$WAIT_MAX" =~ ^[0-9]+$ ]] || die "--wait-max must be a whole number of seconds"
[[ -z "$TIMEOUT" || "$TIMEOUT" =~ ^[0-9]+$ ]] || die "--timeout must be a whole number of seconds"
[[ "$RUNS" -ge 1 ]] || die "--runs must be at least 1"
case "$STUDY" in strong|weak|both) ;; *) die "--study must be strong, weak or both" ;; esac
[[ -z "$COPIES" || "$COPIES" == none || "$COPIES" =~ ^[0-9]+( [0-9]+)*$ ]] ||
  die "--copies must be whole numbers separated by spaces, or none, not '$COPIES'"

if [[ -n "$CASE_FILE" ]]; then
  [[ -f "$CASE_FILE" && -r "$CASE_FILE" ]] || die "--case-file $CASE_FILE: no such readable file"
  [[ $STUDY_GIVEN == 0 || $STUDY == strong ]] ||
    die "--case-file: a weak study needs meshes that grow with the ranks, which only the built-in cases (--case) have; use --study strong"
  CASE_FILE="$(cd "$(dirname "$CASE_FILE")" && pwd)/$(basename "$CASE_FILE")"
  CASE="$(basename "$CASE_FILE" .toml)"
  LEVEL=0 STUDY=strong
fi
if [[ $SMOKE == 1 ]]; then
  LEVEL=0 RUNS=1 STUDY=strong
  TIMEOUT=${TIMEOUT:-300}
fi
TIMEOUT=${TIMEOUT:-0}
if [[ -z "$WEAK_LEVEL" ]]; then
  WEAK_LEVEL=$(( LEVEL > 0 ? LEVEL - 1 : 0 ))
fi

# The points: "study level ranks threads".
POINTS=()
CORES=$(nproc)
if [[ $STUDY != weak ]]; then
  if [[ $SMOKE == 1 ]]; then
    POINTS+=("strong $LEVEL 1 1" "strong $LEVEL 2 1")
    [[ -n "$COPIES" ]] || COPIES=2
  else
    for pt in "1 1" "1 2" "2 1" "2 2" "4 1" "8 1"; do POINTS+=("strong $LEVEL $pt"); done
    if [[ -z "$COPIES" ]]; then
      for p in 2 4 8; do
        if (( p <= CORES )); then COPIES+="${COPIES:+ }$p"; fi
      done
    fi
  fi
  if [[ "$COPIES" != none ]]; then
    for p in $COPIES; do
      (( p >= 2 )) || die "--copies: a ceiling needs at least 2 copies, not $p"
      POINTS+=("copies $LEVEL $p 1")
    done
  fi
fi
if [[ $STUDY != strong ]]; then
  p=1 l=$WEAK_LEVEL
  while [[ $p -le $WEAK_MAX ]]; do
    POINTS+=("weak $l $p 1")
    p=$(( p * 4 )) l=$(( l + 1 ))
  done
fi

command -v mpirun >/dev/null || die "mpirun not found; run run-scripts/setup.sh (it installs openmpi-bin)"
command -v python3 >/dev/null || die "python3 not found; it writes the CSV files and the report"
if [[ ! -x "$BIN" ]]; then
  [[ "$BIN" == "$ROOT/target/release/contact-par" ]] || die "--bin $BIN is not an executable"
  echo "building $BIN"
  (cd "$ROOT" && cargo build --release --quiet)
fi

mkdir -p "$OUT/bin" "$OUT/runs"
OUT="$(cd "$OUT" && pwd)"
cp "$BIN" "$OUT/bin/contact-par"
EXE="$OUT/bin/contact-par"
if [[ -z "$CASE_FILE" ]]; then
  "$EXE" --builtin "$CASE" --print-case >/dev/null ||
    die "the binary does not know the built-in case '$CASE' (see its message above)"
fi

# The case arguments of the binary at a level: the case file, or the built-in case.
case_args() { # level
  if [[ -n "$CASE_FILE" ]]; then
    CASE_ARGS=("$CASE_FILE")
  else
    CASE_ARGS=(--builtin "$CASE" --level "$1")
  fi
}
INDEX="$OUT/runs.tsv"
printf 'study\tcase\tlevel\tranks\tthreads\trun\texit_code\twall_s\tcpu_s\tothers_cores\ttime_maxrss_kb\tuser_s\tsys_s\tminor_faults\tdir\n' >"$INDEX"
HZ=$(getconf CLK_TCK 2>/dev/null || echo 100)

# mpirun refuses root and more ranks than cores unless told.
if [[ $(id -u) == 0 ]]; then
  export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi
export OMPI_MCA_rmaps_base_oversubscribe=1

# The machine and the command, for the report (python3 writes valid JSON).
META_COMMAND="$CMDLINE" META_CORES="$CORES" META_BIND="$BIND" META_MPI_ARGS="$MPI_ARGS" \
META_BIN="$BIN" META_SHA="$(sha256sum "$EXE" | cut -c1-16)" META_CASE="$CASE" META_CASE_FILE="$CASE_FILE" META_LEVEL="$LEVEL" META_WEAK_LEVEL="$WEAK_LEVEL" \
META_RUNS="$RUNS" META_SMOKE="$SMOKE" META_WAIT_IDLE="$WAIT_IDLE" META_COPIES="$COPIES" \
META_CPU="$(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1)" \
META_MPIRUN="$(mpirun --version 2>/dev/null | head -1)" \
META_GIT="$(git -C "$ROOT" rev-parse --short HEAD 2>/dev/null || echo unknown)" \
META_DIRTY="$(git -C "$ROOT" status --porcelain -- src partition Cargo.toml 2>/dev/null | wc -l)" \
python3 - "$OUT/meta.json" <<'PY'
import datetime, json, os, socket, sys
e = os.environ
with open("/proc/meminfo") as f:
    mem = next(int(l.split()[1]) * 1024 for l in f if l.startswith("MemTotal"))
with open("/proc/loadavg") as f:
    load = " ".join(f.read().split()[:3])
meta = {
    "command": e["META_COMMAND"],
    "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    "hostname": socket.gethostname(),
    "cores": int(e["META_CORES"]),
    "cpu": e["META_CPU"],
    "memory_bytes": mem,
    "mpirun": e["META_MPIRUN"],
    "bind_to": e["META_BIND"],
    "mpirun_args": e["META_MPI_ARGS"],
    "binary": e["META_BIN"],
    "binary_sha256_16": e["META_SHA"],
    "git_commit": e["META_GIT"],
    "git_dirty_files": int(e["META_DIRTY"]),
    "load_average_at_start": load,
    "case": e["META_CASE"],
    "case_file": e["META_CASE_FILE"] or None,
    "level": int(e["META_LEVEL"]),
    "weak_level": int(e["META_WEAK_LEVEL"]),
    "runs": int(e["META_RUNS"]),
    "smoke": e["META_SMOKE"] == "1",
    "wait_idle_cores": float(e["META_WAIT_IDLE"]) if e["META_WAIT_IDLE"] else None,
    "copies": [int(p) for p in e["META_COPIES"].split()] if e["META_COPIES"] not in ("", "none") else [],
}
with open(sys.argv[1], "w") as f:
    json.dump(meta, f, indent=2)
PY

# Busy CPU seconds of the whole machine so far (every process, every core).
busy_s() {
  awk -v hz="$HZ" '/^cpu / { print ($2 + $3 + $4 + $7 + $8 + $9) / hz; exit }' /proc/stat
}

# Waits until other processes use fewer than WAIT_IDLE cores (or WAIT_MAX seconds pass).
wait_idle() {
  [[ -n "$WAIT_IDLE" ]] || return 0
  local start=$SECONDS b0 b1
  while true; do
    b0=$(busy_s); sleep 1; b1=$(busy_s)
    if awk -v a="$b0" -v b="$b1" -v x="$WAIT_IDLE" 'BEGIN { exit !(b - a < x) }'; then
      return 0
    fi
    if (( SECONDS - start >= WAIT_MAX )); then
      echo "    the machine stayed busy for ${WAIT_MAX}s; running anyway" >&2
      return 0
    fi
  done
}

# "CPU seconds (user + sys), peak resident kB, user s, sys s, minor page faults" of a
# run, from DIR/time.txt (/usr/bin/time); nothing when /usr/bin/time was missing. The
# system time and the faults show what first-touched memory costs: on a virtual machine
# that returns freed memory to its host, a large part of a run.
cpu_rss() {
  [[ -s "$1/time.txt" ]] || return 0
  tail -n 1 "$1/time.txt" | awk '{ printf "%.3f %s %s %s %s\n", $1 + $2, $3, $1, $2, $4 }'
}

# How many cores other processes kept busy on average: the machine's busy CPU seconds
# (b0 -> b1) minus ours (cpu), per second of wall time (t0 -> t1).
others_cores() { # b0 b1 cpu t0 t1
  awk -v b0="$1" -v b1="$2" -v c="$3" -v a="$4" -v b="$5" \
    'BEGIN { o = (b1 - b0 - c) / (b - a); printf "%.2f", (o < 0 ? 0 : o) }'
}

record() { # study level ranks threads run code wall cpu others rss user sys faults dir: one row of runs.tsv
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$1" "$CASE" "$2" "$3" "$4" "$5" \
    "$6" "$7" "$8" "$9" "${10}" "${11}" "${12}" "${13}" "runs/$(basename "${14}")" >>"$INDEX"
}

report_failure() { # code dir
  if [[ $1 == 124 || $1 == 137 ]]; then
    echo "    killed after --timeout $TIMEOUT s; see $2/stderr.txt" >&2
  elif [[ $1 != 0 && $1 != 3 ]]; then
    echo "    failed; see $2/stderr.txt:" >&2
    # contact-par's own one-line error, else (mpirun or MPI failed to start) all that the
    # launcher said: a machine on which this happens is usually not at hand later.
    grep -m 2 '^contact-par' "$2/stderr.txt" >&2 || tail -n 40 "$2/stderr.txt" >&2 || true
  fi
}

# Kills a run cleanly: SIGTERM to mpirun (which stops its ranks), SIGKILL 10 s later.
# TIMEOUT=0 disables it.
LIMIT=(timeout -k 10 "$TIMEOUT")

run_one() { # study level ranks threads run
  local study=$1 level=$2 ranks=$3 threads=$4 run=$5
  local dir="$OUT/runs/${study}_L${level}_P${ranks}_T${threads}_r${run}"
  rm -rf "$dir" && mkdir -p "$dir"
  local t0 t1 b0 b1 code=0
  local timer=()
  [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f '%U %S %M %R' -o "$dir/time.txt")
  case_args "$level"
  wait_idle
  b0=$(busy_s)
  t0=$(date +%s.%N)
  # A session directory of its own (Open MPI's, and PMIx's shared-memory store): nothing
  # left behind by an earlier run, or by another user's job, can get in the way.
  local session
  session=$(mktemp -d)
  # shellcheck disable=SC2086
  TMPDIR="$session" "${timer[@]}" "${LIMIT[@]}" mpirun -n "$ranks" --oversubscribe --bind-to "$BIND" $MPI_ARGS \
    "$EXE" "${CASE_ARGS[@]}" --threads "$threads" --out "$dir" \
    >"$dir/stdout.txt" 2>"$dir/stderr.txt" || code=$?
  t1=$(date +%s.%N)
  rm -rf "$session"
  b1=$(busy_s)
  rm -f "$dir"/*.vtu "$dir"/*.pvtu
  # Our CPU time (user + sys of mpirun and the ranks) and its largest resident set, from
  # /usr/bin/time; the machine's busy time minus ours is what other users' processes
  # took: "others_cores" is how many cores they kept busy on average during the run.
  local cpu="" rss="" user="" sys="" faults="" others=""
  read -r cpu rss user sys faults < <(cpu_rss "$dir") || true
  [[ -z "$cpu" ]] || others=$(others_cores "$b0" "$b1" "$cpu" "$t0" "$t1")
  local wall
  wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
  record "$study" "$level" "$ranks" "$threads" "$run" "$code" "$wall" "$cpu" "$others" "$rss" \
    "$user" "$sys" "$faults" "$dir"
  printf '  %-6s level %-2s %2s rank(s) x %s thread(s)  run %s: %7ss  exit %s  (others kept %s cores busy)\n' \
    "$study" "$level" "$ranks" "$threads" "$run" "$wall" "$code" "${others:-?}"
  report_failure "$code" "$dir"
}

run_copies() { # copies level P threads run: P 1-rank runs at once, a row each
  local level=$2 copies=$3 run=$5
  local base="$OUT/runs/copies_L${level}_P${copies}_T1_r${run}" k
  # P copies need P times the memory of one: skip the point (with a line) rather than
  # push the machine into swap or the OOM killer, judged by the 1x1 run of this level.
  local one_kb avail_kb
  one_kb=$(awk -F'\t' -v l="$level" '$1 == "strong" && $3 == l && $4 == 1 && $5 == 1 && $11 != "" { kb = $11 } END { print kb }' "$INDEX")
  avail_kb=$(awk '/^MemAvailable:/ { print $2 }' /proc/meminfo)
  if [[ -n "$one_kb" && -n "$avail_kb" ]] && (( copies * one_kb > avail_kb * 9 / 10 )); then
    echo "  copies level $level: $copies copies of a ${one_kb} kB run do not fit in ${avail_kb} kB available; skipped" >&2
    return 0
  fi
  case_args "$level"
  wait_idle
  local b0 b1 t0 t1
  b0=$(busy_s)
  t0=$(date +%s.%N)
  for k in $(seq 1 "$copies"); do
    local dir="${base}_c$k"
    rm -rf "$dir" && mkdir -p "$dir"
    (
      timer=()
      [[ -x /usr/bin/time ]] && timer=(/usr/bin/time -f '%U %S %M %R' -o "$dir/time.txt")
      # mpiruns started together race to create one shared session directory in TMPDIR
      # (Open MPI 4: "File exists", orte_init failed); each copy gets its own.
      session=$(mktemp -d)
      a=$(date +%s.%N) code=0
      # shellcheck disable=SC2086
      TMPDIR="$session" "${timer[@]}" "${LIMIT[@]}" mpirun -n 1 --bind-to "$BIND" $MPI_ARGS \
        "$EXE" "${CASE_ARGS[@]}" --threads 1 --out "$dir" \
        >"$dir/stdout.txt" 2>"$dir/stderr.txt" || code=$?
      echo "$a $(date +%s.%N) $code" >"$dir/wall.txt"
      rm -rf "$session"
    ) &
  done
  wait
  t1=$(date +%s.%N)
  b1=$(busy_s)
  # Others' cores: the machine's busy time minus every copy's own CPU time.
  local cpus=() rsss=() users=() syss=() faultss=() cpu rss user sys faults cpu_all=0
  for k in $(seq 1 "$copies"); do
    cpu="" rss="" user="" sys="" faults=""
    read -r cpu rss user sys faults < <(cpu_rss "${base}_c$k") || true
    cpus+=("$cpu") rsss+=("$rss") users+=("$user") syss+=("$sys") faultss+=("$faults")
    cpu_all=$(awk -v a="$cpu_all" -v c="${cpu:-0}" 'BEGIN { print a + c }')
  done
  local others
  others=$(others_cores "$b0" "$b1" "$cpu_all" "$t0" "$t1")
  for k in $(seq 1 "$copies"); do
    local dir="${base}_c$k" a b code wall
    read -r a b code <"$dir/wall.txt"
    wall=$(awk -v a="$a" -v b="$b" 'BEGIN { printf "%.3f", b - a }')
    cpu=${cpus[k - 1]} rss=${rsss[k - 1]}
    rm -f "$dir"/*.vtu "$dir"/*.pvtu
    record copies "$level" "$copies" 1 "$run" "$code" "$wall" "$cpu" "$others" "$rss" \
      "${users[k - 1]}" "${syss[k - 1]}" "${faultss[k - 1]}" "$dir"
    printf '  %-6s level %-2s %2s copies of 1x1    run %s copy %s: %7ss  exit %s  (others kept %s cores busy)\n' \
      copies "$level" "$copies" "$run" "$k" "$wall" "$code" "$others"
    report_failure "$code" "$dir"
  done
}

echo "contact-par scaling: case $CASE, ${#POINTS[@]} points x $RUNS run(s), $CORES core(s), out $OUT"
# One untimed run first: the binary and the libraries come into the page cache (and a
# case file's mesh, so that the first timed run does not read it from disk).
if [[ -n "$CASE_FILE" ]]; then
  python3 - "$CASE_FILE" <<'PY' || true
import os, sys, tomllib
with open(sys.argv[1], "rb") as f:
    mesh = tomllib.load(f).get("mesh", {}).get("file")
if mesh:
    path = os.path.join(os.path.dirname(sys.argv[1]), mesh)
    with open(path, "rb") as f:
        while f.read(1 << 24):
            pass
PY
fi
if [[ $SMOKE == 0 ]]; then
  # shellcheck disable=SC2086
  "${LIMIT[@]}" mpirun -n 1 --bind-to "$BIND" $MPI_ARGS "$EXE" --builtin "$CASE" --level 0 --quiet \
    --out "$OUT/runs/warmup" >/dev/null 2>&1 || true
  rm -rf "$OUT/runs/warmup"
fi
for run in $(seq 1 "$RUNS"); do
  for pt in "${POINTS[@]}"; do
    # shellcheck disable=SC2086
    case "$pt" in
      copies*) run_copies $pt "$run" ;;
      *) run_one $pt "$run" ;;
    esac
  done
done

# Plots need matplotlib: the system's, or a venv under the output folder.
PY=python3
if [[ $PLOTS == 1 ]] && ! python3 -c 'import matplotlib' 2>/dev/null; then
  if [[ $SMOKE == 1 ]]; then
    PLOTS=0
  else
    VENV="${VENV:-$OUT/.venv}"
    if [[ ! -x "$VENV/bin/python" ]] || ! "$VENV/bin/python" -c 'import matplotlib' 2>/dev/null; then
      echo "installing matplotlib into $VENV"
      if ! { python3 -m venv "$VENV" && "$VENV/bin/python" -m pip install --quiet matplotlib; }; then
        echo "scaling.sh: could not install matplotlib; writing the report without plots" >&2
        PLOTS=0
      fi
    fi
    [[ $PLOTS == 1 ]] && PY="$VENV/bin/python"
  fi
fi
PLOT_FLAG=()
[[ $PLOTS == 1 ]] || PLOT_FLAG=(--no-plots)
status=0
"$PY" "$ROOT/run-scripts/scaling_report.py" "$OUT" "${PLOT_FLAG[@]}" || status=$?
echo "report: $OUT/report.md"
exit "$status"   # non-zero when a run failed (not when one did not converge)
