#!/usr/bin/env bash
# Time `survey process` against scripts/process_numpy.py, whole process
# against whole process (start-up, reading SQLite, processing, writing the
# files), on surveys of 3600, 36000 and 360000 samples (360, 3600 and 36000
# points, 5 runs, both directions, the default simulated bench).
#
#   scripts/compare_process.sh [PYTHON]
#
# PYTHON is an interpreter with numpy and scipy (default python3). Prints the
# median wall time of 5 runs and the peak resident memory of each. Needs GNU
# time (/usr/bin/time) and a release build (`cargo build --release`).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
python="${1:-python3}"
survey="$here/target/release/survey"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
mkdir -p rust py
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
measure() { # command... -> "median_s peak_kib"
  local times=() peak=0
  for _ in 1 2 3 4 5; do
    if ! /usr/bin/time -f "%e %M" -o t.txt "$@" >/dev/null 2>err.txt; then cat err.txt >&2; echo "failed: $*" >&2; return 1; fi
    read -r t m < t.txt
    times+=("$t")
    (( m > peak )) && peak=$m
  done
  echo "$(printf '%s\n' "${times[@]}" | median) $peak"
}
printf '%-9s %-28s %-28s %s\n' samples "survey process (s, MiB)" "numpy/scipy (s, MiB)" ratio
for points in 360 3600 36000; do
  db="s$points.db"
  "$survey" --db "$db" run --points "$points" --bidirectional --json >/dev/null 2>&1
  r="$(measure "$survey" --db "$db" process --json --table-out rust/t.csv)"; read -r rt rm <<<"$r"
  p="$(measure "$python" "$here/scripts/process_numpy.py" "$db" 1 py)"; read -r pt pm <<<"$p"
  printf '%-9s %-28s %-28s %s\n' "$((points * 10))" "$rt s, $((rm / 1024)) MiB" "$pt s, $((pm / 1024)) MiB" \
    "$(awk -v a="$pt" -v b="$rt" 'BEGIN {printf "%.1fx", a / b}')"
done
