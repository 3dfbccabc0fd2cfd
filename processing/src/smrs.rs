//! Several SMRs on the table: the tracker's own error separated from the
//! axis's (issue 48).
//!
//! A tracker's systematic error is a function of the place in space it
//! measures ([`crate::tracker_errors`]): every SMR on one circle of the table
//! sees the same function of its place on the circle, `f(psi)`. SMR `k`,
//! mounted at `phi_k` from the first, reads at axis angle `theta`
//!
//! ```text
//! a_k(theta) = theta_true(theta) + f(theta + phi_k) + c_k
//! ```
//!
//! (each SMR's angle around its own fitted circle, with its own zero; `c_k`
//! a constant). The positioner's error is in `theta_true` and the same for
//! every SMR; the tracker's is not. So the differences between SMRs hold the
//! tracker's error alone: with `f = sum_m F(m) e^(i m psi)`, the
//! difference `a_k - a_0` has, at `m` cycles per revolution,
//! `F(m) (e^(i m phi_k) - 1)`, and least squares over the SMRs gives `F(m)`
//! wherever some `e^(i m phi_k)` differs from 1 (error separation, shearing:
//! Kinnane et al., Metrologia 52 (2015) 244). The mean of the SMRs' angles
//! carries `F(m) g(m)` with `g(m) = mean_k e^(i m phi_k)`; subtracting the
//! separated `F(m) g(m)` leaves the true angle. At equal spacing (`phi_k =
//! 360 k / N`, equal-division averaging) `g(m)` is 0 except at multiples of
//! `N`, where no difference sees `F(m)` either: the mean cancels every
//! harmonic of the tracker's error but the multiples of `N`, and those stay.
//! At unequal spacing nearly every order is separated, each with its own
//! noise `1 / |e^(i m phi_k) - 1|` amplified.
//!
//! What stays of the tracker's error in the angles (its rms over the circle,
//! the budget's systematic part of the reference): a separated order, the
//! noise of its estimate; an order separated but not significant (not
//! corrected), what its estimate and noise allow; an order no SMR difference
//! sees, its share of the specification's bound `u_spec` (one SMR's, from
//! the MPE: `tracker_errors::TransverseMpe::systematic_angle_u_deg`), that
//! bound spread evenly over the orders the survey resolves (the
//! specification says nothing of its shape; with one SMR no order is seen
//! and the whole bound stays, which needs no such assumption).
//!
//! Needs a full circle of evenly spaced targets (the differences are taken
//! to the spectral domain); a partial arc is combined by the mean of the
//! SMRs and keeps the whole bound.

use crate::types::wrap_180;
use std::collections::BTreeMap;

/// Where an SMR sits on the table, relative to the first SMR.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SmrMount {
    /// Its angle from the first SMR's, around the axis in the direction the
    /// readout increases, degrees.
    pub phase_deg: f64,
    /// Its height above the first SMR's, along the axis, mm.
    pub height_mm: f64,
}

impl SmrMount {
    /// The first SMR itself.
    pub const FIRST: SmrMount = SmrMount { phase_deg: 0.0, height_mm: 0.0 };

    /// `n` SMRs at equal spacing, one height.
    pub fn equal(n: usize) -> Vec<SmrMount> {
        let n = n.max(1);
        (0..n).map(|i| SmrMount { phase_deg: 360.0 * i as f64 / n as f64, height_mm: 0.0 }).collect()
    }

    /// Where this SMR is expected at axis angle `axis_deg`, mm, in the frame
    /// of `axis` (located from the first SMR: its centre, normal, in-plane
    /// basis, radius and zero), on the same radius.
    pub fn expected_position_mm(&self, axis: &crate::geometry::AxisFit, axis_deg: f64) -> [f64; 3] {
        let phi = (axis_deg + axis.zero_offset_deg + self.phase_deg).to_radians();
        let (s, c) = phi.sin_cos();
        std::array::from_fn(|i| {
            axis.center_mm[i] + self.height_mm * axis.normal[i] + axis.radius_mm * (c * axis.u[i] + s * axis.v[i])
        })
    }
}

/// The most SMRs a survey measures at a target.
pub const MAX_SMRS: usize = 12;

/// Parse a `[smrs]` table (`phases_deg = [...]`, optional `heights_mm =
/// [...]`, one per SMR): at least 2 and at most [`MAX_SMRS`] SMRs, each
/// phase an angle distinct from the others' (modulo 360), taken from the
/// first's (which is 0); heights within +/-10000 mm. `at(key)` is the line
/// of a key; `section` names the section in messages.
pub fn parse_section(
    t: &toml::Table,
    section: &str,
    at: &dyn Fn(&str) -> Option<usize>,
) -> Result<Vec<SmrMount>, (Option<usize>, String)> {
    for k in t.keys() {
        if k != "phases_deg" && k != "heights_mm" {
            return Err((at(k), format!("{section}: unknown key '{k}' (expected phases_deg, heights_mm)")));
        }
    }
    let numbers = |key: &str| -> Result<Option<Vec<f64>>, (Option<usize>, String)> {
        let Some(v) = t.get(key) else { return Ok(None) };
        let arr = v.as_array().ok_or((at(key), format!("{section}.{key} must be an array of numbers")))?;
        arr.iter()
            .map(|x| match x {
                toml::Value::Float(f) if f.is_finite() => Ok(*f),
                toml::Value::Integer(i) => Ok(*i as f64),
                other => Err((at(key), format!("{section}.{key}: {other} is not a number"))),
            })
            .collect::<Result<Vec<f64>, _>>()
            .map(Some)
    };
    let phases = numbers("phases_deg")?
        .ok_or((at("phases_deg"), format!("{section}: missing key 'phases_deg' (one angle per SMR, degrees)")))?;
    if !(2..=MAX_SMRS).contains(&phases.len()) {
        return Err((
            at("phases_deg"),
            format!("{section}.phases_deg: {} SMRs; a survey measures 2 to {MAX_SMRS}", phases.len()),
        ));
    }
    if let Some(p) = phases.iter().find(|p| p.abs() > 360.0) {
        return Err((at("phases_deg"), format!("{section}.phases_deg: {p} is not an angle within +/-360 deg")));
    }
    let heights = numbers("heights_mm")?.unwrap_or_else(|| vec![0.0; phases.len()]);
    if heights.len() != phases.len() {
        return Err((
            at("heights_mm"),
            format!("{section}.heights_mm: {} heights for {} SMRs (one per SMR)", heights.len(), phases.len()),
        ));
    }
    if let Some(h) = heights.iter().find(|h| h.abs() > 10_000.0) {
        return Err((at("heights_mm"), format!("{section}.heights_mm: {h} mm is not a height on a table (+/-10000)")));
    }
    let mounts: Vec<SmrMount> = phases
        .iter()
        .zip(&heights)
        .map(|(p, h)| SmrMount { phase_deg: (p - phases[0]).rem_euclid(360.0), height_mm: h - heights[0] })
        .collect();
    for (i, a) in mounts.iter().enumerate() {
        for b in &mounts[..i] {
            if wrap_180(a.phase_deg - b.phase_deg).abs() < 1e-6 && (a.height_mm - b.height_mm).abs() < 1e-6 {
                return Err((
                    at("phases_deg"),
                    format!("{section}.phases_deg: two SMRs at the same place ({} deg)", phases[i]),
                ));
            }
        }
    }
    Ok(mounts)
}

/// The `[smrs]` section [`parse_section`] reads back.
pub fn section_toml(smrs: &[SmrMount]) -> String {
    let list = |f: &dyn Fn(&SmrMount) -> f64| {
        smrs.iter().map(|m| crate::num::Num(f(m)).to_string()).collect::<Vec<_>>().join(", ")
    };
    format!("[smrs]\nphases_deg = [{}]\nheights_mm = [{}]\n", list(&|m| m.phase_deg), list(&|m| m.height_mm))
}

/// How the tracker's error was taken out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// One SMR: not at all.
    None,
    /// Several at equal spacing: the mean cancels all but the multiples of `N`.
    EqualDivision,
    /// Several at unequal spacing: the error function separated from the
    /// differences, and subtracted.
    Separation,
}

impl Method {
    /// `"none"`, `"equal-division"`, `"separation"` (the contract's).
    pub fn as_str(self) -> &'static str {
        match self {
            Method::None => "none",
            Method::EqualDivision => "equal-division",
            Method::Separation => "separation",
        }
    }
}

/// One order of the tracker's separated error, as it lands on the angles:
/// `amplitude_deg sin(cycles_per_rev theta + phase_deg)` at the first SMR's
/// place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorLine {
    pub cycles_per_rev: f64,
    pub amplitude_deg: f64,
    pub phase_deg: f64,
}

/// The SMRs' angles combined, and what was learnt of the tracker's error.
#[derive(Debug, Clone, PartialEq)]
pub struct Combined {
    /// Each sample's angle (the first SMR's zero reference).
    pub angles_deg: Vec<f64>,
    pub method: Method,
    /// Whether the tracker's error was measured (several SMRs, a full circle).
    pub separated: bool,
    /// The tracker's error the SMRs separated (significant orders only),
    /// largest first.
    pub lines: Vec<ErrorLine>,
    /// The standard uncertainty (rms over the circle) of what stays of the
    /// tracker's systematic error in the angles, degrees.
    pub u_deg: f64,
    /// In words.
    pub notes: Vec<String>,
}

/// One quadrature pair.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct C {
    re: f64,
    im: f64,
}

impl C {
    fn of_angle(a: f64) -> C {
        C { re: a.cos(), im: a.sin() }
    }
    fn mul(self, o: C) -> C {
        C { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
    fn conj(self) -> C {
        C { re: self.re, im: -self.im }
    }
    fn norm2(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    fn scale(self, k: f64) -> C {
        C { re: self.re * k, im: self.im * k }
    }
    fn add(self, o: C) -> C {
        C { re: self.re + o.re, im: self.im + o.im }
    }
}

/// The family-wise false-alarm rate of the orders tested for correction.
const ALPHA: f64 = 0.01;

/// Combine the angles `angles_deg[k][s]` of SMR `k` (mounted at
/// `phases_deg[k]`, `phases_deg[0] = 0`) for the samples at targets
/// `targets_deg[s]`, with `u_spec_deg` the specification's bound of one
/// SMR's angle (see the module documentation). Every SMR has an angle for
/// every sample.
pub fn combine(targets_deg: &[f64], angles_deg: &[Vec<f64>], phases_deg: &[f64], u_spec_deg: f64) -> Combined {
    let n_smrs = angles_deg.len();
    assert_eq!(n_smrs, phases_deg.len(), "one phase per SMR");
    assert!(angles_deg.iter().all(|a| a.len() == targets_deg.len()), "one angle per sample and SMR");
    if n_smrs <= 1 {
        return Combined {
            angles_deg: angles_deg.first().cloned().unwrap_or_default(),
            method: Method::None,
            separated: false,
            lines: Vec::new(),
            u_deg: u_spec_deg,
            notes: Vec::new(),
        };
    }
    // Each sample's difference from the first SMR, wrapped.
    let diff = |k: usize, s: usize| wrap_180(angles_deg[k][s] - angles_deg[0][s]);
    let mean_angle = |s: usize| angles_deg[0][s] + (1..n_smrs).map(|k| diff(k, s)).sum::<f64>() / n_smrs as f64;
    let equal = {
        let spacing = 360.0 / n_smrs as f64;
        phases_deg.iter().enumerate().all(|(k, p)| wrap_180(p - spacing * k as f64).abs() < 1e-6)
    };
    let method = if equal { Method::EqualDivision } else { Method::Separation };
    // The targets, each with its samples' mean differences.
    let mut by_target: BTreeMap<u64, (f64, Vec<Vec<f64>>)> = BTreeMap::new();
    for (s, t) in targets_deg.iter().enumerate() {
        let e = by_target.entry(wrap_360(*t).to_bits()).or_insert_with(|| (wrap_360(*t), vec![Vec::new(); n_smrs]));
        for k in 1..n_smrs {
            e.1[k].push(diff(k, s));
        }
    }
    let targets: Vec<f64> = by_target.values().map(|(t, _)| *t).collect();
    let n = targets.len();
    let step = 360.0 / n.max(1) as f64;
    let uniform = n >= 8 && targets.iter().enumerate().all(|(j, t)| (t - (targets[0] + step * j as f64)).abs() < 1e-6);
    let mean_angles: Vec<f64> = (0..targets_deg.len()).map(mean_angle).collect();
    if !uniform {
        return Combined {
            angles_deg: mean_angles,
            method,
            separated: false,
            lines: Vec::new(),
            u_deg: u_spec_deg,
            notes: vec![
                "the SMRs' angles are averaged, but the tracker's error is not separated: that needs a full circle \
                 of evenly spaced targets; the whole of its specification's bound stays in U"
                    .into(),
            ],
        };
    }
    // The noise of one target's mean difference: the scatter of the
    // differences about their target's mean (runs, directions).
    let (mut ss, mut dof) = (0.0, 0usize);
    let mut d_mean = vec![vec![0.0; n]; n_smrs];
    for (j, (_, per_k)) in by_target.values().enumerate() {
        for k in 1..n_smrs {
            let v = &per_k[k];
            let m = v.iter().sum::<f64>() / v.len() as f64;
            d_mean[k][j] = m;
            ss += v.iter().map(|x| (x - m).powi(2)).sum::<f64>();
            dof += v.len().saturating_sub(1);
        }
    }
    let reps = targets_deg.len() as f64 / n as f64;
    let sigma_one = if dof > 0 { (ss / dof as f64).sqrt() } else { 0.0 };
    let sigma_target = sigma_one / reps.max(1.0).sqrt();
    // Per quadrature component of an amplitude `2 |X| / n`: sigma sqrt(2 / n).
    let sigma_coeff = sigma_target * (2.0 / n as f64).sqrt();
    let orders = (n - 1) / 2;
    let phis: Vec<f64> = phases_deg.iter().map(|p| p.to_radians()).collect();
    let typical = 2.0 * (n_smrs - 1) as f64;
    // Which orders are seen, their estimates and their noise.
    struct Order {
        m: usize,
        f: C,
        se: f64,
        g: C,
        seen: bool,
    }
    let mut estimates = Vec::with_capacity(orders);
    for m in 1..=orders {
        let z: Vec<C> = phis.iter().map(|p| C::of_angle(m as f64 * p).add(C { re: -1.0, im: 0.0 })).collect();
        let s_m: f64 = z.iter().map(|z| z.norm2()).sum();
        let g = phis.iter().fold(C::default(), |acc, p| acc.add(C::of_angle(m as f64 * p))).scale(1.0 / n_smrs as f64);
        let seen = s_m >= 0.05 * typical;
        let mut f = C::default();
        if seen {
            for k in 1..n_smrs {
                // The amplitude-normalised coefficient of the differences at m:
                // 2/n sum_j d(theta_j) e^(-i m theta_j) (a real signal's `A e^(i phase)` form).
                let d = dft(&d_mean[k], &targets, m);
                f = f.add(z[k].conj().mul(d));
            }
            f = f.scale(1.0 / s_m);
        }
        let se = if seen { sigma_coeff / s_m.sqrt() } else { 0.0 };
        estimates.push(Order { m, f, se, g, seen });
    }
    let tested = estimates.iter().filter(|o| o.seen).count().max(1);
    // |F| / se, two components: a chi-square of 2 degrees of freedom.
    let threshold = (2.0 * (tested as f64 / ALPHA).ln()).sqrt();
    let spec_share = u_spec_deg * u_spec_deg / orders.max(1) as f64;
    let mut var = 0.0;
    let mut lines = Vec::new();
    let mut correction: Vec<(usize, C)> = Vec::new();
    for o in &estimates {
        let g2 = o.g.norm2();
        if !o.seen {
            var += spec_share * g2;
            continue;
        }
        let amplitude = o.f.norm2().sqrt();
        if o.se > 0.0 && amplitude > threshold * o.se || (o.se == 0.0 && amplitude > 0.0) {
            // Separated and corrected: its estimate's noise stays.
            var += g2 * o.se * o.se;
            correction.push((o.m, o.f.mul(o.g)));
            lines.push(line_of(o.m, o.f));
        } else {
            // Seen to be small, left: what the estimate and its noise allow.
            var += g2 * (amplitude * amplitude / 2.0 + o.se * o.se);
        }
    }
    lines.sort_by(|a, b| b.amplitude_deg.total_cmp(&a.amplitude_deg));
    let angles: Vec<f64> = targets_deg
        .iter()
        .zip(&mean_angles)
        .map(|(t, a)| {
            let th = t.to_radians();
            a - correction.iter().map(|(m, c)| value_at(*c, *m, th)).sum::<f64>()
        })
        .collect();
    let unseen: Vec<usize> = estimates.iter().filter(|o| !o.seen && o.g.norm2() > 1e-6).map(|o| o.m).collect();
    let mut notes = vec![format!(
        "{n_smrs} SMRs ({}): {} orders of the tracker's error separated and taken out of the angles; {}",
        if equal {
            "equal spacing: their mean cancels every order but the multiples of the count"
        } else {
            "unequal spacing"
        },
        lines.len(),
        match unseen.len() {
            0 => "every order the survey resolves is seen by the differences".to_string(),
            k => format!(
                "{k} order(s) no difference between them sees ({}{}) keep their share of the specification's bound",
                unseen.iter().take(6).map(|m| m.to_string()).collect::<Vec<_>>().join(", "),
                if unseen.len() > 6 { ", ..." } else { "" }
            ),
        }
    )];
    if sigma_one == 0.0 {
        notes.push("one reading per target and SMR: the separation's noise is not known (no U for it)".into());
    }
    Combined { angles_deg: angles, method, separated: true, lines, u_deg: var.sqrt(), notes }
}

fn wrap_360(d: f64) -> f64 {
    let w = d.rem_euclid(360.0);
    if (360.0 - w) < 1e-9 { 0.0 } else { w }
}

/// `2/n sum_j y_j e^(-i m theta_j)`: the complex amplitude whose real
/// signal is `Re(c e^(i m theta))`.
fn dft(y: &[f64], theta_deg: &[f64], m: usize) -> C {
    let n = y.len() as f64;
    let mut acc = C::default();
    for (v, t) in y.iter().zip(theta_deg) {
        let a = -(m as f64) * t.to_radians();
        acc = acc.add(C::of_angle(a).scale(*v));
    }
    acc.scale(2.0 / n)
}

/// `Re(c e^(i m theta))`.
fn value_at(c: C, m: usize, theta_rad: f64) -> f64 {
    c.mul(C::of_angle(m as f64 * theta_rad)).re
}

/// `Re(c e^(i m theta)) = |c| sin(m theta + phase)` with `phase = atan2(re, -im)`.
fn line_of(m: usize, c: C) -> ErrorLine {
    ErrorLine { cycles_per_rev: m as f64, amplitude_deg: c.norm2().sqrt(), phase_deg: c.re.atan2(-c.im).to_degrees() }
}

#[cfg(test)]
mod tests;
