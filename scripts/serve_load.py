#!/usr/bin/env python3
"""Time `survey serve`'s pages: each path alone, then CLIENTS clients at
once, each fetching its path ROUNDS times in a loop, while one more client
polls `/api/live` every 50 ms; prints one JSON document.

    python scripts/serve_load.py URL PATH [PATH...] [--clients 8] [--rounds 5] [--alone 5]

URL is the server's (`http://127.0.0.1:PORT`, what `survey serve --listen
127.0.0.1:0` prints on its ready line). Each PATH is fetched `--alone` times
on its own first (the best and the median are printed); then the clients
fetch the paths given, client k the path k modulo their count (every
response must be 200). The document gives, per path, the best and median
time alone, and under load the slowest and median response of the clients
and the slowest `/api/live` answer while they ran. Standard library only.
"""

import argparse
import json
import statistics
import threading
import time
import urllib.request


def fetch(url):
    start = time.perf_counter()
    with urllib.request.urlopen(url, timeout=120) as r:
        r.read()
        if r.status != 200:
            raise SystemExit(f"{url}: status {r.status}")
    return time.perf_counter() - start


def main():
    p = argparse.ArgumentParser()
    p.add_argument("url")
    p.add_argument("paths", nargs="+")
    p.add_argument("--clients", type=int, default=8)
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--alone", type=int, default=5)
    a = p.parse_args()
    out = {"alone": {}, "clients": a.clients, "rounds": a.rounds}
    for path in a.paths:
        times = [fetch(a.url + path) for _ in range(a.alone)]
        out["alone"][path] = {"best_s": round(min(times), 4), "median_s": round(statistics.median(times), 4)}

    results = {path: [] for path in a.paths}
    lock = threading.Lock()
    done = threading.Event()

    def client(k):
        path = a.paths[k % len(a.paths)]
        for _ in range(a.rounds):
            t = fetch(a.url + path)
            with lock:
                results[path].append(t)

    live = []

    def poll():
        while not done.is_set():
            live.append(fetch(a.url + "/api/live"))
            time.sleep(0.05)

    poller = threading.Thread(target=poll)
    poller.start()
    clients = [threading.Thread(target=client, args=(k,)) for k in range(a.clients)]
    start = time.perf_counter()
    for c in clients:
        c.start()
    for c in clients:
        c.join()
    wall = time.perf_counter() - start
    done.set()
    poller.join()
    out["under_load"] = {
        path: {"slowest_s": round(max(t), 4), "median_s": round(statistics.median(t), 4), "n": len(t)}
        for path, t in results.items()
        if t
    }
    out["under_load_wall_s"] = round(wall, 3)
    out["live"] = {"slowest_s": round(max(live), 4), "median_s": round(statistics.median(live), 4), "n": len(live)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
