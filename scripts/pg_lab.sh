# A throwaway PostgreSQL cluster for the benchmarks (sourced, not run):
# `start_lab DIR` starts one in DIR on a free loopback port (as `nobody`
# when run as root: the server refuses root) and sets LAB_PSQL and
# lab_url; `lab_database NAME` makes an empty database and prints its URL;
# `stop_lab` stops the cluster. Needs Debian's postgresql package
# (/usr/lib/postgresql/*/bin), as `tests/cli/lab.rs` does.

start_lab() {
  local dir="$1" bin
  bin="$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -1)"
  [[ -x "$bin/initdb" ]] || { echo "no PostgreSQL server (/usr/lib/postgresql/*/bin/initdb)" >&2; return 1; }
  LAB_BIN="$bin" LAB_DIR="$dir"
  local as=()
  if [[ "$(id -u)" == 0 ]]; then
    as=(runuser -u nobody --)
    chown nobody "$dir"
  fi
  LAB_AS=("${as[@]}")
  echo lab-pw > "$dir/pw"
  if [[ "$(id -u)" == 0 ]]; then
    chown nobody "$dir/pw"
    # The server's user must reach its folder.
    "${as[@]}" test -w "$dir" || { echo "nobody cannot write $dir (a parent folder closed to others?)" >&2; return 1; }
  fi
  "${as[@]}" "$bin/initdb" -D "$dir/data" -U survey -A scram-sha-256 --no-sync --pwfile="$dir/pw" >/dev/null || return 1
  LAB_PORT="$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
  "${as[@]}" "$bin/pg_ctl" -D "$dir/data" -l "$dir/log" -w start \
    -o "-p $LAB_PORT -k $dir -c listen_addresses=127.0.0.1 -c max_connections=60" >/dev/null || return 1
  lab_url="postgres://survey:lab-pw@127.0.0.1:$LAB_PORT"
}

lab_database() {
  "$LAB_BIN/psql" -X -q -d "$lab_url/postgres" -c "CREATE DATABASE $1" >/dev/null
  echo "$lab_url/$1"
}

lab_psql() { # database sql -> rows
  "$LAB_BIN/psql" -X -At -d "$lab_url/$1" -c "$2"
}

stop_lab() {
  [[ -n "${LAB_DIR:-}" ]] && "${LAB_AS[@]}" "$LAB_BIN/pg_ctl" -D "$LAB_DIR/data" -m immediate -w stop >/dev/null 2>&1
  return 0
}
