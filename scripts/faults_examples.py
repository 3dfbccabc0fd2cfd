#!/usr/bin/env python3
"""Every shipped configuration through `survey sim --faults RATE`, from outside.

For each configuration of examples/config/ and each seed: `survey sim --config
X --faults RATE --seed S --time-scale T` serves its instruments; `survey run
--config <the configuration sim wrote>` surveys them (a smaller plan than the
shipped one: --points/--runs below, the polygon configurations at their faces),
then `survey resume` up to --resumes times while the survey is interrupted. A
survey counts as complete when it is `complete` with every planned sample once
(`survey show --json`: its samples against its plan, the seq of each).

    scripts/faults_examples.py --bin target/debug/survey --seeds 1,2,3 [--only canopen] [--unverified]

Prints one line per survey and a table: completions per configuration, and how
many resumes each needed.
"""

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLES = os.path.join(HERE, "..", "examples", "config")
FAULT_RATES = [""]


def start_sim(binary, config, rate, seed, scale, folder):
    err = open(os.path.join(folder, "sim.err"), "w")
    sim = subprocess.Popen(
        [binary, "sim", "--config", config, "--faults", str(rate), "--seed", str(seed), "--time-scale", str(scale)]
        + (["--fault-rates", FAULT_RATES[0]] if FAULT_RATES[0] else []),
        stdout=subprocess.PIPE,
        stderr=err,
        text=True,
        env={k: v for k, v in os.environ.items() if k != "RUST_LOG"},
    )
    line = sim.stdout.readline()
    ready = json.loads(line)
    return sim, ready["config"]


def stop_sim(sim):
    sim.send_signal(signal.SIGTERM)
    out = sim.stdout.read()
    sim.wait(timeout=30)
    for line in out.splitlines():
        if '"stopped"' in line:
            return json.loads(line).get("faults", {})
    return {}


def show(binary, db):
    r = subprocess.run([binary, "--db", db, "show", "--json"], capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        return None
    return json.loads(r.stdout)


def last_error(binary, db):
    doc = show(binary, db)
    if not doc:
        return ""
    events = doc.get("events") or []
    for e in reversed(events):
        if e.get("level") == "error":
            return e.get("message", "")[:300]
    return ""


def one(binary, name, rate, seed, args):
    folder = tempfile.mkdtemp(prefix="faults-")
    config = os.path.join(EXAMPLES, name)
    if args.unverified and "scpi" in name:
        # The SCPI controller with FAUL:CLE (`unverified_commands = true`):
        # without it a trip stops the survey, saying to clear it at the controller.
        text = open(config).read().replace("[positioner]\n", "[positioner]\nunverified_commands = true\n", 1)
        config = os.path.join(folder, name)
        open(config, "w").write(text)
    db = os.path.join(folder, "s.db")
    sim, written = start_sim(binary, config, rate, seed, args.time_scale, folder)
    started = time.time()
    polygon = "[autocollimator]" in open(config).read()
    plan = ["--runs", str(args.runs)] + ([] if polygon else ["--points", str(args.points)])
    tries = []
    try:
        cmd = [binary, "--db", db, "run", "--config", written] + plan
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout)
        tries.append(r.returncode)
        while r.returncode != 0 and len(tries) <= args.resumes:
            if show(binary, db) is None:
                break  # nothing stored: nothing to resume
            r = subprocess.run([binary, "--db", db, "resume"], capture_output=True, text=True, timeout=args.timeout)
            tries.append(r.returncode)
        doc = show(binary, db)
    finally:
        faults = stop_sim(sim)
    status = doc["status"] if doc else "nothing stored"
    samples = planned = 0
    once = False
    if doc:
        # The store keys a sample by (survey, seq): none is stored twice, so
        # as many samples as planned is every sample once.
        samples = doc.get("samples") or 0
        planned = doc.get("planned_samples") or 0
        once = samples == planned
    complete = status == "complete" and once
    why = "" if complete else (last_error(binary, db) or (r.stderr.strip().splitlines() or [""])[-1][:300])
    return {
        "config": name,
        "seed": seed,
        "complete": complete,
        "status": status,
        "samples": samples,
        "planned": planned,
        "resumes": len(tries) - 1,
        "exits": tries,
        "seconds": round(time.time() - started, 1),
        "injected": faults.get("injected"),
        "replies": faults.get("replies"),
        "why": why,
    }


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--bin", default=os.path.join(HERE, "..", "target", "debug", "survey"))
    p.add_argument("--seeds", default="1,2")
    p.add_argument("--rate", type=float, default=0.05)
    p.add_argument("--points", type=int, default=12)
    p.add_argument("--runs", type=int, default=2)
    p.add_argument("--resumes", type=int, default=2)
    p.add_argument("--time-scale", type=float, default=100)
    p.add_argument("--timeout", type=float, default=900)
    p.add_argument("--only", default="", help="configurations whose name contains this")
    p.add_argument("--unverified", action="store_true", help="SCPI configurations with unverified_commands = true")
    p.add_argument("--fault-rates", default="", help="survey sim's --fault-rates over --faults (e.g. move=0)")
    args = p.parse_args()
    FAULT_RATES[0] = args.fault_rates
    names = sorted(n for n in os.listdir(EXAMPLES) if n.endswith(".toml") and args.only in n)
    seeds = [int(s) for s in args.seeds.split(",")]
    table = {}
    for name in names:
        for seed in seeds:
            r = one(args.bin, name, args.rate, seed, args)
            print(json.dumps(r), flush=True)
            t = table.setdefault(name, [0, 0, []])
            t[1] += 1
            if r["complete"]:
                t[0] += 1
                t[2].append(r["resumes"])
    print(f"\n{'configuration':32} complete  resumes needed", file=sys.stderr)
    for name, (ok, n, resumes) in table.items():
        print(f"{name:32} {ok}/{n}       {resumes}", file=sys.stderr)


if __name__ == "__main__":
    main()
