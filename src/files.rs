//! Files in and out, trusting nothing. Inputs are read only from regular files and only up to a
//! documented size ([`TEXT_LIMIT_BYTES`], [`DATA_LIMIT_BYTES`]): a part symlinked to `/dev/zero`,
//! a FIFO named `*.stl` or a folder is refused by name before it is opened. Outputs are written
//! whole or not at all, through a temporary file and a rename, so that an interrupted run (or
//! concurrent shards) never leaves a half-written file behind; and only over a regular file or
//! a new path, never over a device, FIFO, socket, folder or symbolic link, which the rename would
//! replace.

use crate::error::{Error, Result};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// Largest text input read, bytes: scenarios, URDF, MJCF and assembly files, baselines, a
/// campaign's `campaign.json` (64 MiB).
pub const TEXT_LIMIT_BYTES: u64 = 64 << 20;
/// Largest data input read, bytes: meshes and manifold files (1 GiB).
pub const DATA_LIMIT_BYTES: u64 = 1 << 30;

/// What a path that is not a regular file is, in words (`None`: a regular file).
fn not_regular(meta: &std::fs::Metadata) -> Option<&'static str> {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    match () {
        _ if t.is_file() => None,
        _ if t.is_dir() => Some("a folder"),
        _ if t.is_symlink() => Some("a symbolic link"),
        _ if t.is_fifo() => Some("a FIFO"),
        _ if t.is_socket() => Some("a socket"),
        _ if t.is_char_device() || t.is_block_device() => Some("a device"),
        _ => Some("not a regular file"),
    }
}

/// Opens `path` for reading if it is a regular file (after symbolic links) of at most `limit`
/// bytes; returns it with its size.
pub fn open_input(path: &Path, limit: u64) -> Result<(std::fs::File, u64)> {
    let meta =
        std::fs::metadata(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    if let Some(what) = not_regular(&meta) {
        return Err(Error::file(
            path,
            format!("is {what}: expected a regular file"),
        ));
    }
    if meta.len() > limit {
        return Err(Error::file(
            path,
            format!(
                "is {} bytes: expected at most {limit} bytes (pegtwin's limit for this kind of file)",
                meta.len()
            ),
        ));
    }
    let file =
        std::fs::File::open(path).map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    Ok((file, meta.len()))
}

/// Reads the regular file `path` whole, at most `limit` bytes (a file that grows past it while
/// read is refused too).
pub fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let (file, len) = open_input(path, limit)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
    if bytes.len() as u64 > limit {
        return Err(Error::file(
            path,
            format!("grew past {limit} bytes while read: expected a file at rest"),
        ));
    }
    Ok(bytes)
}

/// Reads the regular text file `path` whole, at most [`TEXT_LIMIT_BYTES`].
pub fn read_text(path: &Path) -> Result<String> {
    String::from_utf8(read_input(path, TEXT_LIMIT_BYTES)?).map_err(|e| {
        Error::file(
            path,
            format!(
                "is not UTF-8 text (byte {}): expected a text file",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Refuses an output path that exists and is not a regular file: writing it by renaming a new
/// file over it would replace a device, FIFO, socket or link (as root, `/dev/null` itself).
pub fn ensure_replaceable(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(meta) => match not_regular(&meta) {
            Some(what) => Err(Error::file(
                path,
                format!(
                    "is {what}: pegtwin writes only regular files, replacing them whole \
                     (give the path of a regular file or a new one)"
                ),
            )),
            None => Ok(()),
        },
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::file(path, format!("cannot write: {e}"))),
    }
}

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
    ensure_replaceable(path)?;
    let tmp = path.with_file_name(format!(
        ".{}.{}.partial",
        name.to_string_lossy(),
        writer_tag()
    ));
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

/// A name for one write of this process, unique among the writers that may share a folder:
/// the host, the process and a count of the process's writes. Writers of the same file (two
/// shards of a job array caching one manifold on a shared file system) each fill their own
/// temporary file, and each rename replaces the file whole: a reader sees one writer's file,
/// never a mix.
fn writer_tag() -> String {
    static HOST: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let host = HOST.get_or_init(|| {
        let name = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let name: String = (name.trim().chars())
            .filter(|c| c.is_ascii_alphanumeric() || *c == '-')
            .take(64)
            .collect();
        if name.is_empty() { "host".into() } else { name }
    });
    let n = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    format!("{host}-{}-{n}", std::process::id())
}

/// Checks before a long run that `path` can be written later: its folder exists and takes a
/// file, and the path is not a folder. Leaves nothing behind.
pub fn ensure_writable(path: &Path) -> Result<()> {
    if path.is_dir() {
        return Err(Error::file(path, "is a folder: expected a file path"));
    }
    ensure_replaceable(path)?;
    let name = path
        .file_name()
        .ok_or_else(|| Error::file(path, "is not a file path"))?;
    let probe = path.with_file_name(format!(
        ".{}.{}.probe",
        name.to_string_lossy(),
        writer_tag()
    ));
    std::fs::write(&probe, b"")
        .and_then(|()| std::fs::remove_file(&probe))
        .map_err(|e| Error::file(path, format!("cannot write: {e}")))
}

/// The cache folder every command and the Python package use: `given` (`--cache-dir`), else
/// `$XDG_CACHE_HOME/pegtwin`, else `~/.cache/pegtwin`.
pub fn cache_folder(given: Option<&Path>) -> Result<PathBuf> {
    if let Some(d) = given {
        return Ok(d.to_path_buf());
    }
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|v| !v.is_empty()) {
        return Ok(Path::new(&x).join("pegtwin"));
    }
    std::env::var_os("HOME")
        .map(|h| Path::new(&h).join(".cache").join("pegtwin"))
        .ok_or_else(|| {
            Error::Input("no cache folder: set --cache-dir, XDG_CACHE_HOME or HOME".into())
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writers racing to one file (shards caching one manifold) leave one writer's bytes whole
    /// and no temporary file.
    #[test]
    fn racing_writers_leave_one_whole_file() {
        let dir = std::env::temp_dir().join(format!("pegtwin-race-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.manifold");
        let contents: Vec<Vec<u8>> = (0..8u8).map(|i| vec![i; 1 << 20]).collect();
        std::thread::scope(|s| {
            for bytes in &contents {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..4 {
                        write_atomically(path, bytes).unwrap();
                    }
                });
            }
        });
        let written = std::fs::read(&path).unwrap();
        assert!(contents.contains(&written), "a mix of writers' bytes");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("m.manifold")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
