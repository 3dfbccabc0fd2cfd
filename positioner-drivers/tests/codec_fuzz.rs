//! The bounded fuzz run on stable (in CI): every wire codec's fuzz target
//! (`survey_positioner_drivers::fuzz_targets` and `survey_drivers::fuzz_targets`, the same functions the cargo-fuzz
//! harnesses in `fuzz/` run on nightly) on
//!
//! - the seeds: valid messages of each codec, encoded by our encoders;
//! - every file committed under `fuzz/seeds/<target>/` and
//!   `fuzz/regressions/<target>/` (the inputs that once crashed a target);
//! - 20,000 proptest cases per codec: random bytes, and seeds with bytes
//!   flipped, inserted, removed and spliced.
//!
//! `SURVEY_WRITE_FUZZ_SEEDS=DIR` also writes the seeds to `DIR/<target>/`,
//! the starting corpus of a cargo-fuzz run.

use proptest::prelude::*;
use std::path::Path;
use survey_drivers::elcomat;
use survey_drivers::emscon::packets::{Reply as EmsconReply, Request as EmsconRequest};
use survey_drivers::fuzz_targets as reference_targets;
use survey_positioner_drivers::canopen::frame::CanFrame;
use survey_positioner_drivers::canopen::{nmt, sdo, slcan};
use survey_positioner_drivers::fuzz_targets as targets;
use survey_positioner_drivers::modbus::RegisterMap;
use survey_positioner_drivers::scpi::{Address, Command};

type Target = fn(&[u8]);

const TARGETS: [(&str, Target); 6] = [
    ("modbus_map", targets::modbus_map),
    ("canopen", targets::canopen),
    ("slcan", targets::slcan),
    ("scpi", targets::scpi),
    ("emscon", reference_targets::emscon),
    ("elcomat", reference_targets::elcomat),
];

/// Valid inputs of a target, from our encoders.
fn seeds(target: &str) -> Vec<Vec<u8>> {
    match target {
        "modbus_map" => {
            let map = RegisterMap::default();
            let mut v = vec![0u8];
            v.extend(100_000f64.to_le_bytes());
            v.extend([0, 1, 2, 3, 4, 5]);
            for deg in [0.0, 12.5, -359.99, 1234.56789] {
                let w = map.encode_position(deg).unwrap();
                v.extend(w[0].to_be_bytes());
                v.extend(w[1].to_be_bytes());
            }
            let mut f = v.clone();
            f[0] = 3;
            vec![v, f]
        }
        "canopen" => {
            let mut out = Vec::new();
            for r in [
                sdo::SdoRequest::InitiateUpload { index: 0x6064, subindex: 0 },
                sdo::SdoRequest::UploadSegment { toggle: true },
                sdo::SdoRequest::Abort { index: 0x6040, subindex: 0, code: 0x0800_0022 },
            ] {
                out.push(r.encode().to_vec());
            }
            for r in [
                sdo::SdoResponse::InitiateDownload { index: 0x607a, subindex: 0 },
                sdo::SdoResponse::UploadSegment { toggle: false, data: vec![1, 2, 3], last: true },
            ] {
                out.push(r.encode().to_vec());
            }
            let f: CanFrame = nmt::encode_command(nmt::NmtCommand::from_specifier(1).unwrap(), 5);
            let mut b = f.id().to_le_bytes().to_vec();
            b.extend(f.data());
            out.push(b);
            out.push(vec![0x37, 0x06, 0x00, 0x00, 0x23, 0x7a, 0x60, 0x00, 0x10, 0x27, 0, 0]);
            out
        }
        "slcan" => vec![
            b"S6\rO\rt60580123456789ABCDEF0\rt5858400000000\r".to_vec(),
            b"V1011\rN1A2B\rF00\rz\r\x07C\r".to_vec(),
            slcan::Message::Frame(CanFrame::new(0x705, &[5]).unwrap()).encode(),
        ],
        "scpi" => {
            let a = Address::default();
            let mut v = Vec::new();
            for c in [
                Command::SetTarget(12.345),
                Command::Start,
                Command::PositionQuery,
                Command::StatusQuery,
                Command::ErrorQueryAll,
                Command::UnitsQuery,
                Command::Identify,
            ] {
                v.extend(c.encode(a));
            }
            vec![v, b"12.345\n0, \"No error\"\n-222,\"Data out of range\";0,\"No error\"\n128\n6\nON\n".to_vec()]
        }
        "emscon" => {
            let mut v = Vec::new();
            for r in [
                EmsconRequest::Initialize,
                EmsconRequest::StartMeasurement,
                EmsconRequest::GoLastMeasuredPoint,
                EmsconRequest::FindReflector { approx_distance: 2500.0 },
                EmsconRequest::GoPosition { position: [2500.0, 800.0, -300.0], use_adm: false },
                EmsconRequest::SetStatisticMode { stationary: 0, continuous: 0 },
            ] {
                v.extend(r.encode());
            }
            let mut replies = Vec::new();
            for r in
                [EmsconReply::answer(1, 0), EmsconReply::StatusChange(3), EmsconReply::Error { command: 5, status: 36 }]
            {
                replies.extend(r.encode());
            }
            vec![v, replies]
        }
        "elcomat" => vec![
            b"a\r4 003 12.34 -5.67\r\n2 103 0.10 0.20\r4 000\r".to_vec(),
            elcomat::encode_reply(&elcomat::Reply::absolute(-1.5, 2.25)),
            b"r\ra\r".to_vec(),
        ],
        other => panic!("no target {other}"),
    }
}

/// The committed inputs of a target (seeds and crash regressions).
fn committed(target: &str) -> Vec<(String, Vec<u8>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut out = Vec::new();
    for dir in ["seeds", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join(target)) else { continue };
        for e in entries.flatten() {
            out.push((e.path().display().to_string(), std::fs::read(e.path()).unwrap()));
        }
    }
    out
}

#[test]
fn every_seed_and_committed_input_passes_every_target() {
    let write = std::env::var_os("SURVEY_WRITE_FUZZ_SEEDS");
    for (name, target) in TARGETS {
        let seeds = seeds(name);
        for (k, s) in seeds.iter().enumerate() {
            target(s);
            if let Some(dir) = &write {
                let d = Path::new(dir).join(name);
                std::fs::create_dir_all(&d).unwrap();
                std::fs::write(d.join(format!("seed-{k}")), s).unwrap();
            }
        }
        for (path, bytes) in committed(name) {
            eprintln!("replaying {path}");
            target(&bytes);
        }
    }
}

/// A seed of any target, mutated: bytes flipped, inserted, removed, spliced.
fn mutated() -> impl Strategy<Value = (usize, Vec<u8>)> {
    (0..TARGETS.len(), any::<usize>(), prop::collection::vec((any::<u8>(), any::<usize>(), any::<u8>()), 0..12))
        .prop_map(|(t, pick, edits)| {
            let all = seeds(TARGETS[t].0);
            let mut v = all[pick % all.len()].clone();
            for (op, at, byte) in edits {
                let i = if v.is_empty() { 0 } else { at % v.len() };
                match op % 4 {
                    0 if !v.is_empty() => v[i] ^= byte | 1,
                    1 => v.insert(i, byte),
                    2 if !v.is_empty() => {
                        v.remove(i);
                    }
                    _ => {
                        let tail = v[i..].to_vec();
                        v.extend(tail.into_iter().take(usize::from(byte)));
                    }
                }
            }
            (t, v)
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_pass_every_target(data in prop::collection::vec(any::<u8>(), 0..512)) {
        for (_, target) in TARGETS {
            target(&data);
        }
    }

    #[test]
    fn mutated_seeds_pass_their_target((t, data) in mutated()) {
        (TARGETS[t].1)(&data);
    }
}
