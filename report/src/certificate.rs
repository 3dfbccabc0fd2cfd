//! The fields a calibration certificate states, and where each comes
//! from ([`super::html::header`] shows them). In order of precedence: a flag of `survey report` (`--certificate-number`,
//! `--laboratory`, `--traceability`, `--tolerance`, `--positioner`,
//! `--reference-instrument`, `--reference-uncertainty`, `--operator`,
//! `--customer`, `--temperature`, `--signatory`, `--location`,
//! `--item-condition`, `--received`, `--country`); the `[certificate]` section of the
//! configuration file, stored with the survey; what the bench itself says
//! (the simulated preset's name and description, the simulated reference's
//! noise, a configured instrument's driver and address, a simulated
//! reference's lack of traceability); the survey (a certificate number made
//! of its date and uid when none was assigned, [`crate::issue`]); else "not stated".

use survey_acquire::ReferenceKind;
use survey_processing::model::Model;
use survey_processing::tracker_errors::TrackerErrorSpec;
use survey_store::config::readdress::instrument_words;
use survey_store::config::{Address, CertificateSection, Equipment};
use survey_store::survey::{Setup, SurveyRecord};

/// What `survey report`'s flags say (each overrides the stored value): the
/// same fields as the configuration's `[certificate]`.
pub type CertificateFlags = survey_store::config::CertificateSection;

/// What a page states of its issue.
#[derive(Debug, Clone, PartialEq)]
pub enum Issue {
    /// The certificate as issued: its number, when, and what it replaces.
    Issued { number: String, issued_at: String, seq: i64, replaces: Option<Replaced> },
    /// Not issued, and why.
    Draft(String),
}

/// The certificate an amendment replaces.
#[derive(Debug, Clone, PartialEq)]
pub struct Replaced {
    pub number: String,
    pub issued_at: String,
    pub reason: String,
    /// Its DCC's SHA-256, hexadecimal (the DCC's `previousReport` names it by it).
    pub dcc_sha256: String,
}

/// The number made from a survey: its date and the first 12 hexadecimal
/// digits of its uid (see [`crate::issue`]).
pub fn made_number(survey: &SurveyRecord) -> String {
    number_from(&survey.created_at, &survey.uid)
}

fn number_from(created_at: &str, uid: &str) -> String {
    let date: String = created_at.chars().filter(char::is_ascii_digit).take(8).collect();
    let hex: String = uid.chars().filter(char::is_ascii_hexdigit).take(12).collect::<String>().to_lowercase();
    if date.len() == 8 { format!("{date}-{hex}") } else { hex }
}

/// A value and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct Stated<T> {
    pub value: T,
    pub from: &'static str,
}

/// Every field of the header.
#[derive(Debug, Clone, PartialEq)]
pub struct Certificate {
    /// Always present: assigned, or made from the survey.
    pub number: Stated<String>,
    pub laboratory: Option<Stated<String>>,
    pub traceability: Option<Stated<String>>,
    pub tolerance_deg: Option<Stated<f64>>,
    pub positioner: Option<Stated<String>>,
    pub reference: Option<Stated<String>>,
    pub reference_uncertainty_deg: Option<Stated<f64>>,
    pub operator: Option<Stated<String>>,
    pub customer: Option<Stated<String>>,
    pub temperature_c: Option<Stated<f64>>,
    /// Who authorises the certificate: name and function.
    pub signatory: Option<Stated<String>>,
    /// Where the calibration was performed.
    pub location: Option<Stated<String>>,
    /// The item's condition.
    pub item_condition: Option<Stated<String>>,
    /// The date the item was received, `YYYY-MM-DD`.
    pub received: Option<Stated<String>>,
    /// The laboratory's country, ISO 3166-1 alpha-2.
    pub country: Option<Stated<String>>,
    /// Why the survey is a rehearsal on simulated instruments, not a
    /// calibration, when it is ([`survey_store::survey::Setup::rehearsal`]).
    pub rehearsal: Option<String>,
    /// The laboratory's postal address (`[certificate.laboratory_address]`).
    pub laboratory_address: Option<Address>,
    /// The customer's postal address (`[certificate.customer_address]`).
    pub customer_address: Option<Address>,
    /// The item's identifications (`[certificate.item]`).
    pub item: Option<Equipment>,
    /// The reference's identifications and calibration (`[certificate.reference_instrument]`).
    pub reference_instrument: Option<Equipment>,
    /// What the positioner and the reference said they are when the survey began.
    pub identified: Identified,
}

/// What the instruments said they are, read through their drivers.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Identified {
    pub positioner: Option<String>,
    pub reference: Option<String>,
}

/// What an identification the instrument gave is called on the certificate.
pub const IDENTIFIED_AS: &str = "as the instrument identified itself through its protocol";

/// An address on one line: street and number, post code and city, state, country.
pub fn address_line(a: &Address) -> String {
    let join = |parts: &[&Option<String>], sep: &str| {
        parts.iter().filter_map(|p| p.as_deref()).filter(|p| !p.is_empty()).collect::<Vec<_>>().join(sep)
    };
    let street = join(&[&a.street_no, &a.street], " ");
    let city = join(&[&a.post_code, &a.city], " ");
    [street, city, join(&[&a.state], ""), join(&[&a.country], "")]
        .into_iter()
        .filter(|p| !p.is_empty())
        .collect::<Vec<_>>()
        .join(", ")
}

/// An instrument's identifications as the DCC names them: (issuer, value, what it is).
pub fn identifications(e: &Equipment) -> Vec<(&'static str, &str, &'static str)> {
    let mut ids = Vec::new();
    if let Some(s) = &e.serial {
        ids.push(("manufacturer", s.as_str(), "serial number"));
    }
    if let Some(s) = &e.inventory {
        ids.push(("owner", s.as_str(), "inventory number"));
    }
    ids
}

/// An instrument's make, model and identifications on one line.
pub fn equipment_line(e: &Equipment) -> String {
    let mut parts: Vec<String> = Vec::new();
    for (what, v) in [("", &e.manufacturer), ("model ", &e.model)] {
        if let Some(v) = v {
            parts.push(format!("{what}{v}"));
        }
    }
    parts.extend(identifications(e).into_iter().map(|(_, v, name)| format!("{name} {v}")));
    parts.join(", ")
}

/// A reference's own calibration on one line, when one is stated.
pub fn calibration_line(e: &Equipment) -> Option<String> {
    let cert = e.certificate.as_ref()?;
    let mut line = format!("calibration certificate {cert}");
    if let Some(by) = &e.calibrated_by {
        line += &format!(" by {by}");
    }
    if let Some(on) = &e.calibrated {
        line += &format!(", calibrated {on}");
    }
    if let Some(due) = &e.due {
        line += &format!(", due {due}");
    }
    Some(line)
}

/// What a rehearsal's certificate says on every page, in its title and in its DCC.
pub const REHEARSAL: &str = "rehearsal on simulated instruments, not a calibration";

const FLAG: &str = "survey report flag";
const CONFIG: &str = "[certificate] of the configuration";
/// Where a value the bench says came from (its sentences are the software's, errors in degrees).
pub const BENCH: &str = "the bench";
const SURVEY: &str = "made from the survey's date and uid: no number was assigned";

fn pick<T: Clone>(flag: &Option<T>, config: Option<&T>, bench: Option<T>) -> Option<Stated<T>> {
    flag.clone()
        .map(|value| Stated { value, from: FLAG })
        .or_else(|| config.cloned().map(|value| Stated { value, from: CONFIG }))
        .or_else(|| bench.map(|value| Stated { value, from: BENCH }))
}

/// The simulated reference as the survey recorded it: the tracker's own
/// error (typical, ideal or the model file's) and its SMRs; the polygon's
/// certificate against its true faces, the autocollimator's scale error,
/// and whether the polygon was calibrated in place.
fn simulated_reference(s: &survey_store::survey::SimulatedSetup, model: Option<&Model>) -> String {
    match s.reference {
        ReferenceKind::Tracker => {
            let errors = match model.map(|m| &m.tracker_errors) {
                Some(TrackerErrorSpec::None) => "an ideal tracker: its random error only",
                Some(TrackerErrorSpec::Given(_)) => "the tracker's own error as the model file states it",
                _ => "an AT-class tracker's own error, systematic and random",
            };
            let radius = survey_sims::tracker::ArmGeometry::default().radius_mm;
            let smrs = match s.smrs.len() {
                0 | 1 => "an SMR".to_string(),
                n => format!("{n} SMRs"),
            };
            format!("simulated laser tracker ({errors}) on {smrs} on an arm of {radius:.0} mm")
        }
        ReferenceKind::Autocollimator => {
            let faces = s.plan.targets_deg.len();
            let stale = model.and_then(|m| m.polygon.as_ref()).and_then(|p| {
                let c = p.certificate_arcsec.as_ref()?;
                let off = c.iter().zip(&p.face_errors_arcsec).map(|(c, t)| (c - t).abs()).fold(0.0, f64::max);
                (off > 0.0).then_some(off)
            });
            let certificate = match stale {
                Some(off) => format!("a certificate off its true faces by up to {off:.2} arcsec"),
                None => "its faces as its certificate states".to_string(),
            };
            let scale = model.map_or(0.0, |m| m.autocollimator_scale_ppm);
            let scale = if scale != 0.0 { format!(", a scale error of {scale} ppm") } else { String::new() };
            let used = if s.polygon_turns.len() >= 2 {
                format!(
                    "; the polygon turned by {:?} faces between runs on an indexing stage and calibrated in place \
                     (closure), its certificate checked against what was measured",
                    s.polygon_turns
                )
            } else {
                "; the angles computed through its certificate".to_string()
            };
            format!("simulated autocollimator on a {faces}-face polygon with {certificate}{scale}{used}")
        }
    }
}

impl Certificate {
    /// The header of `survey`, with `flags` over what is stored (see the module documentation).
    pub fn of(survey: &SurveyRecord, flags: &CertificateFlags) -> Certificate {
        let stored: CertificateSection = match &survey.setup {
            Setup::Configured(c) => c.config.certificate.clone().unwrap_or_default(),
            _ => CertificateSection::default(),
        };
        // By driver and transport, never a local path (a serial adapter's carries its serial number).
        let described = |key: &str| survey.instruments.get(key).and_then(|v| v.as_str()).map(instrument_words);
        let (bench_positioner, bench_reference, bench_u) = match &survey.setup {
            Setup::Simulated(s) => {
                let preset = survey_sims::Preset::by_name(&s.preset);
                let positioner = match (&s.model_file, &preset) {
                    // By its name: the certificate shows no local path.
                    (Some(file), _) => {
                        format!("simulated positioner, model file {}", file.rsplit('/').next().unwrap_or(file))
                    }
                    (None, Some(p)) => format!("simulated {} positioner: {}", p.name, p.description),
                    (None, None) => format!("simulated {} positioner", s.preset),
                };
                let reference = simulated_reference(s, survey.model.as_ref());
                let u = survey_lab::refit::simulated_reference_u_deg(s.reference);
                (Some(positioner), Some(reference), Some(u))
            }
            _ => (described("positioner"), described("reference"), None),
        };
        let traceability = match &survey.setup {
            Setup::Simulated(_) => Some(
                "none: the reference is a simulated instrument, so these figures show the method and are not \
                 traceable to the SI"
                    .to_string(),
            ),
            _ => None,
        };
        let made = made_number(survey);
        let cert = Certificate {
            number: pick(&flags.number, stored.number.as_ref(), None).unwrap_or(Stated { value: made, from: SURVEY }),
            laboratory: pick(&flags.laboratory, stored.laboratory.as_ref(), None),
            traceability: pick(&flags.traceability, stored.traceability.as_ref(), traceability),
            tolerance_deg: pick(&flags.tolerance_deg, stored.tolerance_deg.as_ref(), None),
            positioner: pick(&flags.positioner, stored.positioner.as_ref(), bench_positioner),
            reference: pick(&flags.reference, stored.reference.as_ref(), bench_reference),
            reference_uncertainty_deg: pick(
                &flags.reference_uncertainty_deg,
                stored.reference_uncertainty_deg.as_ref(),
                bench_u,
            ),
            operator: pick(&flags.operator, stored.operator.as_ref(), None),
            customer: pick(&flags.customer, stored.customer.as_ref(), None),
            temperature_c: pick(&flags.temperature_c, stored.temperature_c.as_ref(), None),
            signatory: pick(&flags.signatory, stored.signatory.as_ref(), None),
            location: pick(&flags.location, stored.location.as_ref(), None),
            item_condition: pick(&flags.item_condition, stored.item_condition.as_ref(), None),
            received: pick(&flags.received, stored.received.as_ref(), None),
            country: pick(&flags.country, stored.country.as_ref(), None).or_else(|| {
                stored
                    .laboratory_address
                    .as_ref()
                    .and_then(|a| a.country.clone())
                    .map(|value| Stated { value, from: CONFIG })
            }),
            rehearsal: None,
            laboratory_address: stored.laboratory_address.clone(),
            customer_address: stored.customer_address.clone(),
            item: stored.item.clone(),
            reference_instrument: stored.reference_instrument.clone(),
            identified: Identified {
                positioner: survey.identified("positioner").map(str::to_string),
                reference: survey.identified("reference").map(str::to_string),
            },
        };
        match survey.rehearsal() {
            Some(why) => cert.rehearsal_of(why),
            None => cert,
        }
    }

    /// A rehearsal's certificate: no traceability claimed whatever was
    /// stated, and the instruments named as simulated stand-ins.
    pub(crate) fn rehearsal_of(mut self, why: String) -> Certificate {
        self.traceability = Some(Stated {
            value: format!(
                "none: a {REHEARSAL} ({why}); nothing on this certificate is traceable to the SI, whatever the \
                 configuration or a flag states"
            ),
            from: BENCH,
        });
        for field in [&mut self.positioner, &mut self.reference] {
            if let Some(s) = field.as_mut().filter(|s| s.from != BENCH) {
                s.value = format!("simulated, standing in for: {}", s.value);
            }
        }
        // A stand-in's calibration is not the rehearsal's: no certificate of the reference is claimed.
        if let Some(r) = self.reference_instrument.as_mut() {
            (r.certificate, r.calibrated_by, r.calibrated, r.due) = (None, None, None, None);
        }
        self.rehearsal = Some(why);
        self
    }

    /// A short name of the positioner for the title.
    pub fn positioner_name(&self, survey: &SurveyRecord) -> String {
        match &self.positioner {
            Some(p) if p.from != BENCH => p.value.clone(),
            _ => match &survey.setup {
                // A model file is the positioner, never the preset it borrows instruments from.
                Setup::Simulated(s) => match &s.model_file {
                    Some(f) => format!("simulated {} positioner", f.rsplit('/').next().unwrap_or(f)),
                    None => format!("simulated {} positioner", s.preset),
                },
                _ => described_or(survey, "positioner", "positioner"),
            },
        }
    }
}

fn described_or(survey: &SurveyRecord, key: &str, default: &str) -> String {
    survey.instruments.get(key).and_then(|v| v.as_str()).map(instrument_words).unwrap_or_else(|| default.to_string())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A survey of the example configuration (a real bench, not a
    /// rehearsal: its `[certificate]` states the reference's calibration).
    pub(crate) fn configured_survey() -> SurveyRecord {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/config/modbus-emscon.toml"))
                .unwrap();
        let config = survey_store::config::SurveyConfig::parse(&text, "modbus-emscon.toml").unwrap();
        let setup = survey_store::survey::ConfiguredSetup {
            config,
            plan: survey_plan::SurveyPlan::full_circle(360, 5, true).unwrap(),
        };
        let instruments = r#"{"positioner": "modbus-tcp 192.168.1.40:502", "reference": "emscon 192.168.1.30:700"}"#;
        let columns = survey_store::survey::StoredColumns::configured(4, &setup, instruments);
        SurveyRecord::parse(columns, "x.db").unwrap()
    }

    #[test]
    fn a_configured_survey_states_its_certificate_section_and_flags_override_it() {
        let survey = configured_survey();
        let cert = Certificate::of(&survey, &CertificateFlags::default());
        let positioner = cert.positioner.as_ref().unwrap();
        assert_eq!(
            (positioner.value.as_str(), positioner.from),
            ("ACME AZ-200 azimuth positioner, serial 1042", CONFIG)
        );
        assert_eq!(cert.reference_uncertainty_deg.as_ref().map(|u| u.value), Some(0.0005));
        assert_eq!(cert.temperature_c.as_ref().map(|t| t.value), Some(20.3));
        assert_eq!(cert.laboratory.as_ref().map(|l| l.from), Some(CONFIG));
        assert!(cert.traceability.as_ref().is_some_and(|t| t.value.contains("certificate 5678")));
        // The structured address and identifications, as the page and the DCC state them.
        assert_eq!(address_line(cert.laboratory_address.as_ref().unwrap()), "1 Bay Road, 38116 Braunschweig, DE");
        let reference = cert.reference_instrument.as_ref().unwrap();
        assert_eq!(equipment_line(reference), "Leica Geosystems, model AT960, serial number 7788");
        assert_eq!(
            calibration_line(reference).as_deref(),
            Some(
                "calibration certificate 5678 by the national metrology institute, calibrated 2026-01-15, due 2027-01-15"
            )
        );
        assert_eq!(identifications(cert.item.as_ref().unwrap()), [("manufacturer", "1042", "serial number")]);
        // A rehearsal claims no calibration of its stand-in reference.
        let rehearsal = cert.clone().rehearsal_of("a test".into());
        assert_eq!(calibration_line(rehearsal.reference_instrument.as_ref().unwrap()), None);
        // No number assigned: made from the survey (its uid; `created_at` here has no date).
        assert_eq!((cert.number.value.as_str(), cert.number.from), ("000000000000", SURVEY));
        let numbered = CertificateFlags { number: Some("CAL-1".into()), ..CertificateFlags::default() };
        assert_eq!(Certificate::of(&survey, &numbered).number, Stated { value: "CAL-1".into(), from: FLAG });
        let flags = CertificateFlags {
            operator: Some("K. Lee".into()),
            signatory: Some("A. Smith, head of laboratory".into()),
            received: Some("2026-11-30".into()),
            ..CertificateFlags::default()
        };
        let cert = Certificate::of(&survey, &flags);
        assert_eq!(cert.operator.as_ref().unwrap().value, "K. Lee");
        assert_eq!(
            cert.signatory.as_ref().map(|s| (s.value.as_str(), s.from)),
            Some(("A. Smith, head of laboratory", FLAG))
        );
        assert_eq!(cert.received.as_ref().unwrap().value, "2026-11-30");
        assert_eq!(cert.location.as_ref().map(|l| l.from), Some(CONFIG), "the example states its location");
        assert_eq!(cert.country.as_ref().map(|c| c.value.as_str()), Some("DE"));
        assert_eq!(cert.positioner_name(&survey), "ACME AZ-200 azimuth positioner, serial 1042");
        // Without a [certificate]: the configured instruments, as described.
        let mut bare = survey.clone();
        if let Setup::Configured(c) = &mut bare.setup {
            c.config.certificate = None;
        }
        let cert = Certificate::of(&bare, &CertificateFlags::default());
        assert_eq!(cert.reference.unwrap().value, "emscon 192.168.1.30:700");
        assert_eq!(cert.reference_uncertainty_deg, None);
        // A serial instrument by its driver and transport, not its device path.
        bare.instruments["positioner"] = "modbus-rtu /dev/serial/by-id/usb-FTDI_A12345-if00 slave 1".into();
        let cert = Certificate::of(&bare, &CertificateFlags::default());
        assert_eq!(cert.positioner.as_ref().unwrap().value, "modbus-rtu (serial port) slave 1");
        assert_eq!(cert.positioner_name(&bare), "modbus-rtu (serial port) slave 1");
    }

    /// The simulated reference is said as the survey recorded it (issue 48):
    /// the tracker's own error (typical, ideal) and its SMRs; the polygon's
    /// certificate against its true faces, the autocollimator's scale error,
    /// and whether the polygon was calibrated in place.
    #[test]
    fn the_simulated_reference_is_said_as_the_survey_recorded_it() {
        let setup = |reference, polygon_turns: Vec<u32>, smrs: usize| survey_store::survey::SimulatedSetup {
            preset: "fig8".into(),
            model_file: None,
            reference,
            seed: 1,
            plan: survey_plan::SurveyPlan::full_circle(24, 4, true).unwrap(),
            timing: Default::default(),
            run_period_s: 60.0,
            faults: None,
            smrs: vec![survey_processing::smrs::SmrMount::FIRST; smrs],
            polygon_turns,
            machine_frame: None,
            asset: None,
        };
        let typical = survey_sims::Preset::by_name("fig8").unwrap().model;
        let said = simulated_reference(&setup(ReferenceKind::Tracker, vec![], 1), Some(&typical));
        assert!(
            said.contains("an AT-class tracker's own error") && said.contains("on an SMR on an arm of 1000 mm"),
            "{said}"
        );
        let ideal = Model { tracker_errors: TrackerErrorSpec::None, ..typical.clone() };
        let said = simulated_reference(&setup(ReferenceKind::Tracker, vec![], 3), Some(&ideal));
        assert!(said.contains("an ideal tracker: its random error only") && said.contains("on 3 SMRs"), "{said}");
        let said = simulated_reference(&setup(ReferenceKind::Autocollimator, vec![], 0), Some(&typical));
        assert!(said.contains("24-face polygon with its faces as its certificate states"), "{said}");
        assert!(said.contains("computed through its certificate") && !said.contains("scale"), "{said}");
        let truth = vec![0.0; 24];
        let mut certificate = truth.clone();
        certificate[5] = 1.5;
        let stale = Model {
            polygon: Some(survey_processing::model::PolygonTruth {
                face_errors_arcsec: truth,
                certificate_arcsec: Some(certificate),
            }),
            autocollimator_scale_ppm: 500.0,
            ..typical
        };
        let said = simulated_reference(&setup(ReferenceKind::Autocollimator, vec![0, 1], 0), Some(&stale));
        assert!(said.contains("a certificate off its true faces by up to 1.50 arcsec"), "{said}");
        assert!(said.contains("a scale error of 500 ppm") && said.contains("calibrated in place (closure)"), "{said}");
    }

    #[test]
    fn a_made_number_is_the_date_and_twelve_digits_of_the_uid() {
        let uid = "0B6C1A2E-4F3D-4a1b-8c9d-0123456789ab";
        assert_eq!(number_from("2026-12-06T13:49:26Z", uid), "20261206-0b6c1a2e4f3d");
        assert_eq!(number_from("t", uid), "0b6c1a2e4f3d");
    }

    #[test]
    fn a_flag_wins_over_the_configuration_which_wins_over_the_bench() {
        let flag = Some("A".to_string());
        assert_eq!(pick(&flag, Some(&"B".to_string()), Some("C".into())).unwrap().from, FLAG);
        assert_eq!(pick(&None, Some(&"B".to_string()), Some("C".into())).unwrap().value, "B");
        assert_eq!(pick(&None, None, Some("C".to_string())).unwrap().from, BENCH);
        assert_eq!(pick::<String>(&None, None, None), None);
    }
}
