//! Writing a file without ever losing the user's print.
//!
//! Input: a destination path and a closure that writes the content. Output: the destination
//! replaced atomically: the content goes to a temporary file in the same folder, is flushed
//! and fsync'ed, then renamed over the destination. On any error the temporary file is
//! removed and the destination is untouched.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Temporary files are named `.NAME.poa-tmp-PID` beside the destination.
pub fn temp_path(dest: &Path) -> PathBuf {
    let name = dest
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "out".into());
    let tmp = format!(".{name}.poa-tmp-{}", std::process::id());
    match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.join(tmp),
        _ => PathBuf::from(tmp),
    }
}

/// Removes temporary files a killed run left beside `dest`.
pub fn remove_stale_temps(dest: &Path) {
    let Some(name) = dest.file_name().map(|n| n.to_string_lossy().to_string()) else {
        return;
    };
    let dir = match dest.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let prefix = format!(".{name}.poa-tmp-");
    if let Ok(entries) = fs::read_dir(&dir) {
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().starts_with(&prefix) {
                let _ = fs::remove_file(e.path());
            }
        }
    }
}

/// Writes `dest` atomically with what `write` produces.
pub fn write_atomic<T>(
    dest: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<T>,
) -> Result<T> {
    write_atomic_twice(dest, write, |_| false, |_, _, _| Ok(()))
}

/// [`write_atomic`] with an optional second pass over what the first wrote (numbers that
/// depend on the whole file): when `again` says so, `rewrite` reads the first temporary file
/// and writes a second, which alone is synced and renamed. The destination is replaced once.
pub fn write_atomic_twice<T>(
    dest: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<T>,
    again: impl FnOnce(&T) -> bool,
    rewrite: impl FnOnce(&T, File, &mut BufWriter<File>) -> Result<()>,
) -> Result<T> {
    remove_stale_temps(dest);
    let first = temp_path(dest);
    // Same prefix: a killed run's second file is cleaned up like the first.
    let mut second = first.clone().into_os_string();
    second.push(".2");
    let second = PathBuf::from(second);
    let werr = |source: io::Error| Error::Write {
        path: dest.to_path_buf(),
        source,
    };
    let create = |path: &Path| -> Result<BufWriter<File>> {
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(werr)?;
        Ok(BufWriter::with_capacity(256 * 1024, file))
    };
    let result = (|| {
        let mut w = create(&first)?;
        let value = write(&mut w)?;
        let mut file = w.into_inner().map_err(|e| werr(e.into_error()))?;
        let mut done = &first;
        if again(&value) {
            drop(file);
            let written = File::open(&first).map_err(werr)?;
            let mut w = create(&second)?;
            rewrite(&value, written, &mut w)?;
            file = w.into_inner().map_err(|e| werr(e.into_error()))?;
            done = &second;
        }
        file.sync_all().map_err(werr)?;
        // Keep the original's permissions when replacing it.
        if let Ok(meta) = fs::metadata(dest) {
            let _ = fs::set_permissions(done, meta.permissions());
        }
        fs::rename(done, dest).map_err(werr)?;
        Ok(value)
    })();
    let _ = fs::remove_file(&first);
    let _ = fs::remove_file(&second);
    result
}
