//! The history cache's version (`survey_lab::life::cache::VERSION`): the
//! package version and a fingerprint of everything that decides what a
//! survey's summary and a pair's comparison hold. A change to any of these
//! files (the processing, the comparisons, the acquisition's arithmetic the
//! drift correction uses, how the store reads samples, how the lab loads,
//! refits and measures a survey and encodes what it keeps) or to a locked
//! dependency (libm, the FFTs) gives a new version: entries of the old one
//! are never read again, and are made anew. It is conservative (an edit of
//! a comment makes one too): a cache made again costs a measurement, a
//! stale one would be a wrong history.

use std::path::{Path, PathBuf};

/// What the cached entries are computed by, from this crate's folder.
const INPUTS: &[&str] = &[
    "../processing/src",
    "../modelgap/src",
    "../motions/src",
    "../plan/src",
    "../store/src/samples.rs",
    "../store/src/pack.rs",
    "../store/src/drift.rs",
    "../store/src/check_points.rs",
    "src/load.rs",
    "src/refit.rs",
    "src/drift.rs",
    "src/life",
    "../Cargo.lock",
];

fn files(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        let mut entries: Vec<PathBuf> =
            std::fs::read_dir(path).expect("a source folder").map(|e| e.expect("an entry").path()).collect();
        entries.sort();
        for e in entries {
            files(&e, out);
        }
    } else if path.is_file() {
        out.push(path.to_path_buf());
    }
}

/// FNV-1a, 64 bits: stable across toolchains (std's hasher is not promised to be).
fn fnv(hash: &mut u64, bytes: &[u8]) {
    for &b in bytes {
        *hash ^= u64::from(b);
        *hash = hash.wrapping_mul(0x0000_0100_0000_01b3);
    }
}

fn main() {
    let mut all = Vec::new();
    for input in INPUTS {
        println!("cargo::rerun-if-changed={input}");
        files(Path::new(input), &mut all);
    }
    let mut hash = 0xcbf2_9ce4_8422_2325;
    for f in &all {
        fnv(&mut hash, f.to_string_lossy().as_bytes());
        fnv(&mut hash, &[0]);
        fnv(&mut hash, &std::fs::read(f).expect("a readable source file"));
        fnv(&mut hash, &[0]);
    }
    println!("cargo::rustc-env=SURVEY_HISTORY_FINGERPRINT={hash:016x}");
}
