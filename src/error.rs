//! The library's one error type. Every variant renders as a message a user can act on,
//! because the slicer shows it verbatim when a post-processing script fails.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path} is not G-code: {reason}")]
    NotGcode { path: PathBuf, reason: String },
    #[error("cannot write {path}: {source}{}", write_hint(source))]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A value or combination the user gave (flag, setting, glob) that cannot be used.
    #[error("{0}")]
    Invalid(String),
    /// Input this command cannot handle, with the reason and what to do.
    #[error("{0}")]
    Refused(String),
    /// A binary G-code file that cannot be read.
    #[error("{path}: {source}")]
    Bgcode {
        path: PathBuf,
        source: crate::bgcode::BgcodeError,
    },
}

pub type Result<T> = std::result::Result<T, Error>;

/// What to do about a failed write, by its cause.
fn write_hint(e: &std::io::Error) -> &'static str {
    use std::io::ErrorKind as K;
    match e.kind() {
        K::NotFound => "; the folder does not exist: create it or write elsewhere",
        K::PermissionDenied => "; write to a folder you may write to",
        K::ReadOnlyFilesystem => "; the disk is read-only: write elsewhere",
        K::StorageFull | K::QuotaExceeded => "; the disk is full: free space and run again",
        _ => "",
    }
}
