#!/usr/bin/env python3
"""A burst of heavy requests against `survey serve`, and its memory:
CLIENTS clients ask PATH at once (one request each) while one more polls
`/api/live` every 50 ms; prints one JSON document with the server's
resident memory (VmRSS of PID) before, at its peak during the burst and
2 s after, the statuses counted, the slowest answer, and the slowest
`/api/live` answer during the burst. Standard library only.

    python scripts/serve_burst.py URL PID PATH [--clients 200]
"""

import argparse
import json
import threading
import time
import urllib.error
import urllib.request


def rss_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return round(int(line.split()[1]) / 1024, 1)
    return None


def fetch(url):
    start = time.perf_counter()
    try:
        with urllib.request.urlopen(url, timeout=300) as r:
            r.read()
            status = r.status
    except urllib.error.HTTPError as e:
        status = e.code
    return status, time.perf_counter() - start


def main():
    p = argparse.ArgumentParser()
    p.add_argument("url")
    p.add_argument("pid", type=int)
    p.add_argument("path")
    p.add_argument("--clients", type=int, default=200)
    a = p.parse_args()
    before = rss_mib(a.pid)
    statuses, times, live = {}, [], []
    lock = threading.Lock()
    done = threading.Event()
    peak = [before]

    def client():
        s, t = fetch(a.url + a.path)
        with lock:
            statuses[s] = statuses.get(s, 0) + 1
            times.append(t)

    def poll():
        while not done.is_set():
            live.append(fetch(a.url + "/api/live")[1])
            peak[0] = max(peak[0], rss_mib(a.pid))
            time.sleep(0.05)

    poller = threading.Thread(target=poll)
    poller.start()
    start = time.perf_counter()
    threads = [threading.Thread(target=client) for _ in range(a.clients)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    wall = time.perf_counter() - start
    done.set()
    poller.join()
    time.sleep(2)
    print(json.dumps({
        "path": a.path, "clients": a.clients, "statuses": statuses, "wall_s": round(wall, 2),
        "slowest_s": round(max(times), 3), "live_slowest_s": round(max(live), 3) if live else None,
        "rss_mib": {"before": before, "peak": peak[0], "after_2s": rss_mib(a.pid)},
    }))


if __name__ == "__main__":
    main()
