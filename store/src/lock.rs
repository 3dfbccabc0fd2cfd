//! One acquirer per survey: [`AcquirerLock`]; whether a process holds a
//! survey: [`is_held`].
//!
//! A survey is acquired (by `run`, `resume` or a verification) by at most one
//! process, ever: on hardware, two would command one positioner. The lock is
//! an exclusive advisory lock on a small file beside the database,
//! `<db>.survey-<id>.lock`, which holds who took it: `pid`, `host`, `since`
//! (JSON). The kernel releases the lock when its process ends in any way
//! (exit, crash, SIGKILL, power loss), so a lock left by a dead process is
//! free at once: the next acquirer takes it over and logs whose it was. A
//! live holder is never taken over: the second acquirer is refused at once
//! with the holder's pid, host and since when ([`SurveyBusy`], exit status 1).
//!
//! # Two locks on one file, and the question readers ask
//!
//! The acquirer takes two locks on the file, both exclusive, both without
//! waiting: a `flock` (through [`std::fs::File::try_lock`]; what versions
//! before this one took, so an older `survey` beside this one is still kept
//! out) and an open-file-description lock (Linux's `F_OFD_SETLK` on the whole
//! file). A reader (`list`, `show`, `history`, the pages) asks whether a
//! survey stored as `running` has a live acquirer with [`is_held`]:
//! `F_OFD_GETLK` on a descriptor of its own, opened read-only. That query only
//! asks the kernel whether a lock would conflict; it takes nothing, so it can
//! never make an acquirer fail or wait (a shared `flock` probe would: an
//! acquirer arriving while the probe holds it would be refused as busy). Why
//! OFD and not the other kinds: `flock` has no query at all, and on Linux
//! `flock` and `fcntl` locks are independent, so `F_OFD_GETLK` does not see a
//! `flock`; classic POSIX record locks (`F_SETLK`) belong to the process and
//! are dropped when the process closes *any* descriptor of the file (a
//! reader in the acquiring process, e.g. `survey serve` beside an
//! acquisition in tests, would release its own lock); `/proc/locks` could be
//! searched for the file's inode instead, but it is Linux-only too, lists
//! every lock of the machine, and its device numbers must be matched by hand.
//! An OFD lock belongs to the open file, is released when the last
//! descriptor of it closes (the process ending in any way), and conflicts
//! with any other open file's lock, in this process or another.
//!
//! The file is removed when the lock is released normally, under the lock, and
//! an acquirer checks after locking that the path still names the file it
//! locked (same device and inode), retrying otherwise: so a file being removed
//! by one process and created by another can never give two holders. A reader
//! that finds no file finds no holder.
//!
//! # The reserve for the last word
//!
//! The lock file also keeps [`RESERVE_BYTES`] of the disk for the survey's
//! final status: the holder's JSON is followed by that much padding
//! (whitespace, which a JSON reader skips), written when the lock is taken.
//! When the disk fills up during an acquisition, every write fails; the
//! store's status write then gives the padding back ([`release_reserve`]) and
//! tries once more, so a survey stopped by a full disk is stored as
//! `interrupted`, not left `running`. Where there is not even room for the
//! reserve when the lock is taken, the lock is taken without it (a warning
//! says so); readers show a `running` survey with no holder as `interrupted`
//! all the same.
//!
//! Our own design (no public document). Locks of this kind hold on a local
//! file system; on a network file system that does not share locks between
//! machines, keep the database on one machine. The lock file is named after
//! the `--db` path as given: a database reached through two names (a
//! symbolic link) has two lock files.

use nix::fcntl::{FcntlArg, fcntl};
use nix::libc;
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

/// The bytes of disk the lock file keeps for the survey's final status
/// (see the module's documentation): room for the status's pages in the
/// write-ahead log (a few 4 KiB frames) and the growth of its shared-memory
/// index (32 KiB), several times over.
pub const RESERVE_BYTES: u64 = 128 * 1024;

/// A lock description covering the whole file (`l_len` 0: to its end, however
/// long), of kind `kind` (`F_WRLCK`, `F_UNLCK`); `l_pid` 0 as OFD locks ask.
fn whole_file(kind: libc::c_int) -> libc::flock {
    libc::flock {
        l_type: kind as libc::c_short,
        l_whence: libc::SEEK_SET as libc::c_short,
        l_start: 0,
        l_len: 0,
        l_pid: 0,
    }
}

/// Take the OFD write lock of `file` without waiting: `Ok(false)` when
/// another open file holds a lock on it.
fn try_ofd_lock(file: &File) -> std::io::Result<bool> {
    match fcntl(file, FcntlArg::F_OFD_SETLK(&whole_file(libc::F_WRLCK))) {
        Ok(_) => Ok(true),
        Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EACCES) => Ok(false),
        Err(e) => Err(std::io::Error::from(e)),
    }
}

/// Whether a live process holds the acquisition lock of survey `survey_id`
/// of the database at `db`: `Some(true)` it does, `Some(false)` no process
/// does (no lock file, or a file no one has locked: its acquirer is gone),
/// `None` when it cannot be told (the file cannot be opened or queried).
///
/// It takes no lock: `F_OFD_GETLK` on a read-only descriptor of its own only
/// asks the kernel whether a write lock would conflict, so an acquirer is
/// never refused or delayed by a reader asking.
pub fn is_held(db: &Path, survey_id: i64) -> Option<bool> {
    let path = lock_path(db, survey_id);
    let file = match File::open(&path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Some(false),
        Err(e) => {
            tracing::debug!(path = %path.display(), error = %e, "cannot open the acquisition lock to ask who holds it");
            return None;
        }
    };
    let mut query = whole_file(libc::F_WRLCK);
    match fcntl(&file, FcntlArg::F_OFD_GETLK(&mut query)) {
        Ok(_) => Some(query.l_type != libc::F_UNLCK as libc::c_short),
        Err(e) => {
            tracing::debug!(path = %path.display(), error = %e, "cannot ask who holds the acquisition lock");
            None
        }
    }
}

/// Give back the disk space the lock file of survey `survey_id` keeps for
/// its final status ([`RESERVE_BYTES`]): the file is cut to the holder's
/// JSON. `true` when there was a reserve to give back. For the status write
/// of a survey whose disk is full; harmless on any other (the file names its
/// holder all the same).
pub fn release_reserve(db: &Path, survey_id: i64) -> bool {
    let path = lock_path(db, survey_id);
    let Ok(mut file) = OpenOptions::new().read(true).write(true).open(&path) else { return false };
    let mut text = Vec::new();
    if file.read_to_end(&mut text).is_err() {
        return false;
    }
    let kept = text.iter().rposition(|b| !b.is_ascii_whitespace()).map_or(0, |i| i + 1);
    if kept as u64 == text.len() as u64 {
        return false;
    }
    let released = file.set_len(kept as u64).is_ok();
    if released {
        tracing::warn!(
            survey = survey_id,
            bytes = text.len() - kept,
            "the disk is full: the reserve kept for the survey's status is given back"
        );
    }
    released
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

/// Write the holder's JSON `me` into the lock file, followed by the reserve
/// (newlines, [`RESERVE_BYTES`] of them) when `reserve`, and sync it. A disk
/// without room for the reserve gets the JSON alone (a warning says so).
fn write_holder(file: &mut File, me: &[u8], reserve: bool) -> std::io::Result<()> {
    file.set_len(0)?;
    file.rewind()?;
    let mut text = me.to_vec();
    if reserve {
        text.push(b'\n');
        text.resize(text.len() + RESERVE_BYTES as usize, b'\n');
    }
    match file.write_all(&text).and_then(|()| file.sync_all()) {
        Err(e) if reserve && e.raw_os_error() == Some(libc::ENOSPC) => {
            tracing::warn!(
                "the disk has no room for the reserve kept for the survey's status: should it fill up during the \
                 acquisition, the survey may stay stored as `running` (readers show it as interrupted)"
            );
            write_holder(file, me, false)
        }
        other => other,
    }
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
            let busy = |file: &mut File| -> anyhow::Error {
                let holder = read_holder(file).unwrap_or_else(unknown_holder);
                SurveyBusy { survey_id, holder, path: path.display().to_string() }.into()
            };
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => return Err(busy(&mut file)),
                Err(TryLockError::Error(e)) => return Err(cannot(e)),
            }
            // The lock readers can ask about (the flock kept out any other
            // acquirer of this version or an older one).
            if !try_ofd_lock(&file).map_err(cannot)? {
                return Err(busy(&mut file));
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
            write_holder(&mut file, me.as_bytes(), true).map_err(cannot)?;
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
    fn a_reader_sees_whether_a_live_process_holds_the_lock() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        assert_eq!(is_held(&db, 1), Some(false), "no lock file: no holder");
        let lock = AcquirerLock::acquire(&db, 1).unwrap();
        // Asked from this process on a descriptor of its own: held.
        assert_eq!(is_held(&db, 1), Some(true));
        assert_eq!(is_held(&db, 2), Some(false), "another survey's lock is not this one's");
        drop(lock);
        assert_eq!(is_held(&db, 1), Some(false));
        // A file left by a killed acquirer, locked by no one: no holder.
        let dead = Holder { pid: 999_999, host: "bench-pc".into(), since: "2026-11-24T10:00:00Z".into() };
        std::fs::write(lock_path(&db, 1), serde_json::to_string(&dead).unwrap()).unwrap();
        assert_eq!(is_held(&db, 1), Some(false));
    }

    /// The question takes nothing: acquirers taking and releasing the lock
    /// while readers ask as fast as they can are never refused.
    #[test]
    fn asking_who_holds_a_lock_never_makes_an_acquirer_fail() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let askers: Vec<_> = (0..2)
            .map(|_| {
                let (db, done) = (db.clone(), done.clone());
                std::thread::spawn(move || {
                    let mut asked = 0u64;
                    while !done.load(std::sync::atomic::Ordering::Relaxed) {
                        assert!(is_held(&db, 1).is_some());
                        asked += 1;
                    }
                    asked
                })
            })
            .collect();
        for round in 0..200 {
            let lock = AcquirerLock::acquire(&db, 1).unwrap_or_else(|e| panic!("round {round}: {e:#}"));
            drop(lock);
        }
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        let asked: u64 = askers.into_iter().map(|a| a.join().unwrap()).sum();
        assert!(asked > 0);
    }

    #[test]
    fn the_lock_file_keeps_a_reserve_that_is_given_back_once() {
        let dir = tempfile::tempdir().unwrap();
        let db = dir.path().join("s.db");
        let lock = AcquirerLock::acquire(&db, 5).unwrap();
        let size = std::fs::metadata(lock.path()).unwrap().len();
        assert!(size > RESERVE_BYTES, "{size} bytes");
        assert!(release_reserve(&db, 5));
        let text = std::fs::read_to_string(lock.path()).unwrap();
        let holder: Holder = serde_json::from_str(&text).unwrap();
        assert_eq!(holder.pid, std::process::id(), "the file still names its holder");
        assert!((text.len() as u64) < 200, "{} bytes left", text.len());
        assert!(!release_reserve(&db, 5), "nothing left to give back");
        assert_eq!(is_held(&db, 5), Some(true), "giving the reserve back keeps the lock");
        assert!(!release_reserve(&db, 6), "no lock file: nothing to give back");
    }

    #[test]
    fn a_lock_file_that_cannot_be_made_is_a_path_error() {
        let err = AcquirerLock::acquire(Path::new("/nonexistent-dir/s.db"), 1).unwrap_err();
        assert!(err.to_string().contains("acquisition lock"), "{err:#}");
    }
}
