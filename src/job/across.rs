//! Across: the second pass over seams whose two sides lie on two pages,
//! on the written images.
//!
//! In: the level's [`CrossSeam`]s, its page sizes, every page's
//! [`Encoded`] images, and per page which texels are covered. Out: the
//! pages whose images changed, re-encoded with their own scale and offset
//! (every other byte kept), and the jump before and after.
//!
//! Each page's stitch ([`crate::lightmap::seams::stitch_page`]) pulled its
//! side of a cross-page seam towards a target both pages trace
//! ([`crate::lightmap::seams::anchor`]):
//! a page cannot see the other's texels while it is baked (pages are baked
//! one at a time, shards on other machines), and each side meets the
//! target only as well as its own constraints let it, so the seams across
//! pages stayed wider than those within one
//! (`docs/measurements/constants.md`, the pass across pages). Once every
//! page is encoded, in one process or in `aobake merge`, this pass solves
//! the two sides together: the
//! within-page stitch's two-sided rows at `POINTS_PER_TEXEL` points per
//! texel of the longer side, over the non-interior texels under their
//! lookups on both pages at once, each texel kept near its written value
//! ([`System`]). It reads and writes 8-bit values only, so a merge of
//! shards computes the same bytes as one process.

use crate::atlas::PageSize;
use crate::encode::{Encoded, from_byte, png, read_png, to_byte};
use crate::error::Result;
use crate::lightmap::Filter;
use crate::lightmap::seams::anchor::point_count;
use crate::lightmap::seams::find::CrossSeam;
use crate::lightmap::seams::interior;
use crate::lightmap::seams::solve::{StitchStats, System};
use crate::sh::{K0, SH_COUNT, VIS_COUNT};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;

/// What the pass did, for the report.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct AcrossReport {
    pub seams: usize,
    /// Points on the seams (both sides' lookups at each).
    pub points: usize,
    /// Mean and 95th percentile of the AO jump |A - B| at the points, from
    /// the 8-bit values before and after the pass.
    pub ao_before: f64,
    pub ao_after: f64,
    pub p95_before: f64,
    pub p95_after: f64,
    /// Pages whose images were re-encoded.
    pub pages_changed: usize,
    pub solve: StitchStats,
}

/// Channels of a texel: AO, the 9 SH, then the visibility layer's.
const CHANNELS: usize = 1 + SH_COUNT + VIS_COUNT;

/// A page's 8-bit images, decoded: AO (grey), the SH's 3 RGBA images and
/// the visibility layer's.
struct Raw {
    width: u32,
    ao: Vec<u8>,
    sh: Vec<Vec<u8>>,
    vis: Vec<Vec<u8>>,
}

fn read(e: &Encoded) -> Result<Raw> {
    let ao = read_png(&e.occlusion_png)?.into_luma8();
    let rgba = |p: &Vec<u8>| Ok(read_png(p)?.into_rgba8().into_raw());
    Ok(Raw {
        width: ao.width(),
        ao: ao.into_raw(),
        sh: e.sh_png.iter().map(rgba).collect::<Result<_>>()?,
        vis: e
            .visibility
            .as_ref()
            .map_or(Ok(Vec::new()), |v| v.png.iter().map(rgba).collect())?,
    })
}

/// The visibility layer's coefficients on a page (0 without it).
fn layer_count(e: &Encoded) -> usize {
    e.visibility.as_ref().map_or(0, |v| v.scale.len())
}

/// Channel `c`'s scale and offset on a page (AO: 1, 0).
fn range(e: &Encoded, c: usize) -> (f32, f32) {
    match c {
        0 => (1.0, 0.0),
        c if c <= SH_COUNT => (e.sh_scale[c - 1], e.sh_offset[c - 1]),
        c => {
            let v = e.visibility.as_ref().expect("the layer's channels");
            (v.scale[c - 1 - SH_COUNT], v.offset[c - 1 - SH_COUNT])
        }
    }
}

/// Where channel `c` lies: its image (0 AO, 1..=3 the SH's, 4.. the
/// layer's) and its byte in a pixel.
fn slot(c: usize) -> (usize, usize) {
    match c {
        0 => (0, 0),
        c if c <= SH_COUNT => (1 + (c - 1) / 4, (c - 1) % 4),
        c => (4 + (c - 1 - SH_COUNT) / 4, (c - 1 - SH_COUNT) % 4),
    }
}

/// Channel `c`'s byte at texel `t`.
fn byte(raw: &mut Raw, c: usize, t: usize) -> &mut u8 {
    match slot(c) {
        (0, _) => &mut raw.ao[t],
        (i @ 1..=3, k) => &mut raw.sh[i - 1][t * 4 + k],
        (i, k) => &mut raw.vis[i - 4][t * 4 + k],
    }
}

/// The value a byte decodes to ([`from_byte`], the channel's range).
fn decoded(q: u8, (scale, offset): (f32, f32)) -> f32 {
    from_byte(q, scale, offset)
}

/// The byte nearest `v` within the channel's range ([`to_byte`]).
fn quantized(v: f32, (scale, offset): (f32, f32)) -> u8 {
    to_byte(v, scale, offset)
}

/// One point of a seam: each side's taps as (texel id, weight).
struct Point {
    a: Vec<(u32, f32)>,
    b: Vec<(u32, f32)>,
    /// Both pages have the visibility layer.
    layer: bool,
}

/// Runs the pass. `covered(page, needed)`: the page's covered texels,
/// decided where `needed` is true. `seam_scale` scales the rows as the
/// within-page stitch's; `filter`: the lookup the pages are read with.
/// Returns per page its new images (`None`: its
/// bytes are unchanged) and the report.
pub fn close(
    seams: &[CrossSeam],
    pages: &[PageSize],
    encoded: &[&Encoded],
    seam_scale: f64,
    filter: Filter,
    covered: impl Fn(u32, &[bool]) -> Vec<bool> + Sync,
) -> Result<(Vec<Option<Encoded>>, AcrossReport)> {
    let mut report = AcrossReport {
        seams: seams.len(),
        ..AcrossReport::default()
    };
    // Every texel a lookup reads, numbered: (page, texel) by id.
    let mut id_of: HashMap<(u32, u32), u32> = HashMap::new();
    let mut key: Vec<(u32, u32)> = Vec::new();
    let mut points = Vec::new();
    for seam in seams {
        let n = point_count(seam, pages);
        let layer = seam
            .page
            .iter()
            .all(|&p| layer_count(encoded[p as usize]) > 0);
        for i in 0..n {
            let t = (i as f32 + 0.5) / n as f32;
            let side = |k: usize, id_of: &mut HashMap<(u32, u32), u32>, key: &mut Vec<_>| {
                let page = seam.page[k];
                let size = pages[page as usize];
                (filter
                    .taps(seam.at(k, t), size.width, size.height)
                    .into_iter())
                .map(|(texel, w)| {
                    let next = key.len() as u32;
                    let id = *id_of.entry((page, texel)).or_insert_with(|| {
                        key.push((page, texel));
                        next
                    });
                    (id, w)
                })
                .collect::<Vec<_>>()
            };
            let a = side(0, &mut id_of, &mut key);
            let b = side(1, &mut id_of, &mut key);
            points.push(Point { a, b, layer });
        }
    }
    report.points = points.len();
    if points.is_empty() {
        return Ok((vec![None; encoded.len()], report));
    }
    // Per page: its texels' ids, which of them are interior (covered with
    // their 3 x 3 neighbourhood) and every channel's value.
    let mut on_page: Vec<Vec<u32>> = vec![Vec::new(); encoded.len()];
    for (id, &(page, _)) in key.iter().enumerate() {
        on_page[page as usize].push(id as u32);
    }
    let per_page: Vec<(Vec<bool>, Vec<f32>)> = on_page
        .par_iter()
        .enumerate()
        .map(|(page, ids)| -> Result<(Vec<bool>, Vec<f32>)> {
            if ids.is_empty() {
                return Ok((Vec::new(), Vec::new()));
            }
            let size = pages[page];
            let (w, h) = (size.width, size.height);
            let mut needed = vec![false; (w * h) as usize];
            for &id in ids {
                let t = key[id as usize].1;
                let (x, y) = (t % w, t / w);
                for j in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                    for i in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                        needed[(j * w + i) as usize] = true;
                    }
                }
            }
            let cover = covered(page as u32, &needed);
            let fixed = ids
                .iter()
                .map(|&id| interior(&cover, w, h, key[id as usize].1))
                .collect();
            let e = encoded[page];
            let mut raw = read(e)?;
            let channels = 1 + SH_COUNT + layer_count(e);
            let mut values = vec![0.0f32; ids.len() * CHANNELS];
            for (k, &id) in ids.iter().enumerate() {
                let t = key[id as usize].1 as usize;
                for c in 0..channels {
                    values[k * CHANNELS + c] = decoded(*byte(&mut raw, c, t), range(e, c));
                }
            }
            Ok((fixed, values))
        })
        .collect::<Result<_>>()?;
    let mut fixed = vec![false; key.len()];
    let mut value = vec![0.0f32; key.len() * CHANNELS];
    for (ids, (f, v)) in on_page.iter().zip(&per_page) {
        for (k, &id) in ids.iter().enumerate() {
            fixed[id as usize] = f[k];
            let id = id as usize;
            value[id * CHANNELS..(id + 1) * CHANNELS]
                .copy_from_slice(&v[k * CHANNELS..(k + 1) * CHANNELS]);
        }
    }
    drop(per_page);
    // The two solves: AO and the SH at every point, the layer where both
    // pages have it.
    let solve = |channels: std::ops::Range<usize>, layer_only: bool| {
        let mut system = System::new(|id: u32| fixed[id as usize]);
        for p in points.iter().filter(|p| p.layer || !layer_only) {
            let a = p.a.iter().map(|&(id, w)| (id, seam_scale * w as f64));
            let b = p.b.iter().map(|&(id, w)| (id, -seam_scale * w as f64));
            system.push_two_sided(a.chain(b), seam_scale);
        }
        let (start, count) = (channels.start, channels.len());
        let value = &value;
        system.solve(
            count,
            |id, out| {
                let at = id as usize * CHANNELS + start;
                out.copy_from_slice(&value[at..at + count]);
            },
            |_| &[],
        )
    };
    let layer = points.iter().any(|p| p.layer);
    let vis = (0..encoded.len())
        .map(|p| layer_count(encoded[p]))
        .max()
        .unwrap_or(0);
    let (ids, solved, stats, _) = solve(0..1 + SH_COUNT, false);
    let (layer_ids, layer_solved, layer_stats, _) = match layer {
        true => solve(1 + SH_COUNT..1 + SH_COUNT + vis, true),
        false => (Vec::new(), Vec::new(), StitchStats::default(), None),
    };
    report.solve = stats;
    report.solve.converged &= !layer || layer_stats.converged;
    // New bytes: AO within [0, 1] (c0 = K0 AO kept, as the stitch keeps
    // it), every channel within its page's range.
    let mut moved: Vec<Vec<(u32, usize, u8)>> = vec![Vec::new(); encoded.len()];
    let mut after_ao: Vec<f32> = (0..key.len()).map(|id| value[id * CHANNELS]).collect();
    let c = 1 + SH_COUNT;
    for (k, &id) in ids.iter().enumerate() {
        let (page, t) = key[id as usize];
        let e = encoded[page as usize];
        let new = &solved[k * c..(k + 1) * c];
        // (Every byte is clamped to its channel's range by `quantized`.)
        let ao = new[0].clamp(0.0, 1.0);
        let sh0 = new[1] + K0 as f32 * (ao - new[0]);
        let bytes = std::iter::once(ao)
            .chain(std::iter::once(sh0))
            .chain(new[2..].iter().copied())
            .enumerate()
            .map(|(ch, v)| (ch, quantized(v, range(e, ch))));
        for (ch, q) in bytes {
            moved[page as usize].push((t, ch, q));
        }
        after_ao[id as usize] = decoded(quantized(ao, (1.0, 0.0)), (1.0, 0.0));
    }
    for (k, &id) in layer_ids.iter().enumerate() {
        let (page, t) = key[id as usize];
        let e = encoded[page as usize];
        let n = layer_count(e);
        for i in 0..n {
            let ch = 1 + SH_COUNT + i;
            moved[page as usize].push((t, ch, quantized(layer_solved[k * vis + i], range(e, ch))));
        }
    }
    // The jump at every point, from the bytes before and after.
    let jumps = |ao: &dyn Fn(u32) -> f32| -> (f64, f64) {
        let side = |s: &[(u32, f32)]| s.iter().map(|&(id, w)| w * ao(id)).sum::<f32>();
        let mut j: Vec<f64> = points
            .iter()
            .map(|p| (side(&p.a) - side(&p.b)).abs() as f64)
            .collect();
        j.sort_by(f64::total_cmp);
        let mean = j.iter().sum::<f64>() / j.len() as f64;
        (mean, j[((0.95 * j.len() as f64) as usize).min(j.len() - 1)])
    };
    (report.ao_before, report.p95_before) = jumps(&|id| value[id as usize * CHANNELS]);
    (report.ao_after, report.p95_after) = jumps(&|id| after_ao[id as usize]);
    // Each page that moved: its images decoded again (rather than kept
    // from the first read: only one page's images at a time per thread),
    // the moved bytes written, the images that changed re-encoded.
    let rewritten: Vec<Option<Encoded>> = moved
        .par_iter()
        .enumerate()
        .map(|(page, moved)| -> Result<Option<Encoded>> {
            let e = encoded[page];
            if moved.is_empty() {
                return Ok(None);
            }
            let mut raw = read(e)?;
            // Which images changed: AO, then the SH's 3, then the layer's.
            let mut changed = vec![false; 1 + 3 + raw.vis.len()];
            for &(t, ch, q) in moved {
                let b = byte(&mut raw, ch, t as usize);
                if *b != q {
                    *b = q;
                    changed[slot(ch).0] = true;
                }
            }
            if !changed.iter().any(|&c| c) {
                return Ok(None);
            }
            let (w, h) = (raw.width, raw.ao.len() as u32 / raw.width);
            let mut out = e.clone();
            let rgba = image::ExtendedColorType::Rgba8;
            if changed[0] {
                out.occlusion_png = png(w, h, &raw.ao, image::ExtendedColorType::L8)?;
            }
            for (i, img) in raw.sh.iter().enumerate() {
                if changed[1 + i] {
                    out.sh_png[i] = png(w, h, img, rgba)?;
                }
            }
            if let Some(v) = out.visibility.as_mut() {
                for (i, img) in raw.vis.iter().enumerate() {
                    if changed[4 + i] {
                        v.png[i] = png(w, h, img, rgba)?;
                    }
                }
            }
            Ok(Some(out))
        })
        .collect::<Result<_>>()?;
    report.pages_changed = rewritten.iter().filter(|e| e.is_some()).count();
    Ok((rewritten, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lightmap::seams::solve::SEAM_WEIGHT;
    use glam::Vec3;

    /// Two 16 x 16 pages: page 0's chart covers x < 4, its edge u = 4/16
    /// is the same world edge as u = 12/16 on page 1, whose chart covers
    /// x >= 12. Page 0 reads 0.6, page 1 0.3 (AO only; SH channels zero).
    fn two_pages() -> (Vec<CrossSeam>, Vec<PageSize>, Vec<Encoded>) {
        let seam = CrossSeam {
            page: [0, 1],
            uv: [
                [[4.0 / 16.0, 2.0 / 16.0], [4.0 / 16.0, 14.0 / 16.0]],
                [[12.0 / 16.0, 2.0 / 16.0], [12.0 / 16.0, 14.0 / 16.0]],
            ],
            ends: [Vec3::ZERO, Vec3::Y],
            normal: [Vec3::Z; 2],
            face: Vec3::Z,
            length: 1.0,
        };
        let page = |ao: f32| {
            let grey = vec![(ao * 255.0).round() as u8; 256];
            let rgba = png(16, 16, &[0u8; 1024], image::ExtendedColorType::Rgba8).unwrap();
            Encoded {
                occlusion_png: png(16, 16, &grey, image::ExtendedColorType::L8).unwrap(),
                sh_png: [rgba.clone(), rgba.clone(), rgba],
                sh_scale: [0.0; SH_COUNT],
                sh_offset: [0.0; SH_COUNT],
                visibility: None,
                scale: None,
                solve_range: None,
                inside: None,
            }
        };
        let size = PageSize {
            width: 16,
            height: 16,
        };
        (vec![seam], vec![size; 2], vec![page(0.6), page(0.3)])
    }

    fn covered(page: u32, needed: &[bool]) -> Vec<bool> {
        (0..needed.len() as u32)
            .map(|t| if page == 0 { t % 16 < 4 } else { t % 16 >= 12 })
            .collect()
    }

    fn ao(e: &Encoded) -> Vec<f32> {
        let raw = read(e).unwrap();
        raw.ao.iter().map(|&q| q as f32 / 255.0).collect()
    }

    fn lookup(ao: &[f32], uv: [f32; 2]) -> f32 {
        crate::lightmap::filter::bilinear_taps(uv, 16, 16)
            .iter()
            .map(|&(t, w)| w * ao[t as usize])
            .sum()
    }

    #[test]
    fn both_sides_move_to_the_closed_form_and_nothing_else_moves() {
        let (seams, pages, encoded) = two_pages();
        let refs: Vec<&Encoded> = encoded.iter().collect();
        // A weak seam weight (scale 0.1) so the closed form stands well
        // above the 8-bit steps. Away from the seam's ends each texel row
        // has two free texels per side (x = 3, 4 and 11, 12: every one has
        // an uncovered neighbour, so none is interior), moving by -d and
        // +d, under 3 points: minimise 4 d^2 + 3 (lambda s)^2 (J0 - 2 d)^2,
        // d = 12 (lambda s)^2 J0 / (8 + 24 (lambda s)^2).
        let s = 0.1;
        let (out, report) = close(&seams, &pages, &refs, s, Filter::Bilinear, covered).unwrap();
        let j0 = (153.0 - 77.0) / 255.0;
        let l2 = (SEAM_WEIGHT * s).powi(2) as f32;
        let d = 12.0 * l2 * j0 / (8.0 + 24.0 * l2);
        let (a, b) = (ao(out[0].as_ref().unwrap()), ao(out[1].as_ref().unwrap()));
        for v in [6.0f32, 8.0, 10.0] {
            let (ua, ub) = ([4.0 / 16.0, v / 16.0], [12.0 / 16.0, v / 16.0]);
            let (la, lb) = (lookup(&a, ua), lookup(&b, ub));
            assert!((la - (0.6 - d)).abs() < 3e-3, "{la} against {}", 0.6 - d);
            assert!((lb - (77.0 / 255.0 + d)).abs() < 3e-3, "{lb}");
        }
        assert!((report.ao_before - j0 as f64).abs() < 1e-6, "{report:?}");
        assert_eq!(report.pages_changed, 2);
        // Interior texels (x <= 2 on page 0, x >= 13 on page 1) and texels
        // outside the lookups' footprints keep their bytes.
        let (a0, b0) = (ao(&encoded[0]), ao(&encoded[1]));
        for t in 0..256 {
            let x = t % 16;
            if !(3..=4).contains(&x) {
                assert_eq!(a[t], a0[t], "page 0 texel {t}");
            }
            if !(11..=12).contains(&x) {
                assert_eq!(b[t], b0[t], "page 1 texel {t}");
            }
        }
    }

    #[test]
    fn at_the_stitch_weight_the_sides_meet_within_8_bits() {
        let (seams, pages, encoded) = two_pages();
        let refs: Vec<&Encoded> = encoded.iter().collect();
        let (out, report) = close(&seams, &pages, &refs, 2.0, Filter::Bilinear, covered).unwrap();
        assert!(report.ao_before > 0.29, "{report:?}");
        // The closed form leaves 8 J0 / (8 + 24 (2 lambda)^2) = 0.001;
        // the bytes add at most one step.
        assert!(report.ao_after < 1.5 / 255.0, "{report:?}");
        assert!(report.solve.converged, "{report:?}");
        // The SH images were untouched: the same bytes.
        for (new, old) in out.iter().zip(&encoded) {
            assert_eq!(new.as_ref().unwrap().sh_png, old.sh_png);
        }
    }

    #[test]
    fn no_seams_change_nothing() {
        let (_, pages, encoded) = two_pages();
        let refs: Vec<&Encoded> = encoded.iter().collect();
        let (out, report) = close(&[], &pages, &refs, 2.0, Filter::Bilinear, covered).unwrap();
        assert!(out.iter().all(Option::is_none));
        assert_eq!(report.points, 0);
    }
}
