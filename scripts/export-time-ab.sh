#!/usr/bin/env bash
# A/B timing of `thicket export` between two builds of the CLI, on one machine in one run:
# the two binaries take turns (so a busy machine slows both alike) and the medians are compared.
#
#   scripts/export-time-ab.sh OLD_THICKET NEW_THICKET PROJECT [ROUNDS]
#
# The time is the whole command (loading the project, meshing, encoding, writing the file).
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: $0 OLD_THICKET NEW_THICKET PROJECT [ROUNDS]" >&2
  exit 2
fi
old=$1 new=$2 project=$3 rounds=${4:-9}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() {
  local start end
  start=$(date +%s.%N)
  "$1" export "$project" -o "$out/export.glb" >/dev/null
  end=$(date +%s.%N)
  echo "$end - $start" | bc
}
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR] = $1} END {print a[int((NR + 1) / 2)]}'; }
a=() b=()
for _ in $(seq "$rounds"); do
  a+=("$(run "$old")")
  b+=("$(run "$new")")
done
ma=$(median "${a[@]}") mb=$(median "${b[@]}")
echo "$project: old median ${ma} s, new median ${mb} s, new/old $(echo "scale=3; $mb / $ma" | bc) ($rounds rounds each)"
