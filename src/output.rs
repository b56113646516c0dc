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
    remove_stale_temps(dest);
    let tmp = temp_path(dest);
    let werr = |source: io::Error| Error::Write {
        path: dest.to_path_buf(),
        source,
    };
    let result = (|| {
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(werr)?;
        let mut w = BufWriter::with_capacity(256 * 1024, file);
        let value = write(&mut w)?;
        let file = w.into_inner().map_err(|e| werr(e.into_error()))?;
        file.sync_all().map_err(werr)?;
        // Keep the original's permissions when replacing it.
        if let Ok(meta) = fs::metadata(dest) {
            let _ = fs::set_permissions(&tmp, meta.permissions());
        }
        fs::rename(&tmp, dest).map_err(werr)?;
        Ok(value)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}
