//! The file's bytes as SQLite will read them, before SQLite reads them: the
//! file's length against its header's page count, and the write-ahead log
//! beside it (`<db>-wal`), which SQLite replays onto any file it finds it
//! beside, since nothing in the file names its log
//! (<https://www.sqlite.org/fileformat2.html#walformat>).
//!
//! # The length
//!
//! The header holds the page size (offset 16, two bytes, 1 meaning 65536)
//! and the database's size in pages (offset 28), which is valid when the
//! change counter (offset 24) equals the "version valid for" number (offset
//! 92). SQLite rounds a length up to whole pages and reads a missing tail as
//! a short read (`SQLITE_IOERR_SHORT_READ`) or zeros, so a file cut short
//! by less than a page opens as if sound. Here a file must hold every page
//! its header counts, whole: a page it lacks, or has only in part, is
//! damage, unless the write-ahead log beside it (one that belongs to it,
//! below) holds that page in a committed frame, as after a checkpoint that
//! was cut by a crash (a checkpoint writes page 1, with the new count,
//! first).
//!
//! # The write-ahead log
//!
//! A log is read as SQLite recovers one: its header (magic 0x377f0682 or
//! 0x377f0683, format 3007000, the page size, the checkpoint sequence, two
//! salts, the header's checksum), then its frames while each carries the
//! header's salts and a valid cumulative checksum; the frames up to the last
//! commit frame are what SQLite replays. A log of zero length, or whose
//! frames are all of an earlier generation (another salt: a log restarted),
//! replays nothing and is left alone. A log whose header is not SQLite's,
//! whose checksum fails or whose page size is not the file's is refused (it
//! would be ignored, and what it held lost).
//!
//! Whether a log belongs to the file is told by page 1, the only page whose
//! history can be followed: every transaction that writes page 1 (one that
//! grows or shrinks the file, changes the schema or the free list) adds 1 to
//! its change counter, so the page-1 images of a log count up, and the file's
//! own page 1 is either one of them byte for byte (the log was checkpointed
//! into the file up to there and not yet restarted) or older than all of them
//! (the log was restarted after the file's last checkpoint). But in WAL mode
//! SQLite need not count every transaction (its file format's documentation),
//! so images of the file's own counter with other bytes may be its own log's
//! (CI's full-disk test met one): those are left to the check of the file as
//! the log makes it. So a log whose committed frames hold a page 1:
//!
//! - whose counters all lie below the file's: the file is newer than the log
//!   (an old log, or one from another copy that made fewer transactions);
//! - whose counters begin at or below the file's with none equal to it: the
//!   log and the file parted at or before that transaction (another copy's);
//!
//! does not belong. A log with no page 1 in its committed frames made no
//! transaction that changed the file's size, so each of its commits must
//! leave the database at the size the file's header counts.
//!
//! Every write of this store also seals page 1 (`crate::tx`): the header's
//! `user_version` (offset 60) becomes a new random number and its
//! `application_id` (offset 68) the one it followed. A log whose first
//! page-1 image followed (or kept) another state than the file's, and none
//! of whose images is the file's page 1, is another copy's: two copies that
//! each wrote after they parted are told apart even when their change
//! counters agree (issue 51's third foreign log). Files and logs written
//! before the seal read 0 in both and are told as before.
//!
//! The limits: a log from a copy that parted from this file after the file's
//! last page-1 change, and wrote only pages other than page 1 (rows updated
//! or added within existing pages), cannot be told from this file's own log
//! by its bytes. The file as that log makes it is then checked as a whole
//! (`PRAGMA quick_check` on an ordinary read-only connection, which reads
//! the log as SQLite does), which finds a mixture of two histories when it
//! breaks a b-tree, not when the pages happen to fit.

use std::io::Read as _;
use std::path::{Path, PathBuf};

/// The write-ahead log's magic numbers (the low bit: big-endian checksums).
const WAL_MAGIC: [u32; 2] = [0x377f_0682, 0x377f_0683];
const WAL_FORMAT: u32 = 3_007_000;
const WAL_HEADER: usize = 32;
const FRAME_HEADER: usize = 24;

/// What was found of a file and the log beside it.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub(crate) struct Found {
    /// What is wrong, in words (empty: nothing found).
    pub problems: Vec<String>,
    /// The log beside the file has committed frames SQLite will replay.
    pub replays: bool,
}

/// The log of the file at `path`.
pub(crate) fn wal_path(path: &Path) -> PathBuf {
    let mut p = path.as_os_str().to_os_string();
    p.push("-wal");
    PathBuf::from(p)
}

/// The header fields that matter here.
#[derive(Debug, Clone, Copy)]
struct Header {
    page_size: u64,
    counter: u32,
    /// The page count, when valid.
    pages: Option<u64>,
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The SQLite header of `first` (the file's first bytes), when it is one.
fn header(first: &[u8]) -> Option<Header> {
    if first.len() < 100 || &first[..16] != b"SQLite format 3\0" {
        return None;
    }
    let page_size = match u16::from_be_bytes([first[16], first[17]]) {
        1 => 65536,
        n if n >= 512 && n.is_power_of_two() => u64::from(n),
        _ => return None,
    };
    let counter = be32(first, 24);
    let pages = Some(u64::from(be32(first, 28))).filter(|&n| n > 0 && counter == be32(first, 92));
    Some(Header { page_size, counter, pages })
}

/// SQLite's log checksum of `data` (a multiple of 8 bytes) from `s`.
fn checksum(big_endian: bool, data: &[u8], mut s: (u32, u32)) -> (u32, u32) {
    for pair in data.chunks_exact(8) {
        let word = |i: usize| {
            let b = [pair[i], pair[i + 1], pair[i + 2], pair[i + 3]];
            if big_endian { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) }
        };
        s.0 = s.0.wrapping_add(word(0)).wrapping_add(s.1);
        s.1 = s.1.wrapping_add(word(4)).wrapping_add(s.0);
    }
    s
}

/// What SQLite would replay of a log: the committed frames' pages, page 1's
/// images (counter and bytes) and the database's size after each commit.
#[derive(Debug, Default)]
struct Replay {
    /// Pages of committed frames.
    pages: std::collections::BTreeSet<u64>,
    /// Page 1's committed images, in order: (change counter, bytes).
    page_ones: Vec<(u32, Vec<u8>)>,
    /// The size in pages after each commit.
    commits: Vec<u64>,
}

/// Read the log `wal` (its bytes) of a file of `page_size`: what SQLite
/// replays of it, or why it is not a log of this file.
fn replay(wal: &[u8], page_size: u64) -> Result<Replay, String> {
    if wal.is_empty() {
        return Ok(Replay::default());
    }
    if wal.len() < WAL_HEADER {
        return Err(format!("it is {} bytes long, shorter than a log's header", wal.len()));
    }
    let magic = be32(wal, 0);
    if !WAL_MAGIC.contains(&magic) {
        return Err("it is not an SQLite write-ahead log (its first bytes are not the log's magic number)".into());
    }
    let big = magic & 1 == 1;
    if be32(wal, 4) != WAL_FORMAT {
        return Err(format!("its format is {}, not SQLite's 3007000", be32(wal, 4)));
    }
    let wal_page = u64::from(be32(wal, 8));
    if wal_page != page_size {
        return Err(format!("its pages are {wal_page} bytes, the file's {page_size}: it is another database's log"));
    }
    let salts = (be32(wal, 16), be32(wal, 20));
    let mut sum = checksum(big, &wal[..24], (0, 0));
    if sum != (be32(wal, 24), be32(wal, 28)) {
        return Err("its header's checksum fails (SQLite would ignore it, and lose what it holds)".into());
    }
    let frame = FRAME_HEADER + page_size as usize;
    let mut out = Replay::default();
    let (mut pending_pages, mut pending_ones) = (Vec::new(), Vec::new());
    for f in wal[WAL_HEADER..].chunks_exact(frame) {
        let (head, data) = f.split_at(FRAME_HEADER);
        let page = u64::from(be32(head, 0));
        if page == 0 || (be32(head, 8), be32(head, 12)) != salts {
            break;
        }
        let s = checksum(big, data, checksum(big, &head[..8], sum));
        if s != (be32(head, 16), be32(head, 20)) {
            break;
        }
        sum = s;
        pending_pages.push(page);
        if page == 1 {
            pending_ones.push((be32(data, 24), data.to_vec()));
        }
        let size = be32(head, 4);
        if size > 0 {
            out.pages.extend(pending_pages.drain(..));
            out.page_ones.append(&mut pending_ones);
            out.commits.push(u64::from(size));
        }
    }
    Ok(out)
}

/// Whether the committed page-1 images `ones` of a log follow the file's
/// page 1 (its change counter `counter`); why not, in words.
fn follows(ones: &[(u32, Vec<u8>)], counter: u32) -> Result<(), String> {
    let (Some(low), Some(high)) = (ones.iter().map(|o| o.0).min(), ones.iter().map(|o| o.0).max()) else {
        return Ok(());
    };
    if high < counter {
        return Err(format!(
            "its page 1 was last changed at change {high} (the header's change counter), and the file is at {counter}: the file is \
             newer than the log"
        ));
    }
    // In WAL mode SQLite need not count a transaction in the change counter
    // (its file format's documentation): page-1 images of one counter may
    // differ from the file's page 1 and still be its own (a log begun again
    // after a checkpoint; CI's full-disk test met one). Those are left to
    // the check of the file as the log makes it.
    match ones.iter().find(|o| o.0 == counter) {
        Some(_) => Ok(()),
        None if low <= counter => Err(format!(
            "its page 1 goes from change {low} to {high} without the file's change {counter}: the log was written by \
             another copy of this database"
        )),
        None => Ok(()),
    }
}

/// Whether the log's committed page-1 images `ones` follow the file's page
/// 1 `first` by the chain every write of this store seals into the header
/// (`crate::tx`: `user_version` a new random number, `application_id` the
/// one it followed): the file's page 1 is one of them (checkpointed up to
/// there), or the first of them followed the file's state (its
/// `application_id` is the file's `user_version`) or kept it (a write that
/// did not seal, its `user_version` the file's). Why not, in words.
fn chained(ones: &[(u32, Vec<u8>)], first: &[u8]) -> Result<(), String> {
    let Some((_, one)) = ones.first() else { return Ok(()) };
    if first.len() < 72 || one.len() < 72 || ones.iter().any(|(_, b)| b.as_slice() == first) {
        return Ok(());
    }
    let (state, followed, kept) = (be32(first, 60), be32(one, 68), be32(one, 60));
    if followed == state || kept == state {
        return Ok(());
    }
    Err(format!(
        "its first transaction followed the database's state {followed:08x}, and the file is at state {state:08x} (the \
         header's user_version, which every write of survey renews): the log was written by another copy of this \
         database"
    ))
}

/// Look at the file at `path` and its log: see the module's documentation.
/// A file too short to have a header, or without SQLite's, is left to the
/// checks that follow.
pub(crate) fn examine(path: &Path) -> std::io::Result<Found> {
    let mut file = std::fs::File::open(path)?;
    let len = file.metadata()?.len();
    let mut first = vec![0u8; 100];
    if len < 100 {
        return Ok(Found::default());
    }
    file.read_exact(&mut first)?;
    let Some(h) = header(&first) else { return Ok(Found::default()) };
    let page_one_len = h.page_size.min(len) as usize;
    first.resize(page_one_len, 0);
    file.read_exact(&mut first[100..])?;
    let wal_file = wal_path(path);
    let wal = match std::fs::read(&wal_file) {
        Ok(bytes) => bytes,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        Err(e) => return Err(e),
    };
    let mut found = Found::default();
    let log = wal_file.display();
    let replay = match replay(&wal, h.page_size) {
        Ok(r) => r,
        Err(why) => {
            found.problems.push(format!(
                "the write-ahead log beside it ({log}) does not belong to it: {why}; the file without that log reads \
                 as of its last checkpoint (move {log} aside to read it so)"
            ));
            return Ok(found);
        }
    };
    found.replays = !replay.commits.is_empty();
    let mut foreign = chained(&replay.page_ones, &first).err().or_else(|| follows(&replay.page_ones, h.counter).err());
    if foreign.is_none()
        && replay.page_ones.is_empty()
        && let (Some(pages), Some(&size)) = (h.pages, replay.commits.iter().find(|&&s| Some(s) != h.pages))
    {
        foreign = Some(format!(
            "it leaves the database at {size} pages without changing page 1, which counts {pages}: the log was \
             written by another copy of this database"
        ));
    }
    if let Some(why) = foreign {
        found.problems.push(format!(
            "the write-ahead log beside it ({log}) does not belong to it: {why}; the file without that log reads as \
             of its last checkpoint (move {log} aside to read it so)"
        ));
        return Ok(found);
    }
    // The length: every page the database has, whole, in the file or the log.
    let whole = len / h.page_size;
    let needed = replay.commits.last().copied().or(h.pages).unwrap_or(len.div_ceil(h.page_size));
    // The page that holds the lock bytes at 1 GiB is never written.
    let pending = (1u64 << 30) / h.page_size + 1;
    let lacking: Vec<u64> = (whole + 1..=needed.max(len.div_ceil(h.page_size)))
        .filter(|p| !replay.pages.contains(p) && *p != pending)
        .collect();
    if let (Some(&from), Some(&to)) = (lacking.first(), lacking.last()) {
        let expected = needed.max(whole + 1) * h.page_size;
        let pages = if from == to { format!("page {from}") } else { format!("pages {from} to {to}") };
        let cut = if len % h.page_size == 0 {
            format!("{}: {} bytes short", pages, expected.saturating_sub(len))
        } else {
            format!("{pages} ({} bytes of page {} are missing)", h.page_size - len % h.page_size, whole + 1)
        };
        let kept = match whole {
            0 => "no page is whole".to_string(),
            1 => "page 1 is whole".to_string(),
            n => format!("pages 1 to {n} are whole"),
        };
        found.problems.push(format!(
            "it is {len} bytes long and its header counts {} pages of {} bytes: it lacks {cut}, cut short (a copy \
             or a disk that stopped); {kept}, what the lost bytes held is gone",
            needed.max(whole + 1),
            h.page_size
        ));
    }
    Ok(found)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A log of `frames` (page, commit size, bytes) with salts `salts`.
    pub(in crate::damage) fn log(page_size: usize, salts: (u32, u32), frames: &[(u32, u32, Vec<u8>)]) -> Vec<u8> {
        let mut out = Vec::new();
        for v in [WAL_MAGIC[1], WAL_FORMAT, page_size as u32, 0, salts.0, salts.1] {
            out.extend(v.to_be_bytes());
        }
        let mut sum = checksum(true, &out, (0, 0));
        out.extend(sum.0.to_be_bytes());
        out.extend(sum.1.to_be_bytes());
        for (page, size, data) in frames {
            let mut head = Vec::new();
            for v in [*page, *size, salts.0, salts.1] {
                head.extend(v.to_be_bytes());
            }
            sum = checksum(true, data, checksum(true, &head[..8], sum));
            head.extend(sum.0.to_be_bytes());
            head.extend(sum.1.to_be_bytes());
            out.extend(head);
            out.extend(data);
        }
        out
    }

    fn page_one(counter: u32, pages: u32) -> Vec<u8> {
        let mut p = vec![0u8; 512];
        p[..16].copy_from_slice(b"SQLite format 3\0");
        p[16..18].copy_from_slice(&512u16.to_be_bytes());
        p[24..28].copy_from_slice(&counter.to_be_bytes());
        p[28..32].copy_from_slice(&pages.to_be_bytes());
        p[92..96].copy_from_slice(&counter.to_be_bytes());
        p
    }

    /// `page_one` sealed at state `now`, having followed `before`.
    fn sealed(counter: u32, pages: u32, before: u32, now: u32) -> Vec<u8> {
        let mut p = page_one(counter, pages);
        p[60..64].copy_from_slice(&now.to_be_bytes());
        p[68..72].copy_from_slice(&before.to_be_bytes());
        p
    }

    #[test]
    fn the_seal_tells_another_copys_log_at_the_same_change_counter() {
        let file = sealed(5, 3, 0x11, 0x22);
        let ones = |v: Vec<Vec<u8>>| v.into_iter().map(|b| (5, b)).collect::<Vec<_>>();
        // The file's own: its first image followed the file's state; or the
        // file is one of them (checkpointed); or a write that did not seal.
        assert!(chained(&ones(vec![sealed(5, 3, 0x22, 0x33), sealed(5, 3, 0x33, 0x44)]), &file).is_ok());
        assert!(chained(&ones(vec![sealed(5, 3, 0x11, 0x22), file.clone(), sealed(5, 3, 0x22, 0x33)]), &file).is_ok());
        assert!(chained(&ones(vec![sealed(5, 3, 0x11, 0x22)]), &file).is_ok());
        assert!(chained(&[], &file).is_ok());
        // Another copy's, parted at 0x11 (both wrote since): the same counter.
        let e = chained(&ones(vec![sealed(5, 3, 0x11, 0x99)]), &file).unwrap_err();
        assert!(e.contains("followed the database's state 00000011") && e.contains("another copy"), "{e}");
        // Unsealed files and logs (written before the seal) read 0: as before.
        assert!(chained(&ones(vec![page_one(6, 3)]), &page_one(5, 3)).is_ok());
    }

    #[test]
    fn a_log_is_read_as_sqlite_recovers_it() {
        let frames = vec![(2, 0, vec![7u8; 512]), (1, 3, page_one(5, 3)), (3, 0, vec![1u8; 512])];
        let wal = log(512, (9, 10), &frames);
        let r = replay(&wal, 512).unwrap();
        // The third frame has no commit after it: not replayed.
        assert_eq!(r.commits, [3]);
        assert_eq!(r.pages.iter().copied().collect::<Vec<_>>(), [1, 2]);
        assert_eq!(r.page_ones.len(), 1);
        // A frame of another salt ends the log; a broken checksum too.
        let mut other = wal.clone();
        other[WAL_HEADER + 8] ^= 1;
        assert!(replay(&other, 512).unwrap().commits.is_empty());
        let mut broken = wal.clone();
        broken[WAL_HEADER + FRAME_HEADER + 100] ^= 1;
        assert!(replay(&broken, 512).unwrap().commits.is_empty());
        let mut header = wal.clone();
        header[14] ^= 1;
        assert!(replay(&header, 512).unwrap_err().contains("checksum"));
        assert!(replay(&wal, 1024).unwrap_err().contains("another database"));
        assert!(replay(&wal[..20], 512).is_err());
        assert!(replay(&[], 512).unwrap().commits.is_empty());
    }

    #[test]
    fn page_one_s_counter_tells_whose_log_it_is() {
        let ones = |c: &[u32]| c.iter().map(|&c| (c, page_one(c, 3))).collect::<Vec<_>>();
        // Restarted after the file's checkpoint, or checkpointed up to it.
        assert!(follows(&ones(&[6, 7]), 5).is_ok());
        assert!(follows(&ones(&[4, 5, 6]), 5).is_ok());
        assert!(follows(&[], 5).is_ok());
        // Older than the file; a gap where the file's transaction should be.
        assert!(follows(&ones(&[3, 4]), 5).unwrap_err().contains("newer"));
        // The file's counter with other bytes is left to the check of the
        // file as the log makes it: in WAL mode SQLite need not count every
        // transaction, so such a log may be the file's own.
        let mut other = page_one(5, 3);
        other[200] = 1;
        assert!(follows(&[(5, other)], 5).is_ok());
        assert!(follows(&[(4, page_one(4, 3)), (6, page_one(6, 3))], 5).unwrap_err().contains("another copy"));
    }

    #[test]
    fn a_file_cut_short_is_named_with_what_it_lacks() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.db");
        let mut bytes = page_one(5, 3);
        bytes.extend(vec![0u8; 1024]);
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(examine(&path).unwrap(), Found::default());
        for cut in [1, 100, 511, 512, 1000] {
            std::fs::write(&path, &bytes[..bytes.len() - cut]).unwrap();
            let found = examine(&path).unwrap();
            assert_eq!(found.problems.len(), 1, "{cut}: {found:?}");
            assert!(found.problems[0].contains("its header counts 3 pages of 512 bytes"), "{:?}", found.problems);
        }
        // The page the file lacks is in its log (a checkpoint cut short).
        std::fs::write(&path, &bytes[..1024]).unwrap();
        std::fs::write(wal_path(&path), log(512, (1, 2), &[(3, 3, vec![0u8; 512])])).unwrap();
        let found = examine(&path).unwrap();
        assert!(found.problems.is_empty() && found.replays, "{found:?}");
        // A log that leaves the database at another size without page 1.
        std::fs::write(&path, &bytes).unwrap();
        std::fs::write(wal_path(&path), log(512, (1, 2), &[(3, 4, vec![0u8; 512])])).unwrap();
        assert!(examine(&path).unwrap().problems[0].contains("another copy"));
    }
}
