//! Output files are written whole or not at all: through a temporary file and a rename, so that
//! an interrupted run (or concurrent shards) never leaves a half-written file behind.

use crate::error::{Error, Result};
use std::path::Path;

/// Write `bytes` to `path` through a temporary file and a rename.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::file(path, "is not a file path"))?;
    let tmp = path.with_file_name(format!(".{}.partial", name.to_string_lossy()));
    let io = |e: std::io::Error| Error::file(path, format!("cannot write: {e}"));
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        io(e)
    })
}
