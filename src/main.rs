//! The `survey` binary: a thin shell over `survey_orchestrator::cli`.
fn main() -> std::process::ExitCode {
    survey_orchestrator::cli::main()
}
