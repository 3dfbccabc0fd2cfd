//! Axes measured over part of a revolution (an elevation from -10 to 90 deg).
//!
//! Spectral resampling treats the survey as one period of a periodic
//! function; over a partial span the error is not periodic (the two ends do
//! not meet), and a Fourier series of it would ring at the ends. Two methods
//! that do not assume periodicity:
//!
//! - [`PartialMethod::LeastSquares`]: the error is fitted over the span, in the
//!   least-squares sense, by a low-order polynomial (Legendre polynomials of
//!   the position scaled to `[-1, 1]`, for conditioning) plus sinusoids at the
//!   given frequencies (cycles per revolution, from the design: gear passes
//!   and their harmonics). The slow part of the error (eccentricity over a
//!   100 degree span, the zero offset) is taken by the polynomial. This is the
//!   counterpart of keeping the repeatable lines on a full circle: the fit
//!   filters the noise (its prediction carries `sigma * leverage`, see
//!   [`PartialFit::leverage`], well below `sigma` when samples far outnumber
//!   parameters), but what it has no term for stays in the residual
//!   ([`PartialFit::residual_rms_deg`]: compare it with the noise and add
//!   frequencies when it is larger). Solved by Householder QR; a basis that is
//!   numerically dependent on the span (a 1-cycle term beside a cubic over a
//!   short span) is refused rather than fitted with wild coefficients.
//! - [`PartialMethod::Cubic`]: 4-point Lagrange (cubic) interpolation of the
//!   mean map, one-sided at the ends. It needs no frequency list and follows
//!   every repeatable component, but keeps the noise of the map (leverage
//!   at most 1).
//!
//! The samples are uniform over the span, both ends included: sample `j` of
//! `M` is at `start + j (end - start) / (M - 1)`.
//!
//! A table has rows all around the circle. [`PartialFit::column`] fills the rows
//! inside the span with the fit, holds (clamps) the rows outside at the value
//! of the nearer end instead of wrapping, and gives the one row just beyond each
//! end the fit's tangent at that end, so that linear interpolation between the
//! last row inside and the first outside still follows the fit up to the end.

use crate::lstsq::{Qr, column_norms};
use crate::types::wrap_360;
use serde::{Deserialize, Serialize};

/// A measured span of an axis, degrees: from `start_deg` up to `end_deg`
/// (`0 < end - start < 360`; angles may be negative, -10 to 90 is an elevation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Span {
    /// Lower end, degrees.
    pub start_deg: f64,
    /// Upper end, degrees.
    pub end_deg: f64,
}

impl Span {
    /// `end - start`, degrees.
    pub fn width_deg(&self) -> f64 {
        self.end_deg - self.start_deg
    }

    /// The representation of `theta_deg` (any turn) nearest the span: inside it
    /// when the angle is in the span, else just beyond the nearer end.
    pub fn unwrap(&self, theta_deg: f64) -> f64 {
        let rel = wrap_360(theta_deg - self.start_deg);
        let w = self.width_deg();
        if rel <= w || rel - w <= 360.0 - rel { self.start_deg + rel } else { self.start_deg + rel - 360.0 }
    }

    fn check(&self) -> Result<(), PartialError> {
        let w = self.width_deg();
        if self.start_deg.is_finite() && self.end_deg.is_finite() && w > 0.0 && w < 360.0 {
            Ok(())
        } else {
            Err(PartialError::BadSpan { start_deg: self.start_deg, end_deg: self.end_deg })
        }
    }
}

/// How a partial-span map is turned into a function of the angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case", deny_unknown_fields)]
pub enum PartialMethod {
    /// Cubic (4-point Lagrange) interpolation of the map: `{ method = "cubic" }`.
    Cubic,
    /// Least squares: Legendre polynomial of `poly_degree` plus a sine and a
    /// cosine at each of `cycles` (cycles per revolution):
    /// `{ method = "least_squares", cycles = [6, 12, 72], poly_degree = 3 }`.
    LeastSquares {
        /// Frequencies of the sinusoids, cycles per revolution.
        cycles: Vec<f64>,
        /// Degree of the polynomial (0 = a constant).
        poly_degree: usize,
    },
}

/// Why a partial-span map cannot be fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PartialError {
    /// The span is not `0 < end - start < 360` with finite ends.
    #[error(
        "span {}..{} deg: it must be finite with 0 < end - start < 360",
        crate::num::Num(*start_deg),
        crate::num::Num(*end_deg)
    )]
    BadSpan {
        /// The lower end given.
        start_deg: f64,
        /// The upper end given.
        end_deg: f64,
    },
    /// Too few samples for the method.
    #[error("{have} samples over the span; the {method} method needs at least {need}")]
    TooFewSamples {
        /// Samples given.
        have: usize,
        /// Samples needed.
        need: usize,
        /// `cubic` or `least-squares`.
        method: &'static str,
    },
    /// A sample is NaN or infinite.
    #[error("sample {index} is {}, not a finite number", crate::num::Num(*value))]
    NotFinite {
        /// Position of the sample (from 0).
        index: usize,
        /// The value.
        value: f64,
    },
    /// A frequency is not a positive, finite number.
    #[error("frequency {} cycles/rev must be positive and finite", crate::num::Num(*.0))]
    BadFrequency(f64),
    /// The basis is numerically dependent over the span.
    #[error(
        "the least-squares basis is degenerate over the span (term {term}: {name}); \
         lower the polynomial degree or drop frequencies the polynomial already covers"
    )]
    Degenerate {
        /// Index of the first dependent basis term.
        term: usize,
        /// What the term is.
        name: String,
    },
    /// The table needs at least two rows.
    #[error("a table needs at least 2 rows, got {0}")]
    TooFewRows(usize),
}

#[derive(Debug, Clone, PartialEq)]
enum Kind {
    Cubic { samples: Vec<f64> },
    LeastSquares { cycles: Vec<f64>, degree: usize, coef: Vec<f64>, qr: Qr },
}

/// A map over a partial span, as a function of the angle.
#[derive(Debug, Clone, PartialEq)]
pub struct PartialFit {
    span: Span,
    step_deg: f64,
    kind: Kind,
    residual_rms_deg: f64,
}

/// Fit `samples` (uniform over `span`, both ends included) with `method`.
pub fn fit_partial(span: Span, samples: &[f64], method: &PartialMethod) -> Result<PartialFit, PartialError> {
    span.check()?;
    if let Some((index, &value)) = samples.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(PartialError::NotFinite { index, value });
    }
    let m = samples.len();
    let step_deg = if m > 1 { span.width_deg() / (m - 1) as f64 } else { 0.0 };
    let at = |j: usize| span.start_deg + j as f64 * step_deg;
    let kind = match method {
        PartialMethod::Cubic => {
            if m < 4 {
                return Err(PartialError::TooFewSamples { have: m, need: 4, method: "cubic" });
            }
            Kind::Cubic { samples: samples.to_vec() }
        }
        PartialMethod::LeastSquares { cycles, poly_degree } => {
            if let Some(&c) = cycles.iter().find(|c| !(c.is_finite() && **c > 0.0)) {
                return Err(PartialError::BadFrequency(c));
            }
            let p = poly_degree + 1 + 2 * cycles.len();
            if m <= p {
                return Err(PartialError::TooFewSamples { have: m, need: p + 1, method: "least-squares" });
            }
            let mut basis = vec![0.0; p];
            let mut cols: Vec<Vec<f64>> = vec![Vec::with_capacity(m); p];
            for j in 0..m {
                fill_basis(&span, cycles, *poly_degree, at(j), &mut basis);
                for (col, b) in cols.iter_mut().zip(&basis) {
                    col.push(*b);
                }
            }
            // A column whose independent part is below 1e-10 of the largest
            // column's norm cannot be resolved.
            let scale = column_norms(&cols).into_iter().fold(0.0, f64::max);
            let qr = Qr::new(cols, |_| 1e-10 * scale)
                .map_err(|term| PartialError::Degenerate { term, name: term_name(cycles, *poly_degree, term) })?;
            let (coef, _) = qr.solve(samples);
            Kind::LeastSquares { cycles: cycles.clone(), degree: *poly_degree, coef, qr }
        }
    };
    let mut fit = PartialFit { span, step_deg, kind, residual_rms_deg: 0.0 };
    let sum2: f64 = samples.iter().enumerate().map(|(j, y)| (fit.eval_unwrapped(at(j)) - y).powi(2)).sum();
    fit.residual_rms_deg = (sum2 / m as f64).sqrt();
    Ok(fit)
}

impl PartialFit {
    /// The span the fit covers.
    pub fn span(&self) -> Span {
        self.span
    }

    /// RMS of fit minus samples at the samples, degrees (0 for the cubic method,
    /// which passes through them).
    pub fn residual_rms_deg(&self) -> f64 {
        self.residual_rms_deg
    }

    /// The fitted error at `theta_deg` (any turn; see [`Span::unwrap`]). Outside
    /// the span this extrapolates the fit: tables use [`PartialFit::column`],
    /// which holds the ends instead.
    pub fn eval(&self, theta_deg: f64) -> f64 {
        self.eval_unwrapped(self.span.unwrap(theta_deg))
    }

    /// How the noise of the samples reaches the fitted value at `theta_deg`: a
    /// sample noise of `sigma` (independent, equal) gives the fit a standard
    /// deviation of `sigma * leverage`. Least squares: `sqrt(a' (A'A)^-1 a)`
    /// with `a` the basis at the angle; cubic: the root sum of squares of the
    /// four Lagrange weights.
    pub fn leverage(&self, theta_deg: f64) -> f64 {
        let x = self.span.unwrap(theta_deg);
        match &self.kind {
            Kind::Cubic { samples } => {
                let (_, w) = cubic_stencil(samples.len(), (x - self.span.start_deg) / self.step_deg);
                w.iter().map(|v| v * v).sum::<f64>().sqrt()
            }
            Kind::LeastSquares { cycles, degree, qr, .. } => {
                let mut a = vec![0.0; qr.cols()];
                fill_basis(&self.span, cycles, *degree, x, &mut a);
                qr.leverage(&a)
            }
        }
    }

    /// A table column of `rows` rows at `360 j / rows`: the fit inside the span,
    /// the tangent at the nearer end for the one row just beyond each end, and
    /// the end's value (held) for the rows further out.
    pub fn column(&self, rows: usize) -> Result<Vec<f64>, PartialError> {
        if rows < 2 {
            return Err(PartialError::TooFewRows(rows));
        }
        let h = 360.0 / rows as f64;
        let (s, e) = (self.span.start_deg, self.span.end_deg);
        let d = 1e-3 * self.step_deg.min(h);
        let (vs, ve) = (self.eval_unwrapped(s), self.eval_unwrapped(e));
        let slope_s = (self.eval_unwrapped(s + d) - vs) / d;
        let slope_e = (ve - self.eval_unwrapped(e - d)) / d;
        Ok((0..rows)
            .map(|j| {
                let x = self.span.unwrap(j as f64 * h);
                if x < s {
                    if s - x <= h { vs + slope_s * (x - s) } else { vs }
                } else if x > e {
                    if x - e <= h { ve + slope_e * (x - e) } else { ve }
                } else {
                    self.eval_unwrapped(x)
                }
            })
            .collect())
    }

    fn eval_unwrapped(&self, x: f64) -> f64 {
        match &self.kind {
            Kind::Cubic { samples } => {
                let (i, w) = cubic_stencil(samples.len(), (x - self.span.start_deg) / self.step_deg);
                (0..4).map(|k| w[k] * samples[i + k]).sum()
            }
            Kind::LeastSquares { cycles, degree, coef, .. } => {
                let mut a = vec![0.0; coef.len()];
                fill_basis(&self.span, cycles, *degree, x, &mut a);
                a.iter().zip(coef).map(|(a, c)| a * c).sum()
            }
        }
    }
}

/// The first node of the 4-point stencil for position `u` (in sample steps
/// from the start) among `m >= 4` samples, and the Lagrange weights.
fn cubic_stencil(m: usize, u: f64) -> (usize, [f64; 4]) {
    let base = (u.floor() as isize - 1).clamp(0, m as isize - 4) as usize;
    let s = u - base as f64 - 1.0; // position relative to node base + 1
    let w = [
        -s * (s - 1.0) * (s - 2.0) / 6.0,
        (s + 1.0) * (s - 1.0) * (s - 2.0) / 2.0,
        -(s + 1.0) * s * (s - 2.0) / 2.0,
        (s + 1.0) * s * (s - 1.0) / 6.0,
    ];
    (base, w)
}

/// Legendre polynomials of the scaled position, then `sin, cos` per frequency.
fn fill_basis(span: &Span, cycles: &[f64], degree: usize, x: f64, out: &mut [f64]) {
    let u = (2.0 * x - span.start_deg - span.end_deg) / span.width_deg();
    let (mut p_prev, mut p) = (0.0, 1.0);
    for (n, slot) in out.iter_mut().take(degree + 1).enumerate() {
        *slot = p;
        let nf = n as f64;
        let next = ((2.0 * nf + 1.0) * u * p - nf * p_prev) / (nf + 1.0);
        p_prev = p;
        p = next;
    }
    for (c, pair) in cycles.iter().zip(out[degree + 1..].chunks_exact_mut(2)) {
        let (s, co) = (c * x).to_radians().sin_cos();
        pair[0] = s;
        pair[1] = co;
    }
}

fn term_name(cycles: &[f64], degree: usize, term: usize) -> String {
    if term <= degree {
        format!("Legendre polynomial of degree {term}")
    } else {
        let i = (term - degree - 1) / 2;
        let part = if (term - degree - 1).is_multiple_of(2) { "sine" } else { "cosine" };
        format!("{part} at {} cycles/rev", cycles[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ELEV: Span = Span { start_deg: -10.0, end_deg: 90.0 };

    fn grid(span: Span, m: usize) -> Vec<f64> {
        (0..m).map(|j| span.start_deg + j as f64 * span.width_deg() / (m - 1) as f64).collect()
    }

    #[test]
    fn unwrap_picks_the_nearer_representation() {
        assert_eq!(ELEV.unwrap(350.0), -10.0);
        assert_eq!(ELEV.unwrap(-5.0), -5.0);
        assert_eq!(ELEV.unwrap(45.0), 45.0);
        assert_eq!(ELEV.unwrap(100.0), 100.0); // beyond the upper end
        assert_eq!(ELEV.unwrap(300.0), -60.0); // nearer the lower end
        assert_eq!(ELEV.unwrap(220.0), 220.0); // exactly half way: the upper end
    }

    #[test]
    fn least_squares_recovers_its_own_model_exactly() {
        let f = |x: f64| {
            0.001 - 0.002 * x / 90.0
                + 3e-7 * x * x
                + 0.028 * (6.0 * x + 20.0).to_radians().sin()
                + 0.006 * (72.0 * x).to_radians().sin()
        };
        let xs = grid(ELEV, 201);
        let y: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
        let fit =
            fit_partial(ELEV, &y, &PartialMethod::LeastSquares { cycles: vec![6.0, 72.0], poly_degree: 2 }).unwrap();
        assert!(fit.residual_rms_deg() < 1e-15);
        for x in [-10.0, -3.3, 0.0, 44.4, 89.99, 90.0] {
            assert!((fit.eval(x) - f(x)).abs() < 1e-14, "{x}");
        }
        // With 201 samples and 7 parameters the fit averages the noise down.
        let mid = fit.leverage(40.0);
        assert!(mid > 0.0 && mid < 0.3, "{mid}");
        assert!(fit.leverage(-10.0) > mid, "the ends are less certain");
    }

    #[test]
    fn cubic_is_exact_for_cubics_including_the_ends() {
        let f = |x: f64| 1e-3 + 2e-5 * x - 3e-7 * x * x + 4e-9 * x * x * x;
        let y: Vec<f64> = grid(ELEV, 41).iter().map(|&x| f(x)).collect();
        let fit = fit_partial(ELEV, &y, &PartialMethod::Cubic).unwrap();
        for x in [-10.0, -9.9, 1.234, 60.0, 89.5, 90.0] {
            assert!((fit.eval(x) - f(x)).abs() < 1e-15, "{x}");
        }
        assert!(fit.leverage(1.25) <= 1.0 && (fit.leverage(0.0) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn column_holds_the_ends_outside_the_span() {
        let f = |x: f64| 0.01 * (2.0 * x).to_radians().sin() + 0.002;
        let y: Vec<f64> = grid(ELEV, 101).iter().map(|&x| f(x)).collect();
        let fit = fit_partial(ELEV, &y, &PartialMethod::Cubic).unwrap();
        let col = fit.column(360).unwrap();
        // Inside: the fit. Row 45 is at 45 deg, row 350 at -10.
        assert!((col[45] - f(45.0)).abs() < 1e-9);
        assert!((col[350] - f(-10.0)).abs() < 1e-9);
        // One row beyond each end: the tangent (f'(90) = 0.01*2*cos(180)*pi/180).
        let slope90 = -0.02 * std::f64::consts::PI / 180.0;
        assert!((col[91] - (f(90.0) + slope90)).abs() < 1e-7);
        // Further out: held at the nearer end, never wrapped.
        let (top, bottom) = (fit.eval(90.0), fit.eval(-10.0));
        assert!(col[92..=220].iter().all(|&v| v == top));
        assert!(col[221..=348].iter().all(|&v| v == bottom));
    }

    #[test]
    fn bad_inputs_are_named() {
        let ls = |c: Vec<f64>, d| PartialMethod::LeastSquares { cycles: c, poly_degree: d };
        let y = vec![0.0; 50];
        assert!(matches!(
            fit_partial(Span { start_deg: 10.0, end_deg: 10.0 }, &y, &PartialMethod::Cubic),
            Err(PartialError::BadSpan { .. })
        ));
        assert!(matches!(
            fit_partial(Span { start_deg: 0.0, end_deg: 360.0 }, &y, &PartialMethod::Cubic),
            Err(PartialError::BadSpan { .. })
        ));
        assert!(matches!(
            fit_partial(ELEV, &y[..3], &PartialMethod::Cubic),
            Err(PartialError::TooFewSamples { need: 4, .. })
        ));
        assert!(matches!(
            fit_partial(ELEV, &y[..5], &ls(vec![6.0], 2)),
            Err(PartialError::TooFewSamples { need: 6, .. })
        ));
        assert!(matches!(fit_partial(ELEV, &y, &ls(vec![-1.0], 2)), Err(PartialError::BadFrequency(_))));
        let mut nan = y.clone();
        nan[7] = f64::NAN;
        assert!(matches!(
            fit_partial(ELEV, &nan, &PartialMethod::Cubic),
            Err(PartialError::NotFinite { index: 7, .. })
        ));
        // A very slow sinusoid over a short span is a polynomial already.
        let short = Span { start_deg: 0.0, end_deg: 1.0 };
        let e = fit_partial(short, &y, &ls(vec![0.01], 6)).unwrap_err();
        assert!(matches!(e, PartialError::Degenerate { .. }), "{e}");
        let fit = fit_partial(ELEV, &y, &PartialMethod::Cubic).unwrap();
        assert_eq!(fit.column(1), Err(PartialError::TooFewRows(1)));
    }

    #[test]
    fn methods_round_trip_through_toml() {
        for m in [PartialMethod::Cubic, PartialMethod::LeastSquares { cycles: vec![6.0, 72.0], poly_degree: 3 }] {
            #[derive(Serialize, Deserialize, PartialEq, Debug)]
            struct Doc {
                span: Span,
                fit: PartialMethod,
            }
            let doc = Doc { span: ELEV, fit: m };
            let text = toml::to_string(&doc).unwrap();
            assert_eq!(toml::from_str::<Doc>(&text).unwrap(), doc, "{text}");
        }
    }
}
