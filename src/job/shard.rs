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

use super::{Job, Level, Report, check_output};
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
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
/// replaces it). Returns the partial's path and the shard's report.
pub fn bake_shard(
    input: &Path,
    output: &Path,
    s: &BakeSettings,
    run: &RunOptions,
    shard: Shard,
) -> Result<(PathBuf, Report)> {
    s.validate()?;
    check_output(input, output)?;
    let mut timer = StageTimer::new();
    let (bytes, scene) = gltf::load_with_bytes(input)?;
    timer.lap("load");
    let mut job = Job::new(&scene, s, run, timer);
    let level = Level::build(&scene, s, run, None, &mut job.timer)?;
    let costs: Vec<f64> = (level.atlas.page_areas().into_iter())
        .zip(level.atlas.page_triangles())
        .map(|(t, n)| page_cost(t, n))
        .collect();
    let mine = assign(&costs, shard.count).swap_remove(shard.index as usize);
    let done = job.pages(&level, &mine, &mut |_, _, _| {})?;
    // Where this shard traced is part of its fingerprint: shards of one
    // level traced on different devices are refused at the merge.
    let mut recorded = s.clone();
    recorded.device = level.backend.device();
    let (settings, settings_bytes) = settings_json(&recorded);
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
    };
    let pages: Vec<(u32, &Encoded)> = done.iter().map(|d| (d.page, &d.encoded)).collect();
    let path = partial_path(output, shard);
    file::write_atomic(&path, &partial::write(header, &pages))?;
    job.timer.lap("save");
    let warnings = scene.warnings.clone();
    let mut report = job.report(&level, &done, warnings, Some(input));
    report.shard = Some(shard);
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
    let mut job = Job::new(&scene, &on_cpu, &run, StageTimer::new());
    // The fingerprint a bake in one process writes.
    job.input_hash = Some(super::reuse::input_hash(&bytes, &scene.doc));
    let level = job.level()?;
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
