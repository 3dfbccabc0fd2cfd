#!/usr/bin/env bash
# A laboratory's store at two sizes 10x apart (issue 40 items 1 and 3):
# SMALL (default 300) then LARGE (default 3000) surveys of 50 assets, each a
# small simulated survey (36 targets x 2 runs, both ways; `survey run
# --asset a-NN`, which keeps each survey's history as it completes), in a
# station's SQLite file and, pushed there, in a PostgreSQL lab store
# (started here: scripts/pg_lab.sh). At each size, best of ROUNDS
# (default 3) wall times:
#
# - `survey list --json`; `survey history --asset a-00 --json` read from
#   what was kept, and computed on read (a copy of the file without the
#   kept history: what a database of schema 7, or a command before issue
#   40, does);
# - `survey push` of one new survey to the lab store; `push --all` of the
#   whole station into a new database (once: it is the lab store read below);
# - `survey list` and `survey history` on the lab store;
# - `survey serve` on both: `/`, an asset's page, a survey's page and
#   `/api/live` alone, then 8 clients each opening an asset's page 5 times
#   while one more polls `/api/live` every 50 ms (scripts/serve_load.py).
#
#   scripts/lab_scale.sh [PYTHON]
#
# SURVEY is the binary (default: the release build, $CARGO_TARGET_DIR or
# target/); KEEP=DIR keeps the databases in DIR. Needs GNU time.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
python="${1:-python3}"
rounds="${ROUNDS:-3}"
small="${SMALL:-300}" large="${LARGE:-3000}" assets=50
survey="${SURVEY:-${CARGO_TARGET_DIR:-$here/target}/release/survey}"
work="${KEEP:-$(mktemp -d)}"
mkdir -p "$work"
chmod 755 "$work" # the lab store's server runs as nobody when this runs as root
source "$here/scripts/pg_lab.sh"
serving=""
trap '[[ -n "$serving" ]] && kill "$serving" 2>/dev/null; stop_lab; [[ -z "${KEEP:-}" ]] && rm -rf "$work"' EXIT
cd "$work"
mkdir -p pg
start_lab "$work/pg" || { echo "the lab store could not be started" >&2; exit 1; }

run_timed() { # label command... -> appends "label wall_s peak_kib cpu_s" to times.txt
  local label="$1"
  shift
  if ! /usr/bin/time -f "%e %M %U %S" -o t.txt "$@" >out.txt 2>err.txt; then cat err.txt >&2; echo "failed: $*" >&2; return 1; fi
  read -r t m u s < t.txt
  echo "$label $t $m $(awk -v u="$u" -v s="$s" 'BEGIN {printf "%.2f", u + s}')" >> times.txt
}
best() { # label -> "best_wall_s peak_mib"
  awk -v l="$1" '$1 == l { if (b == "" || $2 < b) b = $2; if ($3 > m) m = $3 } END { printf "%s %d\n", b, m / 1024 }' times.txt
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (b > 0) printf "%.1f", a / b; else printf "-" }'; }

made=0
grow() { # surveys -> the station holds that many
  local start=$SECONDS
  while (( made < $1 )); do
    "$survey" --db station.db run --points 36 --runs 2 --bidirectional --seed "$made" \
      --asset "a-$(printf %02d $((made % assets)))" --json > /dev/null 2>> build.log
    made=$((made + 1))
  done
  echo "station: $made surveys ($((SECONDS - start)) s to add the last ones)"
}

pages() { # db label -> serve_load.py's document in pages-label.json
  "$survey" --db "$1" serve --listen 127.0.0.1:0 > serve.out 2> serve.err &
  serving=$!
  for _ in $(seq 100); do grep -q listening serve.out 2>/dev/null && break; sleep 0.1; done
  local url uid
  url="$("$python" -c 'import json; print(json.load(open("serve.out"))["listening"])')"
  uid="$("$survey" --db "$1" history --asset a-00 --json | "$python" -c 'import json, sys; print(json.load(sys.stdin)["surveys"][-1]["uid"])')"
  "$python" "$here/scripts/serve_load.py" "$url" / /assets/a-00 "/surveys/$uid" /api/live --alone "$rounds" \
    --clients 1 --rounds 1 > "alone-$2.json"
  local paths=()
  for k in 0 1 2 3 4 5 6 7; do paths+=("/assets/a-0$k"); done
  "$python" "$here/scripts/serve_load.py" "$url" "${paths[@]}" --alone 1 --clients 8 --rounds 5 > "load-$2.json"
  kill "$serving"; wait "$serving" 2>/dev/null || true
  serving=""
}

: > times.txt
for n in "$small" "$large"; do
  grow "$n"
  rm -f read.db*; cp station.db read.db
  "$python" -c 'import sqlite3, sys; c = sqlite3.connect(sys.argv[1]); c.executescript("DELETE FROM survey_summaries; DELETE FROM survey_changes;"); c.close()' read.db
  lab="$(lab_database "lab_$n")"
  run_timed "pushall$n" "$survey" --db station.db push --to "$lab" --all --json
  for _ in $(seq "$rounds"); do
    run_timed "list$n" "$survey" --db station.db list --json
    run_timed "history$n" "$survey" --db station.db history --asset a-00 --json
    run_timed "computed$n" "$survey" --db read.db history --asset a-00 --json
    run_timed "lablist$n" "$survey" --db "$lab" list --json
    run_timed "labhistory$n" "$survey" --db "$lab" history --asset a-00 --json
    # One more survey, pushed alone.
    "$survey" --db station.db run --points 36 --runs 2 --bidirectional --seed "$made" --asset a-00 --json > /dev/null 2>> build.log
    made=$((made + 1))
    run_timed "pushone$n" "$survey" --db station.db push --to "$lab" --json
  done
  cmp <("$survey" --db station.db history --asset a-00 --json) <("$survey" --db read.db history --asset a-00 --json) >/dev/null 2>&1 \
    || echo "note: read.db misses the surveys added since it was copied (expected)"
  pages station.db "station$n"
  pages "$lab" "lab$n"
done

printf '\n%-34s %-18s %-18s %s\n' "" "$small surveys" "$large surveys" "ratio"
for row in "list:survey list (station)" "history:history of a-00, kept" "computed:history of a-00, computed on read" \
  "lablist:survey list (lab store)" "labhistory:history of a-00 (lab store)" "pushone:push of one new survey" \
  "pushall:push --all into a new lab store"; do
  key="${row%%:*}" name="${row#*:}"
  read -r a am <<<"$(best "$key$small")"
  read -r b bm <<<"$(best "$key$large")"
  printf '%-34s %-18s %-18s %s\n' "$name" "$a s, $am MiB" "$b s, $bm MiB" "$(ratio "$b" "$a")"
done
for side in station lab; do
  for n in "$small" "$large"; do
    "$python" - "$side" "$n" "alone-$side$n.json" "load-$side$n.json" <<'EOF'
import json, sys
side, n, alone, load = sys.argv[1:]
a, l = json.load(open(alone)), json.load(open(load))
pages = ", ".join(f"{p} {v['best_s']:.3f} s" for p, v in a["alone"].items())
slowest = max(v["slowest_s"] for v in l["under_load"].values())
print(f"serve ({side}, {n} surveys): alone {pages}; 8 clients on asset pages: slowest {slowest:.3f} s, "
      f"/api/live slowest {l['live']['slowest_s']:.3f} s over {l['live']['n']} polls")
EOF
  done
done
