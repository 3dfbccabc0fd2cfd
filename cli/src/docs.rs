//! `survey completions SHELL` and `survey man [--out DIR]`: shell completion
//! scripts and manual pages generated from the command line itself (clap's
//! `clap_complete` and `clap_mangen`), so they never drift from the flags.

use super::Cli;
use super::support::emit;
use clap::{Args, CommandFactory, ValueEnum, ValueHint};
use std::path::{Path, PathBuf};
use survey_lab::error::path_error;

/// A shell `survey completions` writes for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ShellArg {
    /// GNU Bash.
    Bash,
    /// Z shell.
    Zsh,
    /// fish.
    Fish,
    /// Elvish.
    Elvish,
    /// PowerShell.
    Powershell,
}

#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell.
    #[arg(value_enum)]
    pub shell: ShellArg,
}

#[derive(Debug, Args)]
pub struct ManArgs {
    /// Write survey.1 and one page per command (survey-process.1, ...) into DIR
    /// (created if missing) instead of printing survey.1 on stdout.
    #[arg(long, value_name = "DIR", value_hint = clap::ValueHint::DirPath)]
    pub out: Option<PathBuf>,
}

/// The completion script for `args.shell`, on stdout.
pub fn completions(args: CompletionsArgs) -> anyhow::Result<()> {
    use clap_complete::Shell;
    let shell = match args.shell {
        ShellArg::Bash => Shell::Bash,
        ShellArg::Zsh => Shell::Zsh,
        ShellArg::Fish => Shell::Fish,
        ShellArg::Elvish => Shell::Elvish,
        ShellArg::Powershell => Shell::PowerShell,
    };
    let mut buf = Vec::new();
    clap_complete::generate(shell, &mut no_file_names_but_paths(Cli::command()), "survey", &mut buf);
    emit(&String::from_utf8_lossy(&buf));
    Ok(())
}

/// `cmd` with every value that is neither a path nor one of a list (a
/// number, an id, a name) hinted as such, so the shells offer no file name
/// for it: paths say `ValueHint::FilePath` or `DirPath`, lists their values.
fn no_file_names_but_paths(cmd: clap::Command) -> clap::Command {
    let unhinted: Vec<clap::Id> = cmd
        .get_arguments()
        .filter(|a| a.get_action().takes_values() && a.get_value_hint() == ValueHint::Unknown)
        .filter(|a| a.get_possible_values().is_empty())
        .map(|a| a.get_id().clone())
        .collect();
    let subcommands: Vec<String> = cmd.get_subcommands().map(|s| s.get_name().to_string()).collect();
    let cmd = unhinted.into_iter().fold(cmd, |cmd, id| cmd.mut_arg(id, |a| a.value_hint(ValueHint::Other)));
    subcommands.into_iter().fold(cmd, |cmd, name| cmd.mut_subcommand(name, no_file_names_but_paths))
}

/// The manual page of `cmd` (roff), section by section (clap_mangen's,
/// but for the last two): its after-help examples as EXAMPLES, one a line
/// as typed, and SEE ALSO naming `see_also`, the pages `survey man --out`
/// writes beside it.
fn page(cmd: clap::Command, see_also: &[String]) -> anyhow::Result<Vec<u8>> {
    let man = clap_mangen::Man::new(cmd.clone());
    let mut buf = Vec::new();
    man.render_title(&mut buf)?;
    man.render_name_section(&mut buf)?;
    man.render_synopsis_section(&mut buf)?;
    man.render_description_section(&mut buf)?;
    if cmd.get_arguments().any(|a| !a.is_hide_set()) {
        man.render_options_section(&mut buf)?;
    }
    if cmd.has_subcommands() {
        man.render_subcommands_section(&mut buf)?;
    }
    if let Some(after) = cmd.get_after_help() {
        let text = after.to_string();
        let examples = text.strip_prefix("Examples:").unwrap_or(&text).trim_matches('\n');
        buf.extend(b".SH EXAMPLES\n.nf\n");
        for line in examples.lines() {
            buf.extend(roff_line(line.strip_prefix("  ").unwrap_or(line)).as_bytes());
        }
        buf.extend(b".fi\n");
    }
    buf.extend(ENVIRONMENT_AND_EXIT_STATUS.as_bytes());
    if !see_also.is_empty() {
        let pages: Vec<String> = see_also.iter().map(|p| format!("\\fB{}\\fR(1)", roff_text(p))).collect();
        buf.extend(format!(".SH \"SEE ALSO\"\n{}\n", pages.join(", ")).as_bytes());
    }
    man.render_version_section(&mut buf)?;
    // Each section rendered alone begins with the same string definition: once is enough.
    let text = String::from_utf8(buf)?;
    let mut parts = text.split(ROFF_PREAMBLE);
    let first = parts.next().unwrap_or_default();
    let rest: String = parts.collect();
    Ok(if rest.is_empty() { first.into() } else { format!("{first}{ROFF_PREAMBLE}{rest}").into_bytes() })
}

/// The environment a command reads and the exit statuses it gives, the same
/// on every page (roff).
const ENVIRONMENT_AND_EXIT_STATUS: &str = r#".SH ENVIRONMENT
.TP
\fBSURVEY_DB\fR
The survey database (a SQLite file, or a lab store's postgres:// URL) when \fB\-\-db\fR is not given; \fBsurvey.db\fR when neither is.
.TP
\fBSURVEY_UNITS\fR
The default of \fB\-\-units\fR: deg, arcsec or urad.
.TP
\fBSURVEY_LAB\fR
The lab store \fBsurvey push\fR copies to when \fB\-\-to\fR is not given, and whose sequence \fBsurvey report\fR draws a certificate's number from when \fB\-\-lab\fR is not given (its password never printed).
.TP
\fBSURVEY_CHROMIUM\fR, \fBSURVEY_PDF_TIMEOUT_S\fR
The browser \fBsurvey report \-\-pdf\fR prints with, and how long one print may take (seconds, default 120).
.TP
\fBRUST_LOG\fR
When set, decides what is logged on stderr instead of \fB\-v\fR (tracing's filter syntax).
.SH "EXIT STATUS"
.TP
\fB0\fR
Success (\fBsurvey run \-\-check\fR: in tolerance, or changed within a table that holds).
.TP
\fB1\fR
The work failed at run time: an instrument, the disk, an interrupted survey, a verification not confirmed, a check that could not decide.
.TP
\fB2\fR
Bad usage or bad input (a flag, a file, a configuration, a damaged database); nothing stored was changed.
.TP
\fB3\fR
\fBsurvey run \-\-check\fR made a full survey (recalibrated, or the asset's first calibration).
"#;

/// What clap_mangen writes before every piece of roff it renders.
const ROFF_PREAMBLE: &str = ".ie \\n(.g .ds Aq \\(aq\n.el .ds Aq '\n";

/// `text` for roff: a backslash and a hyphen as themselves (`\e`, `\-`).
fn roff_text(text: &str) -> String {
    text.replace('\\', "\\e").replace('-', "\\-")
}

/// One line of text for roff as typed: never taken for a request.
fn roff_line(line: &str) -> String {
    let text = roff_text(line);
    if text.starts_with(['.', '\'']) { format!("\\&{text}\n") } else { format!("{text}\n") }
}

/// Every page: `survey.1` and `survey-<command>.1`, named; each command's
/// page sees `survey(1)`, `survey(1)` sees every command's.
pub fn pages() -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    // No help command: it has no page of its own (`survey help X` is `survey X --help`).
    let mut root = Cli::command().disable_help_subcommand(true);
    root.build();
    let names: Vec<String> = root.get_subcommands().map(|s| format!("survey-{}", s.get_name())).collect();
    let mut out = vec![("survey.1".to_string(), page(root.clone(), &names)?)];
    for (sub, name) in root.get_subcommands().zip(names) {
        out.push((format!("{name}.1"), page(sub.clone().name(&name), &["survey".to_string()])?));
    }
    Ok(out)
}

/// `survey man`: the page on stdout, or every page into `--out`.
pub fn man(args: ManArgs) -> anyhow::Result<()> {
    let pages = pages()?;
    match &args.out {
        None => emit(&String::from_utf8_lossy(&pages[0].1)),
        Some(dir) => {
            std::fs::create_dir_all(dir).map_err(|e| path_error(e, format!("cannot create {}", dir.display())))?;
            for (name, bytes) in &pages {
                let path: &Path = &dir.join(name);
                std::fs::write(path, bytes).map_err(|e| path_error(e, format!("cannot write {}", path.display())))?;
            }
            survey_bench::say!("wrote {} manual pages into {}", pages.len(), dir.display());
        }
    }
    Ok(())
}
