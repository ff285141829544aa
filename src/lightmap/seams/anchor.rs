//! Anchor: the two pages of a seam that crosses pages meet one target.
//!
//! In: the [`CrossSeam`]s of a level, the page being stitched, its
//! atlas's page sizes and the tracer. Out: the page's [`Anchor`]s: at
//! points along each of its cross-page seams, the page's UV there and
//! the target every channel should read.
//!
//! A page cannot see the other page's images (pages are baked one at a
//! time, shards on other machines), so each side is pulled towards the
//! same target instead of towards the other side: the AO, SH (and
//! visibility layer) of a receiver on the world edge itself, with the two
//! sides' normals averaged, by [`TARGET_RAYS`]-ray Monte Carlo. The points,
//! their rays and their seeds depend only on the seam (both pages'
//! texel lengths, the world edge), so both pages compute the same targets
//! bit for bit, in one process or in two shards.

use super::find::CrossSeam;
use super::solve::{Anchor, POINTS_PER_TEXEL};
use crate::atlas::{PageSize, Receivers};
use crate::bake::{BakeParams, mc, visibility};
use crate::lightmap::filter::bilinear_taps as taps;
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::trace::Tracer;

/// Rays of each target knot. The knots are smoothed along the seam and
/// the texels cannot follow their noise anyway: more rays barely close
/// the jumps further and tracing the targets dominated the seams stage
/// (`docs/measurements/constants.md`, TARGET_RAYS).
pub const TARGET_RAYS: u32 = 64;

/// Side `side`'s length in texels of its page.
fn texels(seam: &CrossSeam, side: usize, pages: &[PageSize]) -> f32 {
    let p = pages[seam.page[side] as usize];
    let uv = seam.uv[side];
    let d = [
        (uv[1][0] - uv[0][0]) * p.width as f32,
        (uv[1][1] - uv[0][1]) * p.height as f32,
    ];
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

/// Points on a seam: [`POINTS_PER_TEXEL`] per texel of the longer side.
pub fn point_count(seam: &CrossSeam, pages: &[PageSize]) -> usize {
    let longer = texels(seam, 0, pages).max(texels(seam, 1, pages));
    ((longer * POINTS_PER_TEXEL).ceil() as usize).max(1)
}

/// A seed index of point `i` of a seam, from its world edge alone.
fn point_seed(seam: &CrossSeam, i: usize) -> u32 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for v in seam.ends.iter().flat_map(|e| e.to_array()) {
        h = (h ^ v.to_bits() as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h = (h ^ i as u64).wrapping_mul(0x0100_0000_01b3);
    (h ^ (h >> 32)) as u32
}

/// Knots of a seam's target: one per texel of the longer side (at
/// least one), at the centres of equal steps.
fn knot_count(seam: &CrossSeam, pages: &[PageSize]) -> usize {
    (texels(seam, 0, pages).max(texels(seam, 1, pages)).ceil() as usize).max(1)
}

/// The anchors of page `page`: its side of every seam in `seams` that
/// touches it. `visibility`: the targets carry the 16 coefficients of the
/// visibility layer after AO and the SH.
///
/// The target is traced at one knot per texel of seam length, smoothed
/// along the seam by [1, 2, 1] / 4 and interpolated linearly to the
/// constraint points ([`point_count`]): independent Monte Carlo targets
/// at every point put their noise into the seam, which the texels cannot
/// follow.
#[allow(clippy::too_many_arguments)]
pub fn anchors(
    seams: &[CrossSeam],
    page: u32,
    pages: &[PageSize],
    tracer: &Tracer,
    max_distance: f32,
    seed: u64,
    with_visibility: bool,
) -> Vec<Anchor> {
    // This page's seams, the side on it, and their knot counts.
    let mine: Vec<(&CrossSeam, usize, usize)> = seams
        .iter()
        .filter(|s| s.page.contains(&page))
        .map(|s| {
            (
                s,
                if s.page[0] == page { 0 } else { 1 },
                knot_count(s, pages),
            )
        })
        .collect();
    // Every knot's receiver, seam by seam.
    let mut r = Receivers::default();
    for &(seam, side, n) in &mine {
        let footprint = seam.length / texels(seam, side, pages).max(1e-6);
        for i in 0..n {
            let t = (i as f32 + 0.5) / n as f32;
            let normal = seam.normal[0]
                .lerp(seam.normal[1], t)
                .normalize_or(seam.face);
            let geo = if seam.face.dot(normal) < 0.0 {
                -seam.face
            } else {
                seam.face
            };
            r.texel.push(point_seed(seam, i));
            r.position.push(seam.ends[0].lerp(seam.ends[1], t));
            r.normal.push(normal);
            r.geo_normal.push(geo);
            r.footprint.push(footprint);
            r.center_inside.push(true);
        }
    }
    if r.texel.is_empty() {
        return Vec::new();
    }
    let params = BakeParams { max_distance, seed };
    let bake = mc::bake(&r, tracer, TARGET_RAYS, &params, &|_| {});
    let layer = with_visibility.then(|| visibility::bake(&r, tracer, TARGET_RAYS, &params));
    let value = |k: usize| -> Vec<f32> {
        let mut v = Vec::with_capacity(1 + SH_COUNT + VIS_COUNT);
        v.push(bake.ao[k]);
        v.extend_from_slice(&bake.sh[k]);
        if let Some(l) = &layer {
            v.extend_from_slice(&l.v[k]);
        }
        v
    };
    let mut out = Vec::new();
    let mut k0 = 0;
    for &(seam, side, n) in &mine {
        let raw: Vec<Vec<f32>> = (k0..k0 + n).map(value).collect();
        k0 += n;
        let knots: Vec<Vec<f32>> = (0..n)
            .map(|i| {
                let (a, b) = (&raw[i.saturating_sub(1)], &raw[(i + 1).min(n - 1)]);
                (0..raw[i].len())
                    .map(|c| 0.25 * a[c] + 0.5 * raw[i][c] + 0.25 * b[c])
                    .collect()
            })
            .collect();
        let points = point_count(seam, pages);
        for j in 0..points {
            let t = (j as f32 + 0.5) / points as f32;
            // Between the knots at (i + 0.5) / n, clamped at the ends.
            let x = (t * n as f32 - 0.5).clamp(0.0, (n - 1) as f32);
            let i = (x.floor() as usize).min(n - 1);
            let f = x - i as f32;
            let next = &knots[(i + 1).min(n - 1)];
            let target = knots[i]
                .iter()
                .zip(next)
                .map(|(a, b)| a + (b - a) * f)
                .collect();
            out.push(Anchor {
                uv: seam.at(side, t),
                target,
                weight: 1.0,
            });
        }
    }
    out
}

/// The AO jump a viewer sees at every point of `seams` ([`point_count`]
/// per seam): each side's bilinear lookup in its own page's image,
/// `ao(page)` = (width, height, AO texels).
pub fn cross_page_jumps<'a>(
    seams: &[CrossSeam],
    pages: &[PageSize],
    ao: impl Fn(u32) -> (u32, u32, &'a [f32]),
) -> Vec<f64> {
    let mut jumps = Vec::new();
    for seam in seams {
        let n = point_count(seam, pages);
        for i in 0..n {
            let t = (i as f32 + 0.5) / n as f32;
            let side = |k: usize| -> f32 {
                let (w, h, img) = ao(seam.page[k]);
                taps(seam.at(k, t), w, h)
                    .iter()
                    .map(|&(x, wt)| wt * img[x as usize])
                    .sum()
            };
            jumps.push((side(0) - side(1)).abs() as f64);
        }
    }
    jumps
}
