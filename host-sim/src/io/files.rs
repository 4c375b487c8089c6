//! Files read and written with errors that name the path.
//!
//! Every error reads `PATH: what went wrong`, the form the command line has
//! always printed.

use std::path::{Path, PathBuf};

/// A file or directory operation that failed, with the path it concerned.
#[derive(Debug, thiserror::Error)]
#[error("{}: {error}", path.display())]
pub struct PathError {
    /// The file or directory.
    pub path: PathBuf,
    /// What went wrong (shown, not chained: the message carries it).
    pub error: std::io::Error,
}

impl PathError {
    /// The error `error` concerning `path`.
    pub fn new(path: &Path, error: std::io::Error) -> Self {
        Self {
            path: path.to_path_buf(),
            error,
        }
    }
}

/// Write `contents` to the file `path` (created or truncated).
pub fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<(), PathError> {
    std::fs::write(path, contents).map_err(|e| PathError::new(path, e))
}

/// Read the file `path` as UTF-8 text.
pub fn read_to_string(path: &Path) -> Result<String, PathError> {
    std::fs::read_to_string(path).map_err(|e| PathError::new(path, e))
}

/// Create the directory `path` and its parents.
pub fn create_dir_all(path: &Path) -> Result<(), PathError> {
    std::fs::create_dir_all(path).map_err(|e| PathError::new(path, e))
}

/// Create (or truncate) the file `path` for writing.
pub fn create(path: &Path) -> Result<std::fs::File, PathError> {
    std::fs::File::create(path).map_err(|e| PathError::new(path, e))
}
