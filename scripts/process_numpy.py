#!/usr/bin/env python3
"""`survey process` written with numpy: the reference the Rust command is
timed against, whole process against whole process.

    python scripts/process_numpy.py DB [SURVEY_ID] [OUT_DIR]

It does what `survey process` does on a full-circle survey, as a numpy user
would write it (no Python loop over samples, targets or bins):

1. read the samples from the SQLite database (the standard library's sqlite3,
   read-only): the survey's sample pack (`sample_packs`, migration 7: 72-byte
   little-endian records, store/src/pack.rs) decoded with np.frombuffer, or,
   without a valid pack, its rows in one column-wise fetch;
2. a tracker survey's axis fitted again from every SMR position (the locate
   points and each sample's: plane by eigen-decomposition, Kasa circle refined
   by Gauss-Newton, one pass dropping points beyond 5 robust sd) and the
   actual angles recomputed around it (processing/src/geometry.rs), with how
   well the centre is known;
3. the error map (readout - actual) as a [direction, run, target] cube, by a
   reshape of the sweeps (a survey stores whole sweeps in acquisition order),
   and the ISO 230-2 figures (A, R, B, E, M, per direction too);
4. the spectral analysis of the runs' bidirectional series: the noise floor
   from the run-to-run scatter of the spectra, the coherent and incoherent
   tests of every bin (F tails in closed form), coherence, repeatability
   (processing/src/analysis); the recipe derived from it (the repeatable
   lines kept);
5. the table: directional when the hysteresis stands 5 sd out of its noise,
   then forward and reverse are the mean's kept lines taken as lines of the
   TRUE angle (fixed-point change of variable, two correction passes) plus and
   minus half the hysteresis model (its mean and its significant lines); 16384
   rows (tables/src/recipe/build.rs, true_angle.rs, direction.rs);
6. the predicted accuracy: the table applied to every sample (native and
   corrected peak and RMS, ISO A of the corrected samples, the repeatability
   floor, the peak spread of a new survey's noise), the Figure 6 interpolation
   comparison (fixed, linear, quadratic, spectral on the map decimated by 2),
   the LinuxCNC table (low-passed to its 255 intervals) and its corrected peak;
7. the files: the table CSV (shortest round-trip numbers, as Rust prints
   them), the two LinuxCNC COMP_FILEs, the binary table (`SVCT` header and
   CRC-32, little-endian f64) and the recipe.

Not done here (the Rust command does them too): the Sinumerik 840D and Fanuc
files and their predicted peaks, the uncertainty budget, what the table
leaves between the targets (tables/src/left.rs: lines that may be aliases,
on a survey whose design names no part; its corrected_peak_deg is then the
in-sample peak and the spread only), the line names' long explanations,
aliased design lines (a design frequency at or above the survey's Nyquist:
refused), partial ranges, drift correction, check points. Checked against
`survey process --json` on simulated tracker surveys of 360 to 36000 points,
5 and 25 runs, one and two directions, from the pack and (reordered) from
the rows: the table within 5e-14 deg, the LinuxCNC files and the recipe the
same bytes, every figure printed within 1e-9 (relative).

Needs numpy from PyPI (measured with numpy 2.4.6, Python 3.11; scipy is not
needed: importing scipy.stats alone took 0.6-0.9 s, its F tail has a closed
form here):

    python3 -m venv /tmp/np && /tmp/np/bin/pip install numpy==2.4.6
    /tmp/np/bin/python scripts/process_numpy.py survey.db

`scripts/compare_process.sh` times both at several sizes.
"""

import os

# BLAS threads only cost on this work (products of 3 x n arrays): one.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import json
import math
import sqlite3
import sys
import zlib

import numpy as np

ROWS = 16384
DENSE = 131072
LINUXCNC = 256
ALPHA = 0.01
HYSTERESIS_FACTOR = 5.0
GEAR_HARMONICS, TOOTH_HARMONICS, SIDEBAND_ORDERS, SIDEBAND_TOOTH_HARMONICS = 6, 3, 2, 1
ORIENTATION_POSITIONS = 4096
THETA_ITERATIONS = 6
GRID_FACTOR = 4
PASSES = 2

# A pack record (migration 7, store/src/pack.rs): 72 bytes, little-endian.
RECORD = np.dtype(
    [
        ("seq", "<i8"),
        ("run", "<u4"),
        ("direction", "u1"),
        ("flags", "u1"),
        ("pad", "V2"),
        ("target", "<f8"),
        ("readout", "<f8"),
        ("actual", "<f8"),
        ("time", "<f8"),
        ("xyz", "<f8", (3,)),
    ]
)
HAS_SMR = 2


# ----------------------------------------------------------------------------
# Reading


class Samples:
    """The survey's samples in seq order, column by column. `readout_all` and
    the SMR positions `xyz` (3 x (L + m), mm) hold the survey's `L` locate
    points first: the refit's points are the locate points, then every
    sample's position, so with a position behind every sample (`has_smr`)
    they are the arrays as read."""

    def __init__(self, m, locate):
        L = len(locate)
        self.L = L
        self.run = np.empty(m, np.uint32)
        self.reverse = np.empty(m, bool)
        self.target = np.empty(m)
        self.actual = np.empty(m)
        self.has_smr = np.empty(m, bool)
        self.readout_all = np.empty(L + m)
        self.readout_all[:L] = locate[:, 0]
        self.readout = self.readout_all[L:]
        self.xyz = np.empty((3, L + m))
        self.xyz[:, :L] = locate[:, 1:].T


def read_pack(con, survey_id, last, locate):
    """The samples from the survey's pack, or None when it has none or one
    that does not hold every sample in seq order (the rows are read then)."""
    heads = con.execute(
        "SELECT first_seq, count, format FROM sample_packs WHERE survey_id = ? ORDER BY first_seq", (survey_id,)
    ).fetchall()
    if not heads or last is None or any(f != 1 or c <= 0 for _, c, f in heads):
        return None
    s = Samples(sum(c for _, c, _ in heads), locate)
    at, previous = 0, -1
    blobs = con.execute("SELECT data FROM sample_packs WHERE survey_id = ? ORDER BY first_seq", (survey_id,))
    for (first, count, _), (data,) in zip(heads, blobs):
        if len(data) != RECORD.itemsize * count:
            return None
        r = np.frombuffer(data, RECORD)
        seq = r["seq"]
        if seq[0] != first or seq[0] <= previous or (count > 1 and not (seq[1:] > seq[:-1]).all()):
            return None
        flags, direction, run = r["flags"], r["direction"], r["run"]
        if run.min() == 0 or direction.max() > 1 or (flags & ~np.uint8(3)).any():
            return None
        previous = seq[-1]
        part = slice(at, at + count)
        s.run[part], s.reverse[part] = run, direction
        s.target[part], s.readout[part], s.actual[part] = r["target"], r["readout"], r["actual"]
        np.not_equal(flags & HAS_SMR, 0, out=s.has_smr[part])
        s.xyz[:, s.L + at : s.L + at + count] = r["xyz"].T
        at += count
    return s if previous == last else None


def read_rows(con, survey_id, locate):
    """The samples from their rows and the SMR positions from the raw
    readings, each query fetched column-wise into one flat array."""

    def fetch(sql, width):
        cur = con.execute(sql, (survey_id,))
        return np.fromiter((np.nan if v is None else v for row in cur for v in row), np.float64).reshape(-1, width)

    a = fetch(
        "SELECT seq, run, direction = 'reverse', target_deg, readout_deg, actual_deg FROM samples "
        "WHERE survey_id = ? ORDER BY seq",
        6,
    )
    s = Samples(len(a), locate)
    s.run[:], s.reverse[:] = a[:, 1], a[:, 2] == 1
    s.target[:], s.readout[:], s.actual[:] = a[:, 3], a[:, 4], a[:, 5]
    raw = fetch(
        "SELECT seq, smr_x_mm, smr_y_mm, smr_z_mm FROM raw_readings WHERE survey_id = ? AND kind = 'smr' ORDER BY seq",
        4,
    )
    at = np.searchsorted(a[:, 0], raw[:, 0])
    found = at < len(a)
    found[found] &= a[at[found], 0] == raw[found, 0]
    s.has_smr[:] = False
    s.has_smr[at[found]] = True
    s.xyz[:, s.L + at[found]] = raw[found, 1:].T
    return s


def load(db, survey_id):
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    if survey_id is None:
        survey_id = con.execute("SELECT MAX(id) FROM surveys").fetchone()[0]
    model, axis_json = con.execute("SELECT model_toml, axis_json FROM surveys WHERE id = ?", (survey_id,)).fetchone()
    last = con.execute("SELECT MAX(seq) FROM samples WHERE survey_id = ?", (survey_id,)).fetchone()[0]
    locate = con.execute(
        "SELECT readout_deg, x_mm, y_mm, z_mm FROM locate_points WHERE survey_id = ? ORDER BY idx", (survey_id,)
    ).fetchall()
    locate = np.array(locate, dtype=np.float64).reshape(-1, 4)  # NULL -> nan
    s = read_pack(con, survey_id, last, locate)
    if s is None:
        s = read_rows(con, survey_id, locate)
    con.close()
    return survey_id, model or "", json.loads(axis_json) if axis_json else None, s


# ----------------------------------------------------------------------------
# The axis fitted again (processing/src/geometry.rs)


def wrap_180(t):
    """wrap_360(t + 180) - 180, in place."""
    t += 180.0
    if not (t.min() >= 0.0 and t.max() < 360.0):
        np.mod(t, 360.0, out=t)
        t[t >= 360.0] = 0.0
    t -= 180.0
    return t


def solve3(m, rhs):
    if not np.isfinite(m).all() or np.linalg.cond(m) > 1e13:
        return None
    return np.linalg.solve(m, rhs)


def circle_pass(x, y, a, b, r, buf):
    """The circle fit's cost at centre (a, b) and radius r and its
    Gauss-Newton normal equations there; `buf` keeps each point's offset from
    the centre, distance, residual and direction (cos, sin)."""
    dx, dy, dist, res, cx, cy = buf
    np.subtract(x, a, out=dx)
    np.subtract(y, b, out=dy)
    np.multiply(dx, dx, out=dist)
    np.multiply(dy, dy, out=res)
    dist += res
    np.sqrt(dist, out=dist)
    np.subtract(dist, r, out=res)
    cost = float(res @ res)
    np.divide(dx, dist, out=cx)
    np.divide(dy, dist, out=cy)
    count = len(x)
    if dist.min() == 0.0:  # a point at the centre has no direction
        at = dist == 0.0
        cx[at] = cy[at] = 0.0
        count -= int(at.sum())
        r_j = np.where(at, 0.0, res)
    else:
        r_j = res
    sx, sy = cx.sum(), cy.sum()
    jtj = np.array([[cx @ cx, cx @ cy, sx], [cx @ cy, cy @ cy, sy], [sx, sy, float(count)]])
    jtr = np.array([cx @ r_j, cy @ r_j, r_j.sum()])
    return cost, jtj, jtr


def fit_circle(x, y, buf):
    """Kasa's algebraic fit refined by Gauss-Newton, halving a step that does
    not reduce the cost (fit_circle in geometry.rs); `buf` ends with the
    final circle's pass."""
    sx, sy, sxx, sxy, syy = x.sum(), y.sum(), x @ x, x @ y, y @ y
    w = buf[2]
    np.multiply(x, x, out=w)
    np.multiply(y, y, out=buf[3])
    w += buf[3]
    m = np.array([[sxx, sxy, sx], [sxy, syy, sy], [sx, sy, float(len(x))]])
    sol = solve3(m, -np.array([x @ w, y @ w, w.sum()]))
    if sol is None:
        return None
    a, b = -sol[0] / 2, -sol[1] / 2
    r2 = a * a + b * b - sol[2]
    if not r2 > 0:
        return None
    r = math.sqrt(r2)
    cost, jtj, jtr = circle_pass(x, y, a, b, r, buf)
    fresh = True  # `buf` holds the pass at (a, b, r)
    for _ in range(50):
        step = solve3(jtj, jtr)
        if step is None:
            break
        norm, tol = math.sqrt(step @ step), 1e-14 * (1 + r)
        if norm <= tol:
            break
        k, accepted = 1.0, False
        for _ in range(20):
            na, nb, nr = a + k * step[0], b + k * step[1], r + k * step[2]
            nxt = circle_pass(x, y, na, nb, nr, buf)
            if nxt[0] <= cost:
                a, b, r = na, nb, nr
                cost, jtj, jtr = nxt
                accepted = fresh = True
                break
            fresh = False
            if norm * k <= tol:
                break
            k /= 2
        if not accepted or norm * k <= 1e-14 * (1 + r):
            break
    if r < 0:
        r, fresh = -r, False
    if not fresh:
        cost, jtj, _ = circle_pass(x, y, a, b, r, buf)
    return a, b, r, cost, jtj


def fit_axis(p, ro):
    """The axis from positions p (3 x n, mm) taken at readouts ro
    (fit_axis_with_angles in geometry.rs): the fit, the raw angle of every
    point (radians), and what the refit reads again: each point's distance
    from the plane (mm), from the centre in the plane (in units of `spread`),
    its direction from the centre, the circle's last normal equations, and
    two spare rows."""
    n = p.shape[1]
    if not math.isfinite(p.sum() + ro.sum()):
        raise SystemExit("the axis cannot be fitted again: a position or readout is not a finite number")
    centroid = p.sum(axis=1) * (1.0 / n)
    d = p - centroid[:, None]
    values, vectors = np.linalg.eigh((d @ d.T) / n)
    if values[2] <= 0 or values[1] <= 1e-12 * values[2]:
        raise SystemExit("the SMR positions do not locate an axis")
    normal = vectors[:, 0] / np.linalg.norm(vectors[:, 0])
    u = vectors[:, 2] - normal * (vectors[:, 2] @ normal)
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    spread = math.sqrt(values[1] + values[2])
    x, y, h = np.stack([u / spread, v / spread, normal]) @ d
    spare = np.empty((3, n))
    buf = [d[0], d[1], d[2], spare[0], spare[1], spare[2]]
    circle = fit_circle(x, y, buf)
    if circle is None:
        raise SystemExit("the projected positions do not determine a circle")
    a, b, r, cost, jtj = circle
    dx, dy, dist, _, cx, cy = buf
    # Orientation: every stride-th position's direction against its readout
    # (every position when the subset does not tell the direction clearly).
    def sums(stride):
        st, ct, sr = cy[::stride], cx[::stride], ro[::stride] * (math.pi / 180.0)
        sn, cs = np.sin(sr), np.cos(sr)
        minus = ((st * cs - ct * sn).sum(), (ct * cs + st * sn).sum())
        plus = ((st * cs + ct * sn).sum(), (ct * cs - st * sn).sum())
        return minus, plus, len(st)

    def resultant(z):
        return z[0] * z[0] + z[1] * z[1]

    stride = max(n // ORIENTATION_POSITIONS, 1)
    minus, plus, taken = sums(stride)
    if stride > 1 and not abs(resultant(minus) - resultant(plus)) >= taken * taken / 2:
        minus, plus, taken = sums(1)
    orientation = (resultant(minus) - resultant(plus)) / 4
    if abs(orientation) <= 1e-9 * taken * taken:
        raise SystemExit("the readouts do not vary enough to tell the direction of rotation")
    raw = np.arctan2(dy, dx)
    flipped = orientation < 0
    if flipped:
        normal, v, b = -normal, -v, -b
        np.negative(raw, out=raw)
        np.negative(cy, out=cy)
        jtj[0, 1] = jtj[1, 0] = -jtj[0, 1]
        jtj[1, 2] = jtj[2, 1] = -jtj[1, 2]
        s, c = -plus[0], plus[1]
    else:
        s, c = minus
    # Zero: the mean of wrap_180(raw - zero - readout) is zero.
    z0 = math.degrees(math.atan2(s, c))
    t = np.multiply(raw, 180.0 / math.pi, out=dx)
    t -= ro
    t -= z0
    z = z0 + wrap_180(t).sum() / n
    fit = {
        "center_mm": centroid + u * (a * spread) + v * (b * spread),
        "normal": normal,
        "u": u,
        "v": v,
        "radius_mm": r * spread,
        "zero_offset_deg": float(wrap_180(np.array([z]))[0]),
    }
    state = {"h": h, "dist": dist, "spread": spread, "cx": cx, "cy": cy, "jtj": jtj, "ss": cost * spread * spread}
    state["spare"] = [x, y, buf[3]]
    return fit, raw, state


def raw_angle(fit, p):
    x, y = np.stack([fit["u"], fit["v"]]) @ (p - fit["center_mm"][:, None])
    return np.arctan2(y, x)


def largest_gap(angles):
    """The largest gap between angles (radians within a turn), across the
    turn's end too: by buckets, a sort only when they cannot tell."""
    lo, hi = angles.min(), angles.max()
    count = len(angles)
    buckets = max(count // 4, 1)
    scale = buckets / (hi - lo) if hi > lo else 0.0
    b = np.minimum(((angles - lo) * scale).astype(np.int64), buckets - 1)
    least, largest = np.full(buckets, np.inf), np.full(buckets, -np.inf)
    np.minimum.at(least, b, angles)
    np.maximum.at(largest, b, angles)
    full = least <= largest
    least, largest = least[full], largest[full]
    best = max(lo + 2 * math.pi - hi, 0.0)
    if len(least) > 1:
        best = max(best, (least[1:] - largest[:-1]).max())
    if best >= (largest - least).max():
        return best
    s = np.sort(angles)
    return max(np.diff(s).max(initial=0.0), s[0] + 2 * math.pi - s[-1])


def center_knowledge(fit, raw, st):
    """How well the centre is known (center_knowledge in geometry.rs), from
    the fit's last pass: the normal equations of the circle, the residuals
    and each point's direction."""
    cx, cy, jtj = st["cx"], st["cy"], st["jtj"]
    count = jtj[2, 2]
    s2 = st["ss"] / max(count - 3, 1)
    try:
        cov = s2 * np.linalg.inv(jtj)[:2, :2]
    except np.linalg.LinAlgError:
        cov = np.array([[np.inf, 0.0], [0.0, np.inf]])
    a, b, c = cov[0, 0], 0.5 * (cov[0, 1] + cov[1, 0]), cov[1, 1]
    worst_se = math.sqrt(max(0.5 * (a + c) + math.sqrt(0.25 * (a - c) ** 2 + b * b), 0.0))
    r = fit["radius_mm"]
    # The angle error a centre error makes at each point, its mean removed.
    g0, g1, var = st["spare"]
    np.subtract(cy, jtj[1, 2] / count, out=g0)
    np.subtract(jtj[0, 2] / count, cx, out=g1)
    np.multiply(g0, g0, out=var)
    var *= a
    g0 *= g1
    g0 *= 2 * b
    var += g0
    g1 *= g1
    g1 *= c
    var += g1
    over_arc = var.max() / (r * r)
    return {
        "center_se_mm": worst_se,
        "once_per_rev_se_deg": math.degrees(worst_se / r),
        "arc_deg": max(math.degrees(2 * math.pi - largest_gap(raw)), 0.0),
        "over_arc_se_deg": math.degrees(math.sqrt(max(over_arc, 0.0))),
    }


def refit(s, located):
    """The actual angles around the axis fitted again from every SMR
    position (the locate points first, then each sample's), and the refit."""
    L = s.L
    if s.has_smr.all():
        p, ro, idx = s.xyz, s.readout_all, None
    else:
        idx = np.flatnonzero(s.has_smr)
        pick = np.concatenate([np.arange(L), L + idx])
        p, ro = s.xyz[:, pick], s.readout_all[pick]
    if p.shape[1] < 3:
        return None
    fit, raw, st = fit_axis(p, ro)
    # Positions beyond 5 robust sd of the circle and plane: dropped, refitted.
    sq = np.multiply(st["dist"], st["spread"], out=st["dist"])
    sq -= fit["radius_mm"]
    sq *= sq
    sq += st["h"] * st["h"]
    mad = math.sqrt(np.partition(sq, len(sq) // 2)[len(sq) // 2])
    limit = 5 * 1.4826 * mad
    beyond = sq > limit * limit if limit > 0 else np.zeros(len(sq), bool)
    del sq
    dropped = int(beyond.sum())
    if dropped and p.shape[1] - dropped >= 3:
        kept = ~beyond
        fit, raw_kept, st = fit_axis(p[:, kept], ro[kept])
        knowledge = center_knowledge(fit, raw_kept, st)
        raw = raw_angle(fit, p)
    else:
        dropped = 0
        knowledge = center_knowledge(fit, raw, st)
    del st
    # Each sample's actual angle: near its target (angle_of_raw).
    t = s.target if idx is None else s.target[idx]
    a = np.multiply(raw[L:], 180.0 / math.pi, out=s.actual if idx is None else None)
    a -= fit["zero_offset_deg"]
    a -= t
    wrap_180(a)
    a += t
    if idx is not None:
        s.actual[idx] = a
    dc = fit["center_mm"] - np.asarray(located["center_mm"])
    shift = float(np.linalg.norm(dc - (dc @ fit["normal"]) * fit["normal"]))
    return {
        "points": p.shape[1],
        "dropped": dropped,
        "radius_mm": fit["radius_mm"],
        "center_shift_mm": shift,
        "located_once_per_rev_deg": math.degrees(shift / fit["radius_mm"]),
        **knowledge,
    }


# ----------------------------------------------------------------------------
# Grouping


class Layout:
    """Each direction's samples as a [run, target] array, targets ascending.

    A survey stores whole sweeps in acquisition order (run 1 forward with the
    targets ascending, run 1 reverse descending, run 2 ...): a direction's
    array is then a view (a reshape, the reverse sweeps flipped). Any other
    order is grouped by index arrays (np.unique)."""

    def __init__(self, run, reverse, target):
        m = len(run)
        self.runs = int(run.max())
        self.dirs = 2 if (reverse.any() and not reverse.all()) else 1
        per = self.runs * self.dirs
        n = m // per
        self.sweeps = False
        if n * per == m and n > 1 and not reverse[0]:
            t0 = target[:n]
            sweep = np.arange(per, dtype=np.uint32)
            ok = (t0[1:] > t0[:-1]).all() and np.array_equal(run, np.repeat(sweep // self.dirs + 1, n))
            ok = ok and np.array_equal(reverse, np.repeat(sweep % self.dirs == 1, n))
            if ok:
                t = target.reshape(self.runs, self.dirs, n)
                ok = (t[:, 0] == t0).all() and (self.dirs == 1 or (t[:, 1, ::-1] == t0).all())
            if ok:
                self.sweeps, self.n, self.targets = True, n, t0.copy()
        if not self.sweeps:
            self.targets, t_index = np.unique(target, return_inverse=True)
            self.n = len(self.targets)
            self.index = []
            for d in range(self.dirs):
                sel = np.flatnonzero(reverse == bool(d)) if self.dirs == 2 else np.arange(m)
                idx = np.full((self.runs, self.n), -1, np.int64)
                idx[run[sel].astype(np.int64) - 1, t_index[sel]] = sel
                if (idx < 0).any() or len(sel) != idx.size:
                    raise SystemExit("the error map is not complete: one sample per run, target and direction")
                self.index.append(idx)

    def view(self, x, d):
        """Direction d's samples of x (a value per sample) as [run, target]."""
        if self.sweeps:
            v = x.reshape(self.runs, self.dirs, self.n)[:, d]
            return v[:, ::-1] if d == 1 else v
        return x[self.index[d]]

    def assign(self, out, d, values):
        if self.sweeps:
            self.view(out, d)[...] = values
        else:
            out[self.index[d]] = values


def iso230(devs, reverse_only=False):
    """ISO 230-2 figures of each direction's deviations (actual - target) as
    [run, target]: forward then reverse, or the one direction measured."""
    mean = [x.mean(axis=0) for x in devs]
    s = [x.std(axis=0, ddof=1) for x in devs]
    hi = [m + 2 * v for m, v in zip(mean, s)]
    lo = [m - 2 * v for m, v in zip(mean, s)]
    f = {"runs": devs[0].shape[0]}
    if len(devs) == 2:
        b = mean[0] - mean[1]
        f["A"] = max(hi[0].max(), hi[1].max()) - min(lo[0].min(), lo[1].min())
        f["A_up"], f["A_down"] = hi[0].max() - lo[0].min(), hi[1].max() - lo[1].min()
        f["B"], f["B_mean"] = np.abs(b).max(), b.mean()
        f["E"] = max(mean[0].max(), mean[1].max()) - min(mean[0].min(), mean[1].min())
        f["E_up"], f["E_down"] = np.ptp(mean[0]), np.ptp(mean[1])
        f["M"] = np.ptp((mean[0] + mean[1]) / 2)
        f["R"] = np.maximum(2 * s[0] + 2 * s[1] + np.abs(b), np.maximum(4 * s[0], 4 * s[1])).max()
        f["R_up"], f["R_down"] = 4 * s[0].max(), 4 * s[1].max()
    else:
        f["A"], f["E"], f["R"] = hi[0].max() - lo[0].min(), np.ptp(mean[0]), 4 * s[0].max()
        way = "down" if reverse_only else "up"
        f["A_" + way], f["E_" + way], f["R_" + way] = f["A"], f["E"], f["R"]
    return {k: (float(v) if k != "runs" else v) for k, v in f.items()}


def iso_a(devs):
    hi = max((x.mean(axis=0) + 2 * x.std(axis=0, ddof=1)).max() for x in devs)
    lo = min((x.mean(axis=0) - 2 * x.std(axis=0, ddof=1)).min() for x in devs)
    return float(hi - lo)


# ----------------------------------------------------------------------------
# Spectra (processing/src/resample: C_0 = X_0 / N, C_k = 2 X_k / N, the
# Nyquist line X_{N/2} / N; a series evaluated at M points)


def analyze(y):
    n = y.shape[-1]
    c = np.fft.rfft(y) * (2.0 / n)
    c[..., 0] = c[..., 0].real / 2
    if n % 2 == 0:
        c[..., -1] = c[..., -1].real / 2
    return c


def synthesize(c, m):
    half = m // 2
    spec = np.zeros(half + 1, complex)
    k = min(len(c), half + 1)
    spec[:k] = c[:k] * 0.5
    spec[0] = c[0].real
    if m % 2 == 0 and len(c) > half:
        spec[half] = c[half].real
    return np.fft.irfft(spec, m) * m


def f_even_sf(m, d, f):
    """P(F > f) for F(2m, d) (d None: the chi-square limit), in closed form."""
    if f <= 0:
        return 1.0
    m = max(m, 1)
    logs, acc = [], 0.0
    if d is None:
        h = m * f
        for j in range(m):
            if j:
                acc += math.log(h) - math.log(j)
            logs.append(acc)
        lead = -h
    else:
        x = d / (d + 2.0 * m * f)
        for j in range(m):
            if j:
                acc += math.log(d / 2 + j - 1) - math.log(j) + math.log(1 - x)
            logs.append(acc)
        lead = d / 2 * math.log(x)
    top = max(logs)
    return min(math.exp(lead + top + math.log(sum(math.exp(v - top) for v in logs))), 1.0)


def f_even_isf(m, d, p):
    lo, hi = 0.0, 4.0
    while f_even_sf(m, d, hi) > p and hi < 1e300:
        hi *= 2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if f_even_sf(m, d, mid) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def normal_two_sided_isf(p):
    lo, hi = 0.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if math.erfc(mid / math.sqrt(2)) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def design_from(model_toml):
    gears, teeth = [], []
    for line in model_toml.splitlines():
        key, _, value = line.partition("=")
        key = key.strip()
        if key in ("gear_ratios", "tooth_counts"):
            nums = [float(x) for x in value.strip().strip("[]").split(",") if x.strip()]
            (gears if key == "gear_ratios" else teeth).extend(nums)
    return gears, teeth


def candidates(gears, teeth):
    """The design's frequencies: (cycles/rev, rank, kind, description)."""
    c = [(1.0, (0, 1, 0), "eccentricity", "once per revolution"), (2.0, (1, 1, 0), "ellipticity", "twice per revolution")]
    for g in gears:
        c += [(g * h, (2, h, 0), "gear_pass", f"{g:g}:1 pinion, harmonic {h}") for h in range(1, GEAR_HARMONICS + 1)]
    for t in teeth:
        c += [(t * h, (3, h, 0), "tooth_mesh", f"{t:g}-tooth gear, harmonic {h}") for h in range(1, TOOTH_HARMONICS + 1)]
        for h in range(1, SIDEBAND_TOOTH_HARMONICS + 1):
            for g in gears:
                for m in range(1, SIDEBAND_ORDERS + 1):
                    for mm in (-m, m):
                        if t * h + g * mm > 0:
                            c.append((t * h + g * mm, (4, h, m), "tooth_mesh", f"sideband {mm:+} x {g:g}:1 of {t:g}-tooth"))
    return c


def name_line(k, cands):
    matched = sorted((c for c in cands if abs(c[0] - k) <= 0.5), key=lambda c: (c[1], c[0]))
    return f"{matched[0][2]}: {matched[0][3]}" if matched else f"harmonic: {k} cycles/rev matches no part of the design"


# ----------------------------------------------------------------------------
# The table through the true angle (tables/src/true_angle.rs)


def cubic_at(grid_padded, m, theta):
    """4-point Lagrange interpolation of a periodic grid of m points over 360
    deg (grid_padded: the grid with one point before and two after)."""
    x = np.mod(theta, 360.0) * (m / 360.0)
    k = np.minimum(x.astype(np.int64), m - 1)
    f = x - k
    a, b, c, d = grid_padded[k], grid_padded[k + 1], grid_padded[k + 2], grid_padded[k + 3]
    fm1, fp1, fm2 = f - 1.0, f + 1.0, f - 2.0
    return (
        (-f * fm1 * fm2 / 6.0) * a
        + (fp1 * fm1 * fm2 / 2.0) * b
        + (-fp1 * f * fm2 / 2.0) * c
        + (fp1 * f * fm1 / 6.0) * d
    )


def through_true_angle(grid, readouts, offset):
    """T_g at the readouts: theta solving theta = r - offset - (g(theta) - mean g)."""
    m = len(grid)
    mean = grid.sum() / m
    gp = np.concatenate([grid[-1:], grid, grid[:2]])
    base = readouts - offset
    theta = base
    for _ in range(THETA_ITERATIONS):
        nxt = base - (cubic_at(gp, m, theta) - mean)
        if np.array_equal(nxt, theta):
            break
        theta = nxt
    return cubic_at(gp, m, theta)


class TrueLines:
    """The kept lines as lines of the true angle behind a measured column."""

    def __init__(self, column, targets, keep_mask, rows):
        def edit(y):
            return analyze(y) * keep_mask

        edited = edit(column)
        self.mean = edited[0].real
        top = (rows + 1) // 2
        g = edited.copy()
        g[0] = 0
        g = g[:top]
        kept = np.flatnonzero(g != 0)
        if len(kept):
            for _ in range(PASSES):
                got = edit(through_true_angle(synthesize(g, GRID_FACTOR * rows), targets, 0.0))
                g[kept] += edited[kept] - got[kept]
        self.g = g

    def column(self, extra, offset, rows):
        g = self.g.copy()
        if extra is not None:
            k = min(len(extra), len(g))
            g[1:k] += extra[1:k]
        readouts = 360.0 * np.arange(rows) / rows
        table = through_true_angle(synthesize(g, GRID_FACTOR * rows), readouts, offset)
        return table + (self.mean + offset - table.sum() / rows)


def error_at(col, readout):
    """A table column read at readouts (linear between rows, wrapping at 360),
    as CorrectionTable::error_at (its wrap is a no-op on readouts in [0, 360))."""
    n = len(col)
    p = readout * (n / 360.0)
    if not (p.min() >= 0.0 and p.max() < n):
        p -= n * np.floor(p * (1.0 / n))
    i = p.astype(np.int64)
    np.clip(i, 0, n - 1, out=i)
    return lerp(np.append(col, col[0]), i, p)


def lerp(v, i, t):
    """v[i] + (v[i + 1] - v[i]) * (t - i), reusing t and i."""
    a = v[i]
    t -= i
    i += 1
    b = v[i]
    b -= a
    b *= t
    b += a
    return b


# ----------------------------------------------------------------------------
# Output formats


def rust_float(x):
    """A float as Rust's `{}` prints it: shortest round trip, never an exponent."""
    s = repr(x)
    if "e" in s:
        s = np.format_float_positional(x, unique=True, trim="-")
    elif s.endswith(".0"):
        s = s[:-2]
    return s


def floats(values):
    """Strings of an array's values as Rust prints them (repr is the same but
    for whole numbers and exponents: those few are made again)."""
    out = list(map(repr, values.tolist()))
    a = np.abs(values)
    for i in np.flatnonzero((a < 1e-4) | (a >= 1e16) | (values == np.trunc(values))).tolist():
        out[i] = rust_float(float(values[i]))
    return out


def recipe_text(survey_id, keep, remove, dense):
    keep = ", ".join(f"{k:g}" for k in keep)
    remove = ", ".join(f"{k:g}" for k in remove)
    return f"""# Made by `survey process` from survey {survey_id}.
# survey processing recipe (format 1): every choice of `survey process`.
# Replay it on a new survey with `survey process --recipe FILE`. Frequencies are cycles
# per revolution (true frequencies); `[[alias]]` entries say what happens to aliased lines.

version = 1
alias = []

[analysis]
series = "bidirectional"
gear_harmonics = {GEAR_HARMONICS}
tooth_harmonics = {TOOTH_HARMONICS}
sideband_orders = {SIDEBAND_ORDERS}
sideband_tooth_harmonics = {SIDEBAND_TOOTH_HARMONICS}
false_alarm_rate = {ALPHA}
partial_window = "hann"

[lines]
keep = [{keep}]
remove = [{remove}]
unlisted = "keep_repeatable"
min_amplitude_deg = 0.0

[table]
dense_points = {dense}
rows = {ROWS}
directional = "auto"
hysteresis_factor = {HYSTERESIS_FACTOR}
remove_mean = false
interpolation = "spectral"

[export]
linuxcnc = true
linuxcnc_points = {LINUXCNC}
sinumerik_840d = true
fanuc = true
generic = false
binary = true
binary_format = "f64"
directions = "auto"
zero_at_reference = false
sinumerik_absolute = false
sign = "error"
values = "absolute"
sinumerik_axis = "C1"
sinumerik_measuring_system = 0
fanuc_unit_deg = 0.001
fanuc_magnification = 1
"""


# ----------------------------------------------------------------------------


def main():
    db = sys.argv[1]
    survey_id = int(sys.argv[2]) if len(sys.argv) > 2 else None
    out_dir = sys.argv[3] if len(sys.argv) > 3 else "."
    survey_id, model, located, s = load(db, survey_id)
    gears, teeth = design_from(model)
    axis_refit = refit(s, located) if located else None
    axis = "refitted" if axis_refit else ("located" if located else "none")

    # The error map (each direction's [run, target]) and the ISO 230-2 figures.
    lay = Layout(s.run, s.reverse, s.target)
    runs, dirs, n, targets = lay.runs, lay.dirs, lay.n, lay.targets
    if runs < 2 or np.abs(np.diff(targets) - 360.0 / n).max(initial=0.0) > 1e-6:
        raise SystemExit("a uniform full circle of two runs or more is needed")
    native = s.readout - s.actual
    err = [lay.view(native, d) for d in range(dirs)]
    iso = iso230([lay.view(s.actual - s.target, d) for d in range(dirs)], bool(s.reverse[0]) and dirs == 1)
    dir_mean = [e.sum(axis=0) / runs for e in err]

    # The analysis of the runs' series (the mean of their two passes).
    series = (err[0] + err[1]) / 2 if dirs == 2 else err[0]
    z = analyze(series)  # [run, bin]: the cosine part real, the sine part -imag
    zbar = z.sum(axis=0) * (1.0 / runs)
    regular = (n - 1) // 2
    dev = z[:, 1 : regular + 1] - zbar[1 : regular + 1]
    dof = 2 * regular * (runs - 1)
    sd_run = math.sqrt(((dev.real**2).sum() + (dev.imag**2).sum()) / dof)
    floor = max(1e-12 * math.sqrt((series**2).mean()), 8 * np.finfo(float).eps * max(1.0, np.abs(targets).max()))
    sd_run = max(sd_run, floor * math.sqrt(2.0 / n))
    tests = regular + (n % 2 == 0)
    p = min(ALPHA / (2 * tests), 0.5)
    coh_2d = math.sqrt(2 * f_even_isf(1, dof, p))
    coh_1d = normal_two_sided_isf(p)
    inc = 2 * runs * f_even_isf(runs, dof, p)
    min_coherence = (1 + 1 / runs) / 2
    ks = np.arange(1, n // 2 + 1)
    one_dim = 2 * ks == n
    sd = np.where(one_dim, sd_run / math.sqrt(2), sd_run)
    zk = z[:, 1:]
    amp = np.hypot(zbar.real, zbar.imag)[1:]
    coherent = amp > np.where(one_dim, coh_1d, coh_2d) * (sd / math.sqrt(runs))
    power = (zk.real**2 + zk.imag**2).sum(axis=0)
    incoherent = ~one_dim & (power / (sd * sd) > inc)
    mean_pow = (zbar.real**2 + zbar.imag**2)[1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        coherence = np.where(power > 0, np.minimum(runs * mean_pow / power, 1.0), 0.0)
    repeatable = coherent & (coherence >= min_coherence)
    lines = ks[coherent | incoherent]
    cands = candidates(gears, teeth)
    if any(c[0] >= n / 2 for c in cands):
        raise SystemExit("a design frequency at or above the Nyquist: aliases are not handled here")
    keep = [int(k) for k in lines if repeatable[k - 1]]
    phase = np.mod(np.degrees(np.arctan2(zbar.real, -zbar.imag)), 360.0)
    total = (mean_pow / np.where(one_dim, 1.0, 2.0)).sum()
    peaks = [
        {
            "cycles_per_rev": float(k),
            "amplitude_deg": float(amp[k - 1] if repeatable[k - 1] else math.sqrt(power[k - 1] / runs)),
            "phase_deg": float(phase[k]),
            "coherence": float(coherence[k - 1]),
            "repeatable": bool(repeatable[k - 1]),
            "share": float(mean_pow[k - 1] / (1 if one_dim[k - 1] else 2) / total) if total > 0 else 0.0,
            "source": name_line(int(k), cands),
            "kept": bool(repeatable[k - 1]),
        }
        for k in lines
    ]
    sample_sd = sd_run * math.sqrt(n / 2)
    noise = {
        "method": "spectrum_scatter",
        "line_sd_run_deg": sd_run,
        "line_sd_mean_deg": sd_run / math.sqrt(runs),
        "sample_sd_deg": sample_sd,
        "dof": dof,
        "tests": tests,
        "false_alarm_rate": ALPHA,
        "coherent_threshold_deg": coh_2d * sd_run / math.sqrt(runs),
        "incoherent_threshold_deg": sd_run * math.sqrt(inc / runs),
        "min_coherence": min_coherence,
    }

    # The table: directional when the hysteresis stands out of its noise.
    keep_mask = np.zeros(n // 2 + 1)
    keep_mask[0] = 1
    keep_mask[keep] = 1
    hysteresis = None
    if dirs == 2:
        hyst = dir_mean[0] - dir_mean[1]
        h_noise = sample_sd * math.sqrt(2) * math.sqrt(2.0 / runs)
        h_max = float(np.abs(hyst).max())
        hysteresis = {
            "factor": HYSTERESIS_FACTOR,
            "max_deg": h_max,
            "mean_deg": float(hyst.sum() / n),
            "noise_deg": h_noise,
            "significant": h_max > HYSTERESIS_FACTOR * h_noise,
        }
    directional = bool(hysteresis and hysteresis["significant"])
    grid_targets = targets[0] + 360.0 * np.arange(n) / n
    direction_model = None
    if directional:
        d = analyze(hyst)
        bins = max((n - 1) // 2, 1)
        threshold = h_noise * math.sqrt(2.0 / n) * math.sqrt(-2 * math.log(min(max(ALPHA, 1e-12), 1.0) / bins))
        d_amp = np.abs(d[1 : bins + 1])
        d_lines = np.flatnonzero(d_amp > threshold) + 1
        half = np.zeros(d_lines[-1] + 1 if len(d_lines) else 1, complex)
        half[d_lines] = d[d_lines] / 2
        direction_model = {
            "lines": [[int(k), float(d_amp[k - 1])] for k in d_lines],
            "mean_deg": float(d[0].real),
            "noise_deg": h_noise,
            "targets": n,
            "threshold_deg": threshold,
        }
        true_lines = TrueLines((dir_mean[0] + dir_mean[1]) / 2, grid_targets, keep_mask, ROWS)
        m = d[0].real
        columns = [true_lines.column(half, m / 2, ROWS), true_lines.column(-half, -m / 2, ROWS)]
    else:
        single = (dir_mean[0] + dir_mean[1]) / 2 if dirs == 2 else dir_mean[0]
        columns = [TrueLines(single, grid_targets, keep_mask, ROWS).column(None, 0.0, ROWS)]
    by_dir = columns if len(columns) == dirs else [columns[0]] * dirs

    # The predicted accuracy: each sample corrected by its direction's column.
    corrected = np.empty_like(native)
    for d in range(dirs):
        r = lay.view(s.readout, d)
        applied = error_at(by_dir[d], r)
        np.subtract(r, applied, out=applied)
        applied -= lay.view(s.actual, d)
        lay.assign(corrected, d, applied)
    del applied
    m_samples = len(native)
    nm, cm = native.mean(), corrected.mean()
    cor = [lay.view(corrected, d) for d in range(dirs)]
    ss = sum(float((c.var(axis=0) * runs).sum()) for c in cor)
    noise_sd = math.sqrt(ss / (dirs * n * (runs - 1)))
    spread = noise_sd * math.log(19) / math.sqrt(2 * math.log(2 * m_samples))
    in_sample = float(max(corrected.max() - cm, cm - corrected.min()))
    floor_deg = max(iso.get("R_up", iso["R"]), iso.get("R_down", 0.0)) / 2 if directional else iso["R"] / 2
    tv = [lay.view(s.target, d) for d in range(dirs)]
    prediction = {
        "native_peak_deg": float(max(native.max() - nm, nm - native.min())),
        "corrected_peak_deg": in_sample + spread,
        "in_sample_corrected_peak_deg": in_sample,
        "native_rms_deg": float(np.sqrt(native.var())),
        "corrected_rms_deg": float(np.sqrt(corrected.var())),
        "native_iso230_a_deg": iso["A"],
        "corrected_iso230_a_deg": iso_a([(t - c) - t for t, c in zip(tv, cor)]),
        "floor_deg": floor_deg,
        "peak_spread_deg": spread,
        "samples": m_samples,
    }
    del cor, tv

    # Figure 6: the bidirectional mean map decimated by 2, interpolated back.
    bi = (dir_mean[0] + dir_mean[1]) / 2 if dirs == 2 else dir_mean[0]
    kept, odd = bi[::2], bi[1::2]
    nxt = np.roll(kept, -1)
    predicted = {
        "fixed": kept,
        "linear": kept + (nxt - kept) * 0.5,
        "quadratic": -0.125 * np.roll(kept, 1) + 0.75 * kept + 0.375 * nxt,
        "spectral": synthesize(analyze(kept), n)[1::2],
    }
    interpolation = [
        {"method": k, "rms_deg": float(np.sqrt(((v - odd) ** 2).sum() / len(odd))), "peak_deg": float(np.abs(v - odd).max())}
        for k, v in predicted.items()
    ]

    # LinuxCNC: the columns low-passed to what 255 intervals hold, read at the
    # grid's 256 points; its corrected peak on every turn some sample falls on.
    interval = 360.0 / (LINUXCNC - 1)
    keep_cycles = (int(360.0 / interval + 1e-9) - 1) // 2
    low = [synthesize(analyze(c)[: keep_cycles + 1], ROWS) if keep_cycles < ROWS // 2 else c for c in columns]
    nominal = np.arange(LINUXCNC) * interval
    comp = [error_at(c, nominal) for c in low]
    comp_f, comp_r = comp[0], comp[-1]
    lo_tol, hi_tol = -1e-9, nominal[-1] + 1e-9
    least, largest = s.readout.min(), s.readout.max()
    worst = None
    for turn in 360.0 * np.arange(math.floor(lo_tol / 360) - 1, math.ceil(hi_tol / 360) + 2):
        if largest + turn < lo_tol or least + turn > hi_tol:
            continue
        count, total_e, e_lo, e_hi = 0, 0.0, np.inf, -np.inf
        for d, col in enumerate([comp_f, comp_r][:dirs] if len(columns) == 2 else [comp_f] * dirs):
            pos = lay.view(s.readout, d) + turn
            e = lay.view(native, d)
            if not (pos.min() >= lo_tol and pos.max() <= hi_tol):
                inside = (pos >= lo_tol) & (pos <= hi_tol)
                pos, e = pos[inside], e[inside]
                if not len(pos):
                    continue
            t = pos * (1.0 / interval)  # AppliedLine::at: its end values outside
            inner = t.min() > 0 and t.max() < LINUXCNC - 1
            ends = None if inner else (t <= 0, t >= LINUXCNC - 1)
            at = lerp(col, np.minimum(t.astype(np.int64), LINUXCNC - 2), t)
            if ends is not None:
                at[ends[0]], at[ends[1]] = col[0], col[-1]
            e = e - at
            count, total_e = count + e.size, total_e + e.sum()
            e_lo, e_hi = min(e_lo, e.min()), max(e_hi, e.max())
        if count:
            mean = total_e / count
            peak = max(e_hi - mean, mean - e_lo)
            worst = peak if worst is None else max(worst, peak)
    prediction["linuxcnc_corrected_peak_deg"] = worst

    # The files.
    os.makedirs(out_dir, exist_ok=True)
    stem = os.path.join(out_dir, f"table-{survey_id}")
    cols = [floats(np.arange(ROWS) * (360.0 / ROWS))] + [floats(c) for c in columns]
    with open(stem + ".csv", "w") as fh:
        fh.write("readout_deg,error_forward_deg,error_reverse_deg\n" if directional else "readout_deg,error_deg\n")
        fh.write("\n".join(map(",".join, zip(*cols))) + "\n")
    nom, cf, cr = nominal.tolist(), comp_f.tolist(), comp_r.tolist()
    with open(stem + ".comp0", "w") as fh:
        fh.write("".join(f"{x:.10f} {x - a:.10f} {x - b:.10f}\n" for x, a, b in zip(nom, cf, cr)))
    with open(stem + ".comp1", "w") as fh:
        fh.write("".join(f"{x:.10f} {a:.10f} {b:.10f}\n" for x, a, b in zip(nom, cf, cr)))
    values = np.concatenate(columns).astype("<f8").tobytes()
    header = b"SVCT" + np.array([1], "<u2").tobytes() + bytes([8, len(columns)])
    header += np.array([ROWS, zlib.crc32(values)], "<u4").tobytes()
    with open(stem + ".bin", "wb") as fh:
        fh.write(header + values)
    with open(stem + ".recipe.toml", "w") as fh:
        # A circle of more targets than the dense grid resamples through the
        # next power of two that holds them (Recipe::from_analysis).
        dense = DENSE if n <= DENSE else min(1 << (n - 1).bit_length(), 1 << 24)
        fh.write(recipe_text(survey_id, keep, [int(k) for k in lines if not repeatable[k - 1]], dense))

    print(
        json.dumps(
            {
                "survey_id": survey_id,
                "axis": axis,
                "axis_refit": axis_refit,
                "iso230_2": iso,
                "noise": noise,
                "peaks": peaks,
                "table": {
                    "path": stem + ".csv",
                    "points": ROWS,
                    "directional": directional,
                    "kept_cycles": [float(k) for k in keep],
                    "hysteresis": hysteresis,
                    "direction_model": direction_model,
                },
                "predicted": prediction,
                "interpolation": interpolation,
            }
        )
    )


if __name__ == "__main__":
    main()
