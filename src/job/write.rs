//! The write-back: a level's output GLB from every page's encoded images.
//!
//! In: the scene, the [`Level`], every page's [`Encoded`] images and the
//! settings. Out: the GLB's bytes ([`gltf::write`](crate::gltf::write)
//! edits the input's JSON, and the fingerprint is sealed in) and the
//! warnings, the scene's and the writer's, with the one a relaxed atlas
//! gets.

use super::level::Level;
use super::reuse::{self, Fingerprint};
use crate::atlas::AtlasSize;
use crate::encode::Encoded;
use crate::error::Result;
use crate::gltf::Scene;
use crate::gltf::write::{self, BakeRecord, OutputOptions};
use crate::job::settings::{BakeSettings, Method, UvSource};
use crate::stage::StageTimer;
use std::path::Path;

/// The output GLB of a level from every page's encoded images (`pages[k]`
/// is page k's), with the scene's warnings and the writer's. `output_dir`:
/// where the GLB will be written, so external URIs resolve from there.
/// `input_hash`: the input's ([`reuse::input_hash`]), when known: the
/// output then carries its sealed [`Fingerprint`].
pub fn write(
    scene: &Scene,
    level: &Level,
    pages: &[&Encoded],
    s: &BakeSettings,
    output_dir: Option<&Path>,
    input_hash: Option<u64>,
    timer: &mut StageTimer,
) -> Result<(Vec<u8>, Vec<String>)> {
    timer.restart();
    let fingerprint = input_hash.map(|h| {
        Fingerprint::new(h, s, scene, &level.geometry.space, &level.atlas, pages).to_json()
    });
    let options = OutputOptions {
        record: BakeRecord {
            method: s.method.name().to_string(),
            rays: match s.method {
                Method::Mc => s.rays,
                Method::Sheared => s.sheared.sparse_rays,
                Method::Adaptive => s.adaptive.quality,
            },
            seed: s.seed,
            max_distance: level.max_distance_world,
            width: level.atlas.width,
            height: level.atlas.height,
            filter: s.filter,
            fingerprint: fingerprint.clone(),
        },
        occlusion: s.occlusion,
        visibility_meshes: level.visibility_meshes.clone(),
        existing_uv: match s.uv {
            UvSource::Existing(set) => Some(set),
            UvSource::Generate => None,
        },
        output_dir: output_dir.map(Path::to_path_buf),
    };
    let mut warnings = scene.warnings.clone();
    if let (Some(relaxed), AtlasSize::Resolution(r)) = (level.atlas.relaxed, s.size) {
        let view = level.ladder.as_ref().filter(|l| l.chosen != 0);
        let why = match (view, relaxed.starved) {
            (Some(l), _) => {
                let (first, kept) = (&l.rungs[0], &l.rungs[l.chosen]);
                format!(
                    "on one {r}x{r} page the engine view read {:.4} AO error with padding {} and minimum chart width {} ({:.0}% of it used) and {:.4} with padding {} and minimum chart width {}",
                    first.ao_rmse,
                    first.padding,
                    first.min_chart_width,
                    100.0 * first.utilization,
                    kept.ao_rmse,
                    kept.padding,
                    kept.min_chart_width
                )
            }
            (None, true) => format!(
                "with padding {} and minimum chart width {} the charts would cover under {:.0}% of one {r}x{r} page",
                s.padding,
                s.min_chart_width,
                100.0 * crate::atlas::unwrap::STARVED_UTILIZATION
            ),
            // (No count: the atlas's is the relaxed packing's, and without
            // a minimum width the bent strips are not cut into pieces.)
            (None, false) => format!(
                "the charts do not fit one {r}x{r} page with padding {} and minimum chart width {}",
                s.padding, s.min_chart_width
            ),
        };
        warnings.push(format!(
            "{why}: packed with padding {} and minimum chart width {}{} (raise --resolution for the requested ones)",
            relaxed.padding,
            relaxed.min_chart_width,
            if relaxed.padding == 0 {
                ", so lookups at chart edges blend neighbouring charts"
            } else {
                ", charts on texel centres"
            },
        ));
    }
    let mut glb = write::build_glb(
        scene,
        &level.geometry,
        &level.atlas,
        pages,
        &options,
        &mut warnings,
    )?;
    if let Some(f) = &fingerprint {
        reuse::seal(&mut glb, f);
    }
    timer.lap("write");
    Ok((glb, warnings))
}
