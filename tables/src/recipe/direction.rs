//! The direction model of a full-circle directional table.
//!
//! A directional table's columns are `m +/- d / 2`, `m` the mean of the two
//! directions and `d` the forward - reverse difference (the hysteresis). Made
//! column by column, each direction's lines are fitted from half the data,
//! and the table's forward - reverse difference carries the difference of
//! two noisy fits at every kept line, even where the positioner's lost motion
//! is the same all round (a backlash): on the default bench that was 1.1e-5
//! deg rms of the 3.2e-5 deg the table was off the truth.
//!
//! So the difference is modelled on its own: its mean (the backlash) and the
//! lines of `d` that are significant in `d` itself (lost motion that varies
//! around the revolution), each tested against the noise of `d` at the
//! analysis' false alarm rate shared over its bins (the Rayleigh tail of a
//! line's amplitude: `sd sqrt(-2 ln(alpha / bins))`, `sd` a quadrature
//! component's standard deviation, `sd_d sqrt(2 / n)`). The mean's lines are
//! fitted once, from all the data, as lines of the true angle
//! ([`crate::true_angle`]); each column is those lines plus or
//! minus half the difference's lines, in a frame of the true angle moved by
//! plus or minus half its mean. That last part matters: the two directions
//! reach the same readout at true angles a backlash apart, so in readout
//! terms each direction's lines are shifted by half the backlash (on Figure
//! 8, 1.1e-5 deg rms of 20- and 40-cycle difference, below any test of the
//! difference, yet the truth).

use serde::Serialize;
use survey_processing::resample::{Resampler, Series};

/// What the direction model holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DirectionModel {
    /// Mean forward - reverse difference (the backlash), degrees.
    pub mean_deg: f64,
    /// Standard deviation of one target's difference from noise, degrees.
    pub noise_deg: f64,
    /// The amplitude a line of the difference must pass to be kept, degrees.
    pub threshold_deg: f64,
    /// The lines of the difference kept: `(cycles/rev, amplitude_deg)`.
    pub lines: Vec<(usize, f64)>,
    /// Targets per revolution.
    pub targets: usize,
}

/// The direction model of `forward` and `reverse` target means (same
/// length, uniform over the circle), `noise_deg` the standard deviation of
/// one target's difference from noise, `alpha` the false alarm rate: the
/// model, and half its lines (no mean) for the columns.
pub(crate) fn direction_model(
    forward: &[f64],
    reverse: &[f64],
    noise_deg: f64,
    alpha: f64,
    rs: &mut Resampler,
) -> (DirectionModel, Series) {
    let n = forward.len();
    let d: Vec<f64> = forward.iter().zip(reverse).map(|(f, r)| f - r).collect();
    let spectrum = rs.analyze(&d);
    let bins = (n.saturating_sub(1) / 2).max(1);
    let sd = noise_deg * (2.0 / n.max(1) as f64).sqrt();
    let threshold_deg = sd * (-2.0 * (alpha.clamp(1e-12, 1.0) / bins as f64).ln()).sqrt();
    let mut half = Series::default();
    let mut lines = Vec::new();
    for k in 1..=bins {
        if spectrum.amplitude(k) > threshold_deg {
            half.set_coeff(k, spectrum.coeff(k) / 2.0);
            lines.push((k, spectrum.amplitude(k)));
        }
    }
    let dm = DirectionModel { mean_deg: spectrum.amplitude(0), noise_deg, threshold_deg, lines, targets: n };
    (dm, half)
}

impl DirectionModel {
    /// In words.
    pub fn text(&self) -> String {
        let lines = if self.lines.is_empty() {
            "no line of it above its threshold".to_string()
        } else {
            let l: Vec<String> = self.lines.iter().map(|(k, a)| format!("{k} cycles/rev {a:.2e} deg")).collect();
            format!("its lines {}", l.join(", "))
        };
        format!(
            "direction model: forward - reverse modelled on its own (mean {:.5} deg, {lines}; a line kept above \
             {:.2e} deg), the lines of the two directions fitted once from both",
            self.mean_deg, self.threshold_deg
        )
    }
}
