//! A polygon calibrated in place (issue 48): an autocollimator survey whose
//! polygon was turned relative to the table between runs (`run
//! --polygon-turns`) measures the polygon's face errors itself
//! (`survey_tables::closure`), and its actual angles are corrected from
//! the certificate's faces to the faces known best before anything is
//! computed of them: each face's measurement and its certificate weighed by
//! their uncertainties (GUM's weighted mean of two independent estimates),
//! or the measurement alone where the two disagree (the certificate is
//! stale there): where their difference passes what the two uncertainties
//! allow at a 5 % false alarm over all the faces together (Bonferroni: the
//! faces' errors are correlated along the closure's chain, and a per-face
//! `E_n > 1` would call one face of 24 stale more often than not). The certificate each sample was computed with is read back from
//! the sample itself (`actual = nominal + (X + c) / 3600`), so nothing but the
//! stored samples and readings is needed.

use serde::Serialize;
use survey_acquire::RawReading;
use survey_processing::Sample;
use survey_store::Store;
use survey_store::survey::SurveyRecord;
use survey_tables::closure::{self, FaceSample};

/// What the survey measured of its polygon: the contract's `polygon`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PolygonClosure {
    /// The polygon's faces.
    pub faces: usize,
    /// The turns (faces) the polygon was read at relative to the table.
    pub turns: Vec<usize>,
    /// Each face's deviation from nominal as measured, arcsec (in the
    /// certificate's convention: the same mean).
    pub face_errors_arcsec: Vec<f64>,
    /// Their standard uncertainties, arcsec.
    pub face_u_arcsec: Vec<f64>,
    /// What the certificate says of each face, arcsec.
    pub certificate_arcsec: Vec<f64>,
    /// The standard uncertainty the certificate states for each face, arcsec.
    pub certificate_u_arcsec: f64,
    /// Each face's `E_n`: `|measured - certificate|` over the expanded
    /// (`k = 2`) uncertainty of the difference.
    pub en: Vec<f64>,
    /// The faces whose measurement disagrees with the certificate (at a 5 %
    /// false alarm over all the faces): their measurement is used alone.
    pub stale_faces: Vec<usize>,
    /// The faces the angles are corrected to, arcsec: the weighted mean of
    /// measurement and certificate, the measurement alone on a stale face.
    pub faces_used_arcsec: Vec<f64>,
    /// Their standard uncertainties, arcsec.
    pub faces_used_u_arcsec: Vec<f64>,
    /// The largest difference between the certificate and the measurement,
    /// arcsec, and its face.
    pub largest_certificate_error_arcsec: f64,
    pub largest_certificate_error_face: usize,
    /// How far the stage left the polygon from its nominal turn in each run,
    /// relative to the first, arcsec.
    pub run_offsets_arcsec: Vec<f64>,
    /// The standard deviation of one reading about the closure, arcsec.
    pub reading_sd_arcsec: f64,
    /// What stays of the polygon's error in the corrected angles (the rms of
    /// the used faces' standard uncertainties), degrees: the budget's
    /// "reference instrument, systematic".
    pub u_deg: f64,
    /// The turn (faces) each run read the polygon at: a drift in time is
    /// told only between runs at the same turn
    /// (`survey_tables::timedrift::estimate_between_placements`).
    #[serde(skip)]
    pub turn_of_run: std::collections::BTreeMap<u32, usize>,
}

impl PolygonClosure {
    /// The turn of each of `samples`' runs (0 for a run it does not know).
    pub fn turns_of(&self, samples: &[Sample]) -> Vec<usize> {
        samples.iter().map(|s| self.turn_of_run.get(&s.run).copied().unwrap_or(0)).collect()
    }
}

impl PolygonClosure {
    /// Its key in a command's JSON document, `polygon` (the contract's
    /// `reference_error` is a tracker's: its methods are the SMRs').
    pub fn put_in(&self, doc: &mut serde_json::Value) {
        doc["polygon"] = serde_json::to_value(self).unwrap_or_default();
    }

    /// Two lines for people.
    pub fn text(&self) -> String {
        let stale = match self.stale_faces.len() {
            0 => "none disagrees with its certificate".to_string(),
            _ => format!("faces {:?} disagree with their certificate: measured values used", self.stale_faces),
        };
        format!(
            "polygon calibrated in place ({} faces read at turns {:?}): measured to {:.2} arcsec a face (1 sigma, \
             rms; one reading scatters {:.2} arcsec), the certificate off by up to {:.2} arcsec (face {}); {stale}; \
             the faces used known to {:.2} arcsec\n",
            self.faces,
            self.turns,
            rms(&self.face_u_arcsec),
            self.reading_sd_arcsec,
            self.largest_certificate_error_arcsec,
            self.largest_certificate_error_face,
            self.u_deg * 3600.0,
        )
    }
}

/// Close the polygon of an autocollimator survey whose polygon was read at
/// two turns or more and correct `samples` (the survey's, in seq order) to
/// the faces known best; `None` for any other survey, or one whose
/// closure cannot be solved (said in a warning: its angles stay computed
/// through the certificate).
pub async fn close_polygon(
    store: &Store,
    survey: &SurveyRecord,
    samples: &mut [Sample],
) -> anyhow::Result<Option<PolygonClosure>> {
    if survey.reference() != Some(survey_acquire::ReferenceKind::Autocollimator) {
        return Ok(None);
    }
    let Some(faces) = survey.setup.plan().map(|p| p.targets_deg.len()).filter(|n| *n >= 2) else {
        return Ok(None);
    };
    let recorded = store.recorded_samples(survey.id).await?;
    if recorded.len() != samples.len() {
        return Ok(None);
    }
    let pitch = 360.0 / faces as f64;
    let mut certificate = vec![None; faces];
    let mut face_samples = Vec::with_capacity(samples.len());
    for (r, s) in recorded.iter().zip(samples.iter()) {
        let RawReading::Autocollimator { face, reading } = r.raw else { return Ok(None) };
        let place = (s.target_deg / pitch).round();
        let target = place.rem_euclid(faces as f64) as usize;
        let face = face as usize;
        if face >= faces {
            return Ok(None);
        }
        let nominal = place * pitch;
        // The certificate the engine read for this face.
        let c = 3600.0 * (s.actual_deg - nominal) - reading.x_arcsec;
        certificate[face].get_or_insert(c);
        face_samples.push(FaceSample {
            target,
            face,
            direction: s.direction,
            run: s.run,
            error_deg: s.readout_deg - s.actual_deg,
        });
    }
    let turns: std::collections::BTreeSet<usize> = face_samples.iter().map(|f| f.orientation(faces)).collect();
    if turns.len() < 2 {
        return Ok(None);
    }
    let Some(certificate): Option<Vec<f64>> = certificate.into_iter().collect() else {
        tracing::warn!(
            survey = survey.id,
            "the polygon was turned, but some faces were never read: it cannot be closed"
        );
        return Ok(None);
    };
    let c = match closure::solve(faces, &face_samples, &certificate) {
        Ok(c) => c,
        Err(e) => {
            // The survey is processed through the certificate, as a survey
            // of an unturned polygon is: said, not failed.
            tracing::warn!(
                survey = survey.id,
                "the polygon cannot be closed ({e}): the angles stay computed through its certificate"
            );
            return Ok(None);
        }
    };
    let u_c = crate::refit::polygon_certificate_u_arcsec(survey);
    let z = survey_processing::special::normal_two_sided_isf(0.05 / faces as f64);
    let mut en = Vec::with_capacity(faces);
    let mut stale_faces = Vec::new();
    let mut faces_used_arcsec = Vec::with_capacity(faces);
    let mut faces_used_u_arcsec = Vec::with_capacity(faces);
    for (k, &cert) in certificate.iter().enumerate() {
        let (m, u_m) = (c.face_errors_arcsec[k], c.face_u_arcsec[k]);
        let e = (m - cert).abs() / (2.0 * (u_m * u_m + u_c * u_c).sqrt());
        en.push(e);
        if 2.0 * e > z {
            stale_faces.push(k);
            faces_used_arcsec.push(m);
            faces_used_u_arcsec.push(u_m);
        } else {
            let (w_m, w_c) = (1.0 / (u_m * u_m), 1.0 / (u_c * u_c));
            faces_used_arcsec.push((m * w_m + cert * w_c) / (w_m + w_c));
            faces_used_u_arcsec.push((1.0 / (w_m + w_c)).sqrt());
        }
    }
    for (s, f) in samples.iter_mut().zip(&face_samples) {
        s.actual_deg += (faces_used_arcsec[f.face] - certificate[f.face]) / 3600.0;
    }
    let (largest_certificate_error_face, largest) = c
        .face_errors_arcsec
        .iter()
        .zip(&certificate)
        .map(|(t, c)| (c - t).abs())
        .enumerate()
        .fold((0, 0.0), |best, (k, d)| if d > best.1 { (k, d) } else { best });
    let u_deg = rms(&faces_used_u_arcsec) / 3600.0;
    let turn_of_run = face_samples.iter().map(|f| (f.run, f.orientation(faces))).collect();
    let closure = PolygonClosure {
        faces,
        turns: c.orientations,
        face_errors_arcsec: c.face_errors_arcsec,
        face_u_arcsec: c.face_u_arcsec,
        certificate_arcsec: certificate,
        certificate_u_arcsec: u_c,
        en,
        stale_faces,
        faces_used_arcsec,
        faces_used_u_arcsec,
        largest_certificate_error_arcsec: largest,
        largest_certificate_error_face,
        run_offsets_arcsec: c.run_offsets_arcsec,
        reading_sd_arcsec: c.reading_sd_arcsec,
        u_deg,
        turn_of_run,
    };
    tracing::info!(survey = survey.id, ?closure, "polygon closed");
    Ok(Some(closure))
}

/// The root mean square.
fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}
