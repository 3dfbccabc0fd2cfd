//! `survey report --pdf`: the page printed to PDF by Chromium, headless,
//! beside the HTML (`index.pdf`). The page's own print stylesheet makes the
//! certificate (A4, a section a page, the running head and "page x of y" in
//! the margins), so the browser's header and footer are switched off
//! (`--no-pdf-header-footer`).
//!
//! The browser: the `SURVEY_CHROMIUM` environment variable, else the first
//! of `chromium`, `chromium-browser`, `google-chrome` on `PATH`. It runs with
//! the flags a machine without a display or a network needs, in a fresh
//! profile, bounded by a timeout (120 s, or `SURVEY_PDF_TIMEOUT_S`); on
//! timeout its whole process group is killed. No browser, a failed run or a
//! file that is not a PDF is a run-time failure (exit status 1) with a
//! message that says what to do; the HTML page stays written.

use anyhow::{Context, anyhow};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Duration;

/// The environment variable that names the browser.
pub const BROWSER_ENV: &str = "SURVEY_CHROMIUM";
/// The environment variable that bounds one print, seconds.
pub const TIMEOUT_ENV: &str = "SURVEY_PDF_TIMEOUT_S";
/// The bound on one print without [`TIMEOUT_ENV`] (a report prints in 2-5 s here).
const DEFAULT_TIMEOUT: Duration = Duration::from_secs(120);
/// The names looked for on `PATH`.
const NAMES: [&str; 3] = ["chromium", "chromium-browser", "google-chrome"];
/// Headless, no sandbox (root in a container), no GPU, and nothing reached
/// over the network (without these it can hang on a closed network).
const FLAGS: [&str; 8] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-pdf-header-footer",
];

/// The browser to print with, or what to do to get one.
pub fn browser() -> anyhow::Result<PathBuf> {
    if let Some(named) = std::env::var_os(BROWSER_ENV) {
        let path = PathBuf::from(named);
        return if path.is_file() { Ok(path) } else { Err(anyhow!("{BROWSER_ENV}={} names no file", path.display())) };
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .flat_map(|dir| NAMES.iter().map(move |n| dir.join(n)))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            anyhow!(
                "no Chromium found: {BROWSER_ENV} is not set and none of {} is on PATH; install it (Debian: \
                 apt-get install chromium) or name it with {BROWSER_ENV}",
                NAMES.join(", ")
            )
        })
}

/// The bound on one print: [`TIMEOUT_ENV`], else 120 s; a value that is not a positive number is bad input.
pub fn timeout() -> anyhow::Result<Duration> {
    match std::env::var(TIMEOUT_ENV) {
        Err(_) => Ok(DEFAULT_TIMEOUT),
        Ok(s) => match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(Duration::from_secs_f64(v)),
            _ => Err(survey_lab::error::bad_input(format!("{TIMEOUT_ENV}={s}: must be a positive number of seconds"))),
        },
    }
}

/// `path` as a `file://` URL (every byte outside the unreserved set and `/` percent-encoded).
fn file_url(path: &Path) -> String {
    let mut url = String::from("file://");
    for b in path.as_os_str().as_encoded_bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' | b'/' => url.push(*b as char),
            _ => url += &format!("%{b:02X}"),
        }
    }
    url
}

/// The number of pages of `pdf`: its `/Type /Page` objects (not `/Pages`).
pub fn page_count(pdf: &[u8]) -> usize {
    let key = b"/Type /Page";
    pdf.windows(key.len() + 1).filter(|w| w.starts_with(key) && !w[key.len()].is_ascii_alphabetic()).count()
}

/// Print the page `html` to the PDF `pdf` with Chromium within `bound`; returns the number of pages.
pub async fn print(html: &Path, pdf: &Path, bound: Duration) -> anyhow::Result<usize> {
    let context = || format!("cannot print {} to PDF (the HTML page is written)", html.display());
    let browser = browser().with_context(context)?;
    let html = std::fs::canonicalize(html).with_context(context)?;
    let out = std::path::absolute(pdf).with_context(context)?;
    match std::fs::remove_file(&out) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e).with_context(context),
        _ => {}
    }
    let profile = tempfile::tempdir().context("a fresh browser profile").with_context(context)?;
    let mut cmd = tokio::process::Command::new(&browser);
    cmd.args(FLAGS)
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg(format!("--print-to-pdf={}", out.display()))
        .arg(file_url(&html))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .process_group(0)
        .kill_on_drop(true);
    let child = cmd.spawn().with_context(|| format!("cannot start {}", browser.display())).with_context(context)?;
    let group = child.id().map(|id| nix::unistd::Pid::from_raw(id as i32));
    let output = match tokio::time::timeout(bound, child.wait_with_output()).await {
        Ok(output) => output.with_context(context)?,
        Err(_) => {
            // The browser and the processes it started.
            if let Some(g) = group {
                let _ = nix::sys::signal::killpg(g, nix::sys::signal::Signal::SIGKILL);
            }
            return Err(anyhow!("{} did not finish within {:?}", browser.display(), bound)).with_context(context);
        }
    };
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(5).collect::<Vec<_>>().into_iter().rev().collect();
        let said = if tail.is_empty() { String::new() } else { format!(": {}", tail.join(" / ")) };
        return Err(anyhow!("{} exited with {}{said}", browser.display(), output.status)).with_context(context);
    }
    let bytes = std::fs::read(&out)
        .map_err(|e| anyhow!("{} exited 0 but wrote no {}: {e}", browser.display(), out.display()))
        .with_context(context)?;
    if !bytes.starts_with(b"%PDF") {
        return Err(anyhow!("{} is not a PDF", out.display())).with_context(context);
    }
    Ok(page_count(&bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_becomes_a_file_url_and_pages_are_counted() {
        assert_eq!(file_url(Path::new("/tmp/a b/ü.html")), "file:///tmp/a%20b/%C3%BC.html");
        let pdf = b"%PDF-1.4 1 0 obj <</Type /Pages /Count 2>> 2 0 obj <</Type /Page>> 3 0 obj <</Type /Page /X 1>>";
        assert_eq!(page_count(pdf), 2);
    }
}
