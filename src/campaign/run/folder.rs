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

    /// Parses `I/N` with 0 <= I < N, or `auto`: the index and count the scheduler running this
    /// process gives it ([`Shard::from_scheduler`] on the process's environment).
    pub fn parse(text: &str) -> Result<Self> {
        if text.trim() == "auto" {
            return Shard::from_scheduler(&|name| std::env::var(name).ok());
        }
        let bad = || {
            Error::Input(format!(
                "--shard {text}: expected I/N with 0 <= I < N (e.g. 0/4), or auto"
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

    /// The shard a job scheduler gives this process, read through `var` (an environment lookup):
    /// a Slurm job array's task (`SLURM_ARRAY_TASK_ID` minus `SLURM_ARRAY_TASK_MIN`, of
    /// `SLURM_ARRAY_TASK_COUNT`; the array's indices must be consecutive), else a Kubernetes
    /// Indexed Job's pod (`JOB_COMPLETION_INDEX`, of `PEGTWIN_SHARD_COUNT`, which the job's
    /// manifest sets to its `completions`). An error names what is missing or inconsistent.
    pub fn from_scheduler(var: &dyn Fn(&str) -> Option<String>) -> Result<Self> {
        if var("SLURM_ARRAY_TASK_ID").is_some() {
            return Shard::from_slurm(var);
        }
        if var("JOB_COMPLETION_INDEX").is_some() {
            let index = scheduler_number(var, "JOB_COMPLETION_INDEX")?;
            let count = var("PEGTWIN_SHARD_COUNT").ok_or_else(|| {
                Error::Input(
                    "--shard auto: JOB_COMPLETION_INDEX is set (a Kubernetes Indexed Job) but \
                     PEGTWIN_SHARD_COUNT is not: set it to the job's `completions` in its manifest"
                        .into(),
                )
            })?;
            let count = parse_number("PEGTWIN_SHARD_COUNT", &count)?;
            return Shard::checked(index, count, "JOB_COMPLETION_INDEX", "PEGTWIN_SHARD_COUNT");
        }
        Err(Error::Input(
            "--shard auto: no job scheduler gave this process a shard: expected SLURM_ARRAY_TASK_ID \
             (a Slurm job array, sbatch --array) or JOB_COMPLETION_INDEX with PEGTWIN_SHARD_COUNT \
             (a Kubernetes Indexed Job); or give the shard as --shard I/N"
                .into(),
        ))
    }

    /// A Slurm job array's task as a shard (see [`Shard::from_scheduler`]).
    fn from_slurm(var: &dyn Fn(&str) -> Option<String>) -> Result<Self> {
        let id = scheduler_number(var, "SLURM_ARRAY_TASK_ID")?;
        let min = scheduler_number(var, "SLURM_ARRAY_TASK_MIN")?;
        let count = scheduler_number(var, "SLURM_ARRAY_TASK_COUNT")?;
        if let Some(step) = var("SLURM_ARRAY_TASK_STEP")
            && parse_number("SLURM_ARRAY_TASK_STEP", &step)? != 1
        {
            return Err(Error::Input(format!(
                "--shard auto: SLURM_ARRAY_TASK_STEP={step}: expected an array of consecutive \
                 indices (sbatch --array=0-{})",
                count.saturating_sub(1)
            )));
        }
        if let Some(max) = var("SLURM_ARRAY_TASK_MAX") {
            let max = parse_number("SLURM_ARRAY_TASK_MAX", &max)?;
            if max.checked_sub(min).map(|span| span + 1) != Some(count) {
                return Err(Error::Input(format!(
                    "--shard auto: the Slurm array runs indices {min}-{max} but has \
                     {count} tasks: expected consecutive indices (sbatch --array={min}-{})",
                    min + count.saturating_sub(1)
                )));
            }
        }
        let index = id.checked_sub(min).ok_or_else(|| {
            Error::Input(format!(
                "--shard auto: SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}"
            ))
        })?;
        Shard::checked(
            index,
            count,
            "SLURM_ARRAY_TASK_ID",
            "SLURM_ARRAY_TASK_COUNT",
        )
    }

    /// `index` of `count`, when 0 <= index < count (the error names the two variables).
    fn checked(index: usize, count: usize, index_var: &str, count_var: &str) -> Result<Self> {
        if count == 0 || index >= count {
            return Err(Error::Input(format!(
                "--shard auto: {index_var} gives shard {index} of {count} ({count_var}): \
                 expected 0 <= index < count"
            )));
        }
        Ok(Shard { index, count })
    }

    pub(super) fn holds(&self, number: usize) -> bool {
        number % self.count == self.index
    }
}

/// The whole number in the scheduler's variable `name`, which must be set.
fn scheduler_number(var: &dyn Fn(&str) -> Option<String>, name: &str) -> Result<usize> {
    let text = var(name).ok_or_else(|| {
        Error::Input(format!(
            "--shard auto: {name} is not set (the scheduler sets it for each task)"
        ))
    })?;
    parse_number(name, &text)
}

/// `text`, the value of the variable `name`, as a whole number.
fn parse_number(name: &str, text: &str) -> Result<usize> {
    text.trim().parse().map_err(|_| {
        Error::Input(format!(
            "--shard auto: {name}={text}: expected a whole number"
        ))
    })
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
