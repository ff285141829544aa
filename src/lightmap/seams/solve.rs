//! Stitch: least-squares agreement of the two sides of every seam
//! (Iwanicki, "Lighting technology of The Last of Us", SIGGRAPH 2013).
//!
//! In: the [`Seam`]s of a page, its size and the per-texel values (every
//! channel the page holds: AO, the 9 SH, the visibility layer). Out: the
//! same values where, at points along each seam ([`POINTS_PER_TEXEL`] per
//! texel of its length), the bilinear lookups from the two sides agree in
//! the least-squares sense, each texel kept near its baked value: minimise
//! Sum_t (x_t - x0_t)^2 + lambda^2 Sum_points (lookup_A(x) - lookup_B(x))^2
//! per channel. Only texels in the seams' bilinear footprints are unknowns
//! (border and gutter texels; the caller may fix others, whose values
//! then enter the constraints as constants); the normal equations (I + lambda^2 C^T C) x =
//! x0 split into independent components (texels tied by constraints), each
//! solved in parallel by a [`Solver`]: on a bilinear page a fixed number of
//! Jacobi-preconditioned Chebyshev steps, so that a solved texel reads only
//! the texels within a few rows of it (a rebake of part of a page needs no
//! more of it), elsewhere conjugate gradients to a tolerance.

use super::find::Seam;
use super::metric::samples;
pub use super::reads::Reads;
pub use super::solver::Solver;
use super::solver::{Row, SPECTRUM_LOW, STEPS, chebyshev, conjugate_gradients};
use crate::lightmap::filter::Filter;
use rayon::prelude::*;
use serde::Serialize;

/// lambda: the weight of a seam constraint against one texel's data term.
/// Larger agrees better and converges slower (the system's condition
/// grows with lambda^2). 5 closes most of the jumps within a tenth of the
/// bake's time; the interior texels stay fixed, since freeing them closes
/// the seams no better and moves them off the reference
/// (`docs/measurements/constants.md`, SEAM_WEIGHT).
pub const SEAM_WEIGHT: f64 = 5.0;

/// Constraint points per texel of seam length.
pub const POINTS_PER_TEXEL: f32 = 3.0;

/// What the solve did.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct StitchStats {
    /// Texels free to move.
    pub unknowns: usize,
    pub constraints: usize,
    pub components: usize,
    /// Most iterations any component and channel took (conjugate
    /// gradients'; the Chebyshev steps: [`STEPS`]).
    pub max_iterations: usize,
    /// Every component and channel reached its solver's end: conjugate
    /// gradients their tolerance, the Chebyshev steps all [`STEPS`] with
    /// finite values (they stop at no tolerance:
    /// `docs/measurements/constants.md`, STEPS).
    pub converged: bool,
}

/// A solve's unknowns' texels, their values (`channels` each), the
/// solve's stats and, when seeds were given, how far its unknowns (in the
/// same order) lie from them ([`System::seeded`]).
pub type Solution = (Vec<u32>, Vec<f32>, StitchStats, Option<Reads>);

/// A constraint's free part in a component's own indices.
type LocalRow = Vec<(usize, f64)>;

/// A one-sided constraint: the page's bilinear lookup at `uv` should
/// equal `target` (one value per channel), for a seam whose other side is
/// on another page ([`super::anchor`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Anchor {
    pub uv: [f32; 2],
    pub target: Vec<f32>,
    /// The row's weight relative to a seam row's of scale 1
    /// ([`SEAM_WEIGHT`]): cross-page anchors 1 (they are seam rows, scaled
    /// with the seams by [`stitch`]), the border fit's points
    /// [`crate::lightmap::border::FIT_WEIGHT`].
    pub weight: f32,
}

/// The stitched values of a `width` x `height` page along `seams`:
/// `baked(texel, out)` writes a texel's `channels` baked values into `out`.
/// Every texel's data term weighs 1: a heavier one for covered texels (they
/// hold their receivers' estimates, the gutter only copies) measured
/// worse at the seams for little at the covered texels
/// (`docs/measurements/constants.md`, the data term's weight).
/// `anchors` add one-sided constraints (lookup = target) of a seam (its
/// other side on another page); seam rows, two-sided and these, are scaled
/// by `seam_scale`. `fitted` add one-sided constraints of their own weight
/// (the border fit's points). Every row reads through `filter`, and the
/// system is solved by [`Solver::for_filter`]. `seeds`: texels whose inputs
/// changed ([`System::seeded`]). Returns the unknowns' texels, values
/// (`channels` each), the solve's stats and how far they lie from a seed.
#[allow(clippy::too_many_arguments)]
pub fn stitch(
    seams: &[Seam],
    anchors: &[Anchor],
    fitted: &[Anchor],
    width: u32,
    height: u32,
    seam_scale: f64,
    channels: usize,
    filter: Filter,
    fixed: impl Fn(u32) -> bool,
    data_weight: &(dyn Fn(u32) -> f64 + Sync),
    baked: impl Fn(u32, &mut [f32]) + Sync,
    seeds: Option<&[bool]>,
) -> Solution {
    // Each row's taps (texel, weight), its anchor and scale, built in
    // parallel and pushed in order (the unknowns are numbered in the order
    // they first appear): two-sided points (side A positive, side B
    // negative), then anchors.
    let tapped = |uv: [f32; 2], scale: f64| {
        (filter.taps(uv, width, height).into_iter()).map(move |(t, w)| (t, scale * w as f64))
    };
    type RowTaps = (Vec<(u32, f64)>, Option<usize>, f64);
    let two_sided: Vec<RowTaps> = seams
        .par_iter()
        .flat_map_iter(|seam| {
            samples(seam, width, height, POINTS_PER_TEXEL).map(move |t| {
                let (uva, uvb) = seam.at(t);
                let both: Vec<(u32, f64)> = tapped(uva, seam_scale)
                    .chain(tapped(uvb, -seam_scale))
                    .collect();
                (both, None, seam_scale)
            })
        })
        .collect();
    // Anchor k: of `anchors`, then of `fitted`.
    let anchor_at = |k: usize| match k.checked_sub(anchors.len()) {
        None => &anchors[k],
        Some(f) => &fitted[f],
    };
    let one_sided: Vec<RowTaps> = (0..anchors.len() + fitted.len())
        .into_par_iter()
        .map(|k| {
            let a = anchor_at(k);
            let seam = if k < anchors.len() { seam_scale } else { 1.0 };
            let scale = seam * a.weight as f64;
            (tapped(a.uv, scale).collect(), Some(k), scale)
        })
        .collect();
    let system = System::new(fixed).solver(Solver::for_filter(filter));
    let mut system = match seeds {
        Some(seeds) => system.seeded(seeds),
        None => system,
    };
    for (row_taps, anchor, scale) in two_sided.into_iter().chain(one_sided) {
        system.push(row_taps, anchor, scale);
    }
    system.solve_weighted(channels, data_weight, baked, |k| &anchor_at(k).target)
}

/// A least-squares system over texels being assembled: rows of bilinear
/// taps, the texels `fixed` says may not move entering as constants, the
/// others numbered as unknowns in the order they first appear. Solved by
/// [`System::solve`]: minimise Sum_t (x_t - x0_t)^2 + lambda^2 Sum_rows
/// (row(x) - target)^2 per channel ([`SEAM_WEIGHT`] = lambda).
pub struct System<'s, F: Fn(u32) -> bool> {
    fixed: F,
    solver: Solver,
    /// Per texel, whether its inputs changed ([`System::seeded`]).
    seeds: Option<&'s [bool]>,
    /// Per texel id, its unknown (`u32::MAX`: none yet); grown on demand.
    unknown_of: Vec<u32>,
    texel_of: Vec<u32>,
    rows: Vec<Row>,
}

impl<'s, F: Fn(u32) -> bool> System<'s, F> {
    /// A system solved by conjugate gradients ([`System::solver`] sets
    /// another).
    pub fn new(fixed: F) -> Self {
        System {
            fixed,
            solver: Solver::Converged,
            seeds: None,
            unknown_of: Vec::new(),
            texel_of: Vec::new(),
            rows: Vec::new(),
        }
    }

    /// The same system solved by `solver`.
    pub fn solver(self, solver: Solver) -> Self {
        System { solver, ..self }
    }

    /// The solution will say how far each unknown lies from `seeds` (per
    /// texel: its value or the rows through its cell changed), in rows
    /// ([`Reads`]): its value reads a seed within [`Solver::reach`] (its
    /// whole component under conjugate gradients).
    pub fn seeded(self, seeds: &'s [bool]) -> Self {
        System {
            seeds: Some(seeds),
            ..self
        }
    }

    /// A two-sided row: its taps (texel, weight, side B's negative) sum to
    /// 0; `scale` is the row's weight, already in the taps' weights.
    pub fn push_two_sided(&mut self, taps: impl IntoIterator<Item = (u32, f64)>, scale: f64) {
        self.push(taps, None, scale);
    }

    /// A row: `anchor`, for a one-sided row, the index of its target.
    fn push(
        &mut self,
        taps: impl IntoIterator<Item = (u32, f64)>,
        anchor: Option<usize>,
        scale: f64,
    ) {
        let mut row = Row {
            anchor,
            scale,
            ..Row::default()
        };
        for (texel, w) in taps {
            if w == 0.0 {
                continue;
            }
            let (list, id) = if (self.fixed)(texel) {
                (&mut row.fixed, texel)
            } else {
                if texel as usize >= self.unknown_of.len() {
                    self.unknown_of.resize(texel as usize + 1, u32::MAX);
                }
                let slot = &mut self.unknown_of[texel as usize];
                if *slot == u32::MAX {
                    *slot = self.texel_of.len() as u32;
                    self.texel_of.push(texel);
                }
                (&mut row.free, *slot)
            };
            match list.iter_mut().find(|e| e.0 == id) {
                Some(e) => e.1 += w,
                None => list.push((id, w)),
            }
        }
        row.free.retain(|e| e.1.abs() > 1e-12);
        if !row.free.is_empty() {
            self.rows.push(row);
        }
    }

    /// The unknowns' texels, their solved values (`channels` each, in the
    /// same order) and what the solve did. `baked(texel, out)` writes a
    /// texel's `channels` values; `target(k)` one-sided row k's.
    pub fn solve<'t>(
        self,
        channels: usize,
        baked: impl Fn(u32, &mut [f32]) + Sync,
        target: impl Fn(usize) -> &'t [f32] + Sync,
    ) -> Solution {
        self.solve_weighted(channels, &|_| 1.0, baked, target)
    }

    /// The same with texel t's data term weighing `data_weight(t)`:
    /// minimise Sum_t w_t (x_t - x0_t)^2 + lambda^2 Sum_rows (row(x) -
    /// target)^2 (weights 1: exactly [`System::solve`]).
    pub fn solve_weighted<'t>(
        self,
        channels: usize,
        data_weight: &(dyn Fn(u32) -> f64 + Sync),
        baked: impl Fn(u32, &mut [f32]) + Sync,
        target: impl Fn(usize) -> &'t [f32] + Sync,
    ) -> Solution {
        let System {
            texel_of,
            rows,
            solver,
            seeds,
            ..
        } = self;
        let n = texel_of.len();
        if n == 0 || rows.is_empty() {
            let stats = StitchStats {
                converged: true,
                ..Default::default()
            };
            return (
                Vec::new(),
                Vec::new(),
                stats,
                seeds.map(|_| Reads::default()),
            );
        }
        // Components: unknowns tied by a row (union-find).
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut i: u32) -> u32 {
            while parent[i as usize] != i {
                parent[i as usize] = parent[parent[i as usize] as usize];
                i = parent[i as usize];
            }
            i
        }
        for row in &rows {
            let first = root(&mut parent, row.free[0].0);
            for &(u, _) in &row.free[1..] {
                let r = root(&mut parent, u);
                if r != first {
                    parent[r as usize] = first;
                }
            }
        }
        // Per root, its component; per unknown, its index in it.
        let mut component_of: Vec<u32> = vec![u32::MAX; n];
        let mut local_of: Vec<u32> = vec![0; n];
        let mut members: Vec<Vec<u32>> = Vec::new();
        for u in 0..n as u32 {
            let r = root(&mut parent, u) as usize;
            if component_of[r] == u32::MAX {
                component_of[r] = members.len() as u32;
                members.push(Vec::new());
            }
            let c = &mut members[component_of[r] as usize];
            local_of[u as usize] = c.len() as u32;
            c.push(u);
        }
        let reached = seeds.map(|seeds| {
            let component = (0..n as u32).map(|u| component_of[root(&mut parent, u) as usize]);
            let component: Vec<u32> = component.collect();
            let mut value = vec![0.0f32; channels];
            let known: Vec<bool> = (texel_of.iter())
                .map(|&t| {
                    baked(t, &mut value);
                    value[0].is_finite()
                })
                .collect();
            super::reads::reached(&rows, &texel_of, &component, seeds, solver.reach(), &known)
        });
        let mut component_rows: Vec<Vec<usize>> = vec![Vec::new(); members.len()];
        for (i, row) in rows.iter().enumerate() {
            let r = root(&mut parent, row.free[0].0) as usize;
            component_rows[component_of[r] as usize].push(i);
        }

        // Each component: local indices, its baked values, the solve.
        // Largest components first (their rows times iterations are most
        // of the work), one per task, so no worker is left with a large
        // one at the end; the results go back into component order.
        let mut order: Vec<usize> = (0..members.len()).collect();
        order.sort_by_key(|&c| std::cmp::Reverse(component_rows[c].len()));
        // (component, (its texels, their values, iterations, converged))
        type Solved = (usize, (Vec<u32>, Vec<f32>, usize, bool));
        let mut solved: Vec<Solved> = order
            .par_iter()
            .with_max_len(1)
            .map(|&component| {
                let (members, row_ids) = (&members[component], &component_rows[component]);
                let c = channels;
                // Each row's free part in local indices, and what its fixed
                // texels add per channel.
                let mut value = vec![0.0f32; c];
                let (rows, constants): (Vec<LocalRow>, Vec<Vec<f64>>) = row_ids
                    .iter()
                    .map(|&r| {
                        let free = rows[r]
                            .free
                            .iter()
                            .map(|&(u, w)| (local_of[u as usize] as usize, w))
                            .collect();
                        let mut k = vec![0.0f64; c];
                        for &(t, w) in &rows[r].fixed {
                            baked(t, &mut value);
                            for (k, v) in k.iter_mut().zip(&value) {
                                *k += w * *v as f64;
                            }
                        }
                        if let Some(a) = rows[r].anchor {
                            for (k, v) in k.iter_mut().zip(target(a)) {
                                *k -= rows[r].scale * *v as f64;
                            }
                        }
                        (free, k)
                    })
                    .unzip();
                let m = members.len();
                let lambda2 = SEAM_WEIGHT * SEAM_WEIGHT;
                let texels: Vec<u32> = members.iter().map(|&u| texel_of[u as usize]).collect();
                let dw: Vec<f64> = texels.iter().map(|&t| data_weight(t)).collect();
                let mut diagonal = dw.clone();
                for row in &rows {
                    for &(i, w) in row {
                        diagonal[i] += lambda2 * w * w;
                    }
                }
                let apply = |x: &[f64], y: &mut [f64]| {
                    for (i, (yi, xi)) in y.chunks_mut(c).zip(x.chunks(c)).enumerate() {
                        for (a, b) in yi.iter_mut().zip(xi) {
                            *a = dw[i] * b;
                        }
                    }
                    let mut d = vec![0.0f64; c];
                    for row in &rows {
                        d.iter_mut().for_each(|v| *v = 0.0);
                        for &(i, w) in row {
                            for (dk, xk) in d.iter_mut().zip(&x[i * c..(i + 1) * c]) {
                                *dk += w * xk;
                            }
                        }
                        for &(i, w) in row {
                            for (yk, dk) in y[i * c..(i + 1) * c].iter_mut().zip(&d) {
                                *yk += lambda2 * w * dk;
                            }
                        }
                    }
                };
                let mut start = vec![0.0f32; m * c];
                for (i, &t) in texels.iter().enumerate() {
                    baked(t, &mut start[i * c..(i + 1) * c]);
                }
                let x0: Vec<f64> = start.iter().map(|&v| v as f64).collect();
                // Right-hand side: x0 less lambda^2 C^T k (the fixed texels'
                // part of each constraint).
                let mut b: Vec<f64> = x0.iter().enumerate().map(|(j, v)| dw[j / c] * v).collect();
                for (row, k) in rows.iter().zip(&constants) {
                    for &(i, w) in row {
                        for (bk, kk) in b[i * c..(i + 1) * c].iter_mut().zip(k) {
                            *bk -= lambda2 * w * kk;
                        }
                    }
                }
                // Values not known (NaN: a bake of part of a page): under
                // conjugate gradients (whose step lengths sum over the
                // component) the component is not known; the Chebyshev
                // steps carry NaN exactly as far as the values read it.
                let finite = |v: &f64| v.is_finite();
                let none_known = !b.iter().chain(&x0).any(finite);
                if none_known || (solver == Solver::Converged && !b.iter().chain(&x0).all(finite)) {
                    return (component, (texels, vec![f32::NAN; m * c], 0, true));
                }
                let (x, most, converged) = match solver {
                    Solver::Converged => conjugate_gradients(&apply, &diagonal, &b, &x0, c),
                    Solver::Steps { high } => {
                        let x =
                            chebyshev(&apply, &diagonal, &b, &x0, c, (SPECTRUM_LOW, high), STEPS);
                        let finite = x.iter().all(|v| v.is_finite());
                        (x, STEPS, finite)
                    }
                };
                let out: Vec<f32> = x.iter().map(|&v| v as f32).collect();
                (component, (texels, out, most, converged))
            })
            .collect();
        solved.sort_unstable_by_key(|&(c, _)| c);
        let mut stats = StitchStats {
            unknowns: n,
            constraints: rows.len(),
            components: members.len(),
            max_iterations: 0,
            converged: true,
        };
        let (mut texels, mut values) = (Vec::with_capacity(n), Vec::with_capacity(n * channels));
        for (_, (t, out, iterations, converged)) in solved {
            stats.max_iterations = stats.max_iterations.max(iterations);
            stats.converged &= converged;
            texels.extend(t);
            values.extend(out);
        }
        // Per unknown in component order, as `texels`.
        let reached = reached.map(
            |Reads {
                 depth,
                 fixed,
                 reach,
             }| Reads {
                depth: members
                    .iter()
                    .flatten()
                    .map(|&u| depth[u as usize])
                    .collect(),
                fixed,
                reach,
            },
        );
        (texels, values, stats, reached)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stitched_seam_agrees_and_untouched_texels_keep_their_values() {
        // Two charts of a 16 x 16 page: a vertical edge at u = 4/16 on the
        // left chart is the same world edge as u = 12/16 on the right one.
        let (w, h) = (16u32, 16u32);
        let seam = Seam {
            a: [[4.0 / 16.0, 2.0 / 16.0], [4.0 / 16.0, 14.0 / 16.0]],
            b: [[12.0 / 16.0, 2.0 / 16.0], [12.0 / 16.0, 14.0 / 16.0]],
            length: 1.0,
        };
        // A smooth ramp in v, plus a side-dependent offset and noise.
        let mut values: Vec<f32> = (0..w * h)
            .map(|t| {
                let (x, y) = (t % w, t / w);
                let side = if x < 8 { 0.05 } else { -0.05 };
                let noise = ((t * 7919) % 13) as f32 / 13.0 * 0.05;
                0.5 + 0.02 * y as f32 + side + noise
            })
            .collect();
        let before = values.clone();
        let sh = vec![[0.0f32; crate::sh::SH_COUNT]; (w * h) as usize];
        let jump =
            |v: &[f32]| super::super::metric::measure(&[seam], w, h, v, &sh, Filter::Bilinear);
        assert!(jump(&values).ao_mean > 0.08);
        let (texels, new, stats, _) = stitch(
            &[seam],
            &[],
            &[],
            w,
            h,
            1.0,
            1,
            Filter::Bilinear,
            |_| false,
            &|_| 1.0,
            |t, out| out[0] = values[t as usize],
            None,
        );
        assert!(stats.converged && stats.unknowns > 0, "{stats:?}");
        for (t, v) in texels.iter().zip(new) {
            values[*t as usize] = v;
        }
        // At the 8-bit level: about one step on average, no line (8 steps).
        let after = jump(&values);
        assert!(
            after.ao_mean < 1.5 / 255.0 && after.ao_over_8bit == 0.0,
            "{after:?}"
        );
        // Texels away from both edges are the baked ones.
        for t in 0..w * h {
            let x = t % w;
            if (x as i32 - 4).abs() > 1 && (x as i32 - 12).abs() > 1 {
                assert_eq!(values[t as usize], before[t as usize], "texel {t}");
            }
        }
    }

    #[test]
    fn an_anchored_side_meets_its_target() {
        // The left chart's edge at u = 4/16 must read 0.3 wherever the
        // page holds 0.6; only texels in the lookups' footprints move.
        let (w, h) = (16u32, 16u32);
        let mut values = vec![0.6f32; (w * h) as usize];
        let anchors: Vec<Anchor> = (0..24)
            .map(|i| Anchor {
                uv: [4.0 / 16.0, (2.0 + 12.0 * (i as f32 + 0.5) / 24.0) / 16.0],
                target: vec![0.3],
                weight: 1.0,
            })
            .collect();
        let (texels, new, stats, _) = stitch(
            &[],
            &anchors,
            &[],
            w,
            h,
            1.0,
            1,
            Filter::Bilinear,
            |t| t % w < 3,
            &|_| 1.0,
            |t, out| out[0] = values[t as usize],
            None,
        );
        assert!(stats.converged && stats.constraints == 24, "{stats:?}");
        for (t, v) in texels.iter().zip(new) {
            values[*t as usize] = v;
        }
        let lookup = |uv: [f32; 2]| {
            crate::lightmap::filter::bilinear_taps(uv, w, h)
                .iter()
                .map(|&(t, wt)| wt * values[t as usize])
                .sum::<f32>()
        };
        // Away from the strip's ends every row holds two free texels (x = 3,
        // 4, tap weights 1/2 each) under two anchors, all moving by one d:
        // minimise 2 d^2 + 2 lambda^2 (0.3 + d)^2, so the lookup reads
        // 0.3 + 0.3 * 2 / (2 + 2 lambda^2) = 0.3115.
        let l2 = SEAM_WEIGHT * SEAM_WEIGHT;
        let expected = 0.3 + 0.3 * 2.0 / (2.0 + 2.0 * l2) as f32;
        for a in &anchors[6..18] {
            assert!(
                (lookup(a.uv) - expected).abs() < 2e-3,
                "{} against {expected}",
                lookup(a.uv)
            );
        }
        for a in &anchors {
            assert!((lookup(a.uv) - 0.3).abs() < 0.05, "{}", lookup(a.uv));
        }
        // Fixed texels (x < 3) and texels beyond the footprints keep 0.6.
        for t in 0..w * h {
            if t % w < 3 || t % w > 5 {
                assert_eq!(values[t as usize], 0.6, "texel {t}");
            }
        }
    }
}
