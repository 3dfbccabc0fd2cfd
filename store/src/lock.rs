//! One acquirer per survey: [`AcquirerLock`].
//!
//! A survey is acquired (by `run`, `resume` or a verification) by at most one
//! process, ever: on hardware, two would command one positioner. The lock is
//! an exclusive advisory lock (`flock`, through [`std::fs::File::try_lock`])
//! on a small file beside the database, `<db>.survey-<id>.lock`, which holds
//! who took it: `pid`, `host`, `since` (JSON). The kernel releases the lock
//! when its process ends in any way (exit, crash, SIGKILL, power loss), so a
//! lock left by a dead process is free at once: the next acquirer takes it
//! over and logs whose it was. A live holder is never taken over: the second
//! acquirer is refused at once with the holder's pid, host and since when
//! ([`SurveyBusy`], exit status 1).
//!
//! The file is removed when the lock is released normally, under the lock, and
//! an acquirer checks after locking that the path still names the file it
//! locked (same device and inode), retrying otherwise: so a file being removed
//! by one process and created by another can never give two holders.
//!
//! Our own design (no public document). Locks of this kind hold on a local
//! file system; on a network file system that does not share `flock` between
//! machines, keep the database on one machine.

use serde::{Deserialize, Serialize};
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read as _, Seek as _, Write as _};
use std::os::unix::fs::MetadataExt as _;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Who holds (or held) a survey's lock.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Holder {
    /// Process id.
    pub pid: u32,
    /// Host name.
    pub host: String,
    /// When the lock was taken (RFC 3339, UTC).
    pub since: String,
}

impl Holder {
    fn this_process() -> Holder {
        let host = nix::unistd::gethostname().ok().and_then(|h| h.into_string().ok()).unwrap_or_else(|| "?".into());
        Holder {
            pid: std::process::id(),
            host,
            since: humantime::format_rfc3339_seconds(SystemTime::now()).to_string(),
        }
    }
}

impl std::fmt::Display for Holder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "process {} on {} since {}", self.pid, self.host, self.since)
    }
}

/// The survey is being acquired by another live process.
#[derive(Debug, thiserror::Error)]
#[error(
    "survey {survey_id} is being acquired by {holder} (lock {path}): one survey has one acquirer; wait for it to end or \
     stop it (SIGINT or SIGTERM), then `survey resume --survey {survey_id}`"
)]
pub struct SurveyBusy {
    /// The survey.
    pub survey_id: i64,
    /// Who holds it, as its lock file says (`?` fields when it could not be read).
    pub holder: Holder,
    /// The lock file.
    pub path: String,
}

/// The lock of one survey, held until dropped.
#[derive(Debug)]
pub struct AcquirerLock {
    file: File,
    path: PathBuf,
    survey_id: i64,
    /// Whose lock this process took over (a holder that had died), if any.
    pub took_over: Option<Holder>,
}

/// The lock file of survey `id` of the database at `db`.
pub fn lock_path(db: &Path, id: i64) -> PathBuf {
    let mut s = db.as_os_str().to_os_string();
    s.push(format!(".survey-{id}.lock"));
    PathBuf::from(s)
}

fn read_holder(file: &mut File) -> Option<Holder> {
    let mut text = String::new();
    file.rewind().ok()?;
    file.read_to_string(&mut text).ok()?;
    serde_json::from_str(&text).ok()
}

fn unknown_holder() -> Holder {
    Holder { pid: 0, host: "?".into(), since: "?".into() }
}

impl AcquirerLock {
    /// Take the lock of survey `survey_id` of the database `db`, or fail at
    /// once with [`SurveyBusy`] when a live process holds it.
    pub fn acquire(db: &Path, survey_id: i64) -> anyhow::Result<AcquirerLock> {
        let path = lock_path(db, survey_id);
        let cannot = |e: std::io::Error| {
            crate::error::path_error(e, format!("cannot take the acquisition lock {}", path.display()))
        };
        loop {
            let mut file =
                OpenOptions::new().read(true).write(true).create(true).truncate(false).open(&path).map_err(cannot)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let holder = read_holder(&mut file).unwrap_or_else(unknown_holder);
                    return Err(SurveyBusy { survey_id, holder, path: path.display().to_string() }.into());
                }
                Err(TryLockError::Error(e)) => return Err(cannot(e)),
            }
            // The file may have been removed (and another made) between our
            // open and our lock: then the lock is on a file no one else sees.
            let ours = file.metadata().map_err(cannot)?;
            match std::fs::metadata(&path) {
                Ok(now) if now.dev() == ours.dev() && now.ino() == ours.ino() => {}
                _ => continue,
            }
            let took_over = read_holder(&mut file);
            if let Some(previous) = &took_over {
                tracing::warn!(survey = survey_id, %previous, "taking over the acquisition lock of a process that is gone");
            }
            let me = serde_json::to_string(&Holder::this_process()).expect("a holder serialises");
            file.set_len(0)
                .and_then(|()| file.rewind())
                .and_then(|()| file.write_all(me.as_bytes()))
                .map_err(cannot)?;
            file.sync_all().map_err(cannot)?;
            return Ok(AcquirerLock { file, path, survey_id, took_over });
        }
    }

    /// The survey this lock is for.
    pub fn survey_id(&self) -> i64 {
        self.survey_id
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for AcquirerLock {
    /// Remove the file while still holding the lock, then release it.
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_acquirer_is_refused_with_the_holder_named() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        let first = AcquirerLock::acquire(&db, 3).unwrap();
        assert!(first.took_over.is_none());
        let err = AcquirerLock::acquire(&db, 3).unwrap_err();
        let busy = err.downcast_ref::<SurveyBusy>().expect("a SurveyBusy");
        assert_eq!(busy.holder.pid, std::process::id());
        assert!(!busy.holder.host.is_empty() && busy.holder.since.ends_with('Z'), "{:?}", busy.holder);
        let text = err.to_string();
        assert!(text.contains("survey 3") && text.contains(&format!("process {}", std::process::id())), "{text}");
        // Another survey of the same database is free.
        let other = AcquirerLock::acquire(&db, 4).unwrap();
        drop(other);
        drop(first);
        assert!(!lock_path(&db, 3).exists(), "a released lock leaves no file");
        let again = AcquirerLock::acquire(&db, 3).unwrap();
        assert!(again.took_over.is_none(), "a released lock is not a dead holder's");
    }

    #[test]
    fn a_lock_left_by_a_dead_process_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        // What a killed acquirer leaves: its file, no lock (the kernel released it).
        let dead = Holder { pid: 999_999, host: "bench-pc".into(), since: "2026-11-24T10:00:00Z".into() };
        std::fs::write(lock_path(&db, 1), serde_json::to_string(&dead).unwrap()).unwrap();
        let lock = AcquirerLock::acquire(&db, 1).unwrap();
        assert_eq!(lock.took_over.as_ref(), Some(&dead));
        let stored: Holder = serde_json::from_str(&std::fs::read_to_string(lock.path()).unwrap()).unwrap();
        assert_eq!(stored.pid, std::process::id(), "the file now names the new holder");
    }

    #[test]
    fn a_lock_file_that_cannot_be_made_is_a_path_error() {
        let err = AcquirerLock::acquire(Path::new("/nonexistent-dir/s.db"), 1).unwrap_err();
        assert!(err.to_string().contains("acquisition lock"), "{err:#}");
    }
}
