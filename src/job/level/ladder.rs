//! A small page's padding and minimum chart width, chosen by the engine
//! view (`--ladder view`, the default).
//!
//! In: a [`Level`] built on the rule's atlas, on a small page where the
//! rule cannot decide ([`crate::atlas::unwrap::ladder_applies`]: tight as
//! asked, or relaxed to no padding), the same charts packed the other ways
//! worth baking, the scene and the settings. Out: the level on the atlas
//! whose small bake reads the least AO error at surface points, and the
//! figures of every option ([`LadderReport`]).
//!
//! Why: on a tight page every texel of padding or of chart width is taken
//! from the density, and whether it pays depends on the charts, which
//! the utilisation alone does not tell (the flight helmet at 512 fits
//! padding 2 at 24% of the page and reads 1.34x the error of a texel of
//! padding; `docs/measurements/chart-count.md`). So each option is baked
//! as the bake will be (the same method, passes, fit and seams) at a low
//! budget, looked up where an engine looks (bilinear lookups of its
//! written textures at [`PROBE_POINTS`] surface points, uniform by area:
//! the options share triangles and differ only in UVs, so the same seed
//! gives every one the same points and reference) and the least error
//! over all points is kept; the rule's pick wins a tie.

use super::Level;
use crate::atlas::Atlas;
use crate::error::Result;
use crate::gltf::Scene;
use crate::job::settings::{BakeSettings, Method, RunOptions};
use crate::stage::StageTimer;
use serde::{Deserialize, Serialize};

/// Surface points each option is measured at.
pub const PROBE_POINTS: usize = 8_000;

/// Rays of the points' reference (its noise is common to every option).
pub const PROBE_REFERENCE_RAYS: u32 = 256;

/// The budget of each option's bake: `--quality`, or Monte Carlo's rays,
/// at most this. The options differ in what the texels reconstruct, which
/// the noise of a few more rays does not change.
pub const PROBE_BUDGET: u32 = 64;

/// Rays of each border fit point in an option's bake (a bake's are
/// [`crate::lightmap::border::FIT_RAYS`]): the fit is most of a small
/// tight page's bake, and its noise is the same for every option.
pub const PROBE_FIT_RAYS: u32 = 16;

/// Seed of the probe's points and reference (never a bake's rays).
const PROBE_SEED: u64 = 0x001a_dde4_5eed;

/// One option of the ladder, as measured.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LadderRung {
    /// Padding and minimum chart width it was packed with.
    pub padding: u32,
    pub min_chart_width: f32,
    /// Whether these are the options asked for.
    pub asked: bool,
    pub charts: u32,
    pub utilization: f32,
    /// Texels per world unit.
    pub texel_density: f64,
    /// The probe bake's engine view: AO RMSE over all points.
    pub ao_rmse: f64,
}

/// The options the engine view chose among and which it kept.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LadderReport {
    /// The rule's pick first, then the other options in the ladder's
    /// order.
    pub rungs: Vec<LadderRung>,
    /// Index of the option kept.
    pub chosen: usize,
}

/// The settings of an option's bake: `s` at most [`PROBE_BUDGET`], without
/// the visibility layer (the AO decides).
fn probe_settings(s: &BakeSettings) -> BakeSettings {
    let mut p = s.clone();
    p.adaptive.quality = p.adaptive.quality.min(PROBE_BUDGET);
    if p.adaptive.mean_rays > 0 {
        p.adaptive.mean_rays = p.adaptive.mean_rays.min(PROBE_BUDGET);
    }
    if p.method == Method::Mc {
        p.rays = p.rays.min(PROBE_BUDGET);
    }
    p
}

/// Puts `level` on the option among its atlas and `others` whose probe
/// bake reads the least AO error at surface points (module doc).
pub(crate) fn choose(
    level: &mut Level,
    others: Vec<Atlas>,
    scene: &Scene,
    s: &BakeSettings,
) -> Result<LadderReport> {
    let probe_s = probe_settings(s);
    let run = RunOptions::QUIET;
    let layer = std::mem::take(&mut level.visibility_meshes);
    level.visibility_meshes = vec![false; layer.len()];
    let mut options = vec![level.atlas.clone()];
    options.extend(others);
    let mut rungs = Vec::with_capacity(options.len());
    let result = (|| -> Result<()> {
        for atlas in &options {
            level.atlas = atlas.clone();
            let mut timer = StageTimer::new();
            let mut page = level.page(0, scene, &mut timer)?;
            page.fit_rays = PROBE_FIT_RAYS;
            // The options share triangles and differ in UVs: the same
            // seed gives every one the same points and reference.
            let probe = page.engine_probe(PROBE_POINTS, PROBE_REFERENCE_RAYS, PROBE_SEED, false);
            let passes = page.bake(&probe_s, &run, &mut timer)?;
            let out = page.finish(&passes, &probe_s, &run, &mut timer)?;
            let view = page.engine_view_against(&probe, &out.encoded, probe_s.filter)?;
            let relaxed = atlas.relaxed;
            rungs.push(LadderRung {
                padding: relaxed.map_or(s.padding, |r| r.padding),
                min_chart_width: relaxed.map_or(s.min_chart_width, |r| r.min_chart_width),
                asked: relaxed.is_none(),
                charts: atlas.charts,
                utilization: atlas.utilization,
                texel_density: atlas.texels_per_unit / level.geometry.space.diagonal,
                ao_rmse: view.all.ao_rmse,
            });
        }
        Ok(())
    })();
    level.visibility_meshes = layer;
    result?;
    // The least error; the earlier option (the rule's pick first) on a tie
    // or where an error is not a number.
    let mut chosen = 0;
    for (k, r) in rungs.iter().enumerate() {
        if r.ao_rmse < rungs[chosen].ao_rmse {
            chosen = k;
        }
    }
    level.atlas = options.swap_remove(chosen);
    Ok(LadderReport { rungs, chosen })
}
