#!/usr/bin/env python3
"""Does a page polling `survey serve` slow a survey acquired into the same SQLite file?

Usage: python3 scripts/serve_polling.py [TIME_SCALE [REPEATS]] (defaults 20 and 3), from the
repository root after `cargo build` (or SURVEY=path/to/survey). Each repeat runs the same
survey (36 targets both ways, 2 runs, against `survey sim --time-scale`) without a server,
then with `survey serve` on the file and a client fetching `/` and `/api/live` every second,
and prints the wall time and the instrument-time ratio (instrument_time_s / bound_s) of each.
Figures: docs/serve.md.
"""
import json, shutil, subprocess, sys, time, os, tempfile, threading, urllib.request, statistics
S = os.path.abspath(os.environ.get("SURVEY", "target/debug/survey"))
SCALE = float(sys.argv[1]) if len(sys.argv) > 1 else 20
N = int(sys.argv[2]) if len(sys.argv) > 2 else 3
def cfg(p, t):
    return ("[survey]\nreference = \"tracker\"\npoints = 36\nruns = 2\nbidirectional = true\n"
            f"[positioner]\ndriver = \"modbus-tcp\"\naddress = \"{p}\"\n"
            f"[tracker]\ndriver = \"emscon\"\naddress = \"{t}\"\n"
            "[timing]\ndwell_s = 0.01\npoll_interval_s = 0.02\n")
def one(poll):
    d = tempfile.mkdtemp()
    open(f"{d}/sim.toml", "w").write(cfg("127.0.0.1:0", "127.0.0.1:0"))
    sim = subprocess.Popen([S, "sim", "--config", "sim.toml", "--time-scale", str(SCALE), "--seed", "3"], cwd=d,
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    ready = json.loads(sim.stdout.readline())
    ins = ready["instruments"]
    open(f"{d}/run.toml", "w").write(cfg(ins["positioner"], ins["tracker"]))
    srv = None; stop = threading.Event(); polls = [0, 0]
    if poll:
        srv = subprocess.Popen([S, "serve", "--listen", "127.0.0.1:0"], cwd=d, stdout=subprocess.PIPE,
                               stderr=subprocess.DEVNULL, text=True)
        url = json.loads(srv.stdout.readline())["listening"]
        def poller():
            # A page open on `/`: loaded once, then /api/live every second; and `/` reloaded every second too.
            while not stop.is_set():
                for path in ["/", "/api/live"]:
                    try:
                        urllib.request.urlopen(url + path).read(); polls[0] += 1
                    except Exception:
                        polls[1] += 1
                stop.wait(1.0)
        th = threading.Thread(target=poller); th.start()
    t0 = time.monotonic()
    out = subprocess.run([S, "run", "--config", "run.toml", "--json"], cwd=d, capture_output=True, text=True)
    wall = time.monotonic() - t0
    stop.set()
    if srv: th.join(); srv.terminate(); srv.wait()
    sim.terminate(); sim.wait()
    shutil.rmtree(d)
    doc = json.loads(out.stdout)
    assert doc["status"] == "complete" and doc["samples"] == 144, out.stderr
    return wall, doc["instrument_time_s"], doc["bound_s"], polls
res = {False: [], True: []}
for i in range(N):
    for poll in (False, True):
        r = one(poll); res[poll].append(r)
        print(("poll" if poll else "none"), "wall %.2f s, instrument %.2f s, bound %.2f s, ratio %.4f, requests ok %d failed %d" % (r[0], r[1], r[2], r[1]/r[2], r[3][0], r[3][1]), flush=True)
for poll in (False, True):
    w = [r[0] for r in res[poll]]; q = [r[1]/r[2] for r in res[poll]]
    print(("poll" if poll else "none"), "wall mean %.2f s (min %.2f, max %.2f); ratio mean %.4f (min %.4f, max %.4f)" % (statistics.mean(w), min(w), max(w), statistics.mean(q), min(q), max(q)))
