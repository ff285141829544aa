//! Contact lines: receivers in contact (filter width 0) whose occluder
//! runs along a row or a column of their chart, filtered along it.
//!
//! In: the receivers, the texel grid, inside marks, each receiver's sigma
//! ([`super::bounds`]), [`AdaptiveOptions`]. Out:
//! [`ContactLines`]: per receiver its [`Line`] and the reach of the filter
//! along it, which [`super::filter::FilterSupport`] reads for N_eff (so
//! the allocation) and for the filtered values.
//!
//! The axis-aligned filter's width is z_min / (2 mu Omega_h), isotropic:
//! a receiver whose nearest occluder lies within half a texel is not
//! filtered, and takes Monte Carlo's ray count alone. Along a contact line
//! (the floor's texels beside a wall, a wall's beside a column's flat
//! side, the corners of a room) the occluder does not change from one
//! receiver to the next: the visibility varies across the line, at the
//! occluder's depth, and along it only at the depth of the other
//! occluders. So such a receiver is averaged with its contact neighbours
//! along the line alone, with a Gaussian of [`LINE_SIGMA`] texels out to
//! [`LINE_REACH`] texels, runs cut symmetric as the filter's are.
//!
//! A receiver is on a line along a row when its two row neighbours are in
//! contact and lend to it (`OnLines::lends`: the same
//! surface, normals within the filter's agreement) and contact runs
//! farther along its row than along its column (counted out to
//! [`EXTENT_REACH`] texels on each side): the region where an occluder
//! lies within half a texel follows the occluder, long along the line and
//! narrow across it (a band beside a wall, a strip under a rail). A
//! contact area as long one way as the other is not a line, nor is a band
//! whose receivers along it do not lend (a column's foot, whose normals
//! turn along it). Likewise along a column.
//!
//! A departure from the paper, measured in `docs/method-adaptive.md`
//! (fewer rays for the contact texels at the same engine view).

use super::grid::{LENDER_NORMAL_AGREEMENT, TexelGrid, symmetric_runs};
use super::options::AdaptiveOptions;
use crate::atlas::Receivers;
use crate::bake::sheared::lends_rays;
use rayon::prelude::*;

/// Gaussian sigma, in texels, of the filter along a contact line: the
/// other occluders' depth bounds how far the line's visibility holds, and
/// a wider one blurs it (`docs/method-adaptive.md`).
pub const LINE_SIGMA: f32 = 1.0;

/// Texels the filter along a contact line reaches on each side (at most
/// the options' `max_reach`).
pub const LINE_REACH: u32 = 2;

/// Texels on each side within which [`contact_lines`] measures how far
/// contact runs along a row and a column: a wall standing through a
/// floor's chart has a band of contact about three texels deep on both
/// of its sides, six across, which two texels a side would take for an
/// area.
pub const EXTENT_REACH: u32 = 4;

/// How far in the world, in footprints per texel of the atlas, a
/// neighbour on a contact line may lie: a chart the minimum chart width
/// stretched across has texels farther apart along it than its
/// footprint (the geometric mean of the two axes), one across a gutter
/// lies much farther.
pub const LINE_SPAN: f32 = 3.0;

/// A receiver's contact line.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Line {
    #[default]
    None,
    /// Along its row (the filter's row pass).
    Row,
    /// Along its column (the column pass).
    Column,
}

/// Every receiver's [`Line`] and the filter's reach along them.
#[derive(Clone, Debug, Default)]
pub struct ContactLines {
    /// Per receiver; empty: no lines (`max_reach` 0, or
    /// [`AdaptiveOptions::contact_lines`] off).
    pub axis: Vec<Line>,
    /// Texels on each side, [`LINE_REACH`] within `max_reach`.
    pub reach: usize,
}

impl ContactLines {
    /// Receiver `r`'s line.
    #[inline]
    pub fn of(&self, r: usize) -> Line {
        self.axis.get(r).copied().unwrap_or_default()
    }

    /// How many receivers lie on a line.
    pub fn count(&self) -> usize {
        self.axis.iter().filter(|&&l| l != Line::None).count()
    }
}

/// What the filter along a contact line reads: the receivers, their
/// grid, inside marks and sigma, and the lines (`None` while they are
/// being found).
#[derive(Clone, Copy)]
pub struct OnLines<'a> {
    pub receivers: &'a Receivers,
    pub grid: &'a TexelGrid,
    pub inside: &'a [bool],
    pub sigma_texels: &'a [f32],
    pub lines: Option<&'a ContactLines>,
}

impl OnLines<'_> {
    /// The filter's weights (`FilterSupport::for_each_weight`) of a
    /// receiver on a contact line, along it (`vertical`: a column) out to
    /// `reach` texels: its contact neighbours on the line ([`Self::lends`])
    /// with Gaussian weights of [`LINE_SIGMA`] texels, each side's run cut
    /// at the first that does not lend and both kept as long as the
    /// shorter.
    #[inline]
    pub(crate) fn for_each_weight(
        &self,
        r: usize,
        reach: usize,
        vertical: bool,
        f: impl FnMut(usize, f32),
    ) {
        let inv2s2 = 1.0 / (2.0 * LINE_SIGMA * LINE_SIGMA);
        let lend = |j: usize, k: usize| {
            self.lends(r, j, k, vertical)
                .then(|| (-((k * k) as f32) * inv2s2).exp())
        };
        symmetric_runs(self.grid, self.receivers, r, reach, vertical, lend, f);
    }

    /// Whether receiver j is in contact: not filtered (sigma 0) and not
    /// inside geometry.
    #[inline]
    fn in_contact(&self, j: usize) -> bool {
        !self.inside[j] && self.sigma_texels[j] <= 0.0
    }

    /// Whether receiver j, `k` texels from receiver r along its row (or
    /// column when `vertical`), may lend to it on a contact line: in
    /// contact itself (not filtered, not inside geometry), not on a line
    /// along a row when `vertical` (the column pass reads the row pass's
    /// values, which must be j's own), within [`LINE_SPAN`] footprints a
    /// texel in the world (the same surface, not across a gutter),
    /// through the leak rule and with a shading normal within
    /// [`LENDER_NORMAL_AGREEMENT`].
    #[inline]
    pub(crate) fn lends(&self, r: usize, j: usize, k: usize, vertical: bool) -> bool {
        let rc = self.receivers;
        let (n, geo) = (rc.normal[r], rc.geo_normal[r]);
        let rel = rc.position[j] - rc.position[r];
        let row_line = vertical && self.lines.is_some_and(|l| l.of(j) == Line::Row);
        self.in_contact(j)
            && !row_line
            && rel.length() <= LINE_SPAN * k as f32 * rc.footprint[r]
            && lends_rays(rel, n, geo, rc.normal[j], rc.geo_normal[j], rc.footprint[r])
            && rc.normal[j].dot(n) >= LENDER_NORMAL_AGREEMENT
    }
}

/// Texels the filter along a contact line reaches on each side under `o`:
/// [`LINE_REACH`] within `max_reach`, 0 with the lines off.
pub fn line_reach(o: &AdaptiveOptions) -> u32 {
    if o.contact_lines {
        LINE_REACH.min(o.max_reach)
    } else {
        0
    }
}

/// How far (texels, Chebyshev) a receiver's ray count reads the pre-pass
/// under `o` ([`super::PageWide::halo`]): its N_eff, through the lines of
/// its lenders [`line_reach`] away (each from the sigma within
/// [`EXTENT_REACH`] of it, each sigma from the z_min within `max_reach`),
/// or with the isotropic filter through its lenders' z_min, each spread
/// over `max_reach`, `max_reach` away.
pub fn count_reach(o: &AdaptiveOptions) -> u32 {
    let isotropic = 2 * o.max_reach;
    match line_reach(o) {
        0 => isotropic,
        l => isotropic.max(l + EXTENT_REACH + o.max_reach),
    }
}

/// Each receiver's contact line (see the module doc).
pub fn contact_lines(
    receivers: &Receivers,
    grid: &TexelGrid,
    inside: &[bool],
    sigma_texels: &[f32],
    o: &AdaptiveOptions,
) -> ContactLines {
    let reach = line_reach(o) as usize;
    if reach == 0 {
        return ContactLines::default();
    }
    let support = OnLines {
        receivers,
        grid,
        inside,
        sigma_texels,
        lines: None,
    };
    let axis = (0..receivers.len())
        .into_par_iter()
        .with_min_len(1024)
        .map(|r| {
            if !support.in_contact(r) {
                return Line::None;
            }
            let neighbour = |k: isize, vertical: bool| grid.offset(receivers, r, k, vertical);
            // Both neighbours along the axis in contact and lending.
            let along = |vertical: bool| {
                [-1, 1].iter().all(|&d| {
                    neighbour(d, vertical).is_some_and(|j| support.lends(r, j, 1, vertical))
                })
            };
            // How far contact runs along the axis, both sides, up to
            // EXTENT_REACH each.
            let extent = |vertical: bool| -> usize {
                [-1isize, 1]
                    .iter()
                    .map(|&d| {
                        (1..=EXTENT_REACH as isize)
                            .map_while(|k| {
                                neighbour(d * k, vertical).filter(|&j| support.in_contact(j))
                            })
                            .count()
                    })
                    .sum()
            };
            let (row, column) = (extent(false), extent(true));
            match (along(false) && row > column, along(true) && column > row) {
                (true, false) => Line::Row,
                (false, true) => Line::Column,
                _ => Line::None,
            }
        })
        .collect();
    ContactLines { axis, reach }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::bake::adaptive::grid::flat_grid;
    use glam::Vec3;

    /// The lines of `rc` whose receivers at `contact` have sigma 0 (the
    /// others 1 texel), nothing inside, default options.
    pub(crate) fn lines_of(
        rc: &Receivers,
        contact: impl Fn(u32, u32) -> bool,
    ) -> (Vec<f32>, ContactLines) {
        let side = rc.width;
        let sigma: Vec<f32> = (0..rc.len() as u32)
            .map(|t| {
                if contact(t % side, t / side) {
                    0.0
                } else {
                    1.0
                }
            })
            .collect();
        let inside = vec![false; rc.len()];
        let grid = TexelGrid::new(rc);
        let lines = contact_lines(rc, &grid, &inside, &sigma, &AdaptiveOptions::DEFAULT);
        (sigma, lines)
    }

    #[test]
    fn a_band_beside_an_occluder_is_a_line_along_it() {
        // Rows 0..=2 of a 12 x 12 chart in contact (a floor beside a wall
        // along y = -1): lines along the rows but at the band's ends (a
        // neighbour missing; the middle row's column neighbours there are
        // in contact and lend, but the band opens along no row).
        let rc = flat_grid(12);
        let (_, lines) = lines_of(&rc, |_, y| y <= 2);
        for t in 0..rc.len() as u32 {
            let (x, y) = (t % 12, t / 12);
            let want = match (x, y) {
                (0 | 11, _) | (_, 3..) => Line::None,
                _ => Line::Row,
            };
            assert_eq!(lines.of(t as usize), want, "({x}, {y})");
        }
        assert_eq!(lines.reach, LINE_REACH as usize);
        // The same band along a column.
        let (_, lines) = lines_of(&rc, |x, _| x >= 10);
        assert_eq!(lines.of(5 * 12 + 11), Line::Column);
        assert_eq!(lines.of(5 * 12 + 9), Line::None);
    }

    #[test]
    fn a_contact_area_a_bent_band_and_no_filter_make_no_lines() {
        // Everything in contact: contact runs as far along either axis, an
        // area.
        let rc = flat_grid(15);
        let (_, lines) = lines_of(&rc, |_, _| true);
        assert_eq!(lines.of(7 * 15 + 7), Line::None);
        // A band whose normals turn 15 degrees a texel along it (a
        // column's foot): its neighbours do not lend.
        let mut bent = flat_grid(12);
        for (t, n) in bent.normal.iter_mut().enumerate() {
            let a = (15.0 * (t % 12) as f32).to_radians();
            *n = Vec3::new(a.sin(), 0.0, a.cos());
        }
        bent.geo_normal = bent.normal.clone();
        let (_, lines) = lines_of(&bent, |_, y| y == 0);
        assert_eq!(lines.count(), 0);
        // max_reach 0 (no filter) or the option off: none.
        let grid = TexelGrid::new(&rc);
        let sigma = vec![0.0; rc.len()];
        let inside = vec![false; rc.len()];
        for o in [
            AdaptiveOptions {
                max_reach: 0,
                ..AdaptiveOptions::DEFAULT
            },
            AdaptiveOptions {
                contact_lines: false,
                ..AdaptiveOptions::DEFAULT
            },
        ] {
            assert!(
                contact_lines(&rc, &grid, &inside, &sigma, &o)
                    .axis
                    .is_empty()
            );
        }
    }

    #[test]
    fn the_halo_covers_what_a_line_reads() {
        // Without lines the isotropic filter's 4 max_reach + 5; with them
        // a count reads a lender's line (reach 2), its extent (4) and the
        // spread z_min (max_reach), past the isotropic reach below a
        // max_reach of 6.
        use crate::bake::adaptive::PageWide;
        let at = |max_reach, contact_lines| AdaptiveOptions {
            max_reach,
            contact_lines,
            ..AdaptiveOptions::DEFAULT
        };
        for m in [0, 1, 4, 8] {
            assert_eq!(PageWide::halo(&at(m, false)), 4 * m + 5);
        }
        assert_eq!(PageWide::halo(&at(0, true)), 5);
        assert_eq!(PageWide::halo(&at(1, true)), 2 + (1 + 4 + 1) + 5);
        assert_eq!(PageWide::halo(&at(4, true)), 8 + (2 + 4 + 4) + 5);
        assert_eq!(PageWide::halo(&at(8, true)), 4 * 8 + 5);
    }
}
