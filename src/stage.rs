//! Stage timing and progress bars, shared by the pipeline and the report.
//!
//! In: the names of stages as they finish. Out: their wall times, in
//! order ([`StageTime`]), for the `--report` JSON and `aobake report`.
//! One [`StageTimer`] is passed through every stage of a bake, so a stage
//! is timed once, where it runs.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::IsTerminal;
use std::time::Instant;

/// Wall time of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
}

/// Laps of a bake's stages: each [`lap`](StageTimer::lap) records the time
/// since the previous one under the stage's name.
#[derive(Clone, Debug)]
pub struct StageTimer {
    stages: Vec<StageTime>,
    last: Instant,
}

impl Default for StageTimer {
    fn default() -> Self {
        StageTimer::new()
    }
}

impl StageTimer {
    pub fn new() -> StageTimer {
        StageTimer {
            stages: Vec::new(),
            last: Instant::now(),
        }
    }

    /// Ends the stage `stage` now.
    pub fn lap(&mut self, stage: &'static str) {
        let now = Instant::now();
        self.stages.push(StageTime {
            stage,
            seconds: (now - self.last).as_secs_f64(),
        });
        self.last = now;
    }

    /// Starts the next stage now, without recording the time since the
    /// last lap (work that belongs to no stage).
    pub fn restart(&mut self) {
        self.last = Instant::now();
    }

    /// The stages so far.
    pub fn stages(&self) -> &[StageTime] {
        &self.stages
    }

    /// Stages recorded since the first `from` of them.
    pub fn since(&self, from: usize) -> &[StageTime] {
        &self.stages[from.min(self.stages.len())..]
    }

    pub fn into_stages(self) -> Vec<StageTime> {
        self.stages
    }

    /// The stages with the laps of one name added up, in the order each
    /// name first finished (a bake of several pages laps each page's
    /// stages once per page).
    pub fn into_merged_stages(self) -> Vec<StageTime> {
        let mut out: Vec<StageTime> = Vec::new();
        for s in self.stages {
            match out.iter_mut().find(|o| o.stage == s.stage) {
                Some(o) => o.seconds += s.seconds,
                None => out.push(s),
            }
        }
        out
    }

    /// Seconds of all stages so far.
    pub fn total(&self) -> f64 {
        total(&self.stages)
    }
}

/// Seconds of a list of stages.
pub fn total(stages: &[StageTime]) -> f64 {
    stages.iter().map(|s| s.seconds).sum()
}

/// Seconds of the stages named `stage` in a list (0 if none).
pub fn seconds_of(stages: &[StageTime], stage: &str) -> f64 {
    stages
        .iter()
        .filter(|s| s.stage == stage)
        .map(|s| s.seconds)
        .sum()
}

/// A progress bar on stderr, drawn only if `show` and stderr is a terminal.
pub fn progress_bar(show: bool, len: u64, msg: &'static str) -> ProgressBar {
    let pb = ProgressBar::with_draw_target(
        Some(len),
        if show && std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    pb.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len}, {per_sec}, eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    pb.set_message(msg);
    pb
}
