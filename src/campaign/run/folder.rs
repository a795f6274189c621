//! The results folder: `campaign.json` (the scenario as run, its fingerprint, the shard), the
//! checks that a folder is new or holds this campaign, and the merge of shard folders into one.

use super::CampaignTrials;
use crate::campaign::records::{TrialSet, TrialsFile, check_complete, index_records, write_sorted};
use crate::campaign::replays::{self};
use crate::campaign::scenario::Scenario;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The campaign description file in a results folder.
pub const CAMPAIGN_FILE: &str = "campaign.json";
/// The trial records in a results folder.
pub const TRIALS_FILE: &str = "trials.jsonl";

/// One part of a campaign split `count` ways: trial number `n` (in cell-major order) belongs to
/// shard `n % count`. Index from 0, as Kubernetes' `JOB_COMPLETION_INDEX`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    /// The whole campaign.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Parses `I/N` with 0 <= I < N.
    pub fn parse(text: &str) -> Result<Self> {
        let bad = || {
            Error::Input(format!(
                "--shard {text}: expected I/N with 0 <= I < N (e.g. 0/4)"
            ))
        };
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count): (usize, usize) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    pub(super) fn holds(&self, number: usize) -> bool {
        number % self.count == self.index
    }
}

/// What `campaign.json` holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CampaignFile {
    pub fingerprint: String,
    pub shard: Shard,
    pub scenario: Scenario,
    /// The folder the scenario's assembly paths are relative to (when it has assemblies).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assembly_dir: Option<PathBuf>,
}

impl CampaignFile {
    /// What `campaign.json` holds for `scenario` run as `shard`.
    pub(super) fn new(scenario: &Scenario, shard: Shard) -> Self {
        CampaignFile {
            fingerprint: scenario.fingerprint(),
            shard,
            scenario: scenario.clone(),
            assembly_dir: (!scenario.assemblies.is_empty()).then(|| scenario.assembly_dir.clone()),
        }
    }
}

/// Checks, writing nothing, that the folder is new (or empty: `Ok(true)`) or holds this campaign
/// (`Ok(false)`; `resume` must be asked for when it holds trials already).
pub(super) fn check_folder(out: &Path, described: &CampaignFile, resume: bool) -> Result<bool> {
    let campaign_path = out.join(CAMPAIGN_FILE);
    if campaign_path.is_file() {
        let existing = read_campaign(out)?;
        if existing.fingerprint != described.fingerprint || existing.shard != described.shard {
            return Err(Error::file(
                out,
                format!(
                    "holds a different campaign (scenario fingerprint {}, shard {}/{}; this one is {}, shard {}/{}): choose another --out",
                    existing.fingerprint,
                    existing.shard.index,
                    existing.shard.count,
                    described.fingerprint,
                    described.shard.index,
                    described.shard.count
                ),
            ));
        }
        let has_trials = std::fs::metadata(out.join(TRIALS_FILE)).is_ok_and(|m| m.len() > 0);
        if has_trials && !resume {
            return Err(Error::file(
                out,
                "already holds trials of this campaign: pass --resume to complete it, or choose another --out",
            ));
        }
        return Ok(false);
    }
    ensure_new_or_empty(out, "holds no campaign.json")?;
    Ok(true)
}

/// Creates the output folder of a new campaign with its `campaign.json`.
pub(super) fn create_folder(out: &Path, described: &CampaignFile) -> Result<()> {
    let campaign_path = out.join(CAMPAIGN_FILE);
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, format!("cannot create: {e}")))?;
    let json = serde_json::to_vec_pretty(described).expect("campaign serialises");
    crate::files::write_atomically(&campaign_path, &json)
}

/// Refuses an output folder that exists and holds anything (`why` says what it lacks).
pub fn ensure_new_or_empty(out: &Path, why: &str) -> Result<()> {
    let occupied = out.is_dir()
        && std::fs::read_dir(out)
            .map_err(|e| Error::file(out, format!("cannot list: {e}")))?
            .next()
            .is_some();
    if occupied {
        return Err(Error::file(
            out,
            format!("is not empty and {why}: choose a new or empty --out"),
        ));
    }
    Ok(())
}

/// A finished, whole results folder (not a shard): its `campaign.json`, and its `trials.jsonl`
/// checked to hold every trial of the scenario once, each record in its own cell.
pub fn read_finished(dir: &Path) -> Result<(CampaignFile, TrialsFile)> {
    let c = read_campaign(dir)?;
    if c.shard != Shard::WHOLE {
        return Err(Error::file(
            dir,
            format!(
                "is shard {}/{}: merge the shards first (pegtwin merge)",
                c.shard.index, c.shard.count
            ),
        ));
    }
    let path = dir.join(TRIALS_FILE);
    let entries = index_records(&path, false)?;
    let wanted = CampaignTrials::of(&c.scenario, Shard::WHOLE);
    if entries.len() < wanted.count() {
        return Err(Error::file(
            &path,
            format!(
                "holds {} of {} trials: the campaign is not finished (--resume it)",
                entries.len(),
                wanted.count()
            ),
        ));
    }
    check_complete(&entries, &wanted, &path)?;
    Ok((c, TrialsFile { path }))
}

/// Reads `campaign.json` of a results folder.
pub fn read_campaign(dir: &Path) -> Result<CampaignFile> {
    let path = dir.join(CAMPAIGN_FILE);
    if !path.exists() {
        return Err(Error::file(
            &path,
            "cannot read (is this a campaign folder?): no such file",
        ));
    }
    let text = crate::files::read_text(&path)?;
    let mut c: CampaignFile = serde_json::from_str(&text)
        .map_err(|e| Error::file(&path, format!("not a campaign file: {e}")))?;
    c.check(&path)?;
    Ok(c)
}

impl CampaignFile {
    /// What was read back from `path` goes through the checks a user's input does: the shard
    /// (`0 <= index < count`), the scenario's every field, and the fingerprint, recomputed with
    /// the assemblies loaded as they are now (an edited scenario or assembly file is another
    /// campaign, whose records these are not).
    fn check(&mut self, path: &Path) -> Result<()> {
        let Shard { index, count } = self.shard;
        if count == 0 || index >= count {
            return Err(Error::file(
                path,
                format!("shard = {index}/{count}: expected I/N with 0 <= I < N"),
            ));
        }
        self.scenario
            .ensure_valid()
            .map_err(|e| Error::file(path, format!("scenario: {e}")))?;
        if let Some(dir) = &self.assembly_dir {
            self.scenario.load_assemblies(dir)?;
        }
        let now = self.scenario.fingerprint();
        if now != self.fingerprint {
            return Err(Error::file(
                path,
                format!(
                    "fingerprint {} does not match its scenario's, {now}: the file was edited, or \
                     an assembly it names changed since the campaign ran (run it anew)",
                    self.fingerprint
                ),
            ));
        }
        Ok(())
    }
}

/// Joins the shards in `dirs` into one campaign folder `out`: same scenario, every shard of the
/// split once, every trial once. Returns the scenario and the merged `trials.jsonl`, in (cell,
/// trial) order, with its number of trials. The shards' replays are copied too. With `resume`,
/// `out` may hold this merge cut short (its `campaign.json` and some of the rest): every file is
/// written again from the shards, each whole or absent after a failure.
pub fn merge(dirs: &[PathBuf], out: &Path, resume: bool) -> Result<(Scenario, TrialsFile, usize)> {
    let first = dirs
        .first()
        .ok_or_else(|| Error::Input("merge: expected at least one shard folder".into()))?;
    let head = read_campaign(first)?;
    let count = head.shard.count;
    let mut shards = BTreeSet::new();
    let mut parts = Vec::new();
    for dir in dirs {
        let c = read_campaign(dir)?;
        if c.fingerprint != head.fingerprint {
            return Err(Error::file(
                dir,
                format!(
                    "is another campaign (fingerprint {}, {} has {})",
                    c.fingerprint,
                    first.display(),
                    head.fingerprint
                ),
            ));
        }
        if c.shard.count != count || !shards.insert(c.shard.index) {
            return Err(Error::file(
                dir,
                format!(
                    "shard {}/{} repeats or does not fit a split in {count}",
                    c.shard.index, c.shard.count
                ),
            ));
        }
        let path = dir.join(TRIALS_FILE);
        let entries = index_records(&path, false)?;
        check_complete(&entries, &CampaignTrials::of(&c.scenario, c.shard), &path)?;
        parts.push((path, entries));
    }
    if shards.len() != count {
        // Named up to ten: a split's count is the user's number, not a bound on the work.
        let missing: Vec<String> = (0..count)
            .filter(|i| !shards.contains(i))
            .take(10)
            .map(|i| format!("{i}/{count}"))
            .collect();
        let more = count - shards.len() - missing.len();
        return Err(Error::file(
            first,
            format!(
                "is part of a split in {count}, and the merge is missing shards {}{}",
                missing.join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            ),
        ));
    }
    let count = parts.iter().map(|p| p.1.len()).sum();
    let described = CampaignFile {
        shard: Shard::WHOLE,
        ..head
    };
    if check_folder(out, &described, resume)? {
        create_folder(out, &described)?;
    }
    let path = out.join(TRIALS_FILE);
    write_sorted(&path, &parts)?;
    replays::merge(dirs, out)?;
    Ok((described.scenario, TrialsFile { path }, count))
}
