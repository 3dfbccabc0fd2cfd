//! Pure processing for rotary-positioner surveys.
//!
//! Functions from data to data: no I/O, no clock, no async runtime, no database.
//! The simulators (`survey-sims`) and the orchestrator both build on it, so the
//! error model that generates simulated data is the same code that explains
//! measured data.

pub mod analysis;
pub mod coverage;
pub mod errormap;
pub mod frame;
pub mod geometry;
pub mod iso230;
pub mod lstsq;
pub mod model;
pub mod num;
pub mod resample;
pub mod smrs;
pub mod special;
pub mod spectrum;
pub mod table;
pub mod tracker_errors;
pub mod types;
pub mod units;
pub mod vdi3441;

pub use types::{Direction, Sample};

#[cfg(test)]
mod purity {
    //! The crate's promise, and `survey-plan`'s and `survey-modelgap`'s: data
    //! in, data out. Their non-test code names no file system, environment,
    //! network, clock, async runtime or database.

    use std::path::{Path, PathBuf};

    fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("a source folder") {
            let path = entry.expect("an entry").path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
            if path.is_dir() {
                if name != "tests" {
                    sources(&path, out);
                }
            } else if name.ends_with(".rs")
                && !name.starts_with("tests")
                && !name.ends_with("tests.rs")
                && name != "testutil.rs"
            {
                out.push(path);
            }
        }
    }

    /// `text` without its `#[cfg(test)] mod name { ... }` blocks.
    fn without_test_modules(text: &str) -> String {
        let mut out = String::new();
        let mut rest = text;
        while let Some(at) = rest.find("#[cfg(test)]") {
            out.push_str(&rest[..at]);
            let after = &rest[at..];
            let Some(open) = after.find('{').filter(|&o| after[..o].contains("mod ")) else {
                // `#[cfg(test)] mod name;`: a test file of its own, skipped above.
                rest = &after["#[cfg(test)]".len()..];
                continue;
            };
            let mut depth = 0usize;
            let mut end = after.len();
            for (i, c) in after[open..].char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            end = open + i + 1;
                            break;
                        }
                    }
                    _ => {}
                }
            }
            rest = &after[end..];
        }
        out.push_str(rest);
        out
    }

    /// This crate's and the pure crates built on it (the acquisition's
    /// arithmetic, the comparisons): data in, data out.
    #[test]
    fn non_test_code_does_no_io() {
        let mut files = Vec::new();
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        for src in [
            here.join("src"),
            here.join("../controllers/src"),
            here.join("../tables/src"),
            here.join("../plan/src"),
            here.join("../modelgap/src"),
            here.join("../motions/src"),
        ] {
            let before = files.len();
            sources(&src, &mut files);
            assert!(files.len() > before + 3, "the source tree {} was found", src.display());
        }
        assert!(files.len() > 40, "the source trees were found");
        let forbidden =
            ["std::fs", "std::path", "std::env", "std::net", "std::process", "SystemTime", "Instant", "tokio", "sqlx"];
        let mut offenders = Vec::new();
        for f in &files {
            let code = without_test_modules(&std::fs::read_to_string(f).expect("readable"));
            for word in forbidden {
                if code.contains(word) {
                    offenders.push(format!("{}: {word}", f.display()));
                }
            }
        }
        assert!(offenders.is_empty(), "processing's non-test code does I/O: {offenders:?}");
    }
}
