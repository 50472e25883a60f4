#!/usr/bin/env bash
# The test suite: formatting, lints, then every unit and integration test (release
# build: the integration tests run the real solver, several under mpirun).
set -euo pipefail
cd "$(dirname "$0")/.."
# mpirun refuses root and more ranks than cores unless told; the tests need both.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1
# PMIx's shared-memory key store (gds ds21) keeps process-shared locks in files of the
# session directory; a rank that dies while holding one makes mpirun report "PMIX ERROR
# ... gds_ds21_lock_pthread.c" and has hung the next launch on a CI machine. The plain
# hash store has no such state and is all a job of a few ranks needs.
export PMIX_MCA_gds=hash
cargo fmt --all -- --check
cargo clippy --release --workspace --all-targets -- -D warnings
# The scaling study's smoke mode: the scripts of run-scripts/ keep working (seconds).
bash run-scripts/scaling.sh --smoke --out "$(mktemp -d)/smoke"
bash run-scripts/scaling.sh --smoke --case-file tests/data/gmsh/quarter_disc.toml \
  --out "$(mktemp -d)/smoke-case-file"
# The start study and the cost model's start on it (seconds).
start_dir="$(mktemp -d)/start"
python3 run-scripts/start_study.py tests/data/gmsh/quarter_disc.toml --runs 1 \
  --split-parts 2,4 --out "$start_dir" >/dev/null
python3 run-scripts/cost_model.py docs/data/scale-summaries/*.json --start "$start_dir" >/dev/null
# The partition study (the first rank's straight cuts against METIS) on two meshes (seconds).
python3 run-scripts/cut_study.py tests/data/gmsh/quarter_disc.toml tests/data/bodies/blocks.toml \
  --ranks 2,3 --runs 1 --out "$(mktemp -d)/cut" >/dev/null
# The bound of independent pieces (halves.sh): the built-in block at level 1 on 4 ranks
# against 4 jobs at level 0, a quarter of its nodes (seconds).
halves_dir="$(mktemp -d)/halves"
mkdir -p "$halves_dir"
target/release/contact-par --builtin block --level 1 --print-case > "$halves_dir/whole.toml"
target/release/contact-par --builtin block --level 0 --print-case > "$halves_dir/part.toml"
bash run-scripts/halves.sh --whole "$halves_dir/whole.toml" --part "$halves_dir/part.toml" \
  --ranks 4 --runs 1 --out "$halves_dir" >/dev/null
if cargo nextest --version >/dev/null 2>&1; then
  cargo nextest run --release --workspace --no-fail-fast
else
  cargo test --release --workspace --no-fail-fast
fi
