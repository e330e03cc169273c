//! A file that could not be read or written: its path, the I/O error, and the
//! message its owner gives (what the file is and how to fix it). Every layer
//! that reads or writes a file wraps this one, so a caller can tell an
//! unreadable file from a bad value and still print the owner's wording.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

#[derive(Debug)]
pub struct FileError {
    /// The file (or folder) that could not be read, written or created.
    pub path: PathBuf,
    source: io::Error,
    /// The whole message shown to the user (it names the path and the fix).
    message: String,
}

impl FileError {
    pub fn new(path: &Path, source: io::Error, message: String) -> FileError {
        FileError {
            path: path.to_path_buf(),
            source,
            message,
        }
    }

    /// The I/O error's kind (not found, permission denied, ...).
    pub fn kind(&self) -> io::ErrorKind {
        self.source.kind()
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for FileError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}
