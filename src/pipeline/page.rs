//! One page: the method's passes, then dilate, seams and encode; and the
//! write-back of every page's images into one GLB.
//!
//! In: a [`Prepared`] page and the settings. Out: [`BakePasses`] (the
//! method's results and figures), [`PageOutput`] (the page's float
//! lightmap, its encoded images and seam figures), and from the encoded
//! pages of a whole level the output GLB bytes ([`write`]).

use super::level::{Level, Prepared, page_seed};
use crate::atlas::dilate;
use crate::bake::adaptive::{self, AdaptiveStats};
use crate::bake::sheared::{self, FilterStats};
use crate::bake::{Bake, BakeParams, mc, visibility};
use crate::encode::{self, Encoded, Lightmap};
use crate::error::{Error, Result};
use crate::file;
use crate::gltf::Scene;
use crate::gltf::write::{self, BakeRecord, OutputOptions};
use crate::seams::{self, SMOOTH_DEGREES, SeamReport};
use crate::settings::{Method, SeamMode, Settings, UvSource};
use crate::stage::{StageTime, StageTimer, progress_bar};
use std::path::{Path, PathBuf};

/// What a method's passes over prepared receivers produced.
pub struct BakePasses {
    pub bake: Bake,
    /// Filtered method only.
    pub filter_stats: Option<FilterStats>,
    /// Adaptive method only.
    pub adaptive_stats: Option<AdaptiveStats>,
    /// The method's own passes: `trace` (Monte Carlo), or `sparse pass` and
    /// `filter pass` (filtered).
    pub stages: Vec<StageTime>,
}

impl BakePasses {
    /// Per receiver: inside geometry, from the validity stage or, when
    /// the method found them itself, from its passes.
    pub fn inside<'a>(&'a self, p: &'a Prepared) -> &'a [bool] {
        match (&p.inside, &self.adaptive_stats) {
            (Some(inside), _) => inside,
            (None, Some(stats)) => &stats.inside,
            (None, None) => &[],
        }
    }
}

/// What the output stages made of one page.
pub struct PageOutput {
    pub lightmap: Lightmap,
    pub encoded: Encoded,
    /// The seams before and after stitching (`--seams stitch`).
    pub seams: Option<SeamReport>,
}

/// Page 0's files go into `dir` itself, page k's into `dir/page-k`.
fn page_dir(dir: &Path, page: u32) -> PathBuf {
    if page == 0 {
        dir.to_path_buf()
    } else {
        dir.join(format!("page-{page}"))
    }
}

/// Runs the method's passes over prepared receivers (`s` validated, as by
/// [`prepare`]).
pub fn bake_prepared(p: &Prepared, s: &Settings, timer: &mut StageTimer) -> Result<BakePasses> {
    let (receivers, tracer) = (&p.receivers, &p.tracer);
    let params = BakeParams {
        max_distance: p.max_distance,
        seed: page_seed(s.seed, p.page),
    };
    let first = timer.stages().len();
    timer.restart();
    let pb = progress_bar(s.progress, receivers.len() as u64, "baking");
    let progress = |n| pb.inc(n);
    let (bake, filter_stats, adaptive_stats) = match s.method {
        Method::Mc => {
            let mut b = mc::bake(receivers, tracer, s.rays, &params, &progress);
            timer.lap("trace");
            if p.bakes_visibility() {
                b.visibility = Some(visibility::bake(receivers, tracer, s.rays, &params));
                timer.lap("visibility pass");
            }
            (b, None, None)
        }
        Method::Sheared => {
            let (b, stats) =
                sheared::bake(receivers, tracer, &s.filter, &params, timer, &progress)?;
            (b, Some(stats), None)
        }
        Method::Adaptive => {
            let (b, stats) = adaptive::bake(
                receivers,
                tracer,
                s.fill_inside,
                p.bakes_visibility(),
                &s.adaptive,
                &params,
                timer,
                &progress,
            );
            (b, None, Some(stats))
        }
    };
    pb.finish_and_clear();
    Ok(BakePasses {
        bake,
        filter_stats,
        adaptive_stats,
        stages: timer.since(first).to_vec(),
    })
}

/// Dilates, stitches and encodes one page's bake (and writes its debug
/// maps and EXR if asked: page 0's into the directories given, page k's
/// into their `page-k` subdirectories).
pub fn output_page(
    p: &Prepared,
    passes: &BakePasses,
    s: &Settings,
    timer: &mut StageTimer,
) -> Result<PageOutput> {
    timer.restart();
    let receivers = &p.receivers;
    let debug_dir = s.debug_dir.as_ref().map(|d| page_dir(d, p.page));
    if let Some(dir) = &debug_dir {
        if let Some(stats) = &passes.filter_stats {
            encode::write_grey_maps(dir, receivers, &stats.debug_maps(p.max_distance))?;
        }
        if let Some(stats) = &passes.adaptive_stats {
            encode::write_grey_maps(dir, receivers, &stats.debug_maps(p.max_distance))?;
        }
    }
    let fill = dilate::fill_map(
        receivers.width,
        receivers.height,
        &receivers.texel,
        passes.inside(p),
    );
    let mut lightmap = encode::lightmap(receivers, &passes.bake, &fill)?;
    timer.lap("dilate");
    let seams = (s.seams == SeamMode::Stitch).then(|| {
        let found = seams::find::smooth_seams(&p.geometry.receivers, &p.atlas, SMOOTH_DEGREES);
        let (w, h) = (lightmap.width, lightmap.height);
        let map = |lm: &Lightmap| {
            let points = seams::metric::points(&found, w, h, &lm.ao, &lm.sh);
            seams::jump_map(&points, w, h)
        };
        let before = debug_dir.as_ref().map(|_| map(&lightmap));
        // Seams to other pages: this side meets the target both compute.
        let anchors = seams::anchor::anchors(
            &p.cross_seams,
            p.page,
            &p.pages,
            &p.tracer,
            p.max_distance,
            s.seed,
            lightmap.visibility.is_some(),
        );
        let report = seams::stitch_page(
            &found,
            &anchors,
            p.geometry.space.diagonal,
            w,
            h,
            &lightmap.covered,
            &mut lightmap.ao,
            &mut lightmap.sh,
            lightmap.visibility.as_deref_mut(),
        );
        let maps = before.map(|b| (b, map(&lightmap)));
        (report, maps)
    });
    let seams = match seams {
        Some((report, maps)) => {
            if let (Some(dir), Some((before, after))) = (&debug_dir, maps) {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
                for (name, img) in [("seams_before", before), ("seams_after", after)] {
                    let png = encode::png(
                        lightmap.width,
                        lightmap.height,
                        &img,
                        image::ExtendedColorType::L8,
                    )?;
                    file::write_atomic(&dir.join(format!("{name}.png")), &png)?;
                }
            }
            timer.lap("seams");
            Some(report)
        }
        None => None,
    };
    let encoded = encode::encode(&lightmap, s.visibility_order)?;
    if let Some(dir) = &s.exr_dir {
        let dir = page_dir(dir, p.page);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        encode::write_exr(&lightmap, &dir.join("lightmap.exr"))?;
    }
    timer.lap("encode");
    Ok(PageOutput {
        lightmap,
        encoded,
        seams,
    })
}

/// The output GLB of a level from every page's encoded images (`pages[k]`
/// is page k's), with the scene's warnings and the writer's. `output_dir`:
/// where the GLB will be written, so external URIs resolve from there.
pub fn write(
    scene: &Scene,
    level: &Level,
    pages: &[&Encoded],
    s: &Settings,
    output_dir: Option<&Path>,
    timer: &mut StageTimer,
) -> Result<(Vec<u8>, Vec<String>)> {
    timer.restart();
    let options = OutputOptions {
        record: BakeRecord {
            method: s.method.name().to_string(),
            rays: match s.method {
                Method::Mc => s.rays,
                Method::Sheared => s.filter.sparse_rays,
                Method::Adaptive => s.adaptive.quality,
            },
            seed: s.seed,
            max_distance: level.max_distance_world,
            width: level.atlas.width,
            height: level.atlas.height,
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
    let glb = write::build_glb(
        scene,
        &level.geometry,
        &level.atlas,
        pages,
        &options,
        &mut warnings,
    )?;
    timer.lap("write");
    Ok((glb, warnings))
}
