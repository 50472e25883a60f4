# Sourced by r_sweep.sh and sweeps_vs_plain.sh: a built-in case with a friction law of
# the studies (none, tresca, coulomb), written as a case file.
#   write_case BIN CASE LAW LEVEL FILE
write_case() {
  local bin=$1 case=$2 law=$3 level=$4 file=$5 fr
  case "$case:$law" in
    hertz:tresca) fr='friction = "tresca"\nthreshold = 500.0' ;;
    hertz:coulomb) fr='friction = "coulomb"\ncoefficient = 0.2' ;;
    block:tresca) fr='friction = "tresca"\nthreshold = 20.0' ;;
    block:coulomb) fr='friction = "coulomb"\ncoefficient = 0.3' ;;
    *) fr='friction = "none"' ;;
  esac
  "$bin" --builtin "$case" --level "$level" --print-case \
    | grep -v -E '^(friction|threshold|coefficient) *=' \
    | awk -v fr="$fr" '{print} /^obstacle_normal/ {gsub(/\\n/, "\n", fr); print fr}' > "$file"
}
