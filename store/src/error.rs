//! The error types every floor above the store shares: [`BadInput`] (the
//! user's input is wrong: exit status 2) and [`PathError`] (an I/O error on
//! a path the user gave: the user's or the machine's, by its kind). What an
//! error means for the exit status is decided once, above every type it
//! names: `survey_lab::error`.

/// Bad input that has no type of its own: a missing flag, a value out of its
/// range, a survey that cannot do what was asked.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct BadInput(pub String);

/// A [`BadInput`] error.
pub fn bad_input(message: impl Into<String>) -> anyhow::Error {
    BadInput(message.into()).into()
}

/// An I/O error on a path the user gave: `what` was done to which path.
/// Whether it is the user's (see [`exit_status`]) depends on its kind.
#[derive(Debug, thiserror::Error)]
#[error("{what}: {io}")]
pub struct PathError {
    /// What was done, naming the path (`cannot create out/t.csv`).
    pub what: String,
    /// The error.
    pub io: std::io::Error,
}

impl PathError {
    /// A path that cannot exist or be reached (missing folder, permission, a
    /// folder where a file belongs) is the user's; anything else (a full
    /// disk, a device error) is a run-time failure.
    pub fn is_the_users(&self) -> bool {
        use std::io::ErrorKind::*;
        matches!(
            self.io.kind(),
            NotFound
                | PermissionDenied
                | IsADirectory
                | NotADirectory
                | InvalidInput
                | InvalidFilename
                | ReadOnlyFilesystem
                | AlreadyExists
        )
    }
}

/// A [`PathError`]: `e` met doing `what`.
pub fn path_error(e: std::io::Error, what: String) -> anyhow::Error {
    PathError { what, io: e }.into()
}

/// An error's chain for people: as `{e:#}` prints it, but a SQLite
/// failure the user can act on said in words where its codes would stand
/// (`(code: 13) database or disk is full`, twice: sqlx's error and its
/// source), and nothing of it beneath.
pub fn said(e: &anyhow::Error) -> String {
    let mut parts: Vec<String> = Vec::new();
    for c in e.chain() {
        // The engine's store failure carries its error as text and no
        // source: said from the error it holds.
        if let Some(survey_acquire::EngineError::Sink(inner)) = c.downcast_ref::<survey_acquire::EngineError>() {
            parts.push("recording failed".to_string());
            parts.push(said(inner));
            break;
        }
        let words = c.downcast_ref::<sqlx::Error>().and_then(crate::sqlite_code).and_then(|code| match code & 0xff {
            13 => Some(
                "the disk is full (SQLite could not write: free some space; a survey stopped by it is kept and \
                 `survey resume` continues it)",
            ),
            11 => Some("the database file is damaged (SQLite found its pages malformed)"),
            10 => Some("the disk could not be read or written (an I/O error beneath SQLite)"),
            _ => None,
        });
        match words {
            Some(w) => {
                parts.push(w.to_string());
                break;
            }
            None => parts.push(c.to_string()),
        }
    }
    parts.dedup();
    parts.join(": ")
}

/// What stopped an acquisition, for people: as `{e:#}` prints it, but a
/// store's failure (a full disk: which file, and that it is full) said as
/// [`said`] says it.
pub fn engine_said(e: &survey_acquire::EngineError) -> String {
    match e {
        survey_acquire::EngineError::Sink(inner) => format!("recording failed: {}", said(inner)),
        other => format!("{other:#}"),
    }
}

#[cfg(test)]
mod tests {
    /// Issue 51: a full disk met by the engine's store (its error held as
    /// text by `EngineError::Sink`) is said in words, not as SQLite's codes.
    #[test]
    fn a_full_disk_met_while_recording_is_said_in_words() {
        let full = sqlx::Error::Database(Box::new(FullDisk));
        let e = anyhow::Error::new(full).context("cannot commit samples of survey 1 in survey.db");
        let e = anyhow::Error::new(survey_acquire::EngineError::Sink(e));
        let text = super::said(&e);
        assert!(
            text.starts_with("recording failed: cannot commit samples of survey 1 in survey.db: the disk is full"),
            "{text}"
        );
        assert!(!text.contains("code: 13"), "{text}");
        let Ok(engine) = e.downcast::<survey_acquire::EngineError>() else { panic!("the engine's error") };
        assert_eq!(super::engine_said(&engine), text);
    }

    #[derive(Debug)]
    struct FullDisk;
    impl std::fmt::Display for FullDisk {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("(code: 13) database or disk is full")
        }
    }
    impl std::error::Error for FullDisk {}
    impl sqlx::error::DatabaseError for FullDisk {
        fn message(&self) -> &str {
            "database or disk is full"
        }
        fn code(&self) -> Option<std::borrow::Cow<'_, str>> {
            Some("13".into())
        }
        fn as_error(&self) -> &(dyn std::error::Error + Send + Sync + 'static) {
            self
        }
        fn as_error_mut(&mut self) -> &mut (dyn std::error::Error + Send + Sync + 'static) {
            self
        }
        fn into_error(self: Box<Self>) -> Box<dyn std::error::Error + Send + Sync + 'static> {
            self
        }
        fn kind(&self) -> sqlx::error::ErrorKind {
            sqlx::error::ErrorKind::Other
        }
    }
}
