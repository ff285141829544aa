//! Edge receivers' rows: a border texel's baked value fitted where it was
//! baked, not at the texel's centre.
//!
//! In: a page's receivers (which texels hold one, whose centre lies outside
//! every triangle, which lie inside geometry), its triangles, the texels
//! free to move, the texels a seam's rows read, and the page's values
//! after [`super::spread`]. Out: [`EdgeRows`]: one-sided rows "the lookup
//! at this UV reads this value" at the edge receivers' own UVs, and the
//! texels whose data term they replace.
//!
//! Why: a covered texel whose centre lies outside its chart is baked at
//! the chart's point nearest its centre (up to 0.7 texels away, on the
//! chart's edge). Its value is as good as any receiver's (the adaptive
//! pass gave it its rays), but the stitch's data term (x_t - x0_t)^2 holds
//! it as if it were the value at the texel's centre, where no surface is.
//! A row at the receiver's own UV asks instead that the bilinear lookup
//! there reads it, which is what an engine does at that point: the border
//! fit ([`super::border`]) gets an accurate target on the chart's edge
//! for every such texel, traced already. The texel keeps a weak data term
//! ([`EDGE_DATA_WEIGHT`]) so that the system stays positive definite.
//!
//! A receiver in contact (its occluders nearer than the contact depth,
//! so the adaptive filter left it unwidened: sigma 0) may lie on a crease,
//! where the signal is singular: AO dips steeply into the corner, and the
//! value at the very edge is not what the area around it shows. Such a
//! receiver gets a row only where its AO agrees with the border fit's
//! traced points near it ([`agrees`]): rows at every edge receiver made
//! the border worse (`docs/measurements/constants.md`, edge rows). Without
//! the adaptive filter's widths (`--method mc`, `sheared`) every edge
//! receiver is judged as a contact one.
//!
//! Texels a seam's rows read keep their data term and get no row: there
//! the two sides' edge receivers are baked independently, and the seam's
//! rows, not either side's value, decide where they meet (rows there too
//! widened the seams' jumps: `docs/measurements/constants.md`, edge rows
//! on seams).

use super::filter::Filter;
use super::seams::Anchor;
use super::seams::find::Seam;
use super::seams::metric::samples;
use super::seams::solve::POINTS_PER_TEXEL;
use crate::atlas::Receivers;
use crate::atlas::rasterize::{SurfaceTri, receiver_uvs};
use glam::Vec2;
use rayon::prelude::*;

/// An edge row's weight, as the border fit's rows'
/// ([`super::border::FIT_WEIGHT`]); the engine view is flat in it
/// between 0.5 and 1 (`docs/measurements/constants.md`, EDGE_WEIGHT).
pub(crate) const EDGE_WEIGHT: f32 = 0.7;

/// The data term's weight of a texel that has an edge row (1 for the
/// others).
pub const EDGE_DATA_WEIGHT: f64 = 0.1;

/// A page's edge rows and the texels they hold.
#[derive(Debug, Default)]
pub struct EdgeRows {
    pub rows: Vec<Anchor>,
    /// Per texel: it has a row (its data term weighs [`EDGE_DATA_WEIGHT`]).
    pub held: Vec<bool>,
}

impl EdgeRows {
    /// The data term's weight of texel `t`.
    pub fn data_weight(&self, t: u32) -> f64 {
        match self.held.get(t as usize) {
            Some(true) => EDGE_DATA_WEIGHT,
            _ => 1.0,
        }
    }
}

/// The texels of a `width` x `height` page that the rows of `seams` (both
/// sides, at the stitch's points) and of `cross_page` anchors read.
pub(crate) fn seam_texels(
    seams: &[Seam],
    cross_page: &[Anchor],
    width: u32,
    height: u32,
    filter: Filter,
) -> Vec<bool> {
    let mut out = vec![false; (width * height) as usize];
    let mut mark = |uv: [f32; 2]| {
        for (t, _) in filter.taps(uv, width, height) {
            out[t as usize] = true;
        }
    };
    for seam in seams {
        for s in samples(seam, width, height, POINTS_PER_TEXEL) {
            let (a, b) = seam.at(s);
            mark(a);
            mark(b);
        }
    }
    for a in cross_page {
        mark(a.uv);
    }
    out
}

/// The edge rows of a page: every texel that is `free`, not read by a
/// seam (`on_seam`) and holds a receiver whose centre lies outside the
/// triangles (`tris`, texel units) and which is not `inside` geometry (per
/// receiver); a receiver that is not `smooth` (receiver index: its signal
/// is not smooth at the texel's scale) only where it agrees with the
/// border fit's `points` near it ([`agrees`]). `value(t, out)` writes
/// texel t's values (AO first, then SH and the layer's, `channels` in all).
#[allow(clippy::too_many_arguments)]
pub fn rows(
    receivers: &Receivers,
    inside: &[bool],
    smooth: &(dyn Fn(usize) -> bool + Sync),
    tris: &[SurfaceTri],
    free: &[bool],
    on_seam: &[bool],
    points: &[Anchor],
    channels: usize,
    value: impl Fn(usize, &mut [f32]) + Sync,
) -> EdgeRows {
    let (w, h) = (receivers.width, receivers.height);
    let n = (w * h) as usize;
    let mut receiver_of = vec![u32::MAX; n];
    for (j, &t) in receivers.texel.iter().enumerate() {
        let t = t as usize;
        if free[t]
            && !on_seam[t]
            && !receivers.center_inside[j]
            && !inside.get(j).copied().unwrap_or(false)
        {
            receiver_of[t] = j as u32;
        }
    }
    let needed: Vec<bool> = receiver_of.iter().map(|&j| j != u32::MAX).collect();
    let uvs = receiver_uvs(tris, w, h, &needed);
    let near = PointGrid::new(points, w, h);
    let found: Vec<(usize, Anchor)> = uvs
        .into_par_iter()
        .enumerate()
        .filter_map(|(t, uv)| {
            let uv = uv?;
            let mut target = vec![0.0f32; channels];
            value(t, &mut target);
            if !smooth(receiver_of[t] as usize) {
                let near = near.ao_near(points, uv);
                if target[0].is_nan() || near.iter().any(|a| a.is_nan()) {
                    // Not known (a bake of part of a page): whether it
                    // agrees is not known either; the row's NaN target
                    // leaves what it ties not known.
                    target.fill(f32::NAN);
                } else if !agrees(target[0], &near) {
                    return None;
                }
            }
            let row = Anchor {
                uv: [uv.x / w as f32, uv.y / h as f32],
                target,
                weight: EDGE_WEIGHT,
            };
            Some((t, row))
        })
        .collect();
    let mut held = vec![false; n];
    let rows = found
        .into_iter()
        .map(|(t, row)| {
            held[t] = true;
            row
        })
        .collect();
    EdgeRows { rows, held }
}

/// Reach (texels) of the fit's points that judge a contact receiver.
pub const CONTACT_REACH: f32 = 0.75;

/// Largest |AO - the mean AO of the fit's points near it| of a contact
/// receiver that gets a row: the largest that leaves the border where no
/// contact rows leave it, while most of the rows' gain elsewhere stays
/// (`docs/measurements/constants.md`, CONTACT_AGREEMENT).
pub const CONTACT_AGREEMENT: f32 = 0.1;

/// Whether a contact receiver's AO `ao` is what the area around it shows:
/// at least two of the fit's points `near` it (their AO), and within
/// [`CONTACT_AGREEMENT`] of their mean. A receiver on a crease samples the
/// signal where it dips into the corner; the lookups around it do not see
/// that dip.
pub fn agrees(ao: f32, near: &[f32]) -> bool {
    if near.len() < 2 {
        return false;
    }
    let mean = near.iter().sum::<f32>() / near.len() as f32;
    (ao - mean).abs() < CONTACT_AGREEMENT
}

/// The fit's points by texel, to find those near a UV.
struct PointGrid {
    cells: std::collections::HashMap<(i32, i32), Vec<u32>>,
    size: Vec2,
}

impl PointGrid {
    fn new(points: &[Anchor], w: u32, h: u32) -> PointGrid {
        let size = Vec2::new(w as f32, h as f32);
        let mut cells: std::collections::HashMap<(i32, i32), Vec<u32>> = Default::default();
        for (k, a) in points.iter().enumerate() {
            let p = Vec2::from(a.uv) * size;
            cells
                .entry((p.x.floor() as i32, p.y.floor() as i32))
                .or_default()
                .push(k as u32);
        }
        PointGrid { cells, size }
    }

    /// The AO of the points within [`CONTACT_REACH`] of `uv` (texels).
    fn ao_near(&self, points: &[Anchor], uv: Vec2) -> Vec<f32> {
        let r = CONTACT_REACH;
        let mut out = Vec::new();
        for y in (uv.y - r).floor() as i32..=(uv.y + r).floor() as i32 {
            for x in (uv.x - r).floor() as i32..=(uv.x + r).floor() as i32 {
                for &k in self.cells.get(&(x, y)).map_or(&[][..], |v| &v[..]) {
                    let a = &points[k as usize];
                    if (Vec2::from(a.uv) * self.size).distance(uv) < r {
                        out.push(a.target[0]);
                    }
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lightmap::seams::solve::stitch;
    use glam::Vec3;

    /// A chart spanning x in [x0, x1], y in [0, 8] texels of a 12 x 8 page,
    /// as two triangles.
    fn strip(x0: f32, x1: f32) -> Vec<SurfaceTri> {
        let c = [
            Vec2::new(x0, 0.0),
            Vec2::new(x1, 0.0),
            Vec2::new(x1, 8.0),
            Vec2::new(x0, 8.0),
        ];
        [[0, 1, 2], [0, 2, 3]]
            .iter()
            .map(|i| SurfaceTri {
                mesh: 0,
                uv: i.map(|k| c[k]),
                pos: i.map(|k| Vec3::new(c[k].x, c[k].y, 0.0)),
                nrm: None,
                geo: Vec3::Z,
                footprint: 1.0,
            })
            .collect()
    }

    #[test]
    fn a_contact_receiver_agrees_with_the_points_around_it_or_gets_no_row() {
        assert!(agrees(0.5, &[0.45, 0.58]));
        assert!(!agrees(0.3, &[0.45, 0.55]), "a dip of 0.2 into the corner");
        assert!(!agrees(0.5, &[0.5]), "one point judges nothing");
        // On a page: the edge column's receivers are contact ones; fit
        // points near the upper half agree, near the lower half not.
        let (w, h) = (12u32, 8u32);
        let tris = strip(2.6, 9.4);
        let n = (w * h) as usize;
        let mut receivers = Receivers {
            width: w,
            height: h,
            ..Default::default()
        };
        for y in 0..h {
            let t = y * w + 2;
            receivers.texel.push(t);
            receivers.position.push(Vec3::new(2.6, y as f32 + 0.5, 0.0));
            receivers.normal.push(Vec3::Z);
            receivers.geo_normal.push(Vec3::Z);
            receivers.footprint.push(1.0);
            receivers.center_inside.push(false);
        }
        let points: Vec<Anchor> = (0..h)
            .flat_map(|y| {
                let ao = if y < 4 { 0.52 } else { 0.8 };
                [2.9f32, 3.1].map(|x| Anchor {
                    uv: [x / w as f32, (y as f32 + 0.5) / h as f32],
                    target: vec![ao],
                    weight: 0.5,
                })
            })
            .collect();
        let all = vec![true; n];
        let none = vec![false; n];
        let edge = rows(
            &receivers,
            &[],
            &|_| false,
            &tris,
            &all,
            &none,
            &points,
            1,
            |_, out| out[0] = 0.5,
        );
        let held: Vec<u32> = (0..h)
            .filter(|&y| edge.held[(y * w + 2) as usize])
            .collect();
        assert_eq!(held, vec![0, 1, 2, 3]);
        assert_eq!(edge.rows.len(), 4);
    }

    #[test]
    fn receiver_uvs_are_the_covered_points_nearest_the_centres() {
        // The chart's left edge at x = 2.6: texel column 2 (centre 2.5) is
        // covered from outside, its receivers on the edge at (2.6, y + 0.5);
        // column 1 (centre 1.5, 1.1 away) is beyond the conservative reach;
        // column 3 lies inside, at its centre.
        let tris = strip(2.6, 9.4);
        let (w, h) = (12u32, 8u32);
        let all = vec![true; (w * h) as usize];
        let uvs = receiver_uvs(&tris, w, h, &all);
        for y in 0..h {
            let at = |x: u32| uvs[(y * w + x) as usize];
            assert_eq!(at(1), None);
            let e = at(2).expect("covered");
            assert!((e - Vec2::new(2.6, y as f32 + 0.5)).length() < 1e-5, "{e}");
            let c = at(3).expect("inside");
            assert!((c - Vec2::new(3.5, y as f32 + 0.5)).length() < 1e-5, "{c}");
        }
    }

    #[test]
    fn an_edge_row_makes_the_lookup_on_the_edge_read_the_edge_receivers_value() {
        // f = 0.2 + 0.05 x on a chart from x = 2.6 to 9.4: the texels whose
        // centre lies inside hold f there (fixed), the edge column holds
        // f at its receivers on the edge (x = 2.6), as the bake does.
        let f = |x: f32| 0.2 + 0.05 * x;
        let (w, h) = (12u32, 8u32);
        let tris = strip(2.6, 9.4);
        let n = (w * h) as usize;
        let x_of = |t: usize| (t % w as usize) as f32 + 0.5;
        let baked: Vec<f32> = (0..n).map(|t| f(x_of(t).clamp(2.6, 9.4))).collect();
        let free: Vec<bool> = (0..n)
            .map(|t| !(3..=8).contains(&(t % w as usize)))
            .collect();
        let mut receivers = Receivers {
            width: w,
            height: h,
            ..Default::default()
        };
        for t in 0..n {
            let x = x_of(t);
            if (2.0..10.0).contains(&x) {
                let inside = (3.0..9.0).contains(&x);
                let uv = Vec2::new(x.clamp(2.6, 9.4), (t / w as usize) as f32 + 0.5);
                receivers.texel.push(t as u32);
                receivers.position.push(uv.extend(0.0));
                receivers.normal.push(Vec3::Z);
                receivers.geo_normal.push(Vec3::Z);
                receivers.footprint.push(1.0);
                receivers.center_inside.push(inside);
            }
        }
        let none = vec![false; n];
        let edge = rows(
            &receivers,
            &[],
            &|_| true,
            &tris,
            &free,
            &none,
            &[],
            1,
            |t, out| out[0] = baked[t],
        );
        // Both edge columns (2 and 9), every row of the page.
        assert_eq!(edge.rows.len(), 2 * h as usize);
        let solve = |rows: &[Anchor], weight: &(dyn Fn(u32) -> f64 + Sync)| {
            let (texels, values, stats, _) = stitch(
                &[],
                &[],
                rows,
                w,
                h,
                1.0,
                1,
                Filter::Bilinear,
                |t| !free[t as usize],
                weight,
                |t, out| out[0] = baked[t as usize],
                None,
            );
            assert!(stats.converged, "{stats:?}");
            let mut out = baked.clone();
            for (t, v) in texels.iter().zip(values) {
                out[*t as usize] = v;
            }
            out
        };
        let lookup = |img: &[f32], x: f32| {
            // Along a row: the two columns around x.
            let i = (x - 0.5).floor() as usize;
            let a = x - 0.5 - i as f32;
            img[3 * w as usize + i] * (1.0 - a) + img[3 * w as usize + i + 1] * a
        };
        // With the rows the lookup on the edge reads f there: the edge
        // texel holds f extrapolated to its centre (within the weak data
        // term's pull).
        let fitted = solve(&edge.rows, &|t| edge.data_weight(t));
        for x in [2.6f32, 9.4] {
            let got = lookup(&fitted, x);
            assert!((got - f(x)).abs() < 2e-3, "{x}: {got} against {}", f(x));
        }
        assert!((fitted[3 * w as usize + 2] - f(2.5)).abs() < 2e-3);
        // Without them the edge texel keeps f(2.6) at its centre, and the
        // lookup on the edge reads a tenth of the way to f(3.5) instead.
        let kept = solve(&[], &|_| 1.0);
        let off = lookup(&kept, 2.6) - f(2.6);
        assert!((off - 0.1 * (f(3.5) - f(2.6))).abs() < 1e-4, "{off}");
    }
}
