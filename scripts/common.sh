# What the run scripts (demo, train_long, sweep, scene_choice, hardcases) start with. Sourced:
#   source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
# root: the repository (the folder above scripts/).
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

# need_args USAGE MIN MAX "$@": exit 2 with "usage: SCRIPT USAGE" unless MIN..MAX arguments.
need_args() {
  local usage=$1 min=$2 max=$3
  shift 3
  if [[ $# -lt $min || $# -gt $max ]]; then
    echo "usage: $0 $usage" >&2
    exit 2
  fi
}

# find_bsms NAME BUILD_DIR: sets bsms to BUILD_DIR/bsms, or exits 2 naming it (NAME: the script).
find_bsms() {
  bsms=$2/bsms
  [[ -x $bsms ]] || { echo "$1: $bsms not found; build first (make build)" >&2; exit 2; }
}
