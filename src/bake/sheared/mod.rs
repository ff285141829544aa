//! The sheared filter (`--method sheared`; `filtered` is an alias): Egan, Durand, Ramamoorthi
//! 2011 ("Practical filtering for efficient ray-traced directional
//! occlusion") on lightmap texels.
//!
//! In: [`Receivers`], a [`Tracer`], [`ShearedOptions`], [`BakeParams`].
//! Out: a [`Bake`] (AO and SH per receiver, same definitions as the Monte
//! Carlo baker) and [`ShearedStats`].
//!
//! | file | what | paper |
//! |---|---|---|
//! | `mod.rs` | [`bake`]: both passes, timed | Section 5 |
//! | `types.rs` | what goes in and out: [`ShearedOptions`], [`Samples`], [`ShearedStats`] | |
//! | `passes` | the sparse pass, the filter pass over all receivers | Algorithm 1's outer loop |
//! | `receiver` | one receiver's state: scratch, marks, pending cells, result | |
//! | `gather` | one receiver: gather, depth bounds, marks, filter | Algorithm 1, lines 1-33 |
//! | `second_pass` | one receiver: brute force over the marked cells, AO and SH | Algorithm 1, line 33; Section 5 |
//! | `geometry` | per-pair math: leak rule, Eq. 8, Eq. 9, Figure 6, weights, Jacobian | Eqs. 8-9, Figure 6 |
//! | `order` | receivers in Morton order of their texels, and back | (locality, ours) |
//!
//! 1. *Sparse pass*: K cosine-weighted rays per receiver; each [`Samples`]
//!    entry keeps the direction and hit distance (or a miss).
//! 2. Per receiver (Algorithm 1): gather world-space neighbours with a k-d
//!    tree inside `gather_radius` texel footprints, keep those that can lend
//!    rays (the *leak rule*, [`lends_rays`]: shading and geometric normals
//!    both within ~25 degrees and the neighbour near the receiver's
//!    geometric tangent plane, on it when the planes are parallel, so the
//!    far side of a thin wall, a facing surface, the other face of a
//!    two-faced sheet whose shading normals agree, or a second sheet just
//!    in front of a flat surface never contributes). Hemisphere *cells* are
//!    the 8x8 equal-projected-area cells of the concentric map. From
//!    neighbours'
//!    occluded hits in the receiver's hemisphere: per-cell `z_min`/`z_max`,
//!    the spatial radius of Eq. 8, which for shading diameter d and
//!    Omega_pix = 0.5/d reduces to z_min z_max / (Omega_v (z_max - z_min)),
//!    and the mid depth of Eq. 9 (harmonic mean). A cell is marked for brute
//!    force when Omega_v / z_min > Omega_pix (occluder closer than
//!    4 footprints at the default Omega_v = 2) or when too little weight
//!    reaches it.
//! 3. Each neighbour sample gets a *target* (its hit point, or where it
//!    crosses the mid-depth plane of its cell), an effective direction from
//!    the receiver and a tangent offset x (Figure 6), a weight from
//!    x / spatial radius, and adds its occlusion to the cell of the effective
//!    direction.
//! 4. Marked cells get brute-force rays: the receiver's sparse Sobol
//!    sequence continued to 64 m points, kept where they fall in a marked
//!    cell (exactly m per cell; the sparse rays among them are reused), so
//!    the second pass keeps the sequence's stratification across cells
//!    (`brute_force_cells`).
//!
//! Results are written as occlusion subtracted from the open hemisphere:
//! AO = 1 - sum_c O_c / 64 and c_i = (A_l/pi) Y_i(n) - sum_c (O Y_i)_c / 64,
//! exact for cells that see nothing, which need no work at all.
//!
//! Where this departs from the paper, and why (each measured on Sponza
//! against a 2048-ray reference, see `docs/method-sheared.md`):
//! - sparse rays are traced to the max distance plus the gather reach, and
//!   the distance test is applied per receiver (the paper traces unbounded
//!   rays; tracing only to the max distance biased AO bright);
//! - a cell's z_max enters Eq. 8 only from [`MIN_DEPTH_HITS`] hits, else it
//!   is taken as infinite (a single sparse hit gives z_min = z_max and an
//!   unbounded radius);
//! - a cell with no hit is open only if [`MIN_CELL_SAMPLES`] unoccluded rays
//!   looked through it, and its radius is bounded by the receiver's nearest
//!   hit in any cell (contact shadows must not borrow open rays);
//! - directions below the receiver's geometric tangent plane are occluded
//!   (the surface itself), as in the Monte Carlo baker;
//! - the default gather radius is 4 texels and the minimum weight 4, both
//!   measured better than the paper's 8-16 pixels and ~2 samples here;
//! - each re-aimed sample is weighted by the [`reprojection_jacobian`]
//!   (the ratio of projected solid angles of its target seen from the
//!   receiver and from the neighbour, as in ReSTIR's spatial reuse), so a
//!   cell's samples estimate the receiver's cosine measure. The paper's
//!   weights assume the re-aimed directions cover a cell evenly; parallax
//!   makes them denser toward near occluders (floor beside a wall, gather
//!   radius 8: AO RMSE 0.0060 -> 0.0050 against 2048-ray Monte Carlo,
//!   the Cornell box 0.0078 -> 0.0069; Sponza unchanged);
//! - a cell that saw no occluder re-aims its misses at the farthest mid
//!   depth of the cells around it ([`miss_depths`]), not at infinity, so
//!   the shift of re-aimed misses is the same on both sides of a
//!   silhouette that runs along a cell boundary (floor beside a wall, K 32,
//!   radius 8: AO bias -0.0026 -> 0.0000, RMSE 0.0043 -> 0.0034; the
//!   Cornell box 512 at 16:8: bias -0.0018 -> +0.0001, RMSE 0.0065 ->
//!   0.0056).

mod gather;
mod geometry;
mod order;
mod passes;
mod receiver;
mod second_pass;
mod types;

pub use geometry::*;
pub use order::{locality_order, unpermuted};
pub use passes::{filter_pass, sparse_pass, sparse_t_max};
pub use receiver::{MIN_CELL_SAMPLES, MIN_DEPTH_HITS};
pub use second_pass::cell_estimates;
pub use types::{MAX_FILTER_RAYS, MAX_GATHER_RADIUS, Samples, ShearedOptions, ShearedStats};

use super::{Bake, BakeParams};
use crate::atlas::Receivers;
use crate::error::Result;
use crate::stage::StageTimer;
use crate::trace::Tracer;

/// Both passes: [`sparse_pass`] then [`filter_pass`], on the receivers in
/// [`locality_order`]; results in the receivers' own order. `timer` gets
/// the laps `sparse pass` and `filter pass`. The options must have passed
/// [`ShearedOptions::validate`] (the pipeline validates all settings before
/// any stage).
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    s: &ShearedOptions,
    p: &BakeParams,
    timer: &mut StageTimer,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Bake, ShearedStats)> {
    let order = locality_order(receivers);
    let local = receivers.permuted(&order);
    let samples = sparse_pass(&local, tracer, s, p);
    timer.lap("sparse pass");
    let (bake, stats) = filter_pass(&local, &samples, tracer, s, p, progress)?;
    let result = unpermuted(bake, stats, &order);
    timer.lap("filter pass");
    Ok(result)
}
