#!/usr/bin/env bash
# Both sides of every speed ratio of docs/performance.md, in one process
# tree, alternated (A, B, A, B, ...) so that the load of the machine falls on
# both alike; the best of ROUNDS wall times, the best CPU time (user + system)
# and the peak resident memory of each side:
#
# - `survey process` against scripts/process_numpy.py, whole process against
#   whole process (start-up, reading SQLite, processing, writing the files),
#   on surveys the simulated tracker acquired: 360, 3600 and 36000 points
#   (3600, 36000 and 360000 samples: 5 runs, both directions, the default
#   simulated bench), and with POINTS_LARGE=180000 also 1.8 M samples;
# - the cost of a sample beyond a fixed start (CPU time) and the resident
#   memory a sample costs beyond a fixed base, of each side: from the smallest
#   and the largest survey;
# - `survey model-gap` against `survey process` on the 360000-sample survey
#   (issue 21 item 2's) and on the largest;
# - the simulation itself: `survey run` of the 36000-point survey (its wall
#   time and its instrument time), best of ROUNDS runs.
#
#   scripts/compare_process.sh [PYTHON]
#
# PYTHON is an interpreter with numpy (default python3). ROUNDS
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

run_timed() { # label command... -> appends "label wall_s peak_kib cpu_s" to times.txt, stdout in out.txt
  local label="$1"
  shift
  if ! /usr/bin/time -f "%e %M %U %S" -o t.txt "$@" >out.txt 2>err.txt; then cat err.txt >&2; echo "failed: $*" >&2; return 1; fi
  read -r t m u s < t.txt
  echo "$label $t $m $(awk -v u="$u" -v s="$s" 'BEGIN {printf "%.2f", u + s}')" >> times.txt
}
best() { # label -> "best_wall_s peak_mib best_cpu_s peak_kib"
  awk -v l="$1" '$1 == l { if (b == "" || $2 < b) b = $2; if ($3 > m) m = $3; if (c == "" || $4 < c) c = $4 }
    END { printf "%s %d %s %d\n", b, m / 1024, c, m }' times.txt
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

printf '%-9s %-32s %-32s %s\n' samples "survey process (wall, CPU, MiB)" "numpy (wall, CPU, MiB)" \
  "faster (wall, CPU)"
for points in "${sizes[@]}"; do
  read -r rt rm rc _ <<<"$(best "survey$points")"
  read -r pt pm pc _ <<<"$(best "numpy$points")"
  printf '%-9s %-32s %-32s %s\n' "$((points * 10))" "$rt s, $rc s, $rm MiB" "$pt s, $pc s, $pm MiB" \
    "$(ratio "$pt" "$rt"), $(ratio "$pc" "$rc")"
done

# A sample's cost beyond a fixed start: the CPU time and the peak resident
# memory between the smallest and the largest survey, over their samples.
first="${sizes[0]}" last="${sizes[-1]}"
for side in survey numpy; do
  read -r _ _ c0 m0 <<<"$(best "$side$first")"
  read -r _ _ c1 m1 <<<"$(best "$side$last")"
  awk -v side="$side" -v c0="$c0" -v c1="$c1" -v m0="$m0" -v m1="$m1" -v n="$(((last - first) * 10))" \
    'BEGIN {printf "%-6s a sample beyond a fixed start: %.2f us CPU, %.0f bytes resident\n", side, (c1 - c0) / n * 1e6, (m1 - m0) * 1024 / n}'
done

# Issue 21 item 2 is specified on the 360000-sample survey; the largest
# survey is measured too when it is larger.
echo
gap_sizes=(36000)
[[ "$last" != 36000 ]] && gap_sizes+=("$last")
for points in "${gap_sizes[@]}"; do
  for _ in $(seq "$rounds"); do
    run_timed "gap$points" "$survey" --db "s$points.db" model-gap --model "$model" --json
    run_timed "process$points" "$survey" --db "s$points.db" process --json --table-out rust/t.csv
  done
  read -r gt gm gc _ <<<"$(best "gap$points")"
  read -r pt pm pc _ <<<"$(best "process$points")"
  printf 'model-gap on %s samples: %s s (%s s CPU), %s MiB; process %s s (%s s CPU), %s MiB: model-gap / process = %s (%s in CPU)\n' \
    "$((points * 10))" "$gt" "$gc" "$gm" "$pt" "$pc" "$pm" "$(ratio "$gt" "$pt")" "$(ratio "$gc" "$pc")"
done

# The simulation again, ROUNDS - 1 more times into new databases (the first
# run above made the surveys measured): the best of them all, like every
# other figure.
for _ in $(seq 2 "$rounds"); do
  rm -rf again.db again.db-wal again.db-shm again.db.survey-1
  run_timed run36000 "$survey" --db again.db run --points 36000 --bidirectional --json
done
read -r st sm sc _ <<<"$(best run36000)"
instrument="$("$python" -c 'import json, sys; print(round(json.load(sys.stdin)["instrument_time_s"]))' < run36000.json)"
printf 'simulating the 36000-point survey (survey run, with its processing): %s s wall, %s s CPU, %s MiB%s\n' \
  "$st" "$sc" "$sm" ", $instrument s of instrument time"
