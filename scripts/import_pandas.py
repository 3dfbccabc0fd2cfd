#!/usr/bin/env python3
"""`survey import` written with pandas and the standard library's sqlite3:
the reference the Rust command is timed against, whole process against
whole process.

    python scripts/import_pandas.py FILE.csv DB

What it does is what `survey import` does with a valid file, the way a
pandas user would write it:

1. read the contract's survey CSV (`run,direction,target_deg,readout_deg,
   actual_deg[,timestamp_s]`) with `pandas.read_csv`, the floats parsed
   to the bit (pandas 3's default; `float_precision="round_trip"` before
   it: `survey` keeps every bit);
2. check it as the contract asks: the header, `run` an integer from 1,
   `direction` `forward` or `reverse`, finite target, readout and actual
   angles, no sample twice (the same run, direction and target); the first
   row at fault is named with its line;
3. store it in one transaction into an SQLite file in WAL mode with
   `synchronous=FULL` (as `survey` stores): a survey row, then one row a
   sample (`to_sql`, many rows a statement), numbered in acquisition order;
4. print the new survey's id.

It stores what `survey import` stores of the samples (the same columns), not
the rest of the survey's schema (no sample packs, no uid): it is the bulk
read-check-write that is compared. Needs pandas from PyPI:

    python3 -m venv /tmp/pd && /tmp/pd/bin/pip install pandas
    /tmp/pd/bin/python scripts/import_pandas.py survey.csv pandas.db

`scripts/compare_commands.sh` times both at 36000 and 360000 rows.
"""

import sqlite3
import sys

import numpy as np
import pandas as pd

COLUMNS = ["run", "direction", "target_deg", "readout_deg", "actual_deg"]


def fail(path, line, why):
    sys.exit(f"{path}: line {line}: {why}")


def read(path):
    # pandas 3 parses floats to the bit by default (and deprecates the option).
    exact = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
    frame = pd.read_csv(path, dtype={"direction": "string"}, **exact)
    header = list(frame.columns)
    if header[:5] != COLUMNS or header[5:] not in ([], ["timestamp_s"]):
        fail(path, 1, f"the header must be {','.join(COLUMNS)}[,timestamp_s], not {','.join(header)}")
    run = pd.to_numeric(frame["run"], errors="coerce")
    bad = run.isna() | (run < 1) | (run != np.floor(run))
    if bad.any():
        fail(path, int(np.argmax(bad.to_numpy())) + 2, "run must be an integer from 1")
    bad = ~frame["direction"].isin(["forward", "reverse"]).fillna(False).to_numpy()
    if bad.any():
        fail(path, int(np.argmax(bad)) + 2, "direction must be forward or reverse")
    for col in COLUMNS[2:]:
        values = pd.to_numeric(frame[col], errors="coerce").to_numpy()
        bad = ~np.isfinite(values)
        if bad.any():
            fail(path, int(np.argmax(bad)) + 2, f"{col} must be a finite number")
    twice = frame.duplicated(["run", "direction", "target_deg"]).to_numpy()
    if twice.any():
        fail(path, int(np.argmax(twice)) + 2, "this sample (run, direction, target) is there twice")
    frame["run"] = run.astype("int64")
    if "timestamp_s" not in frame:
        frame["timestamp_s"] = np.nan
    return frame


def store(frame, db):
    con = sqlite3.connect(db)
    con.execute("PRAGMA journal_mode = WAL")
    con.execute("PRAGMA synchronous = FULL")
    con.execute(
        "CREATE TABLE IF NOT EXISTS surveys (id INTEGER PRIMARY KEY, status TEXT NOT NULL, source TEXT NOT NULL, "
        "points INTEGER, runs INTEGER, bidirectional INTEGER NOT NULL, planned_samples INTEGER)"
    )
    con.execute(
        "CREATE TABLE IF NOT EXISTS samples (survey_id INTEGER NOT NULL REFERENCES surveys (id), seq INTEGER NOT NULL, "
        "run INTEGER NOT NULL, direction TEXT NOT NULL, target_deg REAL NOT NULL, readout_deg REAL NOT NULL, "
        "actual_deg REAL NOT NULL, timestamp_s REAL, PRIMARY KEY (survey_id, seq))"
    )
    # One transaction: the survey row opens it, `to_sql` commits it.
    cur = con.execute(
        "INSERT INTO surveys (status, source, points, runs, bidirectional, planned_samples) VALUES (?, ?, ?, ?, ?, ?)",
        (
            "imported",
            "import:" + sys.argv[1],
            int(frame["target_deg"].nunique()),
            int(frame["run"].max()),
            int((frame["direction"] == "reverse").any()),
            len(frame),
        ),
    )
    survey_id = cur.lastrowid
    rows = frame[COLUMNS + ["timestamp_s"]].copy()
    rows.insert(0, "seq", np.arange(len(rows), dtype="int64"))
    rows.insert(0, "survey_id", survey_id)
    # 8 columns a row: 124 rows a statement stays under SQLite's 999 bound variables of old builds.
    rows.to_sql("samples", con, if_exists="append", index=False, method="multi", chunksize=124)
    con.commit()
    con.close()
    return survey_id


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    print(store(read(sys.argv[1]), sys.argv[2]))


if __name__ == "__main__":
    main()
