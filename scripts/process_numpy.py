#!/usr/bin/env python3
"""`survey process` written with numpy and scipy: the reference the Rust
command is timed against, whole process against whole process.

    python scripts/process_numpy.py DB [SURVEY_ID] [OUT_DIR]

It does what `survey process` does on a full-circle survey, vectorised the
way a numpy user would write it:

1. read the samples from the SQLite database (the standard library's sqlite3,
   read-only), in acquisition order;
2. the error map (readout - actual) per direction, run and target, and the
   ISO 230-2 figures (mean, s, B, R with the bidirectional term, E, M, A);
3. the noise of one sample from the scatter between runs, the spectrum of the
   mean maps in cycles per revolution (real FFT), the per-run spectra and an
   F test of each bin's run-to-run coherence (scipy.stats), the lines named
   from a design (gear and tooth harmonics, eccentricity, ellipticity);
4. the table: the significant lines kept (spectral edit), band-limited
   resampling to 131072 points and decimation to 16384 rows, directional when
   the hysteresis stands 5 standard deviations out of its noise;
5. the predicted accuracy: the table applied to every sample with linear
   interpolation (native and corrected peak and RMS, ISO A of the corrected
   samples), the Figure 6 interpolation comparison (linear, periodic cubic
   spline, spectral on the map decimated by 2), the LinuxCNC decimation to
   255 + 1 points;
6. the files: the table CSV (shortest round-trip numbers), the two LinuxCNC
   COMP_FILEs, the binary table (little-endian f64) and a small recipe.

Needs numpy and scipy from PyPI:

    python3 -m venv /tmp/np && /tmp/np/bin/pip install numpy scipy
    /tmp/np/bin/python scripts/process_numpy.py survey.db

`scripts/compare_process.sh` times both at several sizes.
"""

import json
import os
import sqlite3
import sys

import numpy as np
from scipy import stats
from scipy.interpolate import CubicSpline

DENSE = 131072
ROWS = 16384
LINUXCNC = 256
ALPHA = 0.01


def load(db, survey_id):
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    if survey_id is None:
        survey_id = con.execute("SELECT MAX(id) FROM surveys").fetchone()[0]
    model = con.execute("SELECT model_toml FROM surveys WHERE id = ?", (survey_id,)).fetchone()[0] or ""
    rows = con.execute(
        "SELECT run, direction = 'reverse', target_deg, readout_deg, actual_deg "
        "FROM samples WHERE survey_id = ? ORDER BY seq",
        (survey_id,),
    ).fetchall()
    con.close()
    a = np.array(rows, dtype=np.float64)
    return survey_id, model, a[:, 0].astype(np.int64), a[:, 1].astype(bool), a[:, 2], a[:, 3], a[:, 4]


def design_from(model_toml):
    gears, teeth = [], []
    for line in model_toml.splitlines():
        key, _, value = line.partition("=")
        key = key.strip()
        if key in ("gear_ratios", "tooth_counts"):
            nums = [float(x) for x in value.strip().strip("[]").split(",") if x.strip()]
            (gears if key == "gear_ratios" else teeth).extend(nums)
    return gears, teeth


def name_line(k, gears, teeth):
    if k == 1:
        return "eccentricity"
    if k == 2:
        return "ellipticity"
    for g in gears:
        if g > 0 and abs(k / g - round(k / g)) < 1e-9:
            return f"gear pass {g:g}:1, harmonic {round(k / g)}"
    for t in teeth:
        if t > 0 and abs(k / t - round(k / t)) < 1e-9:
            return f"tooth mesh {t:g}, harmonic {round(k / t)}"
    return "unknown"


def iso230(x):
    """x[direction, run, target]: deviations actual - target."""
    mean = x.mean(axis=1)
    s = x.std(axis=1, ddof=1)
    up, down = mean[0], mean[-1]
    b = up - down
    r_i = np.maximum(2 * s[0] + 2 * s[-1] + np.abs(b), np.maximum(4 * s[0], 4 * s[-1]))
    a = (mean + 2 * s).max() - (mean - 2 * s).min()
    return {
        "A": a,
        "R": r_i.max(),
        "B": np.abs(b).max(),
        "B_mean": b.mean(),
        "E": mean.max() - mean.min(),
        "M": ((up + down) / 2).max() - ((up + down) / 2).min(),
    }


def resample(y, m):
    """Band-limited resampling of one period to m points (up or down)."""
    n = len(y)
    spec = np.fft.rfft(y)
    out = np.zeros(m // 2 + 1, dtype=complex)
    h = min(n, m) // 2
    out[: h + 1] = spec[: h + 1]
    if min(n, m) % 2 == 0:
        out[h] *= 0.5
    return np.fft.irfft(out, m) * (m / n)


def periodic_interp(table, readout):
    n = len(table)
    grid = np.arange(n + 1) * 360.0 / n
    return np.interp(np.mod(readout, 360.0), grid, np.append(table, table[0]))


def main():
    db = sys.argv[1]
    survey_id = int(sys.argv[2]) if len(sys.argv) > 2 else None
    out_dir = sys.argv[3] if len(sys.argv) > 3 else "."
    survey_id, model, run, reverse, target, readout, actual = load(db, survey_id)
    gears, teeth = design_from(model)

    # The error map: [direction, run, target].
    targets, t_index = np.unique(target, return_inverse=True)
    runs = int(run.max())
    dirs = 2 if reverse.any() else 1
    n = len(targets)
    err = np.zeros((dirs, runs, n))
    dev = np.zeros((dirs, runs, n))
    d_index = reverse.astype(np.int64) if dirs == 2 else np.zeros(len(run), dtype=np.int64)
    err[d_index, run - 1, t_index] = readout - actual
    dev[d_index, run - 1, t_index] = actual - target
    iso = iso230(dev)

    # Noise, spectra and the F test of each bin.
    mean_map = err.mean(axis=1)  # [direction, target]
    resid = err - mean_map[:, None, :] - (err.mean(axis=2, keepdims=True) - err.mean(axis=(1, 2), keepdims=True))
    dof = dirs * (runs - 1) * (n - 1)
    sigma = np.sqrt((resid**2).sum() / dof)
    bi = mean_map.mean(axis=0)
    spectrum = np.fft.rfft(bi) / n * 2
    amplitude = np.abs(spectrum)
    per_run = np.fft.rfft(err, axis=2) / n * 2  # [direction, run, bin]
    coherent = np.abs(per_run.mean(axis=1)) ** 2
    scatter = (np.abs(per_run - per_run.mean(axis=1, keepdims=True)) ** 2).sum(axis=1) / (runs - 1)
    f = coherent / np.maximum(scatter / runs, 1e-300)
    p = stats.f.sf(f.mean(axis=0), 2, 2 * (runs - 1) * dirs)
    threshold = sigma * np.sqrt(2.0 / (n * runs * dirs)) * 4.0
    significant = [k for k in range(1, len(amplitude)) if p[k] < ALPHA / len(amplitude) and amplitude[k] > threshold]
    peaks = [
        {
            "cycles_per_rev": k,
            "amplitude_deg": float(amplitude[k]),
            "phase_deg": float(np.degrees(np.angle(spectrum[k])) + 90.0),
            "source": name_line(k, gears, teeth),
            "repeatable": True,
        }
        for k in significant
    ]

    # The table.
    keep = np.zeros(len(amplitude), dtype=bool)
    keep[0] = True
    keep[significant] = True
    hysteresis = mean_map[0] - mean_map[-1]
    h_noise = sigma * np.sqrt(2.0 / runs)
    directional = dirs == 2 and np.abs(hysteresis).max() > 5 * h_noise

    def table_of(m):
        spec = np.fft.rfft(m)
        spec[~keep] = 0
        dense = resample(np.fft.irfft(spec, n), DENSE)
        return dense[:: DENSE // ROWS]

    columns = [table_of(mean_map[0]), table_of(mean_map[-1])] if directional else [table_of(bi)]

    # The predicted accuracy.
    native = readout - actual
    if directional:
        applied = np.where(reverse, periodic_interp(columns[1], readout), periodic_interp(columns[0], readout))
    else:
        applied = periodic_interp(columns[0], readout)
    corrected = native - applied
    shifted = dev.copy()
    shifted[d_index, run - 1, t_index] = -corrected
    prediction = {
        "native_peak_deg": float(np.abs(native - native.mean()).max()),
        "corrected_peak_deg": float(np.abs(corrected - corrected.mean()).max()),
        "native_rms_deg": float(np.sqrt(((native - native.mean()) ** 2).mean())),
        "corrected_rms_deg": float(np.sqrt(((corrected - corrected.mean()) ** 2).mean())),
        "corrected_iso230_a_deg": float(iso230(shifted)["A"]),
    }

    # Figure 6: the map decimated by 2, interpolated back.
    half = bi[::2]
    x_half = targets[::2]
    odd = targets[1::2]
    scores = {
        "linear": np.interp(odd, np.append(x_half, 360.0), np.append(half, half[0])) - bi[1::2],
        "cubic": CubicSpline(np.append(x_half, 360.0), np.append(half, half[0]), bc_type="periodic")(odd) - bi[1::2],
        "spectral": resample(half, n)[1::2] - bi[1::2],
    }
    interpolation = {k: float(np.sqrt((v**2).mean())) for k, v in scores.items()}

    # LinuxCNC: 255 rows low-passed, the first repeated at 360.
    comp_f = resample(columns[0], LINUXCNC - 1)
    comp_r = resample(columns[-1], LINUXCNC - 1)
    nominal = np.arange(LINUXCNC) * 360.0 / (LINUXCNC - 1)
    comp_f = np.append(comp_f, comp_f[0])
    comp_r = np.append(comp_r, comp_r[0])

    # The files.
    os.makedirs(out_dir, exist_ok=True)
    stem = os.path.join(out_dir, f"table-{survey_id}")
    readouts = np.arange(ROWS) * 360.0 / ROWS
    with open(stem + ".csv", "w") as fh:
        if directional:
            fh.write("readout_deg,error_forward_deg,error_reverse_deg\n")
            fh.write("".join(f"{r!r},{a!r},{b!r}\n" for r, a, b in zip(readouts.tolist(), columns[0].tolist(), columns[1].tolist())))
        else:
            fh.write("readout_deg,error_deg\n")
            fh.write("".join(f"{r!r},{a!r}\n" for r, a in zip(readouts.tolist(), columns[0].tolist())))
    with open(stem + ".comp0", "w") as fh:
        fh.write("".join(f"{x:.10f} {x - a:.10f} {x - b:.10f}\n" for x, a, b in zip(nominal, comp_f, comp_r)))
    with open(stem + ".comp1", "w") as fh:
        fh.write("".join(f"{x:.10f} {a:.10f} {b:.10f}\n" for x, a, b in zip(nominal, comp_f, comp_r)))
    with open(stem + ".bin", "wb") as fh:
        fh.write(np.asarray(np.concatenate(columns), dtype="<f8").tobytes())
    with open(stem + ".recipe.toml", "w") as fh:
        fh.write(f"[lines]\nkeep = {significant}\n[table]\nrows = {ROWS}\ndense_points = {DENSE}\n")

    print(
        json.dumps(
            {
                "survey_id": survey_id,
                "iso230_2": {k: float(v) for k, v in iso.items()},
                "noise_deg": float(sigma),
                "peaks": peaks,
                "table": {"path": stem + ".csv", "points": ROWS, "directional": bool(directional)},
                "predicted": prediction,
                "interpolation": interpolation,
            }
        )
    )


if __name__ == "__main__":
    main()
