//! The survey orchestrator: the engine that acquires a survey from the
//! instrument drivers, the SQLite store it writes to, and the `survey` CLI.
//!
//! Layers, from the roof down (a module only uses those below it):
//! `cli` (the command line) -> `conclude`, `verify`, `session`, `process`,
//! `report` (what the commands do) -> `bench` (the simulated or configured
//! instruments, set up) -> `store` (SQLite) and `survey` (typed survey
//! records) -> `config`, `csvio`, `output`, `error` -> `acquire` (the
//! acquisition core, used through its one door: the engine, its settings,
//! the sink it writes into) and `stop` -> the `survey-processing` (plans,
//! bounds, pairing, drift: the pure steps), `survey-drivers` and
//! `survey-sims` crates. No files of a crate import each other in a circle
//! (a test, `import_circles_tests`, checks every crate).

pub mod acquire;
pub mod bench;
pub mod cli;
pub mod conclude;
pub mod config;
pub mod csvio;
pub mod drift;
pub mod error;
pub mod inputs;
pub mod life;
pub mod load;
pub mod output;
pub mod process;
pub mod progress;
pub mod refit;
pub mod report;
pub mod resolving;
pub mod runtime;
pub mod session;
pub mod sim;
pub mod stop;
pub mod store;
pub mod survey;
pub mod verify;

#[cfg(test)]
mod fuzz_tests;

#[cfg(test)]
mod import_circles_tests;

#[cfg(test)]
mod architecture {
    //! ARCHITECTURE.md's claims that a test can check: the CLI is the roof,
    //! every store write goes through `WriteTx`, and every path in the code
    //! map exists.

    use std::path::{Path, PathBuf};

    fn root() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("the workspace root").to_path_buf()
    }

    fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("a source folder") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                rust_files(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }

    #[test]
    fn nothing_below_the_cli_imports_it() {
        let src = root().join("orchestrator/src");
        let mut files = Vec::new();
        rust_files(&src, &mut files);
        let offenders: Vec<_> = files
            .iter()
            // lib.rs only declares the modules (and holds this test's own strings).
            .filter(|f| !f.starts_with(src.join("cli")) && **f != src.join("lib.rs"))
            .filter(|f| std::fs::read_to_string(f).expect("readable").contains("crate::cli"))
            .collect();
        assert!(files.len() > 20, "the source tree was found");
        assert!(offenders.is_empty(), "modules below the CLI import it: {offenders:?}");
    }

    #[test]
    fn every_store_write_goes_through_write_tx() {
        // A write outside `store::tx::WriteTx` runs on a pooled connection
        // with no explicit rollback: a statement executed on the pool itself,
        // a connection taken from it, or sqlx's own transaction.
        let store = root().join("orchestrator/src/store");
        let mut files = Vec::new();
        rust_files(&store, &mut files);
        let mut checked = 0;
        for f in files.iter().filter(|f| !f.ends_with("tx.rs") && !f.ends_with("tests.rs")) {
            let text = std::fs::read_to_string(f).expect("readable");
            // The code before its unit tests (their fixtures build databases by hand).
            let code = text.split("#[cfg(test)]").next().unwrap_or_default();
            for bad in [
                ".execute(&self.pool",
                ".execute(self.sqlite()",
                "pool.acquire()",
                ".begin()",
                "execute(&mut *self.pool",
            ] {
                assert!(!code.contains(bad), "{} writes outside WriteTx (`{bad}`)", f.display());
            }
            checked += code.matches("WriteTx::begin").count();
        }
        assert!(checked >= 10, "only {checked} write transactions found: the store moved?");
    }

    #[test]
    fn every_path_in_the_code_map_exists() {
        let text = std::fs::read_to_string(root().join("ARCHITECTURE.md")).expect("ARCHITECTURE.md");
        let mut checked = 0;
        for quoted in text.split('`').skip(1).step_by(2) {
            let looks_like_a_path =
                ["processing/", "drivers/", "sims/", "orchestrator/", "src/", "tests/", "migrations/"]
                    .iter()
                    .any(|p| quoted.starts_with(p))
                    || [".ci/run", ".cargo/config.toml", "Cargo.toml", "scripts/", "examples/config/"]
                        .contains(&quoted);
            if looks_like_a_path && !quoted.contains('<') && !quoted.contains(' ') {
                assert!(root().join(quoted).exists(), "ARCHITECTURE.md names `{quoted}`, which does not exist");
                checked += 1;
            }
        }
        assert!(checked > 15, "only {checked} paths were found in the code map");
    }
}
