#!/usr/bin/env bash
# Every command of one survey at two sizes 10x apart (issue 40 item 1):
# 36000 and 360000 samples, Figure 8 surveys the simulated tracker acquired
# (`survey run --points 3600|36000 --bidirectional`: 5 runs, both ways).
# Each command is run ROUNDS times (default 3) at each size, the sizes
# alternated, and the best wall time, the best CPU time (user + system) and
# the peak resident memory are printed with the ratio of the large to the
# small (10 is linear):
#
# - `survey export --csv`, `survey import` of that CSV (into a new file each
#   time) and scripts/import_pandas.py, the same file loaded by pandas and
#   sqlite3, side by side;
# - `survey process`, `survey show`, `survey stats`, `survey report`;
# - `survey push` of the survey into a new lab store database each time
#   (PostgreSQL, started here in the temporary folder: scripts/pg_lab.sh;
#   skipped without it);
# - `survey serve`: the survey's page (`/surveys/<uid>`, its report) and
#   its statistics (`/api/surveys/<uid>/stats`), best of ROUNDS requests.
#
#   scripts/compare_commands.sh [PYTHON]
#
# PYTHON has pandas (default python3). SURVEY is the binary (default: the
# release build, $CARGO_TARGET_DIR or target/). Needs GNU time.
# scripts/lab_scale.sh measures what grows with the store (list, history,
# the pages of a lab) instead.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
python="${1:-python3}"
rounds="${ROUNDS:-3}"
survey="${SURVEY:-${CARGO_TARGET_DIR:-$here/target}/release/survey}"
work="$(mktemp -d)"
chmod 755 "$work" # the lab store's server runs as nobody when this runs as root
source "$here/scripts/pg_lab.sh"
trap 'stop_lab; rm -rf "$work"' EXIT
cd "$work"

run_timed() { # label command... -> appends "label wall_s peak_kib cpu_s" to times.txt
  local label="$1"
  shift
  if ! /usr/bin/time -f "%e %M %U %S" -o t.txt "$@" >out.txt 2>err.txt; then cat err.txt >&2; echo "failed: $*" >&2; return 1; fi
  read -r t m u s < t.txt
  echo "$label $t $m $(awk -v u="$u" -v s="$s" 'BEGIN {printf "%.2f", u + s}')" >> times.txt
}
best() { # label -> "best_wall_s peak_mib best_cpu_s"
  awk -v l="$1" '$1 == l { if (b == "" || $2 < b) b = $2; if ($3 > m) m = $3; if (c == "" || $4 < c) c = $4 }
    END { printf "%s %d %s\n", b, m / 1024, c }' times.txt
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (b > 0) printf "%.1f", a / b; else printf "-" }'; }
fresh() { rm -rf "$1" "$1-wal" "$1-shm"; }

: > times.txt
printf 'machine: %s cores, %s; %s; best of %s rounds\n\n' "$(nproc)" \
  "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')" "$("$survey" --version)" "$rounds"

sizes=(3600 36000)
declare -A uid
for points in "${sizes[@]}"; do
  "$survey" --db "s$points.db" run --points "$points" --bidirectional --json > /dev/null 2>&1
  "$survey" --db "s$points.db" export --csv "s$points.csv"
  uid["$points"]="$("$survey" --db "s$points.db" show --json | "$python" -c 'import json, sys; print(json.load(sys.stdin)["uid"])')"
done
lab=""
if mkdir -p pg && start_lab "$work/pg"; then lab=yes; else echo "(no PostgreSQL: push not measured)"; fi

for round in $(seq "$rounds"); do
  for points in "${sizes[@]}"; do
    db="s$points.db"
    run_timed "export$points" "$survey" --db "$db" export --csv e.csv
    fresh i.db; run_timed "import$points" "$survey" --db i.db import "s$points.csv"
    fresh p.db; run_timed "pandas$points" "$python" "$here/scripts/import_pandas.py" "s$points.csv" p.db
    run_timed "process$points" "$survey" --db "$db" process --json --table-out t.csv
    run_timed "show$points" "$survey" --db "$db" show --json
    run_timed "stats$points" "$survey" --db "$db" stats --json
    rm -rf r; run_timed "report$points" "$survey" --db "$db" report --out r
    if [[ -n "$lab" ]]; then
      url="$(lab_database "push_${points}_$round")"
      run_timed "push$points" "$survey" --db "$db" push --to "$url" --json
    fi
  done
done

# The survey's page and statistics on `survey serve`.
for points in "${sizes[@]}"; do
  "$survey" --db "s$points.db" serve --listen 127.0.0.1:0 > serve.out 2>/dev/null &
  pid=$!
  for _ in $(seq 100); do grep -q listening serve.out 2>/dev/null && break; sleep 0.1; done
  url="$("$python" -c 'import json; print(json.load(open("serve.out"))["listening"])')"
  "$python" "$here/scripts/serve_load.py" "$url" "/surveys/${uid[$points]}" "/api/surveys/${uid[$points]}/stats" \
    --alone "$rounds" --clients 1 --rounds 1 > "serve$points.json"
  kill "$pid"; wait "$pid" 2>/dev/null || true
done

printf '%-16s %-30s %-30s %s\n' command "36000 samples (wall, CPU, MiB)" "360000 samples" "ratio (wall, CPU, MiB)"
for c in export import pandas process show stats report push; do
  grep -q "^${c}3600 " times.txt || continue
  read -r t0 m0 c0 <<<"$(best "${c}3600")"
  read -r t1 m1 c1 <<<"$(best "${c}36000")"
  name="survey $c"
  [[ "$c" == pandas ]] && name="import_pandas.py"
  printf '%-16s %-30s %-30s %s\n' "$name" "$t0 s, $c0 s, $m0 MiB" "$t1 s, $c1 s, $m1 MiB" \
    "$(ratio "$t1" "$t0"), $(ratio "$c1" "$c0"), $(ratio "$m1" "$m0")"
done
for page in surveys stats; do
  read -r a0 a1 <<<"$("$python" - "$page" serve3600.json serve36000.json <<'EOF'
import json, sys
page = sys.argv[1]
def best(f):
    d = json.load(open(f))["alone"]
    return next(v["best_s"] for k, v in d.items() if (k.endswith("/stats")) == (page == "stats"))
print(best(sys.argv[2]), best(sys.argv[3]))
EOF
)"
  printf '%-16s %-30s %-30s %s\n' "serve /$page" "$a0 s" "$a1 s" "$(ratio "$a1" "$a0")"
done
read -r i1 _ <<<"$(best import36000)"
read -r p1 _ <<<"$(best pandas36000)"
printf '\nimport of 360000 rows: survey %s s, pandas + sqlite3 %s s (pandas / survey = %s)\n' "$i1" "$p1" "$(ratio "$p1" "$i1")"
