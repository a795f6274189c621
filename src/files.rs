//! Output files are written whole or not at all: through a temporary file and a rename, so that
//! an interrupted run (or concurrent shards) never leaves a half-written file behind.

use crate::error::{Error, Result};
use std::io::Write;
use std::path::Path;

/// Write `bytes` to `path` through a temporary file and a rename.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically_with(path, |w| w.write_all(bytes))
}

/// Write `path` through a temporary file and a rename, streaming: `fill` writes the content into
/// a buffered writer, so a large file is never held in memory whole.
pub fn write_atomically_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let name = path
        .file_name()
        .ok_or_else(|| Error::file(path, "is not a file path"))?;
    let tmp = path.with_file_name(format!(".{}.partial", name.to_string_lossy()));
    let io = |e: std::io::Error| Error::file(path, format!("cannot write: {e}"));
    let written = std::fs::File::create(&tmp).and_then(|f| {
        let mut w = std::io::BufWriter::new(f);
        fill(&mut w)?;
        w.flush()
    });
    written
        .and_then(|()| std::fs::rename(&tmp, path))
        .map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io(e)
        })
}

/// Checks before a long run that `path` can be written later: its folder exists and takes a
/// file, and the path is not a folder. Leaves nothing behind.
pub fn ensure_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::file(path, "is a folder: expected a file path"));
    }
    let name = path
        .file_name()
        .ok_or_else(|| Error::file(path, "is not a file path"))?;
    let probe = path.with_file_name(format!(".{}.probe", name.to_string_lossy()));
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| Error::file(path, format!("cannot write: {e}")))
}
