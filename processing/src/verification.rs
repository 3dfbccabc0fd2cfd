//! The figures of a verification survey (`survey run --verify`): where its
//! targets lie against the calibration targets, and the peak errors that
//! compare the corrected axis with the native one.

use crate::Direction;
use crate::Sample;
use crate::correction::ErrorFigures;
use std::collections::BTreeMap;

/// The distance between two angles around the circle, degrees.
pub fn circular_distance(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// The smallest distance from a verification target to a calibration
/// target, degrees (around the circle).
pub fn offset_deg(targets_deg: &[f64], calibration_deg: &[f64]) -> f64 {
    targets_deg
        .iter()
        .map(|t| calibration_deg.iter().map(|c| circular_distance(*t, *c)).fold(f64::INFINITY, f64::min))
        .fold(f64::INFINITY, f64::min)
}

/// Peak of `|error - mean error|` over every sample: the "+/-" figure of the
/// paper, as processing's prediction computes it.
pub fn peak_deg(samples: &[Sample]) -> f64 {
    let errors: Vec<f64> = samples.iter().map(Sample::error_deg).collect();
    ErrorFigures::of(&errors, None).peak_deg
}

/// Peak of the systematic error: the mean error per target and direction over
/// the runs, less the overall mean (the noise averages down by sqrt(runs)).
pub fn systematic_peak_deg(samples: &[Sample]) -> f64 {
    let mut groups: BTreeMap<(u64, Direction), (f64, usize)> = BTreeMap::new();
    for s in samples {
        let g = groups.entry((s.target_deg.to_bits(), s.direction)).or_default();
        g.0 += s.error_deg();
        g.1 += 1;
    }
    let means: Vec<f64> = groups.values().map(|(sum, n)| sum / *n as f64).collect();
    let mean = means.iter().sum::<f64>() / means.len().max(1) as f64;
    means.iter().map(|m| (m - mean).abs()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(run: u32, direction: Direction, target_deg: f64, error: f64) -> Sample {
        Sample {
            run,
            direction,
            target_deg,
            readout_deg: target_deg + error,
            actual_deg: target_deg,
            timestamp_s: None,
        }
    }

    #[test]
    fn distances_go_around_the_circle() {
        assert_eq!(circular_distance(359.0, 1.0), 2.0);
        assert_eq!(circular_distance(10.0, 40.0), 30.0);
        assert_eq!(offset_deg(&[5.0, 355.5], &[0.0, 90.0, 180.0, 270.0]), 4.5);
    }

    #[test]
    fn the_systematic_peak_averages_the_runs_and_the_peak_does_not() {
        // Two targets, forward, two runs: errors (1, 3) at 0 deg, (-1, -3) at 90 deg.
        let s = [
            sample(1, Direction::Forward, 0.0, 1.0),
            sample(2, Direction::Forward, 0.0, 3.0),
            sample(1, Direction::Forward, 90.0, -1.0),
            sample(2, Direction::Forward, 90.0, -3.0),
        ];
        // Means per target 2 and -2 around an overall 0.
        assert_eq!(systematic_peak_deg(&s), 2.0);
        assert_eq!(systematic_peak_deg(&[]), 0.0);
        // Every sample's error from the overall mean: at most 3.
        assert!((peak_deg(&s) - 3.0).abs() < 1e-12, "{}", peak_deg(&s));
    }
}
