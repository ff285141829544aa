//! Unwrap: every baked placement into lightmap atlas pages.
//!
//! In: the [`ReceiverMesh`]es (bake space) and an [`AtlasSize`]. Out: an
//! [`Atlas`]: its pages' sizes and, per receiver mesh, the new vertices
//! (`xref` into the input vertices, `uv` in `[0,1]` of their page with (0,0)
//! at the image's top-left), the same triangles re-indexed and each
//! triangle's page. A resolution gives one page; a texel density packs as
//! many pages of at most `page_size` texels as the charts need (a chart
//! never spans pages). Backed by the pure-Rust `uvunwrap` crate; the rest of
//! the pipeline sees only these types, so a backend can be swapped.

mod ladder;

pub use super::pages::{ChartTooLarge, ChartedMesh, PageSize};
use super::pages::{crop_last_page, largest_chart};
use crate::error::{Error, Result};
use crate::geometry::ReceiverMesh;
pub use ladder::{LADDER_MAX_EDGE, LADDER_UTILIZATION, Ladder, ladder_applies};
use ladder::{Packed, alternatives};

/// Largest atlas edge in texels (a 16k x 16k page with SH is ~6 GiB of floats).
pub const MAX_ATLAS_EDGE: u32 = 16384;

/// How the atlas is sized.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[non_exhaustive]
pub enum AtlasSize {
    /// The highest density at which everything fits one page of this edge.
    Resolution(u32),
    /// Texels per world unit, on as many pages of at most `page_size`
    /// texels square as the charts need (the last one cropped).
    TexelDensity { density: f64, page_size: u32 },
}

/// Unwrap options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnwrapOptions {
    pub size: AtlasSize,
    /// Empty texels around each chart (charts are `2 * padding` apart).
    pub padding: u32,
    pub packing: Packing,
    /// Smallest chart width in texels (0: none); see
    /// `BakeSettings::min_chart_width`.
    pub min_chart_width: f32,
}

/// Chart packing: `Fast` (rows; measured 6x faster on Sponza, 13x on 27k
/// charts, ~8% fewer texels) or `Shape` (nests charts; densest, slow with
/// thousands of charts).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[non_exhaustive]
pub enum Packing {
    #[default]
    Fast,
    Shape,
}

/// A lightmap atlas of one or more pages.
#[derive(Clone, Debug)]
pub struct Atlas {
    /// The largest page's size (the only page's, with one).
    pub width: u32,
    pub height: u32,
    pub charts: u32,
    pub utilization: f32,
    /// Texels per bake unit.
    pub texels_per_unit: f64,
    pub pages: Vec<PageSize>,
    pub meshes: Vec<ChartedMesh>,
    /// Where the charts fit one page only with less padding or a smaller
    /// minimum chart width than asked ([`relaxed_options`]): what they got.
    pub relaxed: Option<Relaxed>,
}

/// The padding and minimum chart width an atlas was packed with where
/// those asked for would not fit one page, or would starve it
/// ([`STARVED_UTILIZATION`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relaxed {
    pub padding: u32,
    pub min_chart_width: f32,
    /// The asked options fit one page, but at under
    /// [`STARVED_UTILIZATION`] of it.
    pub starved: bool,
}

/// Utilisation below which a `--resolution` page packed as asked is
/// starved: many charts on a small page, where each chart's padding and
/// minimum width take most of the page and the packer shrinks the density
/// until every chart is a few texels of border (the flight helmet's 2,530
/// charts at 256: 2.4%, against 41% at 1024 and 15% with a texel of
/// padding). There, as where the charts do not fit, the next of
/// [`relaxed_options`] is tried, and taken where it at least doubles the
/// texel density ([`STARVED_GAIN`]); a rung that fits starved is passed
/// over the same way (the flight helmet at 128: padding 1 with width 1
/// fits at 23 texels per unit, no padding at 68).
pub const STARVED_UTILIZATION: f32 = 0.2;

/// How many times a starved page's density the next rung must reach to be
/// taken.
pub const STARVED_GAIN: f64 = 2.0;

/// Charts times page texels up to which a relaxed page is also packed by
/// the charts' shapes: the shape packer searches the page for each chart,
/// so its time grows with both. The flight helmet at 256 (3,277 charts,
/// 2.1e8) nests in about 2 s more than rows on 2 threads; the dense city
/// diorama at 1024 (27,742 charts, 2.9e10) took 372 s to nest against 51 s
/// in rows (both beside another job).
pub const NEST_BUDGET: f64 = 1.0e9;

/// The options tried, in order, when the charts of a `--resolution` atlas
/// need more than one page with the `padding` and `min_chart_width` asked
/// for (or fit it starved): one texel of padding (no texel a bilinear
/// lookup reads is shared by two charts) and charts at least one texel
/// wide; then the same padding and no minimum width; then neither (the
/// neighbouring charts' texels touch: lookups at chart edges blend them,
/// which the warning says). The width goes before the padding: on a page
/// that tight, the stretched charts and the bent strips cut into pieces
/// cost more texels than they give back, while a texel of padding keeps
/// every lookup on its own chart (`docs/measurements/chart-count.md`,
/// small pages). Only options smaller than those asked are tried. Each
/// is packed by the texels lookups read, the charts' minima on texel
/// centres (`uvunwrap::Options::lookup_packing`): on a page of many small
/// charts the texels it saves are worth more than the gutter and the free
/// texel beyond a chart's edge that the border fit uses; on a page of
/// large ones they are not (`docs/measurements/chart-count.md`).
pub fn relaxed_options(padding: u32, min_chart_width: f32) -> Vec<Relaxed> {
    let width = min_chart_width.min(1.0);
    let mut options = [(padding.min(1), width), (padding.min(1), 0.0), (0, 0.0)]
        .into_iter()
        .filter(|&(p, w)| p < padding || w < min_chart_width)
        .map(|(padding, min_chart_width)| Relaxed {
            padding,
            min_chart_width,
            starved: false,
        })
        .collect::<Vec<_>>();
    // (Asked without padding or width, some are the same.)
    options.dedup();
    options
}

impl Atlas {
    /// Page `page` alone, as a one-page atlas (every mesh keeps its
    /// vertices and only its triangles on that page).
    pub fn page(&self, page: u32) -> Atlas {
        let size = self.pages[page as usize];
        Atlas {
            width: size.width,
            height: size.height,
            charts: self.charts,
            utilization: self.utilization,
            texels_per_unit: self.texels_per_unit,
            pages: vec![size],
            meshes: self.meshes.iter().map(|m| m.on_page(page)).collect(),
            relaxed: self.relaxed,
        }
    }

    /// Per page, the triangles on it.
    pub fn page_triangles(&self) -> Vec<usize> {
        let mut n = vec![0; self.pages.len()];
        for m in &self.meshes {
            for &p in &m.triangle_page {
                n[p as usize] += 1;
            }
        }
        n
    }

    /// Per page, the texels its triangles cover (their UV area; the
    /// rasterizer's conservative edges add a little).
    pub fn page_areas(&self) -> Vec<f64> {
        let mut area = vec![0.0; self.pages.len()];
        for m in &self.meshes {
            for (t, &p) in m.triangles.chunks_exact(3).zip(&m.triangle_page) {
                let [a, b, c] = [0, 1, 2].map(|k| m.uv[t[k] as usize]);
                let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                let s = self.pages[p as usize];
                area[p as usize] += 0.5 * (cross as f64).abs() * s.width as f64 * s.height as f64;
            }
        }
        area
    }
}

/// Checks an atlas size: a resolution in 16..=[`MAX_ATLAS_EDGE`], a
/// finite positive texel density.
pub fn check_size(size: AtlasSize) -> Result<()> {
    match size {
        AtlasSize::Resolution(r) if !(16..=MAX_ATLAS_EDGE).contains(&r) => Err(Error::option(
            "resolution",
            format!("{r} is outside 16..={MAX_ATLAS_EDGE}"),
        )),
        AtlasSize::TexelDensity { density: t, .. } if !(t.is_finite() && t > 0.0) => Err(
            Error::option("texel_density", format!("{t} must be finite and > 0")),
        ),
        AtlasSize::TexelDensity { page_size: e, .. } if !(16..=MAX_ATLAS_EDGE).contains(&e) => Err(
            Error::option("page_size", format!("{e} is outside 16..={MAX_ATLAS_EDGE}")),
        ),
        _ => Ok(()),
    }
}

/// Unwraps all receiver meshes into pages (its size must have passed
/// [`check_size`]). `diagonal` converts a world texel density into bake
/// space.
pub fn unwrap(meshes: &[ReceiverMesh], options: &UnwrapOptions, diagonal: f64) -> Result<Atlas> {
    match unwrap_with_progress(meshes, options, diagonal, None, false, &|_, _, _| {})? {
        Ok(mut atlases) => Ok(atlases.swap_remove(0)),
        Err(c) => Err(Error::Limit(format!(
            "a chart of receiver mesh {} is {}x{} texels, larger than a page; a texel density of {:.4} would fit",
            c.mesh, c.width, c.height, c.fitting_density
        ))),
    }
}

/// [`unwrap`], reporting (stage name, done, total if known) as it goes,
/// and returning a chart that fits no page as its own outcome (the
/// pipeline names its glTF object). `scales`: per mesh, a factor on its
/// texel density (`--texel-budget signal`); `None`, uniform. The atlas
/// is the first of those returned; with `ladder`, a small page that
/// offers a choice ([`ladder_applies`]) comes with the same charts packed
/// the other ways worth baking after it, for the engine view to choose.
pub(crate) fn unwrap_with_progress(
    meshes: &[ReceiverMesh],
    options: &UnwrapOptions,
    diagonal: f64,
    scales: Option<&[f32]>,
    ladder: bool,
    progress: &(dyn Fn(&'static str, usize, Option<usize>) + Sync),
) -> Result<std::result::Result<Vec<Atlas>, ChartTooLarge>> {
    let density = match options.size {
        AtlasSize::Resolution(r) => uvunwrap::Density::Auto { page_size: r },
        AtlasSize::TexelDensity {
            density: t,
            page_size,
        } => {
            let tpu = t * diagonal;
            if !(tpu.is_finite() && tpu > 0.0) {
                return Err(Error::option(
                    "texel_density",
                    format!("{t} is too large for this scene ({tpu} texels per bake unit)"),
                ));
            }
            uvunwrap::Density::Fixed {
                texels_per_unit: tpu as f32,
                page_size: Some(page_size),
            }
        }
    };
    // Each mesh's density scale: the unwrapper's per-mesh factor from mesh
    // to world units, which only the packer's sizes see.
    let inputs: Vec<uvunwrap::MeshInput> = meshes
        .iter()
        .enumerate()
        .map(|(k, m)| uvunwrap::MeshInput {
            scale: scales.map_or(1.0, |s| s[k]),
            ..uvunwrap::MeshInput::new(&m.shape, &m.triangles)
        })
        .collect();
    let opts = uvunwrap::Options {
        density,
        padding: options.padding,
        packing: match options.packing {
            Packing::Fast => uvunwrap::Packing::Fast,
            Packing::Shape => uvunwrap::Packing::Shape,
        },
        min_chart_width: options.min_chart_width,
        ..Default::default()
    };
    let report = |p: uvunwrap::Progress| {
        let stage = match p.stage {
            uvunwrap::Stage::Segmenting => "segmenting",
            uvunwrap::Stage::Parameterizing => "flattening",
            uvunwrap::Stage::Packing => "packing",
            _ => "unwrapping",
        };
        progress(stage, p.done, p.total);
        true
    };
    // Segmented and flattened once: the relaxing ladder's rungs and the
    // fallbacks differ only in padding, chart width, density and packing
    // (the same atlas as a fresh unwrap under each: vendor/uvunwrap's
    // PATCHES.md).
    let prepared = uvunwrap::prepare_with_progress(&inputs, &opts, report);
    let generate = |opts: &uvunwrap::Options| match &prepared {
        Ok(p) => p.generate_with_progress(&inputs, opts, report),
        Err(e) => Err(e.clone()),
    };
    let mut atlas = match (generate(&opts), options.size) {
        (Ok(a), _) => a,
        (
            Err(uvunwrap::Error::ChartTooLarge { .. }),
            AtlasSize::TexelDensity { density, page_size },
        ) => {
            // Which mesh's chart: the same density on one unbounded page.
            let unbounded = uvunwrap::Options {
                density: uvunwrap::Density::Fixed {
                    texels_per_unit: (density * diagonal) as f32,
                    page_size: None,
                },
                ..opts
            };
            let whole = generate(&unbounded).map_err(|e| Error::Unwrap(e.to_string()))?;
            return Ok(Err(largest_chart(
                &whole,
                options.padding,
                page_size,
                density,
            )));
        }
        (Err(e), _) => return Err(Error::Unwrap(e.to_string())),
    };
    // A `--resolution` atlas is one page: where the charts need more, or
    // fit but starve it, less padding and narrower charts before a refusal.
    let mut relaxed = None;
    let mut others = Vec::new();
    if let AtlasSize::Resolution(resolution) = options.size {
        // The rungs packed and passed over, which the ladder weighs again.
        let mut passed = Vec::new();
        (atlas, relaxed) = relax(atlas, resolution, options, &opts, &generate, &mut passed)?;
        if atlas.page_count > 1 {
            return Err(Error::Limit(format!(
                "the {} charts cannot share one atlas page even without padding (they need {} pages); raise the resolution",
                atlas.chart_count, atlas.page_count
            )));
        }
        if ladder && ladder_applies(resolution, atlas.utilization, relaxed) {
            let density = atlas.texels_per_unit;
            let packed = Packed {
                passed,
                opts: &opts,
                generate: &generate,
            };
            others = alternatives(resolution, relaxed, density, options, packed)?;
        }
    }
    let mut out = vec![to_atlas(atlas, options, relaxed)?];
    for (a, r) in others {
        out.push(to_atlas(a, options, Some(r))?);
    }
    Ok(Ok(out))
}

/// The unwrapper's one-page atlas as the pipeline's [`Atlas`].
fn to_atlas(
    atlas: uvunwrap::Atlas,
    options: &UnwrapOptions,
    relaxed: Option<Relaxed>,
) -> Result<Atlas> {
    if atlas.width > MAX_ATLAS_EDGE || atlas.height > MAX_ATLAS_EDGE {
        return Err(Error::Limit(format!(
            "the atlas would be {}x{} texels, more than the {MAX_ATLAS_EDGE} limit; lower the texel density",
            atlas.width, atlas.height
        )));
    }
    let (w, h) = (atlas.width.max(1), atlas.height.max(1));
    let page_count = atlas.page_count.max(1);
    let mut meshes: Vec<ChartedMesh> = atlas
        .meshes
        .into_iter()
        .map(|m| {
            let page_of = |v: u32| m.vertices[v as usize].page;
            let triangle_page = m
                .indices
                .chunks_exact(3)
                .map(|t| t.iter().find_map(|&v| page_of(v)).unwrap_or(0))
                .collect();
            ChartedMesh {
                xref: m.vertices.iter().map(|v| v.xref).collect(),
                uv: m.vertices.iter().map(|v| v.uv).collect(),
                triangles: m.indices,
                triangle_page,
            }
        })
        .collect();
    let pages = match options.size {
        AtlasSize::TexelDensity { .. } => {
            crop_last_page(&mut meshes, w, h, page_count, options.padding)
        }
        AtlasSize::Resolution(_) => vec![PageSize {
            width: w,
            height: h,
        }],
    };
    Ok(Atlas {
        width: pages.iter().map(|p| p.width).max().unwrap_or(w),
        height: pages.iter().map(|p| p.height).max().unwrap_or(h),
        charts: atlas.chart_count,
        utilization: atlas.utilization,
        texels_per_unit: atlas.texels_per_unit as f64,
        pages,
        meshes,
        relaxed,
    })
}

/// Builds the atlas from an existing UV set of every receiver mesh instead
/// of unwrapping (`uvs[m]`: one UV in [0, 1] per vertex of `meshes[m]`,
/// read and checked by the loader, `gltf::Scene::lightmap_uvs`): the page is
/// `resolution` square, vertices are not split.
pub fn existing(meshes: &[ReceiverMesh], uvs: Vec<Vec<[f32; 2]>>, resolution: u32) -> Atlas {
    let out = meshes
        .iter()
        .zip(uvs)
        .map(|(m, uv)| ChartedMesh {
            xref: (0..m.positions.len() as u32).collect(),
            uv,
            triangle_page: vec![0; m.triangles.len() / 3],
            triangles: m.triangles.clone(),
        })
        .collect();
    Atlas {
        width: resolution,
        height: resolution,
        charts: 0,
        utilization: 0.0,
        texels_per_unit: 0.0,
        pages: vec![PageSize {
            width: resolution,
            height: resolution,
        }],
        meshes: out,
        relaxed: None,
    }
}

/// The ladder of a `--resolution` page `resolution` texels square: while
/// the page does not hold the charts, or
/// holds them starved (under [`STARVED_UTILIZATION`]), the next of
/// [`relaxed_options`], taken where the charts did not fit, or where it
/// multiplies the texel density by at least [`STARVED_GAIN`]. Each rung
/// is packed by the texels lookups read, the charts on texel centres
/// (`uvunwrap::Options::lookup_packing`), and, where it keeps a texel
/// of padding, once more by the charts' shapes, the denser taken: nesting
/// the small charts such a page holds gains more than rows of them do,
/// where the nesting's search stays within [`NEST_BUDGET`] (a page
/// relaxed to no padding holds tens of thousands of charts, where nesting
/// costs most and gave nothing measured).
fn relax(
    mut atlas: uvunwrap::Atlas,
    resolution: u32,
    options: &UnwrapOptions,
    opts: &uvunwrap::Options,
    generate: &dyn Fn(&uvunwrap::Options) -> std::result::Result<uvunwrap::Atlas, uvunwrap::Error>,
    passed: &mut Vec<(Relaxed, uvunwrap::Atlas)>,
) -> Result<(uvunwrap::Atlas, Option<Relaxed>)> {
    let mut relaxed: Option<Relaxed> = None;
    let asked_fits = atlas.page_count <= 1;
    for r in relaxed_options(options.padding, options.min_chart_width) {
        let fits = atlas.page_count <= 1;
        if fits && atlas.utilization >= STARVED_UTILIZATION {
            break;
        }
        let next = pack_rung(&r, resolution, options, opts, generate)?;
        let pays = next.page_count <= 1
            && next.texels_per_unit as f64 >= STARVED_GAIN * atlas.texels_per_unit as f64;
        if !fits || pays {
            let before = std::mem::replace(&mut atlas, next);
            if let Some(b) = relaxed {
                passed.push((b, before));
            }
            relaxed = Some(Relaxed {
                starved: asked_fits,
                ..r
            });
        } else {
            passed.push((r, next));
        }
    }
    Ok((atlas, relaxed))
}

/// Rung `r` of the ladder of a `resolution` page packed (see [`relax`]).
pub(super) fn pack_rung(
    r: &Relaxed,
    resolution: u32,
    options: &UnwrapOptions,
    opts: &uvunwrap::Options,
    generate: &dyn Fn(&uvunwrap::Options) -> std::result::Result<uvunwrap::Atlas, uvunwrap::Error>,
) -> Result<uvunwrap::Atlas> {
    let pack = |o: &uvunwrap::Options| generate(o).map_err(|e| Error::Unwrap(e.to_string()));
    let page = resolution as f64 * resolution as f64;
    let o = uvunwrap::Options {
        padding: r.padding,
        min_chart_width: r.min_chart_width,
        lookup_packing: true,
        ..*opts
    };
    let rows = pack(&o)?;
    if r.padding == 0
        || options.packing != Packing::Fast
        || rows.page_count > 1
        || rows.chart_count as f64 * page > NEST_BUDGET
    {
        return Ok(rows);
    }
    let nested = pack(&uvunwrap::Options {
        packing: uvunwrap::Packing::Shape,
        ..o
    })?;
    Ok(
        if nested.page_count <= 1 && nested.texels_per_unit > rows.texels_per_unit {
            nested
        } else {
            rows
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relaxed_options_shrink_only_what_was_asked_for() {
        let r = |padding, min_chart_width| Relaxed {
            padding,
            min_chart_width,
            starved: false,
        };
        assert_eq!(
            relaxed_options(2, 2.0),
            vec![r(1, 1.0), r(1, 0.0), r(0, 0.0)]
        );
        assert_eq!(
            relaxed_options(3, 0.5),
            vec![r(1, 0.5), r(1, 0.0), r(0, 0.0)]
        );
        assert_eq!(relaxed_options(1, 1.0), vec![r(1, 0.0), r(0, 0.0)]);
        assert_eq!(
            relaxed_options(1, 2.0),
            vec![r(1, 1.0), r(1, 0.0), r(0, 0.0)]
        );
        assert_eq!(relaxed_options(1, 0.0), vec![r(0, 0.0)]);
        assert_eq!(relaxed_options(0, 3.0), vec![r(0, 1.0), r(0, 0.0)]);
        assert_eq!(relaxed_options(0, 1.0), vec![r(0, 0.0)]);
        assert_eq!(relaxed_options(0, 0.0), vec![]);
    }
}
