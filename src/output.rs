//! Writing a file without ever losing the user's print.
//!
//! Input: a destination path, the paths of the run's inputs, and a closure that writes the
//! content. Output: the destination holding exactly what the closure wrote, or, on any error,
//! the destination as it was and no file left behind.
//!
//! Invariants:
//! - a destination that is one of the inputs (under any name: the same device and inode, so
//!   hard links and symlinks count) is refused before anything is written;
//! - a regular destination (or a new one) is replaced atomically: the content goes to a
//!   temporary file beside it, created with `O_EXCL` under a name no other run can pick
//!   (process id and a random suffix), is fsync'ed, then renamed over it; a symlink to a
//!   regular file keeps being a link (the file it points to is replaced);
//! - a destination that is not a regular file (`/dev/null`, a terminal, a FIFO) is written
//!   through and never renamed over or removed;
//! - a temporary file is removed only by the run that made it (also when the run is stopped by
//!   SIGINT, SIGTERM or SIGHUP: [`remove_temps_on_signals`]), or later when the process that
//!   made it is gone (SIGKILL); a run never removes another live run's file.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Marks poa's temporary files: `.NAME.poa-tmp-PID-RANDOM`.
const TEMP_MARK: &str = ".poa-tmp-";
/// Longest part of the destination's name kept in a temporary name: file names are at most
/// 255 bytes, and the mark, a process id and the random suffix need room.
const NAME_BYTES: usize = 200;

/// A file's identity: the same for every name (hard link, symlink, relative path) of one file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FileId {
    dev: u64,
    ino: u64,
}

impl FileId {
    /// The identity of the file `path` names (following symlinks), if it exists.
    pub fn of(path: &Path) -> Option<FileId> {
        use std::os::unix::fs::MetadataExt;
        fs::metadata(path).ok().map(|m| FileId {
            dev: m.dev(),
            ino: m.ino(),
        })
    }
}

/// Whether `a` and `b` name the same existing file.
pub fn same_file(a: &Path, b: &Path) -> bool {
    matches!((FileId::of(a), FileId::of(b)), (Some(x), Some(y)) if x == y)
}

/// Refuses a destination that is one of `inputs`.
pub fn check_not_input(dest: &Path, inputs: &[&Path]) -> Result<()> {
    if let Some(input) = inputs.iter().find(|i| same_file(dest, i)) {
        let same = if dest == *input {
            String::new()
        } else {
            format!(" ({} under another name)", input.display())
        };
        return Err(Error::Invalid(format!(
            "refusing to write {}: it is an input of this run{same}; choose another output file",
            dest.display()
        )));
    }
    Ok(())
}

/// Where the content goes.
enum Target {
    /// A regular or new file, replaced by renaming a temporary file over it.
    Replace(PathBuf),
    /// A device, FIFO or terminal: written through, never renamed over.
    Through(PathBuf),
}

fn target(dest: &Path, inputs: &[&Path]) -> Result<Target> {
    check_not_input(dest, inputs)?;
    match fs::metadata(dest) {
        Ok(meta) if meta.is_dir() => Err(Error::Invalid(format!(
            "cannot write {}: it is a folder; give a file name",
            dest.display()
        ))),
        Ok(meta) if !meta.is_file() => Ok(Target::Through(dest.to_path_buf())),
        // A symlink stays a link: the file it points to is what gets replaced.
        Ok(_) => Ok(Target::Replace(
            fs::canonicalize(dest).unwrap_or_else(|_| dest.to_path_buf()),
        )),
        // A link to nothing yet stays a link too: the file it names is created.
        Err(_) => Ok(Target::Replace(link_target(dest))),
    }
}

/// Where `dest` leads when it is a symbolic link to a file that does not exist yet (links
/// followed up to 40 deep, relative ones from their own folder); `dest` itself otherwise.
fn link_target(dest: &Path) -> PathBuf {
    let mut at = dest.to_path_buf();
    for _ in 0..40 {
        let is_link = fs::symlink_metadata(&at).is_ok_and(|m| m.file_type().is_symlink());
        let Some(next) = is_link.then(|| fs::read_link(&at).ok()).flatten() else {
            return at;
        };
        at = if next.is_absolute() {
            next
        } else {
            dir_of(&at).join(next)
        };
    }
    dest.to_path_buf()
}

fn dir_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// `.NAME.poa-tmp-`, with NAME cut to [`NAME_BYTES`] on a character boundary.
fn temp_prefix(dest: &Path) -> String {
    let name = dest
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "out".into());
    let mut cut = name.len().min(NAME_BYTES);
    while !name.is_char_boundary(cut) {
        cut -= 1;
    }
    format!(".{}{TEMP_MARK}", &name[..cut])
}

fn random_suffix() -> u64 {
    use std::hash::BuildHasher;
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    // RandomState is seeded from the OS per process: different in every run.
    std::collections::hash_map::RandomState::new().hash_one((n, now, std::process::id()))
}

/// The temporary files this process has open, for [`remove_temps_on_signals`].
static LIVE_TEMPS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn forget_temp(path: &Path) {
    if let Ok(mut v) = LIVE_TEMPS.lock() {
        v.retain(|p| p != path);
    }
}

/// Removes this process's temporary files when it is interrupted (SIGINT from Ctrl-C,
/// SIGTERM, SIGHUP), then lets the signal end it as it would have: a slicer or a user that
/// stops a run leaves no `.NAME.poa-tmp-*` beside their file. (SIGKILL cannot be caught: the
/// next run removes what a killed one left.) Call first in `main`, before any thread starts:
/// the signals are blocked in every thread but one that waits for them.
pub fn remove_temps_on_signals() {
    #[cfg(unix)]
    // SAFETY: plain libc signal-mask calls on a zeroed, initialised sigset_t; the waiting
    // thread runs ordinary code (not a signal handler), so it may lock and unlink.
    unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for s in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            libc::sigaddset(&mut set, s);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        let spawned = std::thread::Builder::new()
            .name("poa-signals".into())
            .spawn(move || {
                let mut sig: libc::c_int = 0;
                if libc::sigwait(&set, &mut sig) != 0 {
                    return;
                }
                // The list stays locked until the signal ends the process: no temporary file
                // is made (or left) between the removal and the end.
                let held = LIVE_TEMPS.lock();
                if let Ok(v) = &held {
                    for p in v.iter() {
                        let _ = fs::remove_file(p);
                    }
                }
                libc::signal(sig, libc::SIG_DFL);
                let mut one: libc::sigset_t = std::mem::zeroed();
                libc::sigemptyset(&mut one);
                libc::sigaddset(&mut one, sig);
                libc::pthread_sigmask(libc::SIG_UNBLOCK, &one, std::ptr::null_mut());
                libc::raise(sig);
            });
        if spawned.is_err() {
            libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut());
        }
    }
}

/// A temporary file this run owns: removed on drop unless it was renamed into place.
struct Temp {
    path: PathBuf,
    live: bool,
}

impl Temp {
    /// Creates a fresh temporary file in `dir` for `dest`, never reusing an existing name.
    fn create(dir: &Path, dest: &Path) -> io::Result<(Temp, File)> {
        let prefix = temp_prefix(dest);
        let mut last = None;
        for _ in 0..16 {
            let path = dir.join(format!(
                "{prefix}{}-{:016x}",
                std::process::id(),
                random_suffix()
            ));
            // Made and listed under the lock, so that a signal never finds the file made
            // but not yet listed (it was left behind when one came in between).
            let mut live = LIVE_TEMPS.lock();
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(f) => {
                    if let Ok(v) = &mut live {
                        v.push(path.clone());
                    }
                    return Ok((Temp { path, live: true }, f));
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or_else(|| io::Error::other("no free temporary name")))
    }

    fn keep(mut self) {
        self.live = false;
        forget_temp(&self.path);
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        if self.live {
            let _ = fs::remove_file(&self.path);
            forget_temp(&self.path);
        }
    }
}

fn process_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return false;
    }
    // SAFETY: signal 0 only asks whether the process exists; nothing is sent.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Removes temporary files that runs which no longer exist left beside `dest` (killed, or cut
/// off by a power loss). Files of live runs are left alone.
pub fn remove_stale_temps(dest: &Path) {
    let prefix = temp_prefix(dest);
    let Ok(entries) = fs::read_dir(dir_of(dest)) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let name = name.to_string_lossy();
        let Some(rest) = name.strip_prefix(&prefix) else {
            continue;
        };
        let pid: String = rest.chars().take_while(char::is_ascii_digit).collect();
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        let regular = e.file_type().is_ok_and(|t| t.is_file());
        if regular && !process_alive(pid) {
            let _ = fs::remove_file(e.path());
        }
    }
}

/// Writes `dest` atomically with what `write` produces.
pub fn write_atomic<T>(
    dest: &Path,
    inputs: &[&Path],
    write: impl FnOnce(&mut BufWriter<Writeback>) -> Result<T>,
) -> Result<T> {
    write_atomic_twice(dest, inputs, write, |_| false, |_, _, _| Ok(()))
}

/// A file being written that asks the kernel every [`KICK_BYTES`] to start writing back what
/// it was given, when it is the file to be synced: the disk then writes while the rest is
/// made, and the fsync at the end waits for the last few megabytes only (a 25 MB rewrite:
/// 12 ms of fsync after the last byte). A hint; nothing depends on it.
pub struct Writeback {
    file: File,
    kick: bool,
    written: u64,
    kicked: u64,
}

const KICK_BYTES: u64 = 4 << 20;

impl Writeback {
    fn new(file: File, kick: bool) -> Writeback {
        Writeback {
            file,
            kick,
            written: 0,
            kicked: 0,
        }
    }
}

impl Write for Writeback {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.file.write(buf)?;
        self.written += n as u64;
        if self.kick && self.written - self.kicked >= KICK_BYTES {
            start_writeback(&self.file, self.kicked, self.written - self.kicked);
            self.kicked = self.written;
        }
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.flush()
    }
}

/// Asks the kernel to start writing back `len` bytes of `file` from `from` (a hint; no wait).
#[cfg(target_os = "linux")]
pub(crate) fn start_writeback(file: &File, from: u64, len: u64) {
    use std::os::fd::AsRawFd;
    let (Ok(from), Ok(len)) = (i64::try_from(from), i64::try_from(len)) else {
        return;
    };
    // SAFETY: a plain system call on a descriptor `file` keeps open; it only starts the
    // writeback of the range's dirty pages (no wait, no effect on the content).
    unsafe {
        libc::sync_file_range(file.as_raw_fd(), from, len, libc::SYNC_FILE_RANGE_WRITE);
    }
}

#[cfg(not(target_os = "linux"))]
pub(crate) fn start_writeback(_: &File, _: u64, _: u64) {}

/// Writes `bytes` to `dest` atomically.
pub fn write_bytes(dest: &Path, inputs: &[&Path], bytes: &[u8]) -> Result<()> {
    write_atomic(dest, inputs, |w| {
        w.write_all(bytes).map_err(|source| Error::Write {
            path: dest.to_path_buf(),
            source,
        })
    })
}

/// Syncs `file` (the temporary file `done`) and renames it over `real`, in folder `dir`.
fn install(file: File, done: Temp, real: &Path, dir: &Path) -> io::Result<()> {
    file.sync_all()?;
    // Keep the original's permissions when replacing it, and its owner where this process
    // may set it (run as root, the file stayed the user's, not root's).
    if let Ok(meta) = fs::metadata(real) {
        let _ = fs::set_permissions(&done.path, meta.permissions());
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let _ = std::os::unix::fs::chown(&done.path, Some(meta.uid()), Some(meta.gid()));
        }
    }
    fs::rename(&done.path, real)?;
    done.keep();
    // The rename itself reaches the disk with the folder.
    if let Ok(d) = File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Whether writing `dest` replaces a regular (or new) file by renaming one over it, rather
/// than writing through to a device or FIFO. Refuses a destination that is an input or a
/// folder.
pub fn replaces_file(dest: &Path, inputs: &[&Path]) -> Result<bool> {
    Ok(matches!(target(dest, inputs)?, Target::Replace(_)))
}

/// Writes `dest`, a regular or new file ([`replaces_file`]), atomically: `write` fills the
/// open, empty temporary file at whatever offsets it likes (several threads may write at
/// once), which is then synced and renamed over `dest`.
pub fn write_atomic_at<T>(
    dest: &Path,
    inputs: &[&Path],
    write: impl FnOnce(&File) -> Result<T>,
) -> Result<T> {
    let werr = |source: io::Error| Error::Write {
        path: dest.to_path_buf(),
        source,
    };
    let Target::Replace(real) = target(dest, inputs)? else {
        return Err(Error::Invalid(format!(
            "{} is not a regular file to replace",
            dest.display()
        )));
    };
    remove_stale_temps(&real);
    let dir = dir_of(&real);
    let (done, file) = Temp::create(&dir, &real).map_err(werr)?;
    let value = write(&file)?;
    install(file, done, &real, &dir).map_err(werr)?;
    Ok(value)
}

/// [`write_atomic`] with an optional second pass over what the first wrote (numbers that
/// depend on the whole file): when `again` says so, `rewrite` reads the first temporary file
/// and writes a second, which alone is synced and renamed. The destination is replaced once.
pub fn write_atomic_twice<T>(
    dest: &Path,
    inputs: &[&Path],
    write: impl FnOnce(&mut BufWriter<Writeback>) -> Result<T>,
    again: impl FnOnce(&T) -> bool,
    rewrite: impl FnOnce(&T, File, &mut BufWriter<Writeback>) -> Result<()>,
) -> Result<T> {
    let werr = |source: io::Error| Error::Write {
        path: dest.to_path_buf(),
        source,
    };
    let finish = |w: BufWriter<Writeback>| {
        w.into_inner()
            .map(|w| w.file)
            .map_err(|e| werr(e.into_error()))
    };
    match target(dest, inputs)? {
        Target::Replace(real) => {
            remove_stale_temps(&real);
            let dir = dir_of(&real);
            let (first, file) = Temp::create(&dir, &real).map_err(werr)?;
            // Not kicked: whether it is the file kept is known only once it is written (a
            // second pass deletes it, and its pages need never reach the disk).
            let mut w = BufWriter::with_capacity(256 * 1024, Writeback::new(file, false));
            let value = write(&mut w)?;
            let mut file = finish(w)?;
            let mut done = first;
            if again(&value) {
                drop(file);
                let written = File::open(&done.path).map_err(werr)?;
                let (second, f2) = Temp::create(&dir, &real).map_err(werr)?;
                let mut w = BufWriter::with_capacity(256 * 1024, Writeback::new(f2, true));
                rewrite(&value, written, &mut w)?;
                file = finish(w)?;
                // The first file goes before the rename: a kill in between leaves one file,
                // which the next run removes once this process is gone.
                done = second;
            }
            install(file, done, &real, &dir).map_err(werr)?;
            Ok(value)
        }
        Target::Through(path) => {
            // The content is made in full before the device is opened (a failed run writes
            // nothing to it): first into a temporary file in the system's temporary folder.
            let (tmp, file) = Temp::create(&std::env::temp_dir(), &path).map_err(werr)?;
            let mut w = BufWriter::with_capacity(256 * 1024, Writeback::new(file, false));
            let value = write(&mut w)?;
            finish(w)?;
            let mut written = File::open(&tmp.path).map_err(werr)?;
            let device = OpenOptions::new().write(true).open(&path).map_err(werr)?;
            let mut out = BufWriter::with_capacity(256 * 1024, Writeback::new(device, false));
            if again(&value) {
                rewrite(&value, written, &mut out)?;
            } else {
                io::copy(&mut written, &mut out).map_err(werr)?;
            }
            out.flush().map_err(werr)?;
            Ok(value)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kicked_file_holds_exactly_what_was_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.gcode");
        let data: Vec<u8> = (0..10_000_000u32).map(|i| (i % 251) as u8).collect();
        let mut w = BufWriter::with_capacity(
            256 * 1024,
            Writeback::new(File::create(&path).unwrap(), true),
        );
        for chunk in data.chunks(77_777) {
            w.write_all(chunk).unwrap();
        }
        let wb = w.into_inner().map_err(|e| e.into_error()).unwrap();
        // Every full 4 MB handed to the kernel was kicked; the tail waits for the fsync.
        assert_eq!(wb.written, data.len() as u64);
        assert!(wb.kicked >= 2 * KICK_BYTES && wb.written - wb.kicked < KICK_BYTES + 256 * 1024);
        wb.file.sync_all().unwrap();
        assert_eq!(fs::read(&path).unwrap(), data);
    }
}
