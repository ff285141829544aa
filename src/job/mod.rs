//! The bake job: the one sequence every command runs.
//!
//! load -> [`Level`] (unwrap into pages, BVH, cross-page seams) -> per page
//! ([`Page`]: rasterize, validity; [`Page::bake`]: the method's passes;
//! [`Page::finish`]: the lightmap stage and encode) -> [`write`](fn@write) the GLB,
//! each stage timed on the [`Job`]'s one [`StageTimer`] (a stage's laps
//! over the pages added up in the report). The adaptive method has no
//! validity stage: its pre-pass makes the same test on the same rays.
//!
//! In: a path or a loaded [`Scene`], validated [`BakeSettings`] and
//! [`RunOptions`]. Out, by command:
//!
//! - [`bake`]: the output file and its [`Report`] (`aobake IN OUT`);
//! - [`bake_shard`] and [`merge`]: one shard's partial, and the output
//!   from a complete set ([`shard`](mod@shard); `--shard`, `aobake merge`);
//! - [`bake_scene`] and [`bake_file`]: the output bytes and page 0's
//!   intermediates ([`Baked`]; tests and tools);
//! - `aobake report` (`crate::report`) builds one [`Level`] and bakes its
//!   page many times through [`Level::page`], [`Page::bake`] and
//!   [`Page::finish`].
//!
//! Only one page's working set lives at a time: a page's receivers and
//! arrays are freed once it is encoded.
//!
//! - [`settings`]: what a bake is and how a run goes;
//! - [`across`]: the seams across pages, solved together on the encoded
//!   images before the write;
//! - `level`: what every page shares ([`Level`]) and one page ([`Page`]);
//! - `page`: a page's passes and output, and the write-back;
//! - `report`: the `--report` JSON;
//! - [`device`]: where the rays are traced (`--device`);
//! - [`reuse`]: the output's fingerprint, and `--reuse PREV`;
//! - [`carry`]: what a bake of an edited input takes from PREV;
//! - [`shard`](mod@shard): sharded bakes and their merge.

pub mod across;
pub mod carry;
pub mod device;
pub(crate) mod incremental;
pub(crate) mod level;
pub(crate) mod page;
pub(crate) mod partial;
pub(crate) mod report;
pub mod reuse;
pub mod settings;
pub mod shard;
mod write;

pub use across::AcrossReport;
pub use level::{Level, page_seed};
pub use page::{BakePasses, Page, PageOutput};
pub use report::{
    AdaptiveReport, PageDone, PageReport, Report, ShearedReport, VisibilityReport, level_report,
};
pub use reuse::{Rebake, ReuseReport};
pub use settings::{BakeSettings, Device, Method, RunOptions, UvSource, VisibilityMode};
pub use shard::{Merged, bake_shard, merge};
pub use write::write;

use crate::atlas::{self, Atlas, Receivers};
use crate::bake::Bake;
use crate::bake::adaptive::AdaptiveStats;
use crate::bake::sheared::ShearedStats;
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
use crate::geometry::BakeGeometry;
use crate::gltf::{self, Scene};
use crate::lightmap::BorderMode;
use crate::lightmap::Lightmap;
use crate::lightmap::border;
use crate::stage::StageTimer;
use carry::PageCarry;
use std::path::Path;

/// One bake of one scene: the scene, what the bake is, how the run goes,
/// and the timer every stage laps on. Every command runs its stages
/// through these methods, in this order: [`Job::level`], [`Job::pages`],
/// [`Job::write`], [`Job::report`].
///
/// A bake page by page, keeping each page's float lightmap as it goes
/// (what [`bake`] does, less the file):
///
/// ```
/// use aobake::atlas::AtlasSize;
/// use aobake::job::Job;
/// use aobake::stage::StageTimer;
/// use aobake::{BakeSettings, RunOptions};
///
/// let scene = aobake::gltf::load("assets/cornell_box.glb".as_ref())?;
/// let settings = BakeSettings {
///     size: AtlasSize::Resolution(48),
///     ..BakeSettings::default()
/// };
/// let mut job = Job::new(&scene, &settings, &RunOptions::QUIET, StageTimer::new());
/// let level = job.level()?;
/// let pages: Vec<u32> = (0..level.page_count()).collect();
/// let mut mean_ao = Vec::new();
/// let done = job.pages(&level, &pages, &mut |_page, _passes, out| {
///     let ao = &out.lightmap.ao;
///     mean_ao.push(ao.iter().sum::<f32>() / ao.len() as f32);
/// })?;
/// let encoded: Vec<_> = done.iter().map(|d| &d.encoded).collect();
/// let (glb, warnings) = job.write(&level, &encoded, None)?;
/// let report = job.report(&level, &done, warnings, None);
/// // A closed box: every texel sees some of its walls, none all of them.
/// assert!(mean_ao.iter().all(|&m| m > 0.1 && m < 1.0));
/// assert_eq!(&glb[..4], b"glTF");
/// assert_eq!(report.pages.len(), pages.len());
/// # Ok::<(), aobake::Error>(())
/// ```
pub struct Job<'a> {
    pub scene: &'a Scene,
    pub settings: &'a BakeSettings,
    pub run: &'a RunOptions,
    pub timer: StageTimer,
    /// What [`Job::write`]'s pass over the seams across pages did.
    pub across: Option<AcrossReport>,
    /// The input's hash ([`reuse::input_hash`]), when the input's bytes
    /// are known: the output then carries its fingerprint, for a later
    /// `--reuse`.
    pub input_hash: Option<u64>,
    /// Per page what this bake takes from PREV (`--reuse` of an edited
    /// input on PREV's atlas, [`carry`]).
    pub carry: Option<Vec<PageCarry>>,
    /// With a carry: the changed nodes' world boxes before and after the
    /// edit ([`reuse::NodeChanges::boxes`]), and the receivers they make
    /// dirty so far ([`carry::dirty`]).
    pub edit: Option<(Vec<Option<[f64; 6]>>, usize)>,
    /// The pages whose seams across pages [`Job::write`] solves (`None`:
    /// all): with pages taken from PREV, only those baked again, whose
    /// seams tie them to no other page ([`carry::dirty_pages`]).
    pub across_pages: Option<Vec<bool>>,
}

impl<'a> Job<'a> {
    /// A job on a loaded scene; `timer` holds the stages so far (the load).
    pub fn new(
        scene: &'a Scene,
        settings: &'a BakeSettings,
        run: &'a RunOptions,
        timer: StageTimer,
    ) -> Job<'a> {
        Job {
            scene,
            settings,
            run,
            timer,
            across: None,
            input_hash: None,
            carry: None,
            edit: None,
            across_pages: None,
        }
    }

    /// Validates the settings, unwraps into pages and builds the BVH.
    pub fn level(&mut self) -> Result<Level> {
        Level::new(self.scene, self.settings, self.run, &mut self.timer)
    }

    /// Bakes `pages` of the level one after another: each is rasterized,
    /// baked, run through the lightmap stage and encoded, handed to `keep`
    /// (which may hold on to its intermediates; a bake's own path drops
    /// them), and freed.
    pub fn pages<'l>(
        &mut self,
        level: &'l Level,
        pages: &[u32],
        keep: &mut dyn FnMut(Page<'l>, BakePasses, PageOutput),
    ) -> Result<Vec<PageDone>> {
        let (s, run) = (level.settings(), self.run);
        let mut done = Vec::with_capacity(pages.len());
        for &k in pages {
            let mut page = level.page(k, self.scene, &mut self.timer)?;
            if let Some(carry) = self.carry.as_ref().and_then(|c| c.get(k as usize)) {
                page.carry = carry.clone();
            }
            if let Some((boxes, count)) = &mut self.edit {
                let space = &level.geometry.space;
                let dirty = carry::dirty(&page.receivers, boxes, space, level.max_distance);
                *count += dirty.iter().filter(|&&d| d).count();
                page.dirty = Some(dirty);
            }
            // With PREV's images (`--rebake changed`): only the texels the
            // edit can change, when the page allows it.
            let rebaked = match (&self.edit, &page.carry.images) {
                (Some((boxes, _)), Some(_)) => {
                    partial::rebake(&page, boxes, s, run, &mut self.timer)?
                }
                _ => Err(String::new()),
            };
            let whole = rebaked.as_ref().err().filter(|w| !w.is_empty()).cloned();
            let (passes, out, texels) = match rebaked.ok() {
                Some(r) => (r.passes, r.out, r.baked),
                None => {
                    let passes = page.bake(s, run, &mut self.timer)?;
                    let out = page.finish(&passes, s, run, &mut self.timer)?;
                    (passes, out, page.receivers.len())
                }
            };
            let mut page_done = PageDone::new(k, texels, passes.inside(&page), &passes, &out, s);
            page_done.whole = whole;
            done.push(page_done);
            keep(page, passes, out);
            // A GPU that failed mid-bake left the rest to the CPU: an
            // error where the GPU was asked for (at once, no page more),
            // a warning (in write) for auto.
            if let Some(failure) = level.tracer.accelerator_failure()
                && s.device == Device::Gpu
            {
                return Err(Error::Gpu(format!("{failure}; nothing written")));
            }
        }
        Ok(done)
    }

    /// The output GLB from every page's encoded images (`encoded[k]` is
    /// page k's) and the warnings, after the seams across pages are solved
    /// on them ([`across`]). `output_dir`: where it will be written.
    pub fn write(
        &mut self,
        level: &Level,
        encoded: &[&Encoded],
        output_dir: Option<&Path>,
    ) -> Result<(Vec<u8>, Vec<String>)> {
        let mut closed = Vec::new();
        let seams: std::borrow::Cow<[_]> = match &self.across_pages {
            None => (&level.cross_seams[..]).into(),
            Some(solve) => (level.cross_seams.iter())
                .filter(|s| s.page.iter().all(|&p| solve[p as usize]))
                .cloned()
                .collect::<Vec<_>>()
                .into(),
        };
        if !seams.is_empty() {
            self.timer.restart();
            let scale = match self.settings.border {
                BorderMode::Fit | BorderMode::Band => border::SEAM_SCALE,
                BorderMode::Off => 1.0,
            };
            let receivers = &level.geometry.receivers;
            let (pages, report) = across::close(
                &seams,
                &level.atlas.pages,
                encoded,
                scale,
                self.settings.filter,
                |k, needed| atlas::rasterize::covered(receivers, &level.atlas.page(k), needed),
            )?;
            closed = pages;
            self.across = Some(report);
            self.timer.lap("cross-page seams");
        }
        let encoded: Vec<&Encoded> = (encoded.iter().enumerate())
            .map(|(k, &e)| closed.get(k).and_then(Option::as_ref).unwrap_or(e))
            .collect();
        let (glb, mut warnings) = write(
            self.scene,
            level,
            &encoded,
            self.settings,
            output_dir,
            self.input_hash,
            &mut self.timer,
        )?;
        if let Some(failure) = level.tracer.accelerator_failure() {
            warnings.push(format!(
                "the GPU failed mid-bake ({failure}); the rest was traced on the CPU"
            ));
        }
        Ok((glb, warnings))
    }

    /// The report of the pages baked (`done`), with every stage the timer
    /// saw (a stage's laps over the pages added up).
    pub fn report(
        self,
        level: &Level,
        done: &[PageDone],
        warnings: Vec<String>,
        input: Option<&Path>,
    ) -> Report {
        let mut report = level_report(level, done, self.settings, warnings);
        report.cross_page_seams = self.across;
        if let Some(input) = input {
            report.input = input.display().to_string();
        }
        report.total_seconds = self.timer.total();
        report.stages = self.timer.into_merged_stages();
        report
    }
}

/// Every product of a bake: the output and page 0's intermediates (all of
/// a one-page bake).
pub struct Baked {
    pub geometry: BakeGeometry,
    /// Every page's charts.
    pub atlas: Atlas,
    pub receivers: Receivers,
    pub bake: Bake,
    /// Sheared method only.
    pub sheared_stats: Option<ShearedStats>,
    /// Adaptive method only.
    pub adaptive_stats: Option<AdaptiveStats>,
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    pub glb: Vec<u8>,
    pub report: Report,
}

/// Bakes `input` into `output` (written atomically; `input` is never
/// touched): every page, in one process. What `aobake IN OUT` runs.
///
/// ```
/// use aobake::atlas::AtlasSize;
/// use aobake::{BakeSettings, RunOptions};
///
/// let dir = tempfile::tempdir().unwrap();
/// let out = dir.path().join("cornell_baked.glb");
/// let settings = BakeSettings {
///     size: AtlasSize::Resolution(64),
///     ..BakeSettings::default()
/// };
/// let report = aobake::bake(
///     "assets/cornell_box.glb".as_ref(),
///     &out,
///     &settings,
///     &RunOptions::QUIET,
/// )?;
/// assert!(report.texels > 0);
/// // The output is a glTF that carries the extension.
/// let written = std::fs::read(&out).unwrap();
/// assert!(written.windows(15).any(|w| w == b"AOBAKE_lightmap"));
/// # Ok::<(), aobake::Error>(())
/// ```
pub fn bake(input: &Path, output: &Path, s: &BakeSettings, run: &RunOptions) -> Result<Report> {
    bake_reusing(input, output, None, s, run)
}

/// [`bake`], with `--reuse PREV` (`prev`: PREV's path and what to bake
/// again): PREV is taken as the output when it is what this bake would
/// write ([`reuse`]); an edited input on PREV's atlas bakes only the pages
/// an edit reaches (`job/incremental.rs`); else every texel is baked and the
/// report says why. PREV is read only; it may not be the output.
pub fn bake_reusing(
    input: &Path,
    output: &Path,
    prev: Option<(&Path, Rebake)>,
    s: &BakeSettings,
    run: &RunOptions,
) -> Result<Report> {
    s.validate()?;
    check_output(input, output)?;
    let mut timer = StageTimer::new();
    let (bytes, scene) = gltf::load_with_bytes(input)?;
    let input_hash = reuse::input_hash(&bytes, &scene.doc);
    drop(bytes);
    timer.lap("load");
    let mut plan = match incremental::check(prev, output, &scene, s, input_hash, false, &mut timer)?
    {
        incremental::Start::Reused(prev, prev_bytes) => {
            file::write_atomic(output, &prev_bytes)?;
            timer.lap("save");
            return Ok(report::reused_report(
                &prev_bytes,
                &prev,
                input,
                &scene,
                s,
                timer,
            ));
        }
        incremental::Start::Bake(plan) => *plan,
    };
    let mut job = Job::new(&scene, s, run, timer);
    let (level, from_prev) = incremental::level(&mut job, &mut plan)?;
    job.input_hash = Some(input_hash);
    let pages = level.page_count() as usize;
    let to_bake: Vec<u32> = (0..pages as u32)
        .filter(|&k| from_prev[k as usize].is_none())
        .collect();
    let done = job.pages(&level, &to_bake, &mut |_, _, _| {})?;
    let mut from_bake = done.iter().map(|d| &d.encoded);
    let encoded: Vec<&Encoded> = (from_prev.iter())
        .map(|e| match e {
            Some(e) => e,
            None => from_bake.next().expect("a baked page"),
        })
        .collect();
    let (glb, warnings) = job.write(&level, &encoded, Some(file::parent_dir(output)))?;
    file::write_atomic(output, &glb)?;
    job.timer.lap("save");
    let dirty = job.edit.take().map(|(_, dirty)| dirty);
    let mut report = job.report(&level, &done, warnings, Some(input));
    let pages_reused = from_prev.iter().filter(|e| e.is_some()).count();
    report.reuse = plan.finish(&done, pages_reused, dirty);
    Ok(report)
}

/// Refuses an output path that is the input file.
pub(crate) fn check_output(input: &Path, output: &Path) -> Result<()> {
    if file::same_file(input, output) {
        return Err(Error::option_conflict(
            "output",
            format!(
                "{} is the input file; choose another path (the input is never overwritten)",
                output.display()
            ),
        ));
    }
    Ok(())
}

/// Loads `input` and bakes it quietly (the output's URIs stay relative to
/// the input's directory): the output's bytes and page 0's intermediates,
/// nothing written.
///
/// ```
/// use aobake::atlas::AtlasSize;
/// use aobake::BakeSettings;
///
/// let settings = BakeSettings {
///     size: AtlasSize::Resolution(32),
///     rays: 64,
///     method: aobake::Method::Mc,
///     ..BakeSettings::default()
/// };
/// let baked = aobake::bake_file("assets/cornell_box.glb".as_ref(), &settings)?;
/// // One AO value and nine SH coefficients per texel of the page.
/// let texels = (baked.lightmap.width * baked.lightmap.height) as usize;
/// assert_eq!(baked.lightmap.ao.len(), texels);
/// assert!(baked.lightmap.ao.iter().all(|a| (0.0..=1.0).contains(a)));
/// # Ok::<(), aobake::Error>(())
/// ```
pub fn bake_file(input: &Path, s: &BakeSettings) -> Result<Baked> {
    let mut timer = StageTimer::new();
    let scene = gltf::load(input)?;
    timer.lap("load");
    bake_loaded(&scene, s, timer, Some(input))
}

/// Bakes a loaded scene quietly into lightmaps and the output GLB bytes.
///
/// ```
/// use aobake::atlas::AtlasSize;
/// use aobake::BakeSettings;
///
/// let scene = aobake::gltf::load("assets/cornell_box.glb".as_ref())?;
/// let settings = BakeSettings {
///     size: AtlasSize::Resolution(32),
///     ..BakeSettings::default()
/// };
/// let baked = aobake::bake_scene(&scene, &settings)?;
/// assert_eq!(baked.report.baked_primitives, 6);
/// assert!(baked.glb.len() > 1000);
/// # Ok::<(), aobake::Error>(())
/// ```
pub fn bake_scene(scene: &Scene, s: &BakeSettings) -> Result<Baked> {
    bake_loaded(scene, s, StageTimer::new(), None)
}

fn bake_loaded(
    scene: &Scene,
    s: &BakeSettings,
    timer: StageTimer,
    input: Option<&Path>,
) -> Result<Baked> {
    let mut job = Job::new(scene, s, &RunOptions::QUIET, timer);
    let level = job.level()?;
    let all: Vec<u32> = (0..level.page_count()).collect();
    let mut first = None;
    let done = job.pages(&level, &all, &mut |page, passes, out| {
        if page.page == 0 {
            first = Some((page.receivers, passes, out));
        }
    })?;
    let encoded: Vec<&Encoded> = done.iter().map(|d| &d.encoded).collect();
    let (glb, warnings) = job.write(&level, &encoded, None)?;
    let report = job.report(&level, &done, warnings, input);
    let (receivers, passes, out) = first.expect("page 0 is baked");
    Ok(Baked {
        geometry: level.geometry,
        atlas: level.atlas,
        receivers,
        bake: passes.bake,
        sheared_stats: passes.sheared_stats,
        adaptive_stats: passes.adaptive_stats,
        lightmap: out.lightmap,
        encoded: out.encoded,
        glb,
        report,
    })
}
