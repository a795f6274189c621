//! `trials.jsonl`, the campaign's records on disk, handled without holding them in memory: a
//! 10 000-trial folder is read line by line, sorted through an index of (cell, trial, where the
//! line lies), and summarised by streaming passes ([`TrialsFile`]), so a campaign's memory does
//! not grow with its number of trials (docs/journal/2026-11-26.md, "Soak").

use crate::error::{Error, Result};
use crate::method::config::Method;
use crate::method::trial::TrialResult;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::io::{BufRead, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// One line of `trials.jsonl`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct TrialRecord {
    /// Index of the cell in the scenario's cell order.
    pub cell: usize,
    /// Index of the trial within its cell.
    pub trial: usize,
    #[serde(flatten)]
    pub result: TrialResult,
}

/// A trial to run (and the key of its record).
#[derive(Clone, Copy, Debug)]
pub struct TrialSpec {
    pub cell: usize,
    pub trial: usize,
    pub seed: u64,
    /// The [`condition_key`] of its cell.
    pub condition: u64,
}

/// A checksum of what makes a cell (geometry, clearance, method, observation time): a record
/// carries its own, so that one moved into another cell of the same pair, whose trials share
/// their seeds, is told apart.
pub fn condition_key(geometry: &str, clearance_mm: f64, method: Method, t_obs_s: f64) -> u64 {
    let mut h = crc32fast::Hasher::new();
    h.update(geometry.as_bytes());
    h.update(&clearance_mm.to_bits().to_le_bytes());
    h.update(
        serde_json::to_string(&method)
            .expect("a method serialises")
            .as_bytes(),
    );
    h.update(&t_obs_s.to_bits().to_le_bytes());
    u64::from(h.finalize())
}

impl TrialRecord {
    /// The [`condition_key`] of the cell this record says it ran in.
    pub fn condition(&self) -> u64 {
        let r = &self.result;
        condition_key(&r.geometry, r.clearance_mm, r.method, r.t_obs_s)
    }
}

/// Where one record's line lies in its file, bytes (newline included).
#[derive(Clone, Copy, Debug)]
struct Span {
    offset: u64,
    len: usize,
}

/// One record of a `trials.jsonl`, as the index keeps it: which trial, and where its line is.
#[derive(Clone, Copy, Debug)]
pub struct Entry {
    pub cell: usize,
    pub trial: usize,
    pub seed: u64,
    /// The [`condition_key`] of the cell the record says it ran in.
    pub condition: u64,
    span: Span,
}

/// Reads `path` line by line, handing each record and its span to `each`. A missing file holds
/// no records. With `repair`, a last line cut short by a kill is dropped (and the file truncated
/// to its complete lines); any other unreadable line is an error naming it.
fn scan(
    path: &Path,
    repair: bool,
    mut each: impl FnMut(TrialRecord, Span) -> Result<()>,
) -> Result<()> {
    // Only a missing file is an empty one: a file that cannot be looked at (no permission) is
    // refused by `open_input`, not read as holding no records.
    if matches!(std::fs::symlink_metadata(path), Err(e) if e.kind() == std::io::ErrorKind::NotFound)
    {
        return Ok(());
    }
    let (file, _) = crate::files::open_input(path, u64::MAX)?;
    let mut reader = std::io::BufReader::new(file);
    let mut offset = 0u64;
    let mut line = String::new();
    for n in 1.. {
        line.clear();
        let read = reader
            .read_line(&mut line)
            .map_err(|e| Error::file(path, format!("line {n}: cannot read: {e}")))?;
        if read == 0 {
            break;
        }
        let cut = !line.ends_with('\n');
        match serde_json::from_str::<TrialRecord>(line.trim_end()) {
            Ok(record) if !cut => each(record, Span { offset, len: read })?,
            _ if cut && repair => return truncate(path, offset),
            Ok(_) => {
                return Err(Error::file(
                    path,
                    format!("line {n}: cut short (no newline)"),
                ));
            }
            Err(e) => {
                return Err(Error::file(
                    path,
                    format!("line {n}: not a trial record: {e}"),
                ));
            }
        }
        offset += read as u64;
    }
    Ok(())
}

/// Cuts `path` to its first `len` bytes (the complete lines before a cut one).
fn truncate(path: &Path, len: u64) -> Result<()> {
    let repair = |e: std::io::Error| Error::file(path, format!("cannot repair: {e}"));
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .and_then(|f| f.set_len(len))
        .map_err(repair)
}

/// Reads every record of `path` into memory (for small files and tests; a campaign indexes or
/// streams instead). `repair` as in [`index_records`].
pub fn read_records(path: &Path, repair: bool) -> Result<Vec<TrialRecord>> {
    let mut records = Vec::new();
    scan(path, repair, |r, _| {
        records.push(r);
        Ok(())
    })?;
    Ok(records)
}

/// The index of `path`: one [`Entry`] per record, in file order, each line parsed and checked.
/// With `repair`, a last line cut short by a kill is dropped and the file truncated.
pub fn index_records(path: &Path, repair: bool) -> Result<Vec<Entry>> {
    let mut entries = Vec::new();
    scan(path, repair, |r, span| {
        entries.push(Entry {
            cell: r.cell,
            trial: r.trial,
            seed: r.result.seed,
            condition: r.condition(),
            span,
        });
        Ok(())
    })?;
    Ok(entries)
}

/// The trials a campaign (or one shard of it) runs, as the checks of its records ask for them:
/// generated on demand, so that checking a folder takes memory in proportion to its records,
/// not to the trials its scenario could ask for.
pub trait TrialSet {
    /// Trial `trial` of cell `cell`, when the set holds it.
    fn spec(&self, cell: usize, trial: usize) -> Option<TrialSpec>;
    /// How many trials the set holds.
    fn count(&self) -> usize;
}

/// Checks that every entry is a trial of `wanted` (same seed, same cell conditions) and none
/// repeats.
pub fn check_entries_belong(entries: &[Entry], wanted: &dyn TrialSet, path: &Path) -> Result<()> {
    let mut seen = BTreeSet::new();
    for e in entries {
        let key = (e.cell, e.trial);
        let Some(spec) = wanted.spec(e.cell, e.trial).filter(|w| w.seed == e.seed) else {
            return Err(Error::file(
                path,
                format!(
                    "holds trial {} of cell {} (seed {}), which this campaign does not run",
                    e.trial, e.cell, e.seed
                ),
            ));
        };
        if spec.condition != e.condition {
            return Err(Error::file(
                path,
                format!(
                    "holds a record of trial {} of cell {} (seed {}) whose geometry, \
                     clearance, method or observation time are not that cell's: a record moved \
                     between cells, or a file of another campaign",
                    e.trial, e.cell, spec.seed
                ),
            ));
        }
        if !seen.insert(key) {
            return Err(Error::file(
                path,
                format!("holds trial {} of cell {} twice", e.trial, e.cell),
            ));
        }
    }
    Ok(())
}

/// Checks that `entries` are exactly the trials of `wanted`, each once.
pub fn check_complete(entries: &[Entry], wanted: &dyn TrialSet, path: &Path) -> Result<()> {
    check_entries_belong(entries, wanted, path)?;
    if entries.len() != wanted.count() {
        return Err(Error::file(
            path,
            format!(
                "holds {} of the {} trials expected",
                entries.len(),
                wanted.count()
            ),
        ));
    }
    Ok(())
}

/// Writes `out` (atomically) with the records of every indexed file in `parts`, in (cell,
/// trial) order, copying each line byte for byte; only one line is in memory at a time.
pub fn write_sorted(out: &Path, parts: &[(PathBuf, Vec<Entry>)]) -> Result<()> {
    let mut order: Vec<(usize, usize, usize, Span)> = parts
        .iter()
        .enumerate()
        .flat_map(|(p, (_, entries))| entries.iter().map(move |e| (e.cell, e.trial, p, e.span)))
        .collect();
    order.sort_unstable_by_key(|&(cell, trial, ..)| (cell, trial));
    let mut files = parts
        .iter()
        .map(|(path, _)| crate::files::open_input(path, u64::MAX).map(|(f, _)| f))
        .collect::<Result<Vec<_>>>()?;
    crate::files::write_atomically_with(out, |w| {
        let mut line = Vec::new();
        for &(_, _, p, span) in &order {
            let reading = |e: std::io::Error| {
                std::io::Error::other(format!("reading {}: {e}", parts[p].0.display()))
            };
            line.resize(span.len, 0);
            files[p]
                .seek(SeekFrom::Start(span.offset))
                .map_err(reading)?;
            files[p].read_exact(&mut line).map_err(reading)?;
            w.write_all(&line)?;
        }
        Ok(())
    })
}

/// Records that can be read more than once, in (cell, trial) order: a slice in memory, or a
/// finished `trials.jsonl` streamed from disk ([`TrialsFile`]).
pub trait RecordSource {
    fn for_each(&self, each: &mut dyn FnMut(&TrialRecord)) -> Result<()>;
}

impl RecordSource for [TrialRecord] {
    fn for_each(&self, each: &mut dyn FnMut(&TrialRecord)) -> Result<()> {
        self.iter().for_each(each);
        Ok(())
    }
}

impl RecordSource for Vec<TrialRecord> {
    fn for_each(&self, each: &mut dyn FnMut(&TrialRecord)) -> Result<()> {
        self.as_slice().for_each(each)
    }
}

/// A finished `trials.jsonl`, read afresh on each pass: the summary and the report stream it
/// instead of loading it (its records in file order, which a finished campaign keeps sorted).
pub struct TrialsFile {
    pub path: PathBuf,
}

impl RecordSource for TrialsFile {
    fn for_each(&self, each: &mut dyn FnMut(&TrialRecord)) -> Result<()> {
        scan(&self.path, false, |r, _| {
            each(&r);
            Ok(())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(cell: usize, trial: usize) -> String {
        format!(
            "{{\"cell\":{cell},\"trial\":{trial},\"seed\":{},\"geometry\":\"cross\",\"clearance_mm\":0.5,\"method\":\"direct\",\"start\":\"partial\",\"t_obs_s\":1.0,\"offset\":[0,0,0,0,0,0],\"outcome\":\"failure\",\"stopped\":null,\"success\":false,\"fault\":null,\"estimate\":null,\"errors\":null,\"final_depth_mm\":null,\"contact_observations\":0,\"observations_used\":0,\"peak_fz_n\":{trial}.5,\"mean_fz_n\":0.0,\"insert_fz_n\":[],\"times\":{{\"search_s\":0.0,\"observe_s\":0.0,\"retract_s\":0.0,\"align_s\":0.0,\"insert_s\":0.0}}}}\n",
            cell * 100 + trial
        )
    }

    #[test]
    fn write_sorted_copies_lines_in_cell_trial_order_across_files() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.jsonl");
        let b = dir.path().join("b.jsonl");
        std::fs::write(&a, line(1, 0) + &line(0, 1)).unwrap();
        std::fs::write(&b, line(0, 0) + &line(1, 1)).unwrap();
        let parts = vec![
            (a.clone(), index_records(&a, false).unwrap()),
            (b.clone(), index_records(&b, false).unwrap()),
        ];
        let out = dir.path().join("out.jsonl");
        write_sorted(&out, &parts).unwrap();
        let expected = line(0, 0) + &line(0, 1) + &line(1, 0) + &line(1, 1);
        assert_eq!(std::fs::read_to_string(&out).unwrap(), expected);
    }

    #[test]
    fn repair_drops_a_cut_last_line_and_keeps_the_rest() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.jsonl");
        let whole = line(0, 0) + &line(0, 1);
        std::fs::write(&path, whole.clone() + &line(0, 2)[..40]).unwrap();
        assert!(index_records(&path, false).is_err());
        let entries = index_records(&path, true).unwrap();
        assert_eq!(entries.len(), 2);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), whole);
    }
}
