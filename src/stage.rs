//! Stage timing and progress bars, shared by the pipeline and the report.
//!
//! In: the names of stages as they finish. Out: their wall times and the
//! process CPU time spent in them, in order ([`StageTime`]), for the
//! `--report` JSON and `aobake report`. One [`StageTimer`] is passed
//! through every stage of a bake, so a stage is timed once, where it runs.
//! A stage's utilisation (CPU time over wall time times the worker
//! threads) shows a serial stage on any machine: 1/threads where one
//! thread works, near 1 where all do.

use serde::Serialize;
#[cfg(feature = "cli")]
use std::io::IsTerminal;
use std::time::Instant;

/// Wall time of one stage, and the process's CPU time in it.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
    /// CPU seconds of every thread of the process during the stage (0
    /// where the platform does not say).
    pub cpu_seconds: f64,
    /// Worker threads the stage could use (rayon's pool).
    pub threads: usize,
    /// CPU time over wall time times threads: 1 for a stage that keeps
    /// every worker busy, 1/threads for a serial one (0 for a stage too
    /// short to tell, under a millisecond, or without CPU times).
    pub utilisation: f64,
}

impl StageTime {
    fn new(stage: &'static str, seconds: f64, cpu_seconds: f64, threads: usize) -> StageTime {
        let utilisation = if seconds < 1e-3 || threads == 0 {
            0.0
        } else {
            (cpu_seconds / (seconds * threads as f64)).min(1.0)
        };
        StageTime {
            stage,
            seconds,
            cpu_seconds,
            threads,
            utilisation,
        }
    }
}

/// CPU time of the whole process so far, every thread's (seconds; 0 where
/// the platform has no such clock).
pub(crate) fn process_cpu_seconds() -> f64 {
    #[cfg(unix)]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec; the clock id is a
        // constant every POSIX system defines.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
        if rc == 0 {
            return ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9;
        }
    }
    0.0
}

/// Laps of a bake's stages: each [`lap`](StageTimer::lap) records the time
/// since the previous one under the stage's name.
#[derive(Clone, Debug)]
pub struct StageTimer {
    stages: Vec<StageTime>,
    last: Instant,
    last_cpu: f64,
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
            last_cpu: process_cpu_seconds(),
        }
    }

    /// Ends the stage `stage` now.
    pub fn lap(&mut self, stage: &'static str) {
        let now = Instant::now();
        let cpu = process_cpu_seconds();
        self.stages.push(StageTime::new(
            stage,
            (now - self.last).as_secs_f64(),
            (cpu - self.last_cpu).max(0.0),
            rayon::current_num_threads(),
        ));
        self.last = now;
        self.last_cpu = cpu;
    }

    /// Starts the next stage now, without recording the time since the
    /// last lap (work that belongs to no stage).
    pub fn restart(&mut self) {
        self.last = Instant::now();
        self.last_cpu = process_cpu_seconds();
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
                Some(o) => {
                    *o = StageTime::new(
                        o.stage,
                        o.seconds + s.seconds,
                        o.cpu_seconds + s.cpu_seconds,
                        o.threads.max(s.threads),
                    )
                }
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

/// A stage's progress: with the `cli` feature (the binary's) indicatif's
/// bar on stderr, drawn only if asked and stderr is a terminal; without
/// it, a bar that draws nothing and links nothing.
#[cfg(feature = "cli")]
pub(crate) type Progress = indicatif::ProgressBar;

#[cfg(not(feature = "cli"))]
pub(crate) struct Progress;

/// The calls the stages make on a bar, doing nothing.
#[cfg(not(feature = "cli"))]
impl Progress {
    pub(crate) fn inc(&self, _: u64) {}
    pub(crate) fn set_length(&self, _: u64) {}
    pub(crate) fn set_position(&self, _: u64) {}
    pub(crate) fn set_message(&self, _: impl Into<std::borrow::Cow<'static, str>>) {}
    pub(crate) fn finish_and_clear(&self) {}
}

/// The progress of a stage of `len` steps named `msg` (see [`Progress`]).
#[cfg(feature = "cli")]
pub(crate) fn progress_bar(show: bool, len: u64, msg: &'static str) -> Progress {
    use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
    let bar = ProgressBar::with_draw_target(
        Some(len),
        if show && std::io::stderr().is_terminal() {
            ProgressDrawTarget::stderr()
        } else {
            ProgressDrawTarget::hidden()
        },
    );
    bar.set_style(
        ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len}, {per_sec}, eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    bar.set_message(msg);
    bar
}

/// The progress of a stage, drawing nothing (no `cli` feature).
#[cfg(not(feature = "cli"))]
pub(crate) fn progress_bar(_: bool, _: u64, _: &'static str) -> Progress {
    Progress
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn utilisation_is_cpu_time_over_wall_time_times_threads() {
        // Two threads busy for 1.5 of 2 seconds on a 2-thread pool.
        let s = StageTime::new("x", 2.0, 3.0, 2);
        assert!((s.utilisation - 0.75).abs() < 1e-12);
        // One thread of eight: serial.
        assert!((StageTime::new("x", 1.0, 1.0, 8).utilisation - 0.125).abs() < 1e-12);
        // Clamped at 1 (other threads of the process), 0 when too short.
        assert_eq!(StageTime::new("x", 1.0, 5.0, 2).utilisation, 1.0);
        assert_eq!(StageTime::new("x", 1e-4, 1e-4, 1).utilisation, 0.0);
    }

    #[test]
    fn merged_stages_add_their_times_and_recompute_utilisation() {
        let mut t = StageTimer::new();
        t.stages = vec![
            StageTime::new("a", 1.0, 2.0, 2),
            StageTime::new("b", 1.0, 1.0, 2),
            StageTime::new("a", 1.0, 0.0, 2),
        ];
        let m = t.into_merged_stages();
        assert_eq!(m.len(), 2);
        assert_eq!((m[0].seconds, m[0].cpu_seconds), (2.0, 2.0));
        assert!((m[0].utilisation - 0.5).abs() < 1e-12);
    }

    #[cfg(unix)]
    #[test]
    fn the_process_cpu_clock_counts_work_done() {
        let before = process_cpu_seconds();
        let mut x = 0u64;
        for i in 0..50_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(i));
        }
        assert!(process_cpu_seconds() > before, "{x}");
    }
}
