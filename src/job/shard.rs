//! Sharded bakes through the job: shard I of N bakes its share of the
//! pages into a partial beside the output; a merge writes the output from
//! the set, byte-identical to a bake in one process.
//!
//! In: the input, the output path, the settings and a [`Shard`]. Out:
//! `OUT.shard-I-of-N` ([`crate::shard::partial`]), written atomically;
//! then [`merge`] checks the set ([`crate::shard::read_set`]) and writes
//! OUT.
//!
//! Every shard unwraps the same atlas (the unwrap is deterministic) and
//! bakes its pages with the same per-page seeds as a bake in one process,
//! so its encoded images are the same bytes; the merge loads the input,
//! builds the level again (no ray is cast, no image re-encoded) and
//! writes every page's images. A shard's fingerprint holds the
//! [`BakeSettings`] as JSON: exactly what decides the output's bytes.

use super::reuse::Rebake;
use super::{Job, Level, Report, check_output, incremental};
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
use crate::geometry::BakeSpace;
use crate::gltf;
use crate::job::settings::{BakeSettings, Device, RunOptions};
use crate::shard::partial::{self, FORMAT, PartialHeader};
use crate::shard::{Shard, assign, identity, page_cost, partial_path, read_set};
use crate::stage::StageTimer;
use std::path::{Path, PathBuf};

/// The settings as a shard records them, and their bytes for the hash.
fn settings_json(s: &BakeSettings) -> (serde_json::Value, Vec<u8>) {
    let value = serde_json::to_value(s).expect("settings serialize");
    let bytes = serde_json::to_vec(&value).expect("settings serialize");
    (value, bytes)
}

/// Bakes shard `shard`'s pages of `input` and writes its partial beside
/// `output` (atomically; a shard killed midway leaves none, a re-run
/// replaces it). With `prev` (`--reuse PREV`): the shard's pages that no
/// ray of an edit reaches are PREV's images, as in one process
/// (`job/incremental.rs`). Returns the partial's path and the shard's
/// report.
pub fn bake_shard(
    input: &Path,
    output: &Path,
    prev: Option<(&Path, Rebake)>,
    s: &BakeSettings,
    run: &RunOptions,
    shard: Shard,
) -> Result<(PathBuf, Report)> {
    s.validate()?;
    check_output(input, output)?;
    let mut timer = StageTimer::new();
    let (bytes, scene) = gltf::load_with_bytes(input)?;
    timer.lap("load");
    let input_hash = super::reuse::input_hash(&bytes, &scene.doc);
    let mut plan = match incremental::check(prev, output, &scene, s, input_hash, true, &mut timer)?
    {
        incremental::Start::Bake(plan) => *plan,
        incremental::Start::Reused(..) => unreachable!("a shard's check never reuses the file"),
    };
    let mut job = Job::new(&scene, s, run, timer);
    let (level, from_prev) = incremental::level(&mut job, &mut plan)?;
    let costs: Vec<f64> = (level.atlas.page_areas().into_iter())
        .zip(level.atlas.page_triangles())
        .map(|(t, n)| page_cost(t, n))
        .collect();
    let mine = assign(&costs, shard.count).swap_remove(shard.index as usize);
    let to_bake: Vec<u32> = (mine.iter().copied())
        .filter(|&k| from_prev[k as usize].is_none())
        .collect();
    let done = job.pages(&level, &to_bake, &mut |_, _, _| {})?;
    // Where this shard traced is part of its fingerprint: shards of one
    // level traced on different devices are refused at the merge.
    let mut recorded = s.clone();
    recorded.device = level.backend.device();
    let (settings, settings_bytes) = settings_json(&recorded);
    let space = plan.carried.as_ref().map(|r| r.space.to_array());
    let header = PartialHeader {
        format: FORMAT,
        identity: identity(&bytes, &settings_bytes, shard.count, level.page_count()),
        shard: shard.index,
        input: std::fs::canonicalize(input)
            .map_err(|e| Error::io(input, e))?
            .display()
            .to_string(),
        settings,
        pages: Vec::new(),
        space,
        from_prev: (mine.iter().copied())
            .filter(|&k| from_prev[k as usize].is_some())
            .collect(),
        ladder: (level.ladder.as_ref())
            .map(|l| serde_json::to_value(l).expect("a report serializes")),
    };
    let mut baked = done.iter().map(|d| &d.encoded);
    let pages: Vec<(u32, &Encoded)> = (mine.iter())
        .map(|&k| match &from_prev[k as usize] {
            Some(e) => (k, e),
            None => (k, baked.next().expect("a baked page")),
        })
        .collect();
    let path = partial_path(output, shard);
    file::write_atomic(&path, &partial::write(header, &pages))?;
    job.timer.lap("save");
    let warnings = scene.warnings.clone();
    let dirty = job.edit.take().map(|(_, dirty)| dirty);
    let mut report = job.report(&level, &done, warnings, Some(input));
    report.shard = Some(shard);
    let pages_reused = mine.len() - to_bake.len();
    report.reuse = plan.finish(&done, pages_reused, dirty);
    Ok((path, report))
}

/// What a merge did.
#[derive(Clone, Debug)]
pub struct Merged {
    pub shards: u32,
    pub pages: u32,
    pub input: PathBuf,
    pub warnings: Vec<String>,
}

/// Checks that the partials beside `output` are one complete set of one
/// bake and writes `output` from them (atomically; on any refusal nothing
/// is written). The input is read again from the path the shards baked.
pub fn merge(output: &Path) -> Result<Merged> {
    let set = read_set(output)?;
    let (_, reference) = set.reference();
    // The input as the shards saw it, and the same settings.
    let input = PathBuf::from(&reference.input);
    let (bytes, scene) = gltf::load_with_bytes(&input)?;
    let settings: BakeSettings = serde_json::from_value(reference.settings.clone())
        .map_err(|e| set.refuse(format!("unreadable settings ({e})")))?;
    let page_count = reference.identity.pages;
    let expected = identity(&bytes, &settings_json(&settings).1, set.count, page_count);
    if expected.input_hash != reference.identity.input_hash {
        return Err(set.refuse(format!(
            "{} changed since the shards baked it",
            input.display()
        )));
    }
    if expected.aobake != reference.identity.aobake {
        return Err(set.refuse(format!(
            "baked by aobake {}, this is {}",
            reference.identity.aobake, expected.aobake
        )));
    }
    check_output(&input, output)?;
    let run = RunOptions::QUIET;
    // The merge casts no ray: its level traces on the CPU.
    let mut on_cpu = settings.clone();
    on_cpu.device = Device::Cpu;
    on_cpu.validate()?;
    let mut job = Job::new(&scene, &on_cpu, &run, StageTimer::new());
    // The fingerprint a bake in one process writes.
    job.input_hash = Some(super::reuse::input_hash(&bytes, &scene.doc));
    // With `--reuse`: the level in the bake space the shards took from
    // PREV, and the pass across pages over the pages they baked.
    let space = reference.space.map(BakeSpace::from_array);
    // The small page's atlas the shards' ladder chose, not measured again.
    let chosen = match &reference.ladder {
        Some(v) => Some(
            serde_json::from_value(v.clone())
                .map_err(|e| set.refuse(format!("its atlas choice cannot be read: {e}")))?,
        ),
        None => None,
    };
    let level = Level::build_with(&scene, &on_cpu, &run, space, chosen, &mut job.timer)?;
    let from_prev: Vec<u32> = (set.partials.iter())
        .flat_map(|(_, p)| p.header.from_prev.iter().copied())
        .collect();
    if !from_prev.is_empty() {
        let baked = (0..level.page_count()).map(|k| !from_prev.contains(&k));
        job.across_pages = Some(baked.collect());
    }
    if level.page_count() != page_count {
        return Err(set.refuse(format!(
            "{page_count} pages, but the input unwraps into {}",
            level.page_count()
        )));
    }
    let (glb, warnings) = job.write(&level, &set.pages(), Some(file::parent_dir(output)))?;
    file::write_atomic(output, &glb)?;
    Ok(Merged {
        shards: set.count,
        pages: page_count,
        input,
        warnings,
    })
}
