//! The README and the pages under `docs/` stay true: every relative link
//! points at a file that exists (and at a heading of it, for a `#` link),
//! every `survey` command and flag they show exists, the README is a guide of
//! at most 400 lines, and it shows the test command CI runs.

use super::BIN;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// README.md and every Markdown file under docs/, with their text.
fn pages() -> Vec<(PathBuf, String)> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).expect("docs/ exists") {
            let path = entry.expect("an entry").path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "md") {
                out.push(path);
            }
        }
    }
    let mut paths = vec![root().join("README.md")];
    walk(&root().join("docs"), &mut paths);
    paths.sort();
    paths.into_iter().map(|p| (p.clone(), std::fs::read_to_string(&p).expect("readable"))).collect()
}

/// A Markdown text split into prose and code: the fenced blocks' lines and
/// the inline code spans (of a paragraph, so a span may run over a line
/// break) are code, everything else prose.
struct Parts {
    prose: Vec<String>,
    code: Vec<String>,
}

fn parts(text: &str) -> Parts {
    let mut prose = Vec::new();
    let mut code = Vec::new();
    let mut paragraph = String::new();
    fn flush(paragraph: &mut String, prose: &mut Vec<String>, code: &mut Vec<String>) {
        let mut outside = String::new();
        for (i, piece) in paragraph.split('`').enumerate() {
            if i % 2 == 1 {
                code.push(piece.replace('\n', " "));
                outside.push(' ');
            } else {
                outside.push_str(piece);
            }
        }
        prose.push(outside.replace('\n', " "));
        paragraph.clear();
    }
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            flush(&mut paragraph, &mut prose, &mut code);
            fenced = !fenced;
        } else if fenced {
            code.push(line.to_string());
        } else if line.trim().is_empty() {
            flush(&mut paragraph, &mut prose, &mut code);
        } else {
            paragraph.push_str(line);
            paragraph.push('\n');
        }
    }
    flush(&mut paragraph, &mut prose, &mut code);
    Parts { prose, code }
}

/// The link targets of `[text](target)` in prose lines.
fn links(prose: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    for line in prose {
        let mut rest = line.as_str();
        while let Some(at) = rest.find("](") {
            let after = &rest[at + 2..];
            let end = after.find(')').unwrap_or(after.len());
            out.push(after[..end].trim().to_string());
            rest = &after[end..];
        }
    }
    out
}

/// GitHub's anchor of a heading: lower case, punctuation dropped, spaces as
/// hyphens.
fn slug(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// Every anchor of a page's headings (outside fenced blocks), duplicates
/// numbered as GitHub numbers them.
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    let mut out = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        let Some(heading) = line.strip_prefix('#').filter(|_| !fenced) else { continue };
        let base = slug(heading.trim_start_matches('#'));
        let n = seen.entry(base.clone()).or_default();
        out.insert(if *n == 0 { base.clone() } else { format!("{base}-{n}") });
        *n += 1;
    }
    out
}

#[test]
fn every_relative_link_points_at_a_file_and_heading_that_exist() {
    let pages = pages();
    assert!(pages.len() > 10, "the docs/ pages were found");
    let mut checked = 0;
    let mut broken = Vec::new();
    for (page, text) in &pages {
        let dir = page.parent().unwrap();
        for target in links(&parts(text).prose) {
            if target.contains("://") || target.starts_with("mailto:") {
                continue;
            }
            let (file, anchor) = target.split_once('#').unwrap_or((&target, ""));
            let path = if file.is_empty() { page.clone() } else { dir.join(file) };
            let name = page.strip_prefix(root()).unwrap().display();
            if !path.exists() {
                broken.push(format!("{name}: ({target}): no such file"));
            } else if !anchor.is_empty() {
                let linked = std::fs::read_to_string(&path).unwrap_or_default();
                if !anchors(&linked).contains(anchor) {
                    broken.push(format!("{name}: ({target}): no such heading"));
                }
            }
            checked += 1;
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
    assert!(checked > 100, "only {checked} links were found");
}

#[test]
fn the_link_reader_sees_what_github_sees() {
    let text = "# Top\n\nSee [a](a.md#the-tables-uncertainty) and `[not](code.md)`.\n\
                ```\n[fenced](no.md)\n## Not a heading\n```\n## The table's uncertainty\n## `survey run`\n## Top\n";
    assert_eq!(links(&parts(text).prose), ["a.md#the-tables-uncertainty"]);
    let want: BTreeSet<String> =
        ["top", "the-tables-uncertainty", "survey-run", "top-1"].iter().map(|s| s.to_string()).collect();
    assert_eq!(anchors(text), want);
}

#[test]
fn the_readme_is_a_guide_of_at_most_400_lines_with_cis_test_command() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines <= 400, "README.md has {lines} lines: move reference material to docs/");
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    let command = ci.lines().rev().find(|l| l.starts_with("cargo nextest run")).expect(".ci/run runs cargo nextest");
    assert!(
        readme.contains(&format!("```sh\n{command}\n```")),
        "README.md does not show the test command .ci/run runs: {command}"
    );
    assert!(readme.contains("```sh\ncargo run --release -- run --points 1800 --bidirectional\n```"));
}

/// Each `survey` command line shown in code (a fenced block's line, with
/// the lines indented below it, or an inline span): the command's name and
/// the flags it names. `cargo run ... -- ARGS` counts as `survey ARGS`.
fn shown_commands(code: &[String]) -> Vec<(String, Vec<String>)> {
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    let mut continuing = false;
    for line in code {
        let indented = line.starts_with(' ') && !line.trim().is_empty();
        let tokens: Vec<&str> = line.split_whitespace().collect();
        let start = tokens
            .iter()
            .position(|t| *t == "survey")
            .filter(|&i| i == 0 || ["$", "&&", ";", "|"].contains(&tokens[i - 1]));
        let args: &[&str] = match (start, tokens.iter().position(|t| *t == "--")) {
            (Some(i), _) => &tokens[i + 1..],
            (None, Some(i)) if tokens.starts_with(&["cargo", "run"]) => &tokens[i + 1..],
            _ if continuing && indented => {
                let flags = flags_in(&tokens);
                out.last_mut().unwrap().1.extend(flags);
                continue;
            }
            _ => {
                continuing = false;
                continue;
            }
        };
        let mut args = args.iter().peekable();
        while args.next_if(|a| **a == "--db").is_some() {
            args.next();
        }
        let Some(command) = args.next().filter(|c| c.chars().all(|c| c.is_ascii_lowercase() || c == '-')) else {
            continuing = false;
            continue;
        };
        let rest: Vec<&str> = args.copied().collect();
        out.push((command.to_string(), flags_in(&rest)));
        continuing = true;
    }
    out
}

/// The `--flags` of a command's words, up to the end of the command (a
/// comment, a pipe, a redirection).
fn flags_in(words: &[&str]) -> Vec<String> {
    let mut flags = Vec::new();
    for word in words.iter().take_while(|w| !["#", "&&", "|", ";", ">", "2>", "&"].contains(w)) {
        let mut rest = *word;
        while let Some(at) = rest.find("--") {
            let name: String = rest[at + 2..].chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '-').collect();
            if name.chars().next().is_some_and(|c| c.is_ascii_lowercase()) {
                flags.push(format!("--{name}"));
            }
            rest = &rest[at + 2 + name.len()..];
        }
    }
    flags
}

#[test]
fn the_command_reader_finds_commands_and_their_flags() {
    let code: Vec<String> = [
        "survey --db lab.db run --points N [--bidirectional] [--runs R]",
        "           [--scan step|continuous] # not --a-flag",
        "survey 1: ISO 230-2, 1800 targets",
        "cargo run --release -- run --points 1800",
        "sed -e x bench.toml > r.toml && survey check --config r.toml",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let shown = shown_commands(&code);
    let flags = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    assert_eq!(
        shown,
        [
            ("run".to_string(), flags(&["--points", "--bidirectional", "--runs", "--scan"])),
            ("run".to_string(), flags(&["--points"])),
            ("check".to_string(), flags(&["--config"])),
        ]
    );
}

#[test]
fn every_command_and_flag_the_docs_show_exists() {
    let mut help: BTreeMap<String, Result<String, String>> = BTreeMap::new();
    let mut missing = BTreeSet::new();
    let mut checked = 0;
    for (page, text) in pages() {
        let name = page.strip_prefix(root()).unwrap().display().to_string();
        for (command, flags) in shown_commands(&parts(&text).code) {
            let text = help.entry(command.clone()).or_insert_with(|| {
                // `survey help` is clap's: it prints the help, and takes no --help.
                let args: &[&str] = if command == "help" { &["help"] } else { &[&command, "--help"] };
                let out = Command::new(BIN).args(args).env_remove("RUST_LOG").output().unwrap();
                match out.status.code() {
                    Some(0) => Ok(String::from_utf8_lossy(&out.stdout).into_owned()),
                    _ => Err(String::from_utf8_lossy(&out.stderr).into_owned()),
                }
            });
            match text {
                Err(_) => {
                    missing.insert(format!("{name}: `survey {command}` is not a command"));
                }
                Ok(help) => {
                    for flag in flags {
                        let named = help.match_indices(&flag).any(|(at, _)| {
                            !help[at + flag.len()..].starts_with(|c: char| c.is_ascii_alphanumeric() || c == '-')
                        });
                        if !named {
                            missing.insert(format!("{name}: `survey {command}` has no {flag}"));
                        }
                        checked += 1;
                    }
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "the docs name what does not exist:\n{}",
        missing.iter().cloned().collect::<Vec<_>>().join("\n")
    );
    assert!(checked > 150, "only {checked} flags were found in the docs");
    assert!(help.len() >= 14, "only {} commands were found in the docs: {:?}", help.len(), help.keys());
}
