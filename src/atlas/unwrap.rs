//! Unwrap: every baked placement into one lightmap atlas page.
//!
//! In: the [`ReceiverMesh`]es (bake space) and an [`AtlasSize`]. Out: an
//! [`Atlas`]: page size and, per receiver mesh, the new vertices (`xref` into
//! the input vertices, `uv` in `[0,1]` with (0,0) at the image's top-left)
//! and the same triangles re-indexed. Backed by the pure-Rust `uvunwrap`
//! crate; the rest of the pipeline sees only these types, so a backend can be
//! swapped.

use crate::error::{Error, Result};
use crate::geometry::ReceiverMesh;

/// Largest atlas edge in texels (a 16k x 16k page with SH is ~6 GiB of floats).
pub const MAX_ATLAS_EDGE: u32 = 16384;

/// How the atlas is sized.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AtlasSize {
    /// The highest density at which everything fits one page of this edge.
    Resolution(u32),
    /// Texels per world unit; the page grows to fit.
    TexelDensity(f64),
}

/// Unwrap options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnwrapOptions {
    pub size: AtlasSize,
    /// Empty texels around each chart (charts are `2 * padding` apart).
    pub padding: u32,
    pub packing: Packing,
}

/// Chart packing: `Fast` (rows; measured 6x faster on Sponza, 13x on 27k
/// charts, ~8% fewer texels) or `Shape` (nests charts; densest).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Packing {
    #[default]
    Fast,
    Shape,
}

/// One receiver mesh in the atlas.
#[derive(Clone, Debug, Default)]
pub struct ChartedMesh {
    /// Input vertex of each new vertex.
    pub xref: Vec<u32>,
    /// Atlas coordinate of each new vertex.
    pub uv: Vec<[f32; 2]>,
    /// Triangle list over the new vertices, same order as the input.
    pub triangles: Vec<u32>,
}

/// A single-page lightmap atlas.
#[derive(Clone, Debug)]
pub struct Atlas {
    pub width: u32,
    pub height: u32,
    pub charts: u32,
    pub utilization: f32,
    pub meshes: Vec<ChartedMesh>,
}

/// Checks an atlas size: a resolution in 16..=[`MAX_ATLAS_EDGE`], a
/// finite positive texel density.
pub fn check_size(size: AtlasSize) -> Result<()> {
    match size {
        AtlasSize::Resolution(r) if !(16..=MAX_ATLAS_EDGE).contains(&r) => Err(Error::option(
            "resolution",
            format!("{r} is outside 16..={MAX_ATLAS_EDGE}"),
        )),
        AtlasSize::TexelDensity(t) if !(t.is_finite() && t > 0.0) => Err(Error::option(
            "texel_density",
            format!("{t} must be finite and > 0"),
        )),
        _ => Ok(()),
    }
}

/// Unwraps all receiver meshes into one page (its size must have passed
/// [`check_size`]). `diagonal` converts a world
/// texel density into bake space.
pub fn unwrap(meshes: &[ReceiverMesh], options: &UnwrapOptions, diagonal: f64) -> Result<Atlas> {
    unwrap_with_progress(meshes, options, diagonal, &|_, _, _| {})
}

/// [`unwrap`], reporting (stage name, done, total if known) as it goes.
pub fn unwrap_with_progress(
    meshes: &[ReceiverMesh],
    options: &UnwrapOptions,
    diagonal: f64,
    progress: &(dyn Fn(&'static str, usize, Option<usize>) + Sync),
) -> Result<Atlas> {
    let density = match options.size {
        AtlasSize::Resolution(r) => uvunwrap::Density::Auto { page_size: r },
        AtlasSize::TexelDensity(t) => {
            let tpu = t * diagonal;
            if !(tpu.is_finite() && tpu > 0.0) {
                return Err(Error::option(
                    "texel_density",
                    format!("{t} is too large for this scene ({tpu} texels per bake unit)"),
                ));
            }
            uvunwrap::Density::Fixed {
                texels_per_unit: tpu as f32,
                page_size: None,
            }
        }
    };
    let inputs: Vec<uvunwrap::MeshInput> = meshes
        .iter()
        .map(|m| uvunwrap::MeshInput::new(&m.positions, &m.triangles))
        .collect();
    let opts = uvunwrap::Options {
        density,
        padding: options.padding,
        packing: match options.packing {
            Packing::Fast => uvunwrap::Packing::Fast,
            Packing::Shape => uvunwrap::Packing::Shape,
        },
        ..Default::default()
    };
    let atlas = uvunwrap::generate_with_progress(&inputs, &opts, |p| {
        let stage = match p.stage {
            uvunwrap::Stage::Segmenting => "segmenting",
            uvunwrap::Stage::Parameterizing => "flattening",
            uvunwrap::Stage::Packing => "packing",
            _ => "unwrapping",
        };
        progress(stage, p.done, p.total);
        true
    })
    .map_err(|e| Error::Unwrap(e.to_string()))?;
    if atlas.page_count > 1 {
        return Err(Error::Limit(format!(
            "the {} charts cannot share one atlas page with padding {} (they need {} pages); raise the resolution or lower the padding",
            atlas.chart_count, options.padding, atlas.page_count
        )));
    }
    if atlas.width > MAX_ATLAS_EDGE || atlas.height > MAX_ATLAS_EDGE {
        return Err(Error::Limit(format!(
            "the atlas would be {}x{} texels, more than the {MAX_ATLAS_EDGE} limit; lower the texel density",
            atlas.width, atlas.height
        )));
    }
    Ok(Atlas {
        width: atlas.width.max(1),
        height: atlas.height.max(1),
        charts: atlas.chart_count,
        utilization: atlas.utilization,
        meshes: atlas
            .meshes
            .into_iter()
            .map(|m| ChartedMesh {
                xref: m.vertices.iter().map(|v| v.xref).collect(),
                uv: m.vertices.iter().map(|v| v.uv).collect(),
                triangles: m.indices,
            })
            .collect(),
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
            triangles: m.triangles.clone(),
        })
        .collect();
    Atlas {
        width: resolution,
        height: resolution,
        charts: 0,
        utilization: 0.0,
        meshes: out,
    }
}
