//! The verdict: model-gap is never falsely content. Cases of our own: a
//! partial-range elevation axis (the Figure 1 kind) whose actual angles were
//! taken around an axis off centre, an error no effect of the model file can
//! hold, and control surveys.

use super::tests::{circle, model, periodic, simulate};
use super::*;
use PeriodicKind::{Eccentricity, GearPass, Harmonic};
use survey_processing::model::{Effect, Model, PeriodicKind};
use survey_processing::types::Sample;

fn elevation() -> Model {
    model(
        &[6.0, 72.0],
        &[],
        vec![
            periodic(GearPass, 6.0, 0.028, 20.0),
            periodic(GearPass, 12.0, 0.003, 75.0),
            periodic(GearPass, 72.0, 0.006, 0.0),
            periodic(Eccentricity, 1.0, 0.002, 150.0),
            Effect::Backlash { amplitude_deg: 0.0048 },
            Effect::Noise { sigma_deg: 0.0005 },
        ],
    )
}

fn targets() -> Vec<f64> {
    (0..=400).map(|k| -9.9 + 0.2495 * k as f64).collect()
}

/// The actual angles as measured around an axis `offset_mm` off centre, in
/// the direction `toward_deg`, on an arm of `radius_mm`: each angle is turned
/// by `(offset / radius) sin(angle - toward)` (a once-per-revolution error).
fn around_an_axis_off_centre(s: &[Sample], offset_mm: f64, toward_deg: f64, radius_mm: f64) -> Vec<Sample> {
    let amplitude = (offset_mm / radius_mm).to_degrees();
    s.iter()
        .map(|x| Sample { actual_deg: x.actual_deg + amplitude * (x.actual_deg - toward_deg).to_radians().sin(), ..*x })
        .collect()
}

/// On a partial arc the axis location shows in angle only (over 100 deg a
/// once-per-revolution line is nearly the cubic the line test takes out):
/// with the model exactly right, a tracker whose axis is 0.05 mm off centre
/// on a 1 m arm makes 2.9e-3 deg of once-per-revolution error. Told the
/// reference, model-gap names it, with its size within 5 standard errors of
/// the truth, and the verdict is that the model explains the positioner; told
/// nothing of the reference, it says plainly that the model does not explain
/// the data, and never that it does.
#[test]
fn the_axis_location_is_named_with_its_size() {
    let truth = elevation();
    let (offset, radius) = (0.05, 1000.0);
    let s = around_an_axis_off_centre(&simulate(&truth, &targets(), 3, true, 0.0, 61), offset, 30.0, radius);
    let tracker = ReferenceInfo::Tracker { radius_mm: radius, points: 12, axis_se_deg: 1.6e-3, refitted: false };
    let told = ModelGapOptions { reference: tracker, ..ModelGapOptions::default() };
    let g = model_gap(&s, &truth, &told).unwrap();
    let text = g.to_text();
    assert!(g.effects_added.is_empty(), "{text}");
    assert!(g.verdict.explained, "{text}");
    let f = &g.verdict.reference[0];
    assert_eq!(f.source, "the reference: axis location");
    let want = (offset / radius).to_degrees();
    assert!((f.amplitude_deg - want).abs() < 5.0 * f.standard_error_deg, "{} against {want}\n{text}", f.amplitude_deg);
    let mm = f.center_offset_mm.unwrap();
    assert!((mm - offset).abs() < 5.0 * f.standard_error_deg.to_radians() * radius, "{mm} mm\n{text}");
    assert!(text.contains("verdict: the model explains the positioner, and the rest is the reference's"), "{text}");
    assert!(!text.contains("the model explains the data down to the noise floor)"), "{text}");

    let blind = model_gap(&s, &truth, &ModelGapOptions::default()).unwrap();
    let text = blind.to_text();
    assert!(!blind.verdict.explained && blind.verdict.reference.is_empty(), "{text}");
    assert!(blind.verdict.statement.starts_with("NOT explained"), "{text}");
    assert!(blind.verdict.targets_outside > 0 || blind.verdict.repeatable.as_ref().unwrap().rejects, "{text}");
    assert!(
        text.contains("effects added: none (see the verdict)") && !text.contains("explains the data down"),
        "{text}"
    );
}

/// A 17-cycle error matches no part of the elevation axis's design, and a
/// partial range is tested at the design frequencies only: no effect is
/// named, and the verdict says plainly that the model does not explain the
/// data (the error is 2.5 x the band of a target's mean).
#[test]
fn what_nothing_explains_is_said_plainly() {
    let mut truth = elevation();
    truth.effects.push(periodic(Harmonic, 17.0, 0.0015, 40.0));
    let given = elevation();
    let s = simulate(&truth, &targets(), 3, true, 0.0, 62);
    let tracker = ReferenceInfo::Tracker { radius_mm: 1000.0, points: 18000, axis_se_deg: 3e-5, refitted: true };
    let g = model_gap(&s, &given, &ModelGapOptions { reference: tracker, ..ModelGapOptions::default() }).unwrap();
    let text = g.to_text();
    assert!(!g.verdict.explained, "{text}");
    assert!(g.verdict.statement.starts_with("NOT explained"), "{text}");
    assert!(g.verdict.statement.contains("not periodic over the range, or periodic at a frequency"), "{text}");
    assert!(!text.contains("explains the data down"), "{text}");
}

/// With the model right, the verdict is "explained" (control surveys on a
/// full circle and a partial range, with and without a tracker told).
#[test]
fn a_right_model_is_explained() {
    let truth = elevation();
    for seed in [63, 64, 65] {
        let s = simulate(&truth, &targets(), 3, true, 0.0, seed);
        let tracker = ReferenceInfo::Tracker { radius_mm: 1000.0, points: 18000, axis_se_deg: 3e-5, refitted: true };
        for reference in [ReferenceInfo::Unknown, tracker] {
            let g = model_gap(&s, &truth, &ModelGapOptions { reference, ..ModelGapOptions::default() }).unwrap();
            assert!(g.verdict.explained && g.verdict.reference.is_empty(), "{}", g.to_text());
            assert!(g.to_text().contains("effects added: none (the model explains the data down to the noise floor)"));
        }
        let full = model(&[20.0], &[], vec![periodic(GearPass, 20.0, 0.008, 0.0), Effect::Noise { sigma_deg: 3e-4 }]);
        let s = simulate(&full, &circle(360), 3, true, 0.0, seed);
        let g = model_gap(&s, &full, &ModelGapOptions::default()).unwrap();
        assert!(g.verdict.explained, "{}", g.to_text());
    }
}
