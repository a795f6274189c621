//! An append-only journal: JSON lines under a header line, one per piece of work finished, so
//! that a long search resumes after a kill where it was (`pegtwin tune --resume`). Each entry is
//! written whole and flushed as it is finished; a last line cut short by a kill is dropped on
//! resume, and the work it stood for runs again.

use crate::error::{Error, Result};
use serde_json::Value;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// A journal file open for appending.
pub struct Journal {
    path: PathBuf,
    file: Mutex<std::fs::File>,
}

impl Journal {
    /// Opens the journal `path` of the work `header` describes: a new one (with `resume`, also
    /// when there is none yet), or with `resume` the one there, which must have been started
    /// for the same `header`. Returns it with the entries it holds.
    pub fn open(path: &Path, header: &Value, resume: bool) -> Result<(Journal, Vec<Value>)> {
        let (entries, keep) = if resume && path.is_file() {
            read_entries(path, header)?
        } else {
            if path.exists() {
                return Err(Error::file(
                    path,
                    "exists: pass --resume to go on with it, or choose another --out",
                ));
            }
            let mut first = serde_json::to_vec(header).expect("a header serialises");
            first.push(b'\n');
            crate::files::write_atomically(path, &first)?;
            (Vec::new(), first.len() as u64)
        };
        let io = |e: std::io::Error| Error::file(path, format!("cannot write: {e}"));
        let file = std::fs::OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(io)?;
        // Drop a last line a kill cut short, so the next entry starts a line of its own.
        file.set_len(keep).map_err(io)?;
        let journal = Journal {
            path: path.to_path_buf(),
            file: Mutex::new(file),
        };
        Ok((journal, entries))
    }

    /// Appends `entry` as one line and flushes it to the file.
    pub fn append(&self, entry: &Value) -> Result<()> {
        let mut line = serde_json::to_vec(entry).expect("an entry serialises");
        line.push(b'\n');
        let mut file = self.file.lock().expect("no writer panicked");
        file.write_all(&line)
            .and_then(|()| file.flush())
            .map_err(|e| Error::file(&self.path, format!("cannot write: {e}")))
    }
}

/// The entries of the journal `path` after its header, which must be `header`, and the length
/// of its whole lines, bytes.
fn read_entries(path: &Path, header: &Value) -> Result<(Vec<Value>, u64)> {
    let bytes = crate::files::read_input(path, crate::files::TEXT_LIMIT_BYTES)?;
    let mut lines = bytes.split_inclusive(|&b| b == b'\n');
    let first = lines.next().unwrap_or_default();
    let found: Option<Value> = serde_json::from_slice(first).ok();
    if found.as_ref() != Some(header) {
        return Err(Error::file(
            path,
            format!(
                "was started for other work ({}): this is {}; choose another --out",
                found.map_or("no header".into(), |v| v.to_string()),
                header
            ),
        ));
    }
    let mut keep = first.len() as u64;
    let mut entries = Vec::new();
    for line in lines {
        let whole = line.ends_with(b"\n");
        match serde_json::from_slice::<Value>(line) {
            Ok(v) if whole => {
                entries.push(v);
                keep += line.len() as u64;
            }
            _ => break,
        }
    }
    Ok((entries, keep))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn a_cut_line_is_dropped_and_another_header_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("j.jsonl");
        let header = json!({"work": 1});
        let (j, known) = Journal::open(&path, &header, false).unwrap();
        assert!(known.is_empty());
        j.append(&json!({"a": 1})).unwrap();
        drop(j);
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("{\"a\": 2");
        std::fs::write(&path, text).unwrap();
        assert!(Journal::open(&path, &header, false).is_err(), "exists");
        let (j, known) = Journal::open(&path, &header, true).unwrap();
        assert_eq!(known, vec![json!({"a": 1})]);
        j.append(&json!({"a": 3})).unwrap();
        let (_, known) = Journal::open(&path, &header, true).unwrap();
        assert_eq!(known, vec![json!({"a": 1}), json!({"a": 3})]);
        let e = Journal::open(&path, &json!({"work": 2}), true)
            .err()
            .unwrap();
        assert!(e.to_string().contains("other work"), "{e}");
    }
}
