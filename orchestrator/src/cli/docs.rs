//! `survey completions SHELL` and `survey man [--out DIR]`: shell completion
//! scripts and manual pages generated from the command line itself (clap's
//! `clap_complete` and `clap_mangen`), so they never drift from the flags.

use super::Cli;
use super::support::emit;
use crate::error::path_error;
use clap::{Args, CommandFactory, ValueEnum, ValueHint};
use std::path::{Path, PathBuf};

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

/// The manual page of `cmd` (roff).
fn page(cmd: clap::Command) -> anyhow::Result<Vec<u8>> {
    let mut buf = Vec::new();
    clap_mangen::Man::new(cmd).render(&mut buf)?;
    Ok(buf)
}

/// Every page: `survey.1` and `survey-<command>.1`, named.
pub fn pages() -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    let mut root = Cli::command();
    root.build();
    let mut out = vec![("survey.1".to_string(), page(root.clone())?)];
    for sub in root.get_subcommands().filter(|s| s.get_name() != "help") {
        let name = format!("survey-{}", sub.get_name());
        out.push((format!("{name}.1"), page(sub.clone().name(name))?));
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
            eprintln!("wrote {} manual pages into {}", pages.len(), dir.display());
        }
    }
    Ok(())
}
