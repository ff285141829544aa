//! The filter: each receiver's integrated values averaged over its atlas
//! neighbours with Gaussian weights, rows then columns (separable).
//!
//! In: [`FilterSupport`] (receivers, the texel grid, inside marks, each
//! receiver's sigma in texels and the z_min it reads up to), the 10
//! values each receiver lends ([`super::sums::below_compensated`]). Out:
//! the filtered AO and 9 SH values, and for the allocation each
//! receiver's N_eff ([`FilterSupport::effective_neighbours`]).
//!
//! Weights are the Gaussian of the offset in the receiver's tangent plane;
//! a lender must pass the leak rule ([`lends_rays`]), lie within z_min of
//! the receiver, not be inside geometry and have a shading normal within
//! [`LENDER_NORMAL_AGREEMENT`]. Each side's run along a row or column
//! ends at the first neighbour that does not lend or at a chart border,
//! and both sides keep the shorter run, so a gradient is not shifted.

pub use super::grid::LENDER_NORMAL_AGREEMENT;
use super::grid::{TexelGrid, symmetric_runs};
use super::line::{ContactLines, Line, OnLines};
use super::options::MAX_REACH;
use crate::atlas::Receivers;
use crate::bake::sheared::lends_rays;
use crate::sh::SH_COUNT;
use glam::Vec3;
use rayon::prelude::*;

/// What the filter reads: the receivers, their bounds and widths.
#[derive(Clone, Copy)]
pub struct FilterSupport<'a> {
    pub receivers: &'a Receivers,
    pub grid: &'a TexelGrid,
    pub inside: &'a [bool],
    pub sigma_texels: &'a [f32],
    pub z_min: &'a [f32],
    /// The receivers on contact lines, filtered along them alone
    /// ([`super::line`]); `None`: no lines.
    pub lines: Option<&'a ContactLines>,
}

impl FilterSupport<'_> {
    /// What the filter along a contact line reads of this support.
    #[inline]
    fn on_lines(&self) -> OnLines<'_> {
        OnLines {
            receivers: self.receivers,
            grid: self.grid,
            inside: self.inside,
            sigma_texels: self.sigma_texels,
            lines: self.lines,
        }
    }

    /// The reach in texels of receiver `r`'s filter, if it is filtered.
    #[inline]
    fn reach(&self, r: usize) -> Option<usize> {
        let sigma = self.sigma_texels[r];
        (sigma > 0.0).then(|| ((2.0 * sigma).ceil() as usize).min(MAX_REACH as usize))
    }

    /// Whether receiver j, at `rel` from receiver r, may lend to it: not
    /// inside geometry, within r's z_min,
    /// through the leak rule and with a shading normal within
    /// [`LENDER_NORMAL_AGREEMENT`].
    #[inline]
    fn lends(&self, r: usize, j: usize, rel: Vec3) -> bool {
        let rc = self.receivers;
        let (n, geo) = (rc.normal[r], rc.geo_normal[r]);
        // (Written as the rejections, so a NaN passes as it did.)
        !(self.inside[j]
            || rel.length() > self.z_min[r]
            || !lends_rays(rel, n, geo, rc.normal[j], rc.geo_normal[j], rc.footprint[r])
            || rc.normal[j].dot(n) < LENDER_NORMAL_AGREEMENT)
    }

    /// Calls `f(j, w)` for each receiver j that lends to receiver `r` along
    /// its row (`vertical` false) or column, with its Gaussian weight w on
    /// the offset in r's tangent plane; r itself has w = 1. A side's run
    /// ends at the first neighbour inside geometry, beyond z_min, failing
    /// the leak rule or [`LENDER_NORMAL_AGREEMENT`] or missing (a chart
    /// border), and both sides keep the
    /// shorter run's length. Nothing for an unfiltered receiver.
    #[inline]
    fn for_each_weight(&self, r: usize, vertical: bool, f: impl FnMut(usize, f32)) {
        if let Some(lines) = self.lines {
            match lines.of(r) {
                Line::None => {}
                Line::Row if vertical => return,
                Line::Column if !vertical => return,
                _ => return self.on_lines().for_each_weight(r, lines.reach, vertical, f),
            }
        }
        let Some(reach) = self.reach(r) else {
            return;
        };
        let rc = self.receivers;
        let fp = rc.footprint[r];
        let sigma_world = self.sigma_texels[r] * fp;
        let inv2s2 = 1.0 / (2.0 * sigma_world * sigma_world);
        let (pr, geo) = (rc.position[r], rc.geo_normal[r]);
        let lend = |j: usize, _| {
            let rel = rc.position[j] - pr;
            self.lends(r, j, rel).then(|| {
                let t = rel - geo * rel.dot(geo);
                (-t.length_squared() * inv2s2).exp()
            })
        };
        symmetric_runs(self.grid, rc, r, reach, vertical, lend, f);
    }

    /// Effective number of receivers the separable filter averages for
    /// each receiver: (sum W)^2 / sum W^2 over its final weights W (1 when
    /// not filtered). With row sums S_j = sum w, Q_j = sum w^2 and column
    /// weights c_j this is (sum c_j S_j)^2 / sum c_j^2 Q_j.
    pub fn effective_neighbours(&self) -> Vec<f32> {
        let n = self.receivers.len();
        let rows: Vec<(f32, f32)> = (0..n)
            .into_par_iter()
            .with_min_len(256)
            .map(|r| {
                let (mut s, mut q) = (0.0f32, 0.0f32);
                self.for_each_weight(r, false, |_, w| {
                    s += w;
                    q += w * w;
                });
                if s > 0.0 { (s, q) } else { (1.0, 1.0) }
            })
            .collect();
        (0..n)
            .into_par_iter()
            .with_min_len(256)
            .map(|r| {
                let (mut num, mut den) = (0.0f32, 0.0f32);
                self.for_each_weight(r, true, |j, c| {
                    num += c * rows[j].0;
                    den += c * c * rows[j].1;
                });
                if den > 0.0 {
                    (num * num / den).max(1.0)
                } else {
                    // No column pass (unfiltered, or on a line along its
                    // row): the row's own.
                    (rows[r].0 * rows[r].0 / rows[r].1).max(1.0)
                }
            })
            .collect()
    }

    /// One pass of the separable filter over `src` (rows, or columns
    /// when `vertical`), each value weighted by `src_w` (the row pass's
    /// weight sums) if given: per receiver its filtered values and their
    /// weight sum; unfiltered receivers keep their own.
    fn pass<'s, const N: usize>(
        &'s self,
        src: &'s [[f32; N]],
        src_w: Option<&'s [f32]>,
        vertical: bool,
    ) -> impl IndexedParallelIterator<Item = ([f32; N], f32)> + 's {
        (0..self.receivers.len())
            .into_par_iter()
            .with_min_len(256)
            .map(move |r| {
                let mut mean = WeightedMean::default();
                self.for_each_weight(r, vertical, |j, w| {
                    mean.add(w * src_w.map_or(1.0, |s| s[j]), src[j]);
                });
                mean.get().unwrap_or((src[r], src_w.map_or(1.0, |s| s[r])))
            })
    }

    /// The separable Gaussian filter of the integrated values (see the
    /// module doc), rows then columns; each row result carries its weight
    /// sum into the column pass. `values` (AO, then the 9 SH) is dropped
    /// after the row pass; the column pass writes the filtered AO and SH
    /// arrays themselves.
    pub fn filter(&self, values: Vec<[f32; 10]>) -> (Vec<f32>, Vec<[f32; SH_COUNT]>) {
        let (row_values, row_weights): (Vec<[f32; 10]>, Vec<f32>) =
            self.pass(&values, None, false).unzip();
        drop(values);
        self.pass(&row_values, Some(&row_weights), true)
            .map(|(v, _)| (v[0], std::array::from_fn(|i| v[1 + i])))
            .unzip()
    }

    /// The same filter, with the same weights, of any other per-receiver
    /// values (the visibility layer's occluded share above the plane).
    pub fn filter_values<const N: usize>(&self, values: Vec<[f32; N]>) -> Vec<[f32; N]> {
        let (row_values, row_weights): (Vec<[f32; N]>, Vec<f32>) =
            self.pass(&values, None, false).unzip();
        drop(values);
        self.pass(&row_values, Some(&row_weights), true)
            .map(|(v, _)| v)
            .collect()
    }
}

/// A weighted mean of the filter's values (AO, then the 9 SH; or the
/// visibility layer's 16).
struct WeightedMean<const N: usize> {
    sum: [f32; N],
    weight: f32,
}

impl<const N: usize> Default for WeightedMean<N> {
    fn default() -> Self {
        WeightedMean {
            sum: [0.0; N],
            weight: 0.0,
        }
    }
}

impl<const N: usize> WeightedMean<N> {
    #[inline]
    fn add(&mut self, w: f32, v: [f32; N]) {
        for (a, v) in self.sum.iter_mut().zip(v) {
            *a += w * v;
        }
        self.weight += w;
    }

    /// The mean and the weight sum; none without weight.
    #[inline]
    fn get(&self) -> Option<([f32; N], f32)> {
        (self.weight > 0.0).then(|| (self.sum.map(|a| a / self.weight), self.weight))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bake::adaptive::grid::flat_grid;

    /// The grid filter's inputs over some receivers: nothing inside, one
    /// cell, the same sigma and z_min everywhere.
    struct Uniform {
        grid: TexelGrid,
        inside: Vec<bool>,
        sigma_texels: Vec<f32>,
        z_min: Vec<f32>,
    }

    impl Uniform {
        fn new(rc: &Receivers, sigma: f32, z_min: f32) -> Uniform {
            let n = rc.len();
            Uniform {
                grid: TexelGrid::new(rc),
                inside: vec![false; n],
                sigma_texels: vec![sigma; n],
                z_min: vec![z_min; n],
            }
        }

        /// The atlas-grid filter over `rc` (no world-space gather).
        fn support<'a>(&'a self, rc: &'a Receivers) -> FilterSupport<'a> {
            FilterSupport {
                receivers: rc,
                grid: &self.grid,
                inside: &self.inside,
                sigma_texels: &self.sigma_texels,
                z_min: &self.z_min,
                lines: None,
            }
        }
    }

    /// (sum w)^2 / sum w^2 of a Gaussian of `sigma` texels over the texel
    /// offsets `xs` x `ys`: the effective neighbours, summed directly.
    fn gaussian_n_eff(
        sigma: f32,
        xs: std::ops::RangeInclusive<i32>,
        ys: std::ops::RangeInclusive<i32>,
    ) -> f64 {
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        for y in ys {
            for x in xs.clone() {
                let w = (-((x * x + y * y) as f64) / (2.0 * (sigma as f64).powi(2))).exp();
                s1 += w;
                s2 += w * w;
            }
        }
        s1 * s1 / s2
    }

    #[test]
    fn effective_neighbours_of_the_separable_filter_on_a_plane() {
        // Against the direct sum (sum w)^2 / sum w^2 of a Gaussian over the
        // square of reach ceil(2 sigma) around the centre, the filter's
        // support; at a corner, a quarter of it.
        let side = 21u32;
        let rc = flat_grid(side);
        let n = rc.len();
        for sigma in [0.75f32, 1.0, 2.0] {
            let uniform = Uniform::new(&rc, sigma, f32::INFINITY);
            let support = uniform.support(&rc);
            let ours = support.effective_neighbours();
            let reach = (2.0 * sigma).ceil() as i32;
            let direct = |xs: std::ops::RangeInclusive<i32>| gaussian_n_eff(sigma, xs.clone(), xs);
            let centre = (side * side / 2) as usize;
            let (c, d) = (ours[centre] as f64, direct(-reach..=reach));
            assert!((c - d).abs() / d < 1e-3, "{sigma}: {c} vs {d}");
            // Near a border both sides keep the shorter run: one texel in
            // from a corner, a 3x3 square; the corner itself, alone.
            let (c, d) = (ours[(side + 1) as usize] as f64, direct(-1..=1));
            assert!((c - d).abs() / d < 1e-3, "by a corner {sigma}: {c} vs {d}");
            assert_eq!(ours[0], 1.0);
            // Unfiltered receivers average only themselves.
            let none = vec![0.0f32; n];
            let alone = FilterSupport {
                sigma_texels: &none,
                ..support
            };
            assert!(alone.effective_neighbours().iter().all(|&v| v == 1.0));
        }
    }

    #[test]
    fn lenders_whose_shading_normal_turns_beyond_ten_degrees_do_not_lend() {
        // A flat grid whose shading normals turn about y from column to
        // column (a curved surface's normals on a flat chart): at 15
        // degrees per column (within the leak rule's 25) the row lends
        // nothing, so the centre averages its column only; at 4 degrees
        // (8 at two columns) the whole square lends.
        let side = 9u32;
        let sigma = 1.0f32;
        let reach = 2i32;
        let direct = |xs, ys| gaussian_n_eff(sigma, xs, ys);
        let centre = (side * side / 2) as usize;
        for (degrees, want) in [
            (15.0f32, direct(0..=0, -reach..=reach)),
            (4.0, direct(-reach..=reach, -reach..=reach)),
        ] {
            let mut rc = flat_grid(side);
            for (t, n) in rc.normal.iter_mut().enumerate() {
                let a = (degrees * ((t as u32 % side) as f32 - 4.0)).to_radians();
                *n = Vec3::new(a.sin(), 0.0, a.cos());
            }
            let uniform = Uniform::new(&rc, sigma, f32::INFINITY);
            let got = uniform.support(&rc).effective_neighbours()[centre] as f64;
            assert!(
                (got - want).abs() / want < 1e-3,
                "{degrees}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn the_filter_keeps_a_gradient_up_to_a_chart_border() {
        // AO rising linearly across a chart whose right part is missing
        // (another chart's texels): a one-sided average beside the border
        // would be biased by the slope times the weights' offset; the
        // symmetric support keeps the ramp exact to rounding.
        let side = 12u32;
        let full = flat_grid(side);
        // Keep columns 0..8: the chart border is between columns 7 and 8.
        let keep: Vec<usize> = (0..full.len())
            .filter(|&t| t % side as usize <= 7)
            .collect();
        let rc = Receivers {
            texel: keep.iter().map(|&t| t as u32).collect(),
            position: keep.iter().map(|&t| full.position[t]).collect(),
            normal: keep.iter().map(|&t| full.normal[t]).collect(),
            geo_normal: keep.iter().map(|&t| full.geo_normal[t]).collect(),
            footprint: keep.iter().map(|&t| full.footprint[t]).collect(),
            center_inside: vec![true; keep.len()],
            ..full
        };
        let uniform = Uniform::new(&rc, 2.0, f32::INFINITY);
        assert_filter_keeps(&uniform.support(&rc), |p| 0.1 + 0.1 * p.x);
    }

    /// `support`'s filter keeps a linear function of position exactly (to
    /// rounding), in the AO and every SH value.
    fn assert_filter_keeps(support: &FilterSupport, f: impl Fn(Vec3) -> f32) {
        let rc = support.receivers;
        let values: Vec<[f32; 10]> = rc.position.iter().map(|&p| [f(p); 10]).collect();
        let (ao, sh) = support.filter(values);
        for (r, &p) in rc.position.iter().enumerate() {
            assert!((ao[r] - f(p)).abs() < 1e-5, "{p}: {}", ao[r]);
            assert!(sh[r].iter().all(|&v| (v - f(p)).abs() < 1e-5), "{p}");
        }
    }

    #[test]
    fn the_filter_keeps_a_constant_and_does_not_cross_z_min() {
        // A constant is kept exactly; a neighbour beyond z_min is not read.
        let rc = flat_grid(9);
        let n = rc.len();
        let uniform = Uniform::new(&rc, 2.0, 1.5);
        let support = uniform.support(&rc);
        let (ao, sh) = support.filter(vec![[0.25f32; 10]; n]);
        assert!(
            ao.iter()
                .chain(sh.iter().flatten())
                .all(|&v| (v - 0.25).abs() < 1e-6)
        );
        // One bright texel: only receivers within 1.5 texels (row or column
        // offsets of 1) see it.
        let mut values = vec![[0.0f32; 10]; n];
        values[40] = [1.0; 10];
        let (out, _) = support.filter(values.clone());
        for (r, v) in out.iter().enumerate() {
            let (dx, dy) = ((r % 9) as i32 - 4, (r / 9) as i32 - 4);
            let reach = dx.abs() <= 1 && dy.abs() <= 1;
            assert_eq!(*v > 0.0, reach, "texel {dx},{dy}");
        }
        // Inside receivers lend nothing.
        let mut inside = vec![false; n];
        inside[40] = true;
        let masked = FilterSupport {
            inside: &inside,
            ..support
        };
        let (out, _) = masked.filter(values);
        assert!(out.iter().enumerate().all(|(r, &v)| r == 40 || v == 0.0));
    }

    #[test]
    fn a_line_receiver_averages_along_the_line_alone() {
        // The band of rows 0..=2; the receiver at (5, 0) is on a line along
        // its row with both runs LINE_REACH long. Weights 1, a = e^-1/2, b =
        // e^-2 at 0, 1 and 2 texels (a Gaussian of 1 texel).
        let rc = flat_grid(12);
        let (sigma, lines) = crate::bake::adaptive::line::tests::lines_of(&rc, |_, y| y <= 2);
        let (inside, z) = (vec![false; rc.len()], vec![f32::INFINITY; rc.len()]);
        let grid = TexelGrid::new(&rc);
        let support = FilterSupport {
            receivers: &rc,
            grid: &grid,
            inside: &inside,
            sigma_texels: &sigma,
            z_min: &z,
            lines: Some(&lines),
        };
        let r = 5usize;
        let (a, b) = ((-0.5f64).exp(), (-2.0f64).exp());
        let (s1, s2) = (1.0 + 2.0 * a + 2.0 * b, 1.0 + 2.0 * a * a + 2.0 * b * b);
        let n_eff = support.effective_neighbours()[r] as f64;
        assert!((n_eff - s1 * s1 / s2).abs() < 1e-4, "{n_eff}");
        // x^2 along the row: the weighted mean of (x + k)^2 is x^2 plus
        // the weights' second moment; the rows across are not read (a
        // step of 0.5 between y = 0 and y = 1 would show).
        let f = |p: Vec3| 0.01 * p.x * p.x + if p.y < 0.5 { 0.0 } else { 0.5 };
        let values: Vec<[f32; 10]> = rc.position.iter().map(|&p| [f(p); 10]).collect();
        let (ao, sh) = support.filter(values);
        let want = 0.01 * (25.0 + (2.0 * a + 8.0 * b) / s1);
        assert!((ao[r] as f64 - want).abs() < 1e-5, "{} vs {want}", ao[r]);
        assert!(sh[r].iter().all(|&v| (v as f64 - want).abs() < 1e-5));
        // A receiver off the band keeps its filter (sigma 1 here, the
        // isotropic one), one at the band's end its own value.
        assert_eq!(ao[0], f(rc.position[0]));
    }
}
