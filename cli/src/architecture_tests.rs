//! ARCHITECTURE.md's claims that a test can check: every crate uses only
//! the floors below it (the one-way graph of crates), every store write goes
//! through `WriteTx`, every path in the code map exists, and no crate
//! outgrows a room (12,000 lines of Rust, its tests included).

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

/// Each crate and the crates of this workspace it may use: ARCHITECTURE.md's
/// one-way graph, from the bottom up. Cargo refuses a circle between crates;
/// this keeps the floors (a crate may use only what sits below it here).
const MAY_USE: &[(&str, &[&str])] = &[
    ("processing", &[]),
    ("controllers", &["survey-processing"]),
    ("tables", &["survey-processing", "survey-controllers"]),
    ("plan", &["survey-processing"]),
    ("modelgap", &["survey-processing"]),
    ("motions", &["survey-processing"]),
    ("drivers", &["survey-processing"]),
    ("positioner-drivers", &["survey-processing", "survey-drivers"]),
    ("sims", &["survey-processing", "survey-drivers"]),
    ("sim-servers", &["survey-processing", "survey-drivers", "survey-positioner-drivers", "survey-sims"]),
    ("acquire", &["survey-processing", "survey-plan", "survey-drivers", "survey-sims"]),
    ("config", &["survey-processing", "survey-plan", "survey-drivers", "survey-positioner-drivers", "survey-acquire"]),
    (
        "store",
        &[
            "survey-processing",
            "survey-plan",
            "survey-drivers",
            "survey-positioner-drivers",
            "survey-sims",
            "survey-acquire",
            "survey-config",
        ],
    ),
    (
        "bench",
        &[
            "survey-processing",
            "survey-tables",
            "survey-plan",
            "survey-drivers",
            "survey-positioner-drivers",
            "survey-sims",
            "survey-sim-servers",
            "survey-acquire",
            "survey-store",
        ],
    ),
    (
        "lab",
        &[
            "survey-processing",
            "survey-controllers",
            "survey-tables",
            "survey-plan",
            "survey-modelgap",
            "survey-motions",
            "survey-drivers",
            "survey-sims",
            "survey-acquire",
            "survey-store",
            "survey-bench",
        ],
    ),
    (
        "report",
        &[
            "survey-processing",
            "survey-tables",
            "survey-plan",
            "survey-modelgap",
            "survey-motions",
            "survey-sims",
            "survey-acquire",
            "survey-store",
            "survey-bench",
            "survey-lab",
        ],
    ),
    ("serve", &["survey-processing", "survey-store", "survey-lab", "survey-report"]),
];

/// The workspace's own crates that `manifest`'s `[dependencies]` name.
fn own_dependencies(manifest: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in manifest.lines().map(str::trim) {
        if line.starts_with('[') {
            inside = line == "[dependencies]";
        } else if inside && line.starts_with("survey-") {
            out.push(line.split(['.', ' ', '=']).next().unwrap_or_default().to_string());
        }
    }
    out
}

#[test]
fn every_crate_uses_only_the_floors_below_it() {
    for (dir, allowed) in MAY_USE {
        let manifest = std::fs::read_to_string(root().join(dir).join("Cargo.toml")).expect("a crate's manifest");
        for dep in own_dependencies(&manifest) {
            assert!(allowed.contains(&dep.as_str()), "{dir}/Cargo.toml uses {dep}, above it or beside it");
        }
    }
    // The roof: the command line uses the floors; nothing uses it but the binary.
    let members = std::fs::read_to_string(root().join("Cargo.toml")).expect("the workspace manifest");
    for (dir, _) in MAY_USE {
        assert!(members.contains(&format!("\"{dir}\"")), "{dir} is a member of the workspace");
        let manifest = std::fs::read_to_string(root().join(dir).join("Cargo.toml")).expect("a crate's manifest");
        assert!(!own_dependencies(&manifest).contains(&"survey-cli".to_string()), "{dir} uses the command line");
    }
    assert_eq!(own_dependencies(&members), ["survey-cli"], "the binary is a shell over the command line");
}

/// The most lines of Rust a crate may hold (sources, tests and benches):
/// past it, a crate holds more than one concern (issue 47).
const MOST_LINES: usize = 12_000;

#[test]
fn no_crate_is_over_twelve_thousand_lines() {
    let mut sizes = Vec::new();
    for (dir, _) in MAY_USE.iter().chain(&[("cli", &[][..])]) {
        let mut files = Vec::new();
        rust_files(&root().join(dir), &mut files);
        let lines: usize = files.iter().map(|f| std::fs::read_to_string(f).expect("readable").lines().count()).sum();
        sizes.push((*dir, lines));
    }
    let over: Vec<_> = sizes.iter().filter(|(_, n)| *n > MOST_LINES).collect();
    assert!(over.is_empty(), "crates over {MOST_LINES} lines: {over:?}");
    assert!(sizes.iter().any(|(d, n)| *d == "processing" && *n > 1000), "the crates were not found: {sizes:?}");
}

#[test]
fn every_store_write_goes_through_write_tx() {
    // A write outside `store::tx::WriteTx` runs on a pooled connection
    // with no explicit rollback: a statement executed on the pool itself,
    // a connection taken from it, or sqlx's own transaction.
    let store = root().join("store/src");
    let mut files = Vec::new();
    rust_files(&store, &mut files);
    let mut checked = 0;
    for f in files.iter().filter(|f| !f.ends_with("tx.rs") && !f.ends_with("tests.rs")) {
        let text = std::fs::read_to_string(f).expect("readable");
        // The code before its unit tests (their fixtures build databases by hand).
        let code = text.split("#[cfg(test)]").next().unwrap_or_default();
        for bad in
            [".execute(&self.pool", ".execute(self.sqlite()", "pool.acquire()", ".begin()", "execute(&mut *self.pool"]
        {
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
        let looks_like_a_path = [
            "processing/",
            "controllers/",
            "tables/",
            "plan/",
            "modelgap/",
            "drivers/",
            "sims/",
            "acquire/",
            "store/",
            "bench/",
            "lab/",
            "report/",
            "serve/",
            "cli/",
            "src/",
            "tests/",
            "migrations/",
        ]
        .iter()
        .any(|p| quoted.starts_with(p))
            || [".ci/run", ".cargo/config.toml", "Cargo.toml", "scripts/", "examples/config/"].contains(&quoted);
        if looks_like_a_path && !quoted.contains('<') && !quoted.contains(' ') {
            assert!(root().join(quoted).exists(), "ARCHITECTURE.md names `{quoted}`, which does not exist");
            checked += 1;
        }
    }
    assert!(checked > 15, "only {checked} paths were found in the code map");
}
