//! Progress bars on standard error (indicatif) for the library's progress reports; hidden when
//! standard error is not a terminal.

use indicatif::{ProgressBar, ProgressStyle};
use pegtwin::campaign::run::CampaignProgress;
use pegtwin::method::manifold::cache::BuildProgress;
use pegtwin::twin::geometry::PartPair;
use std::io::IsTerminal;
use std::path::Path;
use std::sync::Mutex;

/// The bar of the manifold builds (one bar for the builds that run side by side) or of the
/// trials, whichever runs.
pub struct Bars {
    shown: bool,
    bar: Mutex<Option<ProgressBar>>,
    /// Manifold builds started and not finished.
    builds: Mutex<usize>,
}

impl Bars {
    /// Bars on a terminal, nothing otherwise.
    pub fn on_terminal() -> Self {
        Self::new(std::io::stderr().is_terminal())
    }

    pub fn new(shown: bool) -> Self {
        Bars {
            shown,
            bar: Mutex::new(None),
            builds: Mutex::new(0),
        }
    }

    fn start(&self, bar: ProgressBar) {
        *self.bar.lock().expect("no bar user panicked") = Some(bar);
    }

    fn inc(&self) {
        if let Some(b) = self.bar.lock().expect("no bar user panicked").as_ref() {
            b.inc(1);
        }
    }

    fn finish(&self) {
        if let Some(b) = self.bar.lock().expect("no bar user panicked").take() {
            b.finish_and_clear();
        }
    }
}

fn styled(len: usize, template: &str) -> ProgressBar {
    let bar = ProgressBar::new(len as u64);
    bar.set_style(
        ProgressStyle::with_template(template)
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar
}

impl BuildProgress for Bars {
    fn build_started(&self, pair: &PartPair, path: &Path, episodes: usize) {
        if !self.shown {
            return;
        }
        let message = format!(
            "building the reference manifold of {} at {} mm into {} (once)",
            pair.name,
            pair.clearance_m * 1e3,
            path.display()
        );
        let mut builds = self.builds.lock().expect("no bar user panicked");
        *builds += 1;
        // Builds that run side by side share one bar.
        if let Some(b) = self.bar.lock().expect("no bar user panicked").as_ref() {
            b.println(message);
            b.inc_length(episodes as u64);
            return;
        }
        eprintln!("{message}");
        if episodes == 0 {
            // No episodes to count (the geometric sampler): the message alone.
            return;
        }
        self.start(styled(
            episodes,
            "[{bar:40}] {pos}/{len} episodes, {elapsed} elapsed, ETA {eta}",
        ));
    }

    fn episode_done(&self) {
        self.inc();
    }

    fn build_finished(&self) {
        if !self.shown {
            return;
        }
        let mut builds = self.builds.lock().expect("no bar user panicked");
        *builds -= 1;
        if *builds == 0 {
            self.finish();
        }
    }
}

impl CampaignProgress for Bars {
    fn trials_started(&self, total: usize, done: usize) {
        if !self.shown {
            return;
        }
        let bar = styled(
            total,
            "{bar:40} {pos}/{len} trials, {elapsed} elapsed, ETA {eta}",
        );
        bar.set_position(done as u64);
        bar.reset_eta();
        self.start(bar);
    }

    fn trial_done(&self) {
        self.inc();
    }

    fn trials_finished(&self) {
        self.finish();
    }
}
