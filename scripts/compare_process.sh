#!/usr/bin/env bash
# Both sides of every speed ratio of docs/performance.md, in one process
# tree, alternated (A, B, A, B, ...) so that the load of the machine falls on
# both alike; the best of ROUNDS wall times and the peak resident memory of
# each side:
#
# - `survey process` against scripts/process_numpy.py, whole process against
#   whole process (start-up, reading SQLite, processing, writing the files),
#   on surveys the simulated tracker acquired: 360, 3600 and 36000 points
#   (3600, 36000 and 360000 samples: 5 runs, both directions, the default
#   simulated bench), and with POINTS_LARGE=180000 also 1.8 M samples;
# - `survey model-gap` against `survey process` on the largest survey;
# - the simulation itself: `survey run` of the 36000-point survey (its wall
#   time and its instrument time).
#
#   scripts/compare_process.sh [PYTHON]
#
# PYTHON is an interpreter with numpy and scipy (default python3). ROUNDS
# (default 3) sets the number of alternations. Needs GNU time (/usr/bin/time)
# and a release build (`cargo build --release`).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
python="${1:-python3}"
rounds="${ROUNDS:-3}"
survey="$here/target/release/survey"
model="$here/sims/presets/fig8.toml"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
mkdir -p rust py

run_timed() { # label command... -> appends "label wall_s peak_kib" to times.txt, stdout in out.txt
  local label="$1"
  shift
  if ! /usr/bin/time -f "%e %M" -o t.txt "$@" >out.txt 2>err.txt; then cat err.txt >&2; echo "failed: $*" >&2; return 1; fi
  read -r t m < t.txt
  echo "$label $t $m" >> times.txt
}
best() { # label -> "best_wall_s peak_mib"
  awk -v l="$1" '$1 == l { if (b == "" || $2 < b) b = $2; if ($3 > m) m = $3 } END { printf "%s %d\n", b, m / 1024 }' times.txt
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.1fx", a / b}'; }

: > times.txt
printf 'machine: %s cores, %s, %s MiB memory; best of %s alternated rounds\n\n' "$(nproc)" \
  "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')" \
  "$(awk '/MemTotal/ {print int($2 / 1024)}' /proc/meminfo)" "$rounds"

sizes=(360 3600 36000)
[[ -n "${POINTS_LARGE:-}" ]] && sizes+=("$POINTS_LARGE")
for points in "${sizes[@]}"; do
  run_timed "run$points" "$survey" --db "s$points.db" run --points "$points" --bidirectional --json
  cp out.txt "run$points.json"
  for _ in $(seq "$rounds"); do
    run_timed "survey$points" "$survey" --db "s$points.db" process --json --table-out rust/t.csv
    run_timed "numpy$points" "$python" "$here/scripts/process_numpy.py" "s$points.db" 1 py
  done
done

printf '%-9s %-24s %-24s %s\n' samples "survey process (s, MiB)" "numpy/scipy (s, MiB)" faster
for points in "${sizes[@]}"; do
  read -r rt rm <<<"$(best "survey$points")"
  read -r pt pm <<<"$(best "numpy$points")"
  printf '%-9s %-24s %-24s %s\n' "$((points * 10))" "$rt s, $rm MiB" "$pt s, $pm MiB" "$(ratio "$pt" "$rt")"
done

last="${sizes[-1]}"
for _ in $(seq "$rounds"); do
  run_timed gap "$survey" --db "s$last.db" model-gap --model "$model" --json
  run_timed process "$survey" --db "s$last.db" process --json --table-out rust/t.csv
done
read -r gt gm <<<"$(best gap)"
read -r pt pm <<<"$(best process)"
printf '\nmodel-gap on %s samples: %s s, %s MiB; process %s s, %s MiB: model-gap / process = %s\n' \
  "$((last * 10))" "$gt" "$gm" "$pt" "$pm" "$(ratio "$gt" "$pt")"

read -r st sm <<<"$(best run36000)"
instrument="$("$python" -c 'import json, sys; print(round(json.load(sys.stdin)["instrument_time_s"]))' < run36000.json)"
printf 'simulating the 36000-point survey (survey run, with its processing): %s s wall, %s MiB%s\n' \
  "$st" "$sm" ", $instrument s of instrument time"
