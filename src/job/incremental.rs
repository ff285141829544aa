//! A bake with `--reuse PREV`, in one process or in a shard: the
//! decision ([`check`]), then the level and which pages are PREV's
//! ([`level`]), then the report's `reuse` ([`Plan::finish`]).
//!
//! In: PREV's path and `--rebake`, the loaded input, its hash, the
//! settings. Out: [`Start::Reused`] (PREV is the output), or a [`Plan`]
//! whose [`level`] is built in PREV's bake space with PREV's page-wide
//! numbers carried ([`super::carry`]) when its atlas is PREV's, or as
//! without PREV otherwise; per page PREV's images when no ray of the edit
//! reaches it and `--rebake changed`, else `None` (bake it).

use super::carry::{self, PrevRecord};
use super::report::PageDone;
use super::reuse::{self, Decision, Rebake, ReuseReport};
use super::{Job, Level};
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
use crate::gltf::Scene;
use crate::job::settings::BakeSettings;
use crate::stage::StageTimer;
use std::path::{Path, PathBuf};

/// What a bake with `--reuse` starts from.
pub(crate) enum Start {
    /// PREV (its path and bytes) is the output.
    Reused(PathBuf, Vec<u8>),
    Bake(Box<Plan>),
}

/// A bake to make, and what it may take from PREV.
#[derive(Default)]
pub(crate) struct Plan {
    /// What to bake again (`Changed` without PREV: nothing is taken).
    pub rebake: Rebake,
    /// The report's `reuse` so far (none without PREV).
    pub reused: Option<ReuseReport>,
    /// PREV's record, when it may be carried.
    pub carried: Option<PrevRecord>,
}

/// Decides what the bake takes from PREV (`prev`; `None`: a bake
/// without it). `shard`: a shard's, which writes a partial, never OUT: an
/// unchanged input is planned as an edit with no change (every page
/// PREV's), not copied.
pub(crate) fn check(
    prev: Option<(&Path, Rebake)>,
    output: &Path,
    scene: &Scene,
    s: &BakeSettings,
    input_hash: u64,
    shard: bool,
    timer: &mut StageTimer,
) -> Result<Start> {
    let Some((prev, rebake)) = prev else {
        return Ok(Start::Bake(Box::default()));
    };
    if file::same_file(prev, output) {
        return Err(Error::option_conflict(
            "reuse",
            format!(
                "{} is OUT; PREV is only read, write the new bake elsewhere",
                output.display()
            ),
        ));
    }
    let prev_bytes = std::fs::read(prev).map_err(|e| {
        Error::option_conflict("reuse", format!("cannot read {}: {e}", prev.display()))
    })?;
    let decision = reuse::decide(
        &prev_bytes,
        &reuse::Wanted {
            input: input_hash,
            settings: s,
            nodes: reuse::node_prints(scene),
            node_name: &|k| {
                let name = scene.doc.json.pointer(&format!("/nodes/{k}/name"));
                name.and_then(serde_json::Value::as_str).map(str::to_string)
            },
            moved_uris: reuse::moved_uris(&scene.doc, prev, output),
        },
        rebake == Rebake::All || shard,
    );
    timer.lap("reuse check");
    let (full_bake, nodes, carried) = match decision {
        Decision::Reuse => return Ok(Start::Reused(prev.to_path_buf(), prev_bytes)),
        Decision::Full(why, nodes) => (why, nodes, None),
        // A shard asked for PREV as it is: every page is PREV's.
        Decision::Edited(_, nodes, record)
            if shard && rebake != Rebake::All && nodes == Default::default() =>
        {
            (
                "nothing the bake reads changed (a shard takes PREV's pages)".into(),
                Some(nodes),
                Some(record),
            )
        }
        Decision::Edited(why, nodes, record) => (why, Some(nodes), Some(record)),
    };
    Ok(Start::Bake(Box::new(Plan {
        rebake,
        reused: Some(ReuseReport {
            prev: prev.display().to_string(),
            reused: false,
            carried: false,
            full_bake: Some(full_bake),
            nodes,
            texels_baked: 0,
            texels_dirty: 0,
            pages_reused: 0,
            pages_whole: Vec::new(),
        }),
        carried,
    })))
}

/// The job's level under `plan`, and per page PREV's images where the
/// page is taken from PREV (`None`: bake it). An edited input is mapped
/// into PREV's bake space; when its atlas turns out not to be PREV's, the
/// level is built again in its own, so a full bake is always what a bake
/// without PREV writes. With a carry the job gets PREV's page-wide
/// numbers ([`Job::carry`]), the edit's boxes ([`Job::edit`]) and, when
/// pages are taken, the pages whose seams the pass across pages solves.
pub(crate) fn level(job: &mut Job, plan: &mut Plan) -> Result<(Level, Vec<Option<Encoded>>)> {
    let (scene, s, run) = (job.scene, job.settings, job.run);
    let space = plan.carried.as_ref().map(|r| r.space);
    let mut level = Level::build(scene, s, run, space, &mut job.timer)?;
    if let (Some(record), Some(r)) = (&mut plan.carried, &mut plan.reused) {
        match carry::carries(record, &level.atlas) {
            Ok(()) => {
                job.carry = Some(std::mem::take(&mut record.pages));
                let boxes = (r.nodes.as_ref()).map(|n| n.boxes.clone());
                job.edit = Some((boxes.unwrap_or_default(), 0));
                r.carried = true;
            }
            Err(why) => {
                let full = r.full_bake.as_mut().expect("a reason");
                *full = format!("{full}; {why}");
                plan.carried = None;
                level = Level::build(scene, s, run, None, &mut job.timer)?;
            }
        }
    }
    let pages = level.page_count() as usize;
    // PREV's images leave the carry (which every baked page copies): a
    // page no ray of the edit reaches takes them.
    let mut from_prev = vec![None; pages];
    if let Some(carries) = &mut job.carry {
        let images: Vec<Option<Encoded>> = carries.iter_mut().map(|c| c.images.take()).collect();
        if let (Some((boxes, _)), Rebake::Changed | Rebake::Texels) = (&job.edit, plan.rebake) {
            let dirty = carry::dirty_pages(
                &level.geometry,
                &level.atlas,
                &level.cross_seams,
                boxes,
                level.max_distance,
            );
            // With `--rebake texels` a dirty page keeps them: it may rebake
            // only the texels the edit reaches, and write them over PREV's
            // (`job/partial.rs`).
            let texels = plan.rebake == Rebake::Texels;
            from_prev = (images.into_iter().zip(&dirty).zip(carries.iter_mut()))
                .map(|((e, &d), c)| match d {
                    true => {
                        c.images = e.filter(|_| texels);
                        None
                    }
                    false => e,
                })
                .collect();
            job.across_pages = Some(from_prev.iter().map(Option::is_none).collect());
        }
    }
    Ok((level, from_prev))
}

impl Plan {
    /// The report's `reuse` once the pages are baked (`done`;
    /// `pages_reused`: those taken from PREV; `dirty`: the receivers the
    /// edit reached).
    pub(crate) fn finish(
        self,
        done: &[PageDone],
        pages_reused: usize,
        dirty: Option<usize>,
    ) -> Option<ReuseReport> {
        let mut r = self.reused?;
        r.texels_baked = done.iter().map(|d| d.texels).sum();
        r.texels_dirty = dirty.unwrap_or(r.texels_baked);
        r.pages_reused = pages_reused;
        r.pages_whole = (done.iter())
            .filter_map(|d| Some((d.page, d.whole.clone()?)))
            .collect();
        Some(r)
    }
}
