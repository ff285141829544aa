//! What a bake carries over from an earlier one of an edited input
//! (`--reuse PREV` with PREV's settings and aobake): the numbers that are
//! global to a page, so that a texel far from the edit comes out of the
//! new bake as it came out of PREV's.
//!
//! In: PREV's JSON (its fingerprint's `space`, `atlas`, `scales`,
//! `solveRanges` and `inside`, every baked primitive's `shScale`,
//! `shOffset` and visibility ranges), the new level's atlas. Out: per page
//! a [`PageCarry`] (the adaptive allocation's [`Scale`], each channel's
//! [`Ranges`], the solve's [`SolveRange`], the receivers inside geometry)
//! when the new atlas is PREV's, else why not; and for every output the
//! fingerprint's `atlas` hash and per-page fields ([`atlas_hash`],
//! [`pages_json`]).
//!
//! Why these: a texel's rays see only geometry within `maxDistance`, but
//! some things in a bake are the level's or a page's as a whole: the bake
//! space (the scene's bounding box: every vertex is mapped by it), the
//! charts' places (the packer packs every mesh), the allocation's scale
//! (one bisection per page turns every receiver's predicted variance into
//! its ray count), the encoding's range (each coefficient's minimum and
//! maximum over the page) and the solve's range (the same before the
//! solve). Taken from PREV (the solve's widened by the page's own), an
//! edit changes none of them, so it reaches only the texels near it. The
//! inside marks are not page-wide, but the dilate's fill reads them far
//! from a texel; carried, a bake of only the texels an edit reaches fills
//! them as the whole page's bake does (`docs/incremental.md`).

use crate::atlas::{Atlas, Receivers};
use crate::bake::adaptive::Scale;
use crate::bits::mix64;
use crate::encode::{Encoded, EncodedVisibility, Ranges};
use crate::geometry::{BakeGeometry, BakeSpace};
use crate::lightmap::seams::SolveRange;
use crate::lightmap::seams::find::CrossSeam;
use glam::DVec3;
use rayon::prelude::*;
use serde_json::{Value, json};

/// What one page takes from PREV.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PageCarry {
    /// The adaptive allocation's scale (none for the other methods).
    pub scale: Option<Scale>,
    /// Each channel's scale and offset.
    pub ranges: Option<Ranges>,
    /// The lightmap stage's solve's range ([`SolveRange`]).
    pub solve_range: Option<SolveRange>,
    /// The receivers inside geometry, as runs of texels ([`inside_runs`]).
    pub inside: Option<Vec<u32>>,
    /// PREV's images of the page as written, for a page no edit reaches
    /// (`None` when they do not read).
    pub images: Option<Encoded>,
}

/// What PREV recorded for a later bake to carry: its atlas's hash and
/// per page what [`PageCarry`] holds.
#[derive(Clone, Debug, PartialEq)]
pub struct PrevRecord {
    /// PREV's bake space: the new bake's geometry is mapped by it, so that
    /// an edit that changes the scene's bounds moves no other vertex.
    pub space: BakeSpace,
    pub atlas: String,
    pub pages: Vec<PageCarry>,
}

/// A hash of everything the atlas decides about the output: the pages'
/// sizes and, per charted mesh, its vertices' input vertices and lightmap
/// UVs, its triangles and their pages.
pub fn atlas_hash(atlas: &Atlas) -> u64 {
    let mut h = mix64(0xa71a5 ^ atlas.pages.len() as u64);
    for p in &atlas.pages {
        h = mix64(h ^ (u64::from(p.width) << 32 | u64::from(p.height)));
    }
    for m in &atlas.meshes {
        h = mix64(h ^ m.xref.len() as u64);
        h = m.xref.iter().fold(h, |h, &x| mix64(h ^ u64::from(x)));
        h = (m.uv.iter()).fold(h, |h, uv| {
            mix64(h ^ (u64::from(uv[0].to_bits()) << 32 | u64::from(uv[1].to_bits())))
        });
        h = m
            .triangles
            .iter()
            .fold(mix64(h ^ 1), |h, &t| mix64(h ^ u64::from(t)));
        h = (m.triangle_page.iter()).fold(mix64(h ^ 2), |h, &p| mix64(h ^ u64::from(p)));
    }
    h
}

/// The fingerprint's `space`: the bake space's centre and unit.
pub fn space_json(space: &BakeSpace) -> Value {
    json!(space.to_array())
}

/// The fingerprint's fields a later bake carries per page: `scales`,
/// `solveRanges` and `inside`, as one JSON object.
pub fn pages_json(pages: &[&Encoded]) -> Value {
    json!({
        "scales": scales_json(pages),
        "solveRanges": solve_ranges_json(pages),
        "inside": inside_json(pages),
    })
}

/// The fingerprint's `scales`: per page `[log2 scale, margin]` of the
/// adaptive allocation, or null.
pub fn scales_json(pages: &[&Encoded]) -> Value {
    (pages.iter())
        .map(|e| match e.scale {
            Some(s) => json!([s.log_scale, s.margin]),
            None => Value::Null,
        })
        .collect()
}

/// The fingerprint's `solveRanges`: per page `[lo, hi]`, each channel's
/// lowest and highest value before the solve, or null (no border fit, or
/// a value JSON cannot hold).
pub fn solve_ranges_json(pages: &[&Encoded]) -> Value {
    (pages.iter())
        .map(|e| match &e.solve_range {
            Some(r) if r.lo.iter().chain(&r.hi).all(|x| x.is_finite()) => json!([r.lo, r.hi]),
            _ => Value::Null,
        })
        .collect()
}

/// The fingerprint's `inside`: per page the runs of texels whose receiver
/// lies inside geometry ([`inside_runs`]), or null.
pub fn inside_json(pages: &[&Encoded]) -> Value {
    (pages.iter())
        .map(|e| e.inside.as_ref().map_or(Value::Null, |runs| json!(runs)))
        .collect()
}

/// The texels of the receivers marked `inside` (per receiver, keyed by
/// `texels`) as runs `[gap, count, ...]` in texel order, each gap the
/// texels skipped since the previous run's end (since texel 0 for the
/// first): small numbers, for a short JSON. The dilate's fill reads these
/// marks over the whole page; a bake of only the texels an edit reaches
/// takes the others from PREV.
pub fn inside_runs(texels: &[u32], inside: &[bool]) -> Vec<u32> {
    let mut marked: Vec<u32> = (texels.iter().zip(inside))
        .filter(|&(_, &i)| i)
        .map(|(&t, _)| t)
        .collect();
    marked.sort_unstable();
    let (mut runs, mut end): (Vec<u32>, u32) = (Vec::new(), 0);
    for t in marked {
        match runs.last_mut() {
            Some(count) if t == end => *count += 1,
            _ => runs.extend([t - end, 1]),
        }
        end = t + 1;
    }
    runs
}

/// Per texel of a `texels`-texel page, whether [`inside_runs`]' `runs`
/// mark it; `None` when they do not read (odd length, past the page).
pub fn inside_texels(runs: &[u32], texels: usize) -> Option<Vec<bool>> {
    if !runs.len().is_multiple_of(2) {
        return None;
    }
    let (mut marked, mut end) = (vec![false; texels], 0usize);
    for run in runs.chunks_exact(2) {
        let first = end.checked_add(run[0] as usize)?;
        end = first.checked_add(run[1] as usize)?;
        marked.get_mut(first..end)?.fill(true);
    }
    Some(marked)
}

/// PREV's record, from its JSON and BIN chunk; `None` when its
/// fingerprint has no `atlas` (an older aobake's) or the pages' fields do
/// not read.
pub fn read(json: &Value, bin: &[u8]) -> Option<PrevRecord> {
    let f = json.pointer("/extensions/AOBAKE_lightmap/fingerprint")?;
    let atlas = f.get("atlas")?.as_str()?.to_string();
    let space = (f.get("space")?.as_array()?.iter())
        .map(Value::as_f64)
        .collect::<Option<Vec<f64>>>()?;
    let space = BakeSpace::from_array(space.try_into().ok()?);
    let scales = f.get("scales")?.as_array()?;
    let mut pages: Vec<PageCarry> = (scales.iter())
        .map(|s| {
            let scale = match s {
                Value::Null => None,
                s => Some(Scale {
                    log_scale: s.get(0)?.as_f64()? as f32,
                    margin: s.get(1)?.as_f64()?,
                }),
            };
            Some(PageCarry {
                scale,
                ..PageCarry::default()
            })
        })
        .collect::<Option<_>>()?;
    // Absent in an older aobake's output: nothing carried.
    let ranges = f.get("solveRanges").and_then(Value::as_array);
    for (page, r) in pages.iter_mut().zip(ranges.into_iter().flatten()) {
        let floats = |v: Option<&Value>| -> Option<Vec<f32>> {
            (v?.as_array()?.iter())
                .map(|x| x.as_f64().map(|x| x as f32))
                .collect()
        };
        page.solve_range = match (floats(r.get(0)), floats(r.get(1))) {
            (Some(lo), Some(hi)) if lo.len() == hi.len() => Some(SolveRange { lo, hi }),
            _ => None,
        };
    }
    let inside = f.get("inside").and_then(Value::as_array);
    for (page, runs) in pages.iter_mut().zip(inside.into_iter().flatten()) {
        page.inside = (runs.as_array().into_iter().flatten())
            .map(|v| v.as_u64().and_then(|v| u32::try_from(v).ok()))
            .collect::<Option<Vec<u32>>>()
            .filter(|r| runs.is_array() && r.len().is_multiple_of(2));
    }
    // Every baked primitive holds its page's ranges; the first read of a
    // page gives them, a later one with the layer adds the layer's.
    let prims = (json.get("meshes")?.as_array()?.iter())
        .filter_map(|m| m.get("primitives")?.as_array())
        .flatten();
    for p in prims {
        let Some(ext) = p.pointer("/extensions/AOBAKE_lightmap") else {
            continue;
        };
        let page = ext.get("page").and_then(Value::as_u64).unwrap_or(0) as usize;
        let floats = |k: &str| -> Option<Vec<f32>> {
            (ext.get(k)?.as_array()?.iter())
                .map(|v| v.as_f64().map(|x| x as f32))
                .collect()
        };
        let ranges = pages.get_mut(page)?.ranges.get_or_insert(Ranges {
            sh_scale: floats("shScale")?.try_into().ok()?,
            sh_offset: floats("shOffset")?.try_into().ok()?,
            visibility: None,
        });
        if ranges.visibility.is_none()
            && let (Some(scale), Some(offset)) =
                (floats("visibilityScale"), floats("visibilityOffset"))
        {
            ranges.visibility = Some((scale, offset));
        }
    }
    for (p, page) in pages.iter_mut().enumerate() {
        page.images = page_images(json, bin, p, page);
    }
    Some(PrevRecord {
        space,
        atlas,
        pages,
    })
}

/// Page `p`'s images in PREV, by the names the writer gives them
/// (`aobake_occlusion`, `aobake_page{p}_sh0`, ...), with the page's ranges
/// and scale. A visibility layer whose ranges no primitive of the page
/// records (none of them has the layer) gets zeros: nothing reads them.
fn page_images(json: &Value, bin: &[u8], p: usize, page: &PageCarry) -> Option<Encoded> {
    let name = |base: &str| match p {
        0 => format!("aobake_{base}"),
        p => format!("aobake_page{p}_{base}"),
    };
    let images = json.get("images")?.as_array()?;
    let views = json.get("bufferViews")?.as_array()?;
    let png = |base: &str| -> Option<Vec<u8>> {
        let wanted = name(base);
        let image = images
            .iter()
            .find(|i| i.get("name").and_then(Value::as_str) == Some(&wanted))?;
        let view = views.get(image.get("bufferView")?.as_u64()? as usize)?;
        let at = view.get("byteOffset").and_then(Value::as_u64).unwrap_or(0) as usize;
        let len = view.get("byteLength")?.as_u64()? as usize;
        bin.get(at..at.checked_add(len)?).map(<[u8]>::to_vec)
    };
    let ranges = page.ranges.as_ref()?;
    let layer: Vec<Vec<u8>> = (0..)
        .map_while(|i| png(&format!("visibility{i}")))
        .collect();
    let visibility = (!layer.is_empty()).then(|| {
        let count = if layer.len() == 4 { 16 } else { 9 };
        let (scale, offset) = (ranges.visibility.clone())
            .filter(|(s, _)| s.len() == count)
            .unwrap_or((vec![0.0; count], vec![0.0; count]));
        EncodedVisibility {
            png: layer,
            scale,
            offset,
        }
    });
    Some(Encoded {
        occlusion_png: png("occlusion")?,
        sh_png: [png("sh0")?, png("sh1")?, png("sh2")?],
        sh_scale: ranges.sh_scale,
        sh_offset: ranges.sh_offset,
        visibility,
        scale: page.scale,
        solve_range: page.solve_range.clone(),
        inside: page.inside.clone(),
    })
}

/// The changed nodes' world boxes (`boxes`, from
/// [`super::reuse::NodeChanges`]) in bake space, min and max; `None` when
/// one of them bounds nothing (PREV did not record it, or it has no finite
/// vertex): then everything is dirty.
fn boxes_in(boxes: &[Option<[f64; 6]>], space: &BakeSpace) -> Option<Vec<(DVec3, DVec3)>> {
    let to_bake = |x: f64, y: f64, z: f64| (DVec3::new(x, y, z) - space.center) / space.diagonal;
    (boxes.iter())
        .map(|b| b.map(|b| (to_bake(b[0], b[1], b[2]), to_bake(b[3], b[4], b[5]))))
        .collect()
}

/// The distance between the box [`lo`, `hi`] and any of `boxes` is at most
/// `reach`.
fn within(lo: DVec3, hi: DVec3, boxes: &[(DVec3, DVec3)], reach: f64) -> bool {
    (boxes.iter()).any(|&(blo, bhi)| (blo - hi).max(lo - bhi).max(DVec3::ZERO).length() <= reach)
}

/// Per page: whether an edit can change any ray traced from it. Every
/// ray of a page (its receivers', its border fit's points', its
/// cross-page anchors') starts on a triangle charted on it, so a page is
/// dirty when the bounding box of one of its triangles lies within
/// `max_distance` (bake units, with the origin offset and a margin for
/// rounding) of a changed node's world box (`boxes`, before and after
/// the edit; a `None` makes every page dirty). Then closed over the
/// seams across pages: the pass that solves them reads both pages, so a
/// page tied to a dirty one is baked again with it.
pub fn dirty_pages(
    geometry: &BakeGeometry,
    atlas: &Atlas,
    cross_seams: &[CrossSeam],
    boxes: &[Option<[f64; 6]>],
    max_distance: f32,
) -> Vec<bool> {
    let pages = atlas.pages.len();
    let Some(boxes) = boxes_in(boxes, &geometry.space) else {
        return vec![true; pages];
    };
    let reach = (max_distance as f64 + 1e-4) * (1.0 + 1e-3);
    let mut dirty = vec![false; pages];
    for (mesh, charted) in geometry.receivers.iter().zip(&atlas.meshes) {
        for (t, &page) in mesh.triangles.chunks_exact(3).zip(&charted.triangle_page) {
            if dirty[page as usize] {
                continue;
            }
            let p =
                [t[0], t[1], t[2]].map(|i| DVec3::from(mesh.positions[i as usize].map(f64::from)));
            let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            // A triangle with a non-finite vertex casts no ray.
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            dirty[page as usize] = within(lo, hi, &boxes, reach);
        }
    }
    // Across the pages' seams, to a fixed point.
    loop {
        let mut grew = false;
        for s in cross_seams {
            let [a, b] = s.page.map(|p| p as usize);
            if dirty[a] != dirty[b] {
                (dirty[a], dirty[b], grew) = (true, true, true);
            }
        }
        if !grew {
            return dirty;
        }
    }
}

/// Whether PREV's pages may be carried: the new atlas (`atlas`, hashed as
/// [`atlas_hash`]) is PREV's; else why not, in a clause.
pub fn carries(prev: &PrevRecord, atlas: &Atlas) -> Result<(), String> {
    if prev.atlas != format!("{:016x}", atlas_hash(atlas)) {
        return Err(
            "the edit moves the atlas's charts (new or reshaped meshes are not packed into PREV's free space yet)"
                .into(),
        );
    }
    if prev.pages.len() != atlas.pages.len() {
        return Err("PREV's pages do not read".into());
    }
    Ok(())
}

/// Per receiver: whether an edit can change what its rays see, by the
/// changed nodes' world boxes before and after it (`boxes`, from
/// [`super::reuse::NodeChanges`]): its point lies within `max_distance`
/// (bake units) of one, with the rays' origin offset and a relative
/// margin for the boxes' rounding into bake space. A box that is `None`
/// bounds nothing: every receiver is dirty.
pub fn dirty(
    receivers: &Receivers,
    boxes: &[Option<[f64; 6]>],
    space: &BakeSpace,
    max_distance: f32,
) -> Vec<bool> {
    dirty_within(receivers, boxes, space, max_distance, 0.0)
}

/// [`dirty`] with each receiver's reach grown by `texels` of its
/// footprint: the receivers next to a surface point (a border fit's point
/// in their cell) that the edit reaches.
pub fn dirty_within(
    receivers: &Receivers,
    boxes: &[Option<[f64; 6]>],
    space: &BakeSpace,
    max_distance: f32,
    texels: f32,
) -> Vec<bool> {
    let Some(boxes) = boxes_in(boxes, space) else {
        return vec![true; receivers.len()];
    };
    // The ray origin's offset along the normal is 1e-5 of the diagonal at
    // most (the contract's); a thousandth more for rounding.
    let reach = (max_distance as f64 + 2e-5) * (1.0 + 1e-3) + 1e-6;
    (receivers.position.par_iter().zip(&receivers.footprint))
        .with_min_len(4096)
        .map(|(p, &f)| {
            let reach = reach + (texels * f.max(0.0)) as f64;
            within(p.as_dvec3(), p.as_dvec3(), &boxes, reach)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_reads_back_the_scales_and_each_pages_ranges() {
        let s = Scale {
            log_scale: 0.1f32 + 1e-7,
            margin: 1.0 + 1.0 / 3.0,
        };
        let sh: Vec<f32> = (0..9).map(|i| 0.1 + i as f32 / 7.0).collect();
        let lo: Vec<f32> = (0..10).map(|i| -1.0 / (3.0 + i as f32)).collect();
        let hi: Vec<f32> = (0..10).map(|i| 1.0 + 1e-7 * i as f32).collect();
        let json = json!({
            "extensions": {"AOBAKE_lightmap": {"fingerprint": {
                "space": [0.1, -2.0, 1e-300, 3.5],
                "atlas": "00000000000000aa",
                "scales": [[s.log_scale, s.margin], null],
                "solveRanges": [[lo, hi], null],
                "inside": [[3, 2, 9, 1], null],
            }}},
            "meshes": [{"primitives": [
                {"extensions": {"AOBAKE_lightmap": {"page": 1, "shScale": sh, "shOffset": sh}}},
                {"extensions": {"AOBAKE_lightmap": {"page": 0, "shScale": sh, "shOffset": sh,
                    "visibilityScale": [0.5, 0.25], "visibilityOffset": [-0.5, 0.0]}}},
                {},
            ]}],
        });
        let json: Value = serde_json::from_str(&json.to_string()).unwrap();
        let r = read(&json, &[]).unwrap();
        assert_eq!(r.atlas, "00000000000000aa");
        assert_eq!(r.space.center, DVec3::new(0.1, -2.0, 1e-300));
        assert_eq!(r.space.diagonal, 3.5);
        // The numbers come back to the bit through their JSON.
        assert_eq!(r.pages[0].scale, Some(s));
        assert_eq!(r.pages[1].scale, None);
        let range = r.pages[0].solve_range.as_ref().unwrap();
        assert_eq!((&range.lo, &range.hi), (&lo, &hi));
        assert_eq!(r.pages[1].solve_range, None);
        assert_eq!(r.pages[0].inside, Some(vec![3, 2, 9, 1]));
        assert_eq!(r.pages[1].inside, None);
        let ranges = r.pages[0].ranges.as_ref().unwrap();
        assert_eq!(ranges.sh_scale.to_vec(), sh);
        assert_eq!(ranges.visibility, Some((vec![0.5, 0.25], vec![-0.5, 0.0])));
        assert_eq!(r.pages[1].ranges.as_ref().unwrap().visibility, None);
        // An older fingerprint (no atlas) carries nothing.
        let mut old = json.clone();
        old["extensions"]["AOBAKE_lightmap"]["fingerprint"]
            .as_object_mut()
            .unwrap()
            .remove("atlas");
        assert_eq!(read(&old, &[]), None);
    }

    #[test]
    fn inside_runs_read_back_as_the_marked_texels() {
        // Receivers in any order; runs join neighbouring texels.
        let texels = [7u32, 2, 3, 4, 9, 0, 8];
        let inside = [true, true, true, false, true, true, true];
        let runs = inside_runs(&texels, &inside);
        assert_eq!(runs, vec![0, 1, 1, 2, 3, 3]);
        let marked = inside_texels(&runs, 10).unwrap();
        let want: Vec<bool> = (0..10).map(|t| [0, 2, 3, 7, 8, 9].contains(&t)).collect();
        assert_eq!(marked, want);
        // Past the page or half a run: not read.
        assert_eq!(inside_texels(&runs, 9), None);
        assert_eq!(inside_texels(&[1], 9), None);
        assert_eq!(inside_texels(&[], 4), Some(vec![false; 4]));
    }
}
