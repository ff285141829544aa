//! Filter: Egan, Durand, Ramamoorthi 2011 ("Practical filtering for
//! efficient ray-traced directional occlusion") on lightmap texels.
//!
//! In: [`Receivers`], a [`Tracer`], [`FilterSettings`]. Out: a [`Bake`] (AO
//! and SH per receiver, same definitions as the Monte Carlo baker) and
//! [`FilterStats`].
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
//! against a 2048-ray reference, see the README's benchmark):
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

use crate::error::{Error, Result};
use crate::mc::Bake;
use crate::rasterize::Receivers;
use crate::sample::{
    CELL_COUNT, Frame, cell_of_fast, cosine_hemisphere, in_cell, receiver_seed, sobol_2d,
    square_cell,
};
use crate::sh::{self, SH_COUNT};
use crate::trace::{Tracer, offset_origin};
use glam::{Vec2, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::sync::LazyLock;

/// Filter settings (paper defaults where the paper gives one).
#[derive(Clone, Copy, Debug)]
pub struct FilterSettings {
    /// Sparse rays per receiver (paper: 4-32). 4 measured best at the
    /// default radius: at 1024 texels against 8 it took 0.91x the time on
    /// Sponza (AO RMSE 0.0113 vs 0.0115), 0.98x on the engine (0.0107 vs
    /// 0.0108) and 0.82x on the Cornell box (0.0071 vs 0.0069, where
    /// Monte Carlo pays about 4% more time per 3% less error).
    pub sparse_rays: u32,
    /// Neighbour gather radius in texel footprints (paper: 8-16 pixels).
    pub gather_radius: f32,
    /// Angular bandlimit Omega_v^max (paper: 2).
    pub omega_v_max: f32,
    /// Cells with less filter weight than this are brute-forced (paper: ~2
    /// samples; 4 measured better on Sponza: AO RMSE 0.0147 vs 0.0156).
    pub min_weight: f32,
    /// Brute-force rays per marked cell (paper: 1).
    pub cell_rays: u32,
    /// Max occluder distance, bake units.
    pub max_distance: f32,
    pub seed: u64,
}

impl Default for FilterSettings {
    fn default() -> Self {
        FilterSettings {
            sparse_rays: 4,
            gather_radius: 4.0,
            omega_v_max: 2.0,
            min_weight: 4.0,
            cell_rays: 2,
            max_distance: 0.1,
            seed: 0,
        }
    }
}

/// Counters and per-receiver diagnostics of a filtered bake.
#[derive(Clone, Debug, Default)]
pub struct FilterStats {
    pub sparse_rays: u64,
    pub brute_rays: u64,
    /// Cells whose occlusion came from the filter, from brute force, or that
    /// no neighbour ray saw an occluder in (open).
    pub cells_filtered: u64,
    pub cells_brute: u64,
    /// Of `cells_brute`: cells sent to brute force by the paper's bandlimit
    /// test (an occluder closer than 2 Omega_v footprints).
    pub cells_contact: u64,
    /// Of `cells_brute`: cells in which no neighbour ray hit an occluder,
    /// but too few looked through them to trust them open (fewer than
    /// [`MIN_CELL_SAMPLES`] misses, or too little filter weight). The rest
    /// of `cells_brute` had hits but too little weight.
    pub cells_no_hit: u64,
    pub cells_open: u64,
    /// Receivers whose whole neighbourhood saw no occluder.
    pub receivers_open: u64,
    /// Per receiver: fraction of cells brute-forced, nearest occluder (bake
    /// units, INFINITY if none), neighbours that lent rays, AO of the
    /// receiver's own sparse rays alone.
    pub brute_fraction: Vec<f32>,
    pub z_min: Vec<f32>,
    pub neighbours: Vec<u32>,
    pub sparse_ao: Vec<f32>,
}

impl FilterStats {
    /// A count of cells as a fraction of all hemisphere cells (64 per
    /// receiver).
    pub fn cell_share(&self, cells: u64) -> f64 {
        cells as f64 / (self.brute_fraction.len() * CELL_COUNT).max(1) as f64
    }
}

/// The sparse pass: K samples per receiver, receiver-major.
#[derive(Clone, Debug, Default)]
pub struct Samples {
    pub per_receiver: usize,
    pub dir: Vec<Vec3>,
    /// Cell of each direction in its own receiver's frame (exact, from the
    /// sample's point in the square): reused by neighbours with the same
    /// normal, hence the same frame, which is most of a flat surface.
    pub cell: Vec<u8>,
    /// Hit distance; `INFINITY` for a miss within [`sparse_t_max`];
    /// negative for a direction below the geometric horizon (it enters the
    /// receiver's own surface and says nothing about occluders).
    pub t: Vec<f32>,
    /// Unit geometric normal of the hit (either side; zero for a miss):
    /// for the solid-angle Jacobian of the reprojection.
    pub hit_normal: Vec<Vec3>,
}

/// Fewest hits in a cell for its z_max to be trusted in Eq. 8.
pub const MIN_DEPTH_HITS: u16 = 8;
/// Shading and geometric normals this close (cos 2.6 degrees) leave a
/// negligible part of the shading hemisphere below the surface.
const OPEN_NORMAL_AGREEMENT: f32 = 0.999;
/// Normal agreement of the leak rule: cos 25 degrees.
const NORMAL_AGREEMENT: f32 = 0.906;
/// Largest tangent-plane distance of a neighbour, as a fraction of its
/// distance (plus one footprint): keeps neighbours on the same sheet.
const TANGENT_SLOPE: f32 = 0.25;
/// Geometric normals this close (cos 0.5 degrees) are parallel planes.
const PARALLEL_AGREEMENT: f32 = 0.99996;
/// Largest offset along the normal, in footprints, of a neighbour on a
/// parallel plane: anything farther is another sheet.
const SHEET_OFFSET: f32 = 0.01;

/// The leak rule: whether a neighbour at `rel` from the receiver (shading
/// and geometric normals `n`, `geo`; the neighbour's `n_j`, `geo_j`) may
/// lend its rays. Both normals within 25 degrees, and the neighbour near
/// the receiver's geometric tangent plane: within a slope of 0.25 plus a
/// footprint on curved surfaces, and on the plane itself (0.01 footprint,
/// plus the 0.5-degree tilt) when the planes are parallel, so a second
/// sheet in front of or behind a flat surface (a light quad under a
/// ceiling, a decal, a coplanar duplicate pushed out) never lends rays
/// that its own surface does not see.
#[inline]
pub fn lends_rays(rel: Vec3, n: Vec3, geo: Vec3, n_j: Vec3, geo_j: Vec3, footprint: f32) -> bool {
    let agree = geo_j.dot(geo);
    if n_j.dot(n) < NORMAL_AGREEMENT || agree < NORMAL_AGREEMENT {
        return false;
    }
    let offset = rel.dot(geo).abs();
    let dist = rel.length();
    if agree >= PARALLEL_AGREEMENT {
        offset <= SHEET_OFFSET * footprint + 0.01 * dist + 1e-6
    } else {
        offset <= TANGENT_SLOPE * dist + footprint
    }
}

/// Fewest unoccluded samples a cell without hits must receive to be trusted
/// open: a cell occluded with probability p shows no hit among N samples with
/// probability (1-p)^N, a bright bias of at most ~1/(e (N+1)) per cell.
pub const MIN_CELL_SAMPLES: u16 = 12;

/// Cell centre directions in the local frame.
static CELL_CENTRES: LazyLock<[Vec3; CELL_COUNT]> =
    LazyLock::new(|| std::array::from_fn(|c| cosine_hemisphere(in_cell(c, Vec2::splat(0.5)))));

/// Spatial radius of Eq. 8 (times the shading diameter): the filter's reach
/// for a cell whose occluders lie in [z_min, z_max]. Infinite when
/// z_min = z_max (the shear is exact) or no occluder was seen.
#[inline]
pub fn spatial_radius(z_min: f32, z_max: f32, omega_v_max: f32) -> f32 {
    let inv_diff = 1.0 / z_min - 1.0 / z_max;
    if inv_diff > 0.0 && inv_diff.is_finite() {
        1.0 / (omega_v_max * inv_diff)
    } else if z_min > 0.0 {
        f32::INFINITY
    } else {
        0.0
    }
}

/// Mid depth of Eq. 9: the harmonic mean of z_min and z_max.
#[inline]
pub fn mid_depth(z_min: f32, z_max: f32) -> f32 {
    let s = 1.0 / z_min + 1.0 / z_max;
    if s > 0.0 { 2.0 / s } else { f32::INFINITY }
}

/// Depth at which each cell's unoccluded sample rays are re-aimed: the
/// cell's mid depth (Eq. 9), and for a cell without hits (mid depth
/// infinite) the farthest mid depth among the cells around it in the 8x8
/// grid, infinite only when none of them saw an occluder.
///
/// Re-aiming shifts a miss's effective direction by about the neighbour's
/// offset over the aim depth. Where an occluder's silhouette runs along a
/// cell boundary, an open cell re-aimed at infinity shifts nothing across
/// the boundary while the occluded cell's misses shift out of it, so the
/// silhouette cell loses open rays and comes out too dark (floor beside a
/// wall: -0.006). With one depth on both sides the shifts cancel. The
/// farthest neighbour is the one that shifts least.
pub fn miss_depths(mid: &[f32; CELL_COUNT], aim: &mut [f32; CELL_COUNT]) {
    let side = crate::sample::CELLS_PER_SIDE as i32;
    for c in 0..CELL_COUNT {
        aim[c] = mid[c];
        if mid[c].is_finite() {
            continue;
        }
        let (cx, cy) = (c as i32 % side, c as i32 / side);
        let mut farthest = 0.0f32;
        for y in (cy - 1).max(0)..=(cy + 1).min(side - 1) {
            for x in (cx - 1).max(0)..=(cx + 1).min(side - 1) {
                let m = mid[(y * side + x) as usize];
                if m.is_finite() {
                    farthest = farthest.max(m);
                }
            }
        }
        if farthest > 0.0 {
            aim[c] = farthest;
        }
    }
}

/// Whether the paper's bandlimit test sends a cell to brute force:
/// Omega_v^max / z_min > Omega_pix with Omega_pix = 0.5 / shading diameter.
#[inline]
pub fn needs_brute_force(z_min: f32, omega_v_max: f32, footprint: f32) -> bool {
    // Written so that a NaN z_min also sends the cell to brute force.
    z_min.is_nan() || z_min < omega_v_max * footprint * 2.0
}

/// Filter weight for a tangent offset x over a spatial radius (biweight,
/// 1 at x = 0, 0 from x = radius on).
#[inline]
pub fn weight(x: f32, radius: f32) -> f32 {
    let q = x / radius;
    if q < 1.0 {
        (1.0 - q * q) * (1.0 - q * q)
    } else {
        0.0
    }
}

/// [`weight`] from the squared offset (no square root in the hot loop).
#[inline]
pub fn weight_sq(x2: f32, radius: f32) -> f32 {
    let q2 = x2.max(0.0) / (radius * radius);
    if q2 < 1.0 {
        (1.0 - q2) * (1.0 - q2)
    } else {
        0.0
    }
}

/// Effective direction and tangent offset of a sample ray (origin `o`,
/// direction `d`) re-aimed from `receiver` at `target` (Figure 6). `None`
/// if the target is the receiver or the ray runs parallel to the plane.
#[inline]
pub fn reproject(receiver: Vec3, o: Vec3, d: Vec3, target: Vec3) -> Option<(Vec3, f32, f32)> {
    let v = target - receiver;
    let dist = v.length();
    if dist.is_nan() || dist <= 0.0 {
        return None;
    }
    let e = v / dist;
    let de = d.dot(e);
    if de.abs() < 1e-6 {
        return None;
    }
    let rel = o - receiver;
    let u = -rel.dot(e) / de;
    Some((e, (rel + d * u).length(), dist))
}

/// Where a neighbour's hit lies relative to the receiver: the neighbour at
/// `rel` from the receiver, its ray `d` hitting at distance `t`. Summed
/// from the offset, not from absolute positions: `pj + d t - p` rounds a
/// hit closer than an ulp of the coordinates (a surface through the
/// receiver, ~1e-8 of the scene) to exactly the receiver, which then
/// looked open (two-cylinder engine at 1024: a texel of AO 0.5 came out 1).
#[inline]
pub fn hit_offset(rel: Vec3, d: Vec3, t: f32) -> Vec3 {
    rel + d * t
}

/// Squared tangent offset x^2 of a sample ray (origin at `rel` from the
/// receiver, direction `d`) re-aimed along the effective direction `e`:
/// where the ray crosses the plane through the receiver perpendicular to
/// `e` ([`reproject`] with the target already known). `None` if the ray
/// runs parallel to that plane.
#[inline]
pub fn tangent_offset_sq(rel: Vec3, d: Vec3, e: Vec3) -> Option<f32> {
    let de = d.dot(e);
    if de.abs() < 1e-6 {
        return None;
    }
    let u = -rel.dot(e) / de;
    Some((rel + d * u).length_squared())
}

/// Largest reprojection Jacobian a sample may carry: grazing targets
/// (a hit seen edge-on from the neighbour) would otherwise dominate a cell.
pub const MAX_JACOBIAN: f32 = 4.0;

/// Weight correcting a re-aimed sample for the change of density between
/// the neighbour's cosine-distributed directions and the receiver's: the
/// ratio of projected solid angles of the target patch seen from the
/// receiver and from the neighbour,
/// (cos theta_r |cos alpha_r| / dist_r^2) / (cos theta_n |cos alpha_n| / dist_n^2),
/// with theta against each one's normal and alpha against the target's
/// surface normal (the same Jacobian as spatial reuse in ReSTIR). 1 for a
/// target at infinity seen from the same plane. Clamped to
/// [0, MAX_JACOBIAN]; 0 for targets behind either point.
#[inline]
pub fn reprojection_jacobian(
    cos_receiver: f32,
    cos_neighbour: f32,
    cos_target_receiver: f32,
    cos_target_neighbour: f32,
    dist_receiver: f32,
    dist_neighbour: f32,
) -> f32 {
    let num = cos_receiver * cos_target_receiver.abs() * dist_neighbour * dist_neighbour;
    let den = cos_neighbour * cos_target_neighbour.abs() * dist_receiver * dist_receiver;
    // Written so that NaN inputs also give 0.
    if cos_receiver <= 0.0 || den.is_nan() || den <= 0.0 {
        return 0.0;
    }
    let j = num / den;
    if j.is_nan() { 0.0 } else { j.min(MAX_JACOBIAN) }
}

/// How far sparse rays are traced: the max distance plus the widest gather
/// reach, so an occluder within the max distance of a *receiver* is found
/// by every neighbour whose rays it lends (the paper traces unbounded rays
/// and applies the distance test per receiver, Section 5).
pub fn sparse_t_max(receivers: &Receivers, s: &FilterSettings) -> f32 {
    let widest = receivers.footprint.iter().copied().fold(0.0f32, f32::max);
    s.max_distance + (s.gather_radius * widest).min(s.max_distance)
}

/// Casts the sparse rays.
pub fn sparse_pass(receivers: &Receivers, tracer: &Tracer, s: &FilterSettings) -> Samples {
    let t_max = sparse_t_max(receivers, s);
    let k = s.sparse_rays as usize;
    let n = receivers.len();
    let mut dir = vec![Vec3::ZERO; n * k];
    let mut t = vec![0.0f32; n * k];
    let mut cell = vec![0u8; n * k];
    let mut hit_normal = vec![Vec3::ZERO; n * k];
    const CHUNK: usize = 64;
    dir.par_chunks_mut(k * CHUNK)
        .zip(t.par_chunks_mut(k * CHUNK))
        .zip(cell.par_chunks_mut(k * CHUNK))
        .zip(hit_normal.par_chunks_mut(k * CHUNK))
        .enumerate()
        .for_each(|(c, (((dir, t), cell), hit_normal))| {
            for (local, (((dirs, ts), cells), normals)) in dir
                .chunks_mut(k)
                .zip(t.chunks_mut(k))
                .zip(cell.chunks_mut(k))
                .zip(hit_normal.chunks_mut(k))
                .enumerate()
            {
                let r = c * CHUNK + local;
                let frame = Frame::from_normal(receivers.normal[r]);
                let geo = receivers.geo_normal[r];
                let origin = offset_origin(receivers.position[r], geo, receivers.footprint[r]);
                let seed = receiver_seed(s.seed, receivers.texel[r] as u64, 1);
                for i in 0..k {
                    let u = sobol_2d(i as u32, seed);
                    let d = frame.to_world(cosine_hemisphere(u)).normalize();
                    cells[i] = square_cell(u) as u8;
                    dirs[i] = d;
                    ts[i] = if d.dot(geo) <= 0.0 {
                        -1.0
                    } else if let Some((t, ng)) = tracer.closest_hit_normal(origin, d, t_max) {
                        normals[i] = ng;
                        t
                    } else {
                        f32::INFINITY
                    };
                }
            }
        });
    Samples {
        per_receiver: k,
        dir,
        t,
        cell,
        hit_normal,
    }
}

/// Per-receiver scratch, reused across receivers of one worker.
struct Scratch {
    neighbours: Vec<u32>,
    /// Neighbours' hits in this receiver's hemisphere, in neighbour order,
    /// reprojected once (line 1-14 pass) for the filter pass; `hit_start[n]`
    /// is where neighbour n's hits begin.
    hit_cache: Vec<CachedHit>,
    hit_start: Vec<u32>,
    z_min: [f32; CELL_COUNT],
    z_max: [f32; CELL_COUNT],
    count: [u16; CELL_COUNT],
    hits: [u16; CELL_COUNT],
    radius: [f32; CELL_COUNT],
    mid: [f32; CELL_COUNT],
    /// Depth at which misses of each cell are re-aimed ([`miss_depths`]).
    aim: [f32; CELL_COUNT],
    brute: [bool; CELL_COUNT],
    w: [f32; CELL_COUNT],
    occ: [f32; CELL_COUNT],
    occ_sh: [[f32; SH_COUNT]; CELL_COUNT],
}

impl Scratch {
    fn new() -> Scratch {
        Scratch {
            neighbours: Vec::with_capacity(1024),
            hit_cache: Vec::with_capacity(4096),
            hit_start: Vec::with_capacity(1024),
            z_min: [0.0; CELL_COUNT],
            z_max: [0.0; CELL_COUNT],
            count: [0; CELL_COUNT],
            hits: [0; CELL_COUNT],
            radius: [0.0; CELL_COUNT],
            mid: [0.0; CELL_COUNT],
            aim: [0.0; CELL_COUNT],
            brute: [false; CELL_COUNT],
            w: [0.0; CELL_COUNT],
            occ: [0.0; CELL_COUNT],
            occ_sh: [[0.0; SH_COUNT]; CELL_COUNT],
        }
    }
}

/// A neighbour's hit seen from the receiver: its sample, the effective
/// direction toward the hit point, that direction's cell and the distance.
#[derive(Clone, Copy)]
struct CachedHit {
    sample: u32,
    cell: u8,
    e: Vec3,
    dist: f32,
}

/// What one receiver's filtering produced.
struct ReceiverResult {
    ao: f32,
    sh: [f32; SH_COUNT],
    filtered: u32,
    brute: u32,
    contact: u32,
    no_hit: u32,
    open: u32,
    brute_rays: u32,
    z_min: f32,
    neighbours: u32,
}

/// The k-d tree over receiver positions that the neighbour gather queries.
fn receiver_tree(receivers: &Receivers) -> Result<ImmutableKdTree<f32, 3>> {
    let points: Vec<[f32; 3]> = receivers.position.iter().map(|p| p.to_array()).collect();
    ImmutableKdTree::<f32, 3>::new_from_slice(&points)
        .map_err(|e| Error::Limit(format!("cannot build the receivers' k-d tree: {e}")))
}

/// Filters every receiver from the sparse samples (Algorithm 1), casting
/// brute-force rays for the cells it marks.
pub fn filter_pass(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &FilterSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Bake, FilterStats)> {
    let tree = receiver_tree(receivers)?;
    let n = receivers.len();
    let results: Vec<ReceiverResult> = (0..n)
        .into_par_iter()
        .with_min_len(64)
        .map_init(Scratch::new, |scratch, r| {
            let out = filter_receiver(receivers, samples, &tree, tracer, s, r, scratch);
            if r % 1024 == 1023 {
                progress(1024);
            }
            out
        })
        .collect();
    let k = samples.per_receiver;
    let mut stats = FilterStats {
        sparse_rays: samples.t.iter().filter(|&&t| t >= 0.0).count() as u64,
        ..Default::default()
    };
    let mut bake = Bake {
        ao: Vec::with_capacity(n),
        sh: Vec::with_capacity(n),
        rays: 0,
    };
    for (r, res) in results.iter().enumerate() {
        bake.ao.push(res.ao);
        bake.sh.push(res.sh);
        stats.brute_rays += res.brute_rays as u64;
        stats.cells_filtered += res.filtered as u64;
        stats.cells_brute += res.brute as u64;
        stats.cells_contact += res.contact as u64;
        stats.cells_no_hit += res.no_hit as u64;
        stats.cells_open += res.open as u64;
        stats.receivers_open += (res.open as usize == CELL_COUNT) as u64;
        stats
            .brute_fraction
            .push(res.brute as f32 / CELL_COUNT as f32);
        stats.z_min.push(res.z_min);
        stats.neighbours.push(res.neighbours);
        let own = &samples.t[r * k..(r + 1) * k];
        // Sparse rays reach past the max distance: hits beyond it are visible.
        let visible = own.iter().filter(|&&t| t > s.max_distance).count();
        stats.sparse_ao.push(visible as f32 / k as f32);
    }
    bake.rays = stats.sparse_rays + stats.brute_rays;
    Ok((bake, stats))
}

/// An order of the receivers in which texels near each other in the atlas
/// are near each other in memory (Morton order of their texel
/// coordinates), so a receiver's world-space neighbours, which are mostly
/// its atlas neighbours, and their samples share cache lines.
pub fn locality_order(receivers: &Receivers) -> Vec<u32> {
    fn spread(v: u32) -> u64 {
        let mut x = v as u64 & 0xffff_ffff;
        x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
        x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
        x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        x = (x | (x << 2)) & 0x3333_3333_3333_3333;
        (x | (x << 1)) & 0x5555_5555_5555_5555
    }
    let w = receivers.width.max(1);
    let mut order: Vec<u32> = (0..receivers.len() as u32).collect();
    order.sort_by_key(|&i| {
        let t = receivers.texel[i as usize];
        spread(t % w) | (spread(t / w) << 1)
    });
    order
}

/// The receivers in `order` (`order[new] = old`).
pub fn permuted(receivers: &Receivers, order: &[u32]) -> Receivers {
    let pick = |i: &u32| *i as usize;
    Receivers {
        texel: order.iter().map(|i| receivers.texel[pick(i)]).collect(),
        position: order.iter().map(|i| receivers.position[pick(i)]).collect(),
        normal: order.iter().map(|i| receivers.normal[pick(i)]).collect(),
        geo_normal: order
            .iter()
            .map(|i| receivers.geo_normal[pick(i)])
            .collect(),
        footprint: order.iter().map(|i| receivers.footprint[pick(i)]).collect(),
        ..receivers.clone_header()
    }
}

/// A bake and its per-receiver statistics, from `order` back to the
/// receivers' own order.
pub fn unpermuted(bake: Bake, stats: FilterStats, order: &[u32]) -> (Bake, FilterStats) {
    fn back<T: Copy + Default>(v: &[T], order: &[u32]) -> Vec<T> {
        let mut out = vec![T::default(); v.len()];
        for (new, &old) in order.iter().enumerate() {
            out[old as usize] = v[new];
        }
        out
    }
    (
        Bake {
            ao: back(&bake.ao, order),
            sh: back(&bake.sh, order),
            rays: bake.rays,
        },
        FilterStats {
            brute_fraction: back(&stats.brute_fraction, order),
            z_min: back(&stats.z_min, order),
            neighbours: back(&stats.neighbours, order),
            sparse_ao: back(&stats.sparse_ao, order),
            ..stats
        },
    )
}

/// Both passes: [`sparse_pass`] then [`filter_pass`], on the receivers in
/// [`locality_order`]; results in the receivers' own order.
pub fn bake(
    receivers: &Receivers,
    tracer: &Tracer,
    s: &FilterSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(Bake, FilterStats)> {
    let order = locality_order(receivers);
    let local = permuted(receivers, &order);
    let samples = sparse_pass(&local, tracer, s);
    let (bake, stats) = filter_pass(&local, &samples, tracer, s, progress)?;
    Ok(unpermuted(bake, stats, &order))
}

/// Debugging aid: per cell of receiver `r`, the filter weight, occluded
/// weight and brute-force mark, before the second pass.
#[doc(hidden)]
pub fn cell_estimates(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &FilterSettings,
    r: usize,
) -> Vec<(f32, f32, bool)> {
    let tree = receiver_tree(receivers).expect("k-d tree");
    let mut sc = Scratch::new();
    filter_receiver(receivers, samples, &tree, tracer, s, r, &mut sc);
    (0..CELL_COUNT)
        .map(|c| (sc.w[c], sc.occ[c], sc.brute[c]))
        .collect()
}

/// The cell of sample `i`'s own direction in the receiver's `frame`: cached
/// when the sample's receiver shares the frame, else computed; `None` below
/// the receiver's hemisphere.
#[inline]
fn sample_cell(samples: &Samples, i: usize, same_frame: bool, frame: &Frame) -> Option<usize> {
    if same_frame {
        return Some(samples.cell[i] as usize);
    }
    let ld = frame.to_local(samples.dir[i]);
    (ld.z > 0.0).then(|| cell_of_fast(ld))
}

/// The receiver Algorithm 1 is filtering: its position, normals, texel
/// footprint and shading frame.
#[derive(Clone, Copy)]
struct Receiver {
    p: Vec3,
    n: Vec3,
    geo: Vec3,
    footprint: f32,
    frame: Frame,
}

impl Receiver {
    fn new(receivers: &Receivers, r: usize) -> Receiver {
        Receiver {
            p: receivers.position[r],
            n: receivers.normal[r],
            geo: receivers.geo_normal[r],
            footprint: receivers.footprint[r],
            frame: Frame::from_normal(receivers.normal[r]),
        }
    }
}

/// Algorithm 1 for receiver `r`, then the second pass for the cells it
/// cannot serve; combines both into AO and SH.
fn filter_receiver(
    receivers: &Receivers,
    samples: &Samples,
    tree: &ImmutableKdTree<f32, 3>,
    tracer: &Tracer,
    s: &FilterSettings,
    r: usize,
    sc: &mut Scratch,
) -> ReceiverResult {
    let rc = Receiver::new(receivers, r);
    let Receiver {
        n,
        geo,
        footprint,
        frame,
        ..
    } = rc;
    gather_neighbours(receivers, tree, s, &rc, sc);
    let any_occluder = depth_bounds(receivers, samples, s, &rc, sc);
    let neighbours = sc.neighbours.len() as u32;
    // Early out: the neighbourhood's rays saw no occluder (and enough of
    // them looked: at least one per cell on average).
    // The shading hemisphere must also lie above the geometric plane (within
    // 2.6 degrees), or part of it is occluded by the surface itself.
    let looked: u32 = sc.count.iter().map(|&c| c as u32).sum();
    if !any_occluder && looked >= CELL_COUNT as u32 && n.dot(geo) > OPEN_NORMAL_AGREEMENT {
        return ReceiverResult {
            ao: 1.0,
            sh: sh::open_hemisphere(n),
            filtered: 0,
            brute: 0,
            contact: 0,
            no_hit: 0,
            open: CELL_COUNT as u32,
            brute_rays: 0,
            z_min: f32::INFINITY,
            neighbours,
        };
    }

    let (nearest, reach2) = mark_cells(s, &rc, sc);
    filter_samples(receivers, samples, s, &rc, reach2, sc);

    // Normalize, brute-force what the filter cannot serve, combine.
    let mut occ_ao = 0.0f32;
    let mut occ_sh = [0.0f32; SH_COUNT];
    let (mut filtered, mut brute, mut open) = (0u32, 0u32, 0u32);
    let (mut contact, mut no_hit) = (0u32, 0u32);
    let mut marked = 0u64;
    let inv_cells = 1.0 / CELL_COUNT as f32;
    for c in 0..CELL_COUNT {
        if !sc.brute[c] && sc.w[c] >= s.min_weight {
            if sc.occ[c] == 0.0 {
                open += 1;
                continue;
            }
            filtered += 1;
            let inv = inv_cells / sc.w[c];
            occ_ao += sc.occ[c] * inv;
            for (acc, v) in occ_sh.iter_mut().zip(sc.occ_sh[c]) {
                *acc += v * inv;
            }
            continue;
        }
        brute += 1;
        marked |= 1 << c;
        contact += (sc.z_min[c].is_finite()
            && needs_brute_force(sc.z_min[c], s.omega_v_max, footprint)) as u32;
        no_hit += sc.z_min[c].is_infinite() as u32;
        // The second pass replaces whatever weight the filter gave it
        // (adding the filter's few samples to it measured worse on Sponza:
        // AO RMSE 0.0128 -> 0.0132 at 8:4).
        sc.w[c] = 0.0;
        sc.occ[c] = 0.0;
        sc.occ_sh[c] = [0.0; SH_COUNT];
    }
    let brute_rays = if marked != 0 {
        let traced = brute_force_cells(receivers, samples, tracer, s, r, &frame, marked, sc);
        for c in 0..CELL_COUNT {
            if marked & (1 << c) != 0 && sc.occ[c] > 0.0 {
                let inv = inv_cells / sc.w[c];
                occ_ao += sc.occ[c] * inv;
                for (acc, v) in occ_sh.iter_mut().zip(sc.occ_sh[c]) {
                    *acc += v * inv;
                }
            }
        }
        traced
    } else {
        0
    };
    let open_sh = sh::open_hemisphere(n);
    ReceiverResult {
        ao: (1.0 - occ_ao).clamp(0.0, 1.0),
        sh: std::array::from_fn(|i| open_sh[i] - occ_sh[i]),
        filtered,
        brute,
        contact,
        no_hit,
        open,
        brute_rays,
        z_min: nearest,
        neighbours,
    }
}

/// The neighbours that may lend rays (the leak rule, [`lends_rays`]) within
/// the gather radius, into `sc.neighbours`.
#[inline]
fn gather_neighbours(
    receivers: &Receivers,
    tree: &ImmutableKdTree<f32, 3>,
    s: &FilterSettings,
    rc: &Receiver,
    sc: &mut Scratch,
) {
    let Receiver {
        p,
        n,
        geo,
        footprint,
        ..
    } = *rc;
    let reach = s.gather_radius * footprint;
    sc.neighbours.clear();
    tree.query(&p.to_array())
        .within::<SquaredEuclidean<f32>>(reach * reach)
        .unsorted()
        .visit(|it| {
            let j = it.item as usize;
            let rel = receivers.position[j] - p;
            if lends_rays(
                rel,
                n,
                geo,
                receivers.normal[j],
                receivers.geo_normal[j],
                footprint,
            ) {
                sc.neighbours.push(j as u32);
            }
        });
}

/// Algorithm 1, lines 1-10: per-cell z_min, z_max and hit counts from the
/// neighbours' hits in the receiver's hemisphere, the open evidence of
/// misses per cell, and each hit's effective direction cached for the
/// filter. Returns whether any occluder within the max distance was seen.
#[inline]
fn depth_bounds(
    receivers: &Receivers,
    samples: &Samples,
    s: &FilterSettings,
    rc: &Receiver,
    sc: &mut Scratch,
) -> bool {
    let Receiver {
        p, n, geo, frame, ..
    } = *rc;
    let k = samples.per_receiver;
    let d_max = s.max_distance;
    sc.z_min = [f32::INFINITY; CELL_COUNT];
    sc.z_max = [0.0; CELL_COUNT];
    sc.count = [0; CELL_COUNT];
    sc.hits = [0; CELL_COUNT];
    sc.hit_cache.clear();
    sc.hit_start.clear();
    let mut any_occluder = false;
    for &j in &sc.neighbours {
        sc.hit_start.push(sc.hit_cache.len() as u32);
        let j = j as usize;
        let pj = receivers.position[j];
        let same_frame = receivers.normal[j] == n;
        for i in j * k..(j + 1) * k {
            let t = samples.t[i];
            if t < 0.0 {
                continue;
            }
            let d = samples.dir[i];
            if t.is_infinite() {
                // Evidence that the direction is open: counted in its own
                // cell, if it is above this receiver's surface.
                if d.dot(geo) <= 0.0 {
                    continue;
                }
                let Some(c) = sample_cell(samples, i, same_frame, &frame) else {
                    continue;
                };
                sc.count[c] = sc.count[c].saturating_add(1);
            } else {
                // The hit point is the target of Figure 6: its direction
                // from the receiver is the effective direction.
                let v = hit_offset(pj - p, d, t);
                let z = v.length();
                if z == 0.0 {
                    // The receiver's own ray hit at distance 0 (a surface
                    // through its origin): contact in the ray's cell.
                    if let Some(c) = sample_cell(samples, i, same_frame, &frame) {
                        sc.z_min[c] = 0.0;
                        sc.hits[c] = sc.hits[c].saturating_add(1);
                        any_occluder = true;
                    }
                } else if v.dot(n) > 0.0 && z.is_finite() {
                    let e = v / z;
                    let c = cell_of_fast(frame.to_local(e));
                    sc.hit_cache.push(CachedHit {
                        sample: i as u32,
                        cell: c as u8,
                        e,
                        dist: z,
                    });
                    if z <= d_max {
                        sc.z_min[c] = sc.z_min[c].min(z);
                        sc.hits[c] = sc.hits[c].saturating_add(1);
                        sc.z_max[c] = sc.z_max[c].max(z);
                        any_occluder = true;
                    }
                }
            }
        }
    }
    sc.hit_start.push(sc.hit_cache.len() as u32);
    any_occluder
}

/// Algorithm 1, lines 11-14: per cell the spatial radius (Eq. 8), the mid
/// depth (Eq. 9) and the brute-force mark, and where misses are re-aimed.
/// Returns the receiver's nearest occluder and the squared gather reach the
/// filtered cells can use.
#[inline]
fn mark_cells(s: &FilterSettings, rc: &Receiver, sc: &mut Scratch) -> (f32, f32) {
    let footprint = rc.footprint;
    let reach = s.gather_radius * footprint;
    let nearest = sc.z_min.iter().copied().fold(f32::INFINITY, f32::min);
    let mut widest = 0.0f32;
    for c in 0..CELL_COUNT {
        let (lo, hi) = (sc.z_min[c], sc.z_max[c]);
        if lo.is_infinite() {
            // No occluder seen in this cell: it is open if enough unoccluded
            // rays looked through it. Its nearest occluder may still be as
            // close as the receiver's nearest in any cell, which bounds how
            // far those rays may come from (so a contact shadow's edge does
            // not borrow open rays from outside it).
            sc.brute[c] = sc.count[c] < MIN_CELL_SAMPLES;
            sc.radius[c] = spatial_radius(nearest, f32::INFINITY, s.omega_v_max);
            sc.mid[c] = f32::INFINITY;
            if !sc.brute[c] {
                widest = widest.max(sc.radius[c]);
            }
        } else {
            sc.brute[c] = needs_brute_force(lo, s.omega_v_max, footprint);
            // z_max from fewer than MIN_DEPTH_HITS hits underestimates the
            // depth range (one hit gives z_min = z_max: an unbounded radius),
            // so such cells use z_max = infinity: radius z_min / Omega_v.
            let hi = if sc.hits[c] < MIN_DEPTH_HITS {
                f32::INFINITY
            } else {
                hi
            };
            sc.radius[c] = spatial_radius(lo, hi, s.omega_v_max);
            sc.mid[c] = mid_depth(lo, hi);
            if !sc.brute[c] {
                widest = widest.max(sc.radius[c]);
            }
        }
    }
    miss_depths(&sc.mid, &mut sc.aim);
    // The gather radius shrinks to what the filtered cells can use.
    let reach2 = widest.min(reach).powi(2);

    (nearest, reach2)
}

/// Algorithm 1, lines 15-33: each neighbour sample within `reach2` adds its
/// weight, and its occlusion, to the cell of its effective direction.
#[inline]
fn filter_samples(
    receivers: &Receivers,
    samples: &Samples,
    s: &FilterSettings,
    rc: &Receiver,
    reach2: f32,
    sc: &mut Scratch,
) {
    let Receiver {
        p, n, geo, frame, ..
    } = *rc;
    let k = samples.per_receiver;
    let d_max = s.max_distance;
    sc.w = [0.0; CELL_COUNT];
    sc.occ = [0.0; CELL_COUNT];
    sc.occ_sh = [[0.0; SH_COUNT]; CELL_COUNT];
    for (ni, &j) in sc.neighbours.iter().enumerate() {
        let j = j as usize;
        let pj = receivers.position[j];
        let rel = pj - p;
        let rel2 = rel.length_squared();
        if rel2 > reach2 {
            continue;
        }
        let nj = receivers.normal[j];
        // Hits: target, effective direction and cell come from the depth
        // pass; only the tangent offset x is left (Figure 6).
        let hits = sc.hit_start[ni] as usize..sc.hit_start[ni + 1] as usize;
        for h in &sc.hit_cache[hits] {
            let c = h.cell as usize;
            if sc.brute[c] {
                continue;
            }
            let si = h.sample as usize;
            let d = samples.dir[si];
            let Some(x2) = tangent_offset_sq(rel, d, h.e) else {
                continue;
            };
            let w = weight_sq(x2, sc.radius[c]);
            if w == 0.0 {
                continue;
            }
            let w = w * reprojection_jacobian(
                h.e.dot(n),
                d.dot(nj),
                h.e.dot(samples.hit_normal[si]),
                d.dot(samples.hit_normal[si]),
                h.dist,
                samples.t[si],
            );
            // Occluded: a hit within the max distance of this receiver, or
            // a direction into the receiver's own surface.
            sc.w[c] += w;
            if h.dist <= d_max || h.e.dot(geo) <= 0.0 {
                sc.occ[c] += w;
                sh::accumulate(&mut sc.occ_sh[c], w, h.e);
            }
        }
        // Misses: re-aimed through the mid-depth plane of their cell.
        let same_frame = nj == n;
        for i in j * k..(j + 1) * k {
            let t = samples.t[i];
            if t < 0.0 || t.is_finite() {
                continue;
            }
            let d = samples.dir[i];
            let Some(c0) = sample_cell(samples, i, same_frame, &frame) else {
                continue;
            };
            let mid = sc.aim[c0];
            if mid.is_infinite() {
                // Target at infinity: the effective direction is the
                // ray's own; it only adds weight (V = 1) to its cell.
                if sc.brute[c0] {
                    continue;
                }
                let along = rel.dot(d);
                let w = weight_sq(rel2 - along * along, sc.radius[c0]);
                // Same direction: only the two frames' cosines differ.
                let w = w * reprojection_jacobian(d.dot(n), d.dot(nj), 1.0, 1.0, 1.0, 1.0);
                sc.w[c0] += w;
                if w > 0.0 && d.dot(geo) <= 0.0 {
                    // Into the receiver's own surface: occluded.
                    sc.occ[c0] += w;
                    sh::accumulate(&mut sc.occ_sh[c0], w, d);
                }
                continue;
            }
            let centre = frame.to_world(CELL_CENTRES[c0]);
            let dc = d.dot(centre);
            if dc <= 1e-6 {
                continue;
            }
            let along = (mid - rel.dot(centre)) / dc;
            if along <= 0.0 {
                continue;
            }
            let Some((e, x, dist)) = reproject(p, pj, d, pj + d * along) else {
                continue;
            };
            let le = frame.to_local(e);
            if le.z <= 0.0 {
                continue;
            }
            let c = cell_of_fast(le);
            if sc.brute[c] {
                continue;
            }
            let w = weight(x, sc.radius[c]);
            if w == 0.0 {
                continue;
            }
            // The target lies on the mid-depth plane, normal `centre`.
            let w = w * reprojection_jacobian(e.dot(n), d.dot(nj), e.dot(centre), dc, dist, along);
            sc.w[c] += w;
            if e.dot(geo) <= 0.0 {
                sc.occ[c] += w;
                sh::accumulate(&mut sc.occ_sh[c], w, e);
            }
        }
    }
}

/// The second pass for receiver `r`: Monte Carlo over the cells set in
/// `marked`, whose sums in `sc` (weight, occluded weight, occluded SH) must
/// be zero on entry. Returns the rays traced.
///
/// The rays are the receiver's own sparse sequence continued: points
/// `0..64 m` (m = `cell_rays`) of the same Owen-scrambled Sobol sequence,
/// kept where they fall in a marked cell. Each aligned block of 64 points
/// of a (0,2)-sequence is a (0,6,2)-net, which puts exactly one point in
/// each of the 8x8 cells, so every marked cell gets exactly m points, and
/// those of the first K are the sparse rays already traced (reused, not
/// traced again). Together the points keep the sequence's stratification
/// across cells: on Sponza 512 with every cell marked this equals
/// `--method mc` at 64 m rays (AO RMSE 0.0123 at 128), where m rays drawn
/// per cell independently gave 0.0146.
#[allow(clippy::too_many_arguments)]
fn brute_force_cells(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &FilterSettings,
    r: usize,
    frame: &Frame,
    marked: u64,
    sc: &mut Scratch,
) -> u32 {
    let geo = receivers.geo_normal[r];
    let origin = offset_origin(receivers.position[r], geo, receivers.footprint[r]);
    // The sparse pass's sequence (stream 1).
    let seed = receiver_seed(s.seed, receivers.texel[r] as u64, 1);
    let k = samples.per_receiver;
    let m = s.cell_rays.max(1);
    let mut traced = 0u32;
    for i in 0..CELL_COUNT as u32 * m {
        let u = sobol_2d(i, seed);
        let c = square_cell(u);
        if marked & (1 << c) == 0 {
            continue;
        }
        let (d, occluded) = if (i as usize) < k {
            let si = r * k + i as usize;
            let t = samples.t[si];
            (samples.dir[si], t < 0.0 || t <= s.max_distance)
        } else {
            let d = frame.to_world(cosine_hemisphere(u)).normalize();
            traced += (d.dot(geo) > 0.0) as u32;
            (d, !tracer.receiver_visible(origin, geo, d, s.max_distance))
        };
        sc.w[c] += 1.0;
        if occluded {
            sc.occ[c] += 1.0;
            sh::accumulate(&mut sc.occ_sh[c], 1.0, d);
        }
    }
    traced
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locality_order_is_a_morton_permutation_and_round_trips() {
        // A 4x4 atlas with two texels uncovered.
        let texels: Vec<u32> = (0..16).filter(|&t| t != 5 && t != 10).collect();
        let receivers = Receivers {
            width: 4,
            height: 4,
            position: texels.iter().map(|&t| Vec3::splat(t as f32)).collect(),
            normal: vec![Vec3::Z; texels.len()],
            geo_normal: vec![Vec3::Z; texels.len()],
            footprint: texels.iter().map(|&t| t as f32).collect(),
            texel: texels,
            ..Default::default()
        };
        let order = locality_order(&receivers);
        let mut sorted = order.clone();
        sorted.sort();
        assert_eq!(sorted, (0..14).collect::<Vec<u32>>());
        // Z order: (0,0) (1,0) (0,1) (1,1) (2,0) ...: texels 0 1 4 (5 missing) 2 3 6 7.
        let local = permuted(&receivers, &order);
        assert_eq!(&local.texel[..7], &[0, 1, 4, 2, 3, 6, 7]);
        assert_eq!(local.footprint[2], 4.0);
        assert_eq!((local.width, local.height), (4, 4));
        // Results computed in that order come back to each receiver.
        let bake = Bake {
            ao: local.footprint.clone(),
            sh: local.footprint.iter().map(|&f| [f; SH_COUNT]).collect(),
            rays: 7,
        };
        let stats = FilterStats {
            z_min: local.footprint.clone(),
            neighbours: local.texel.clone(),
            brute_fraction: local.footprint.clone(),
            sparse_ao: local.footprint.clone(),
            brute_rays: 3,
            ..Default::default()
        };
        let (bake, stats) = unpermuted(bake, stats, &order);
        assert_eq!(bake.ao, receivers.footprint);
        assert_eq!(bake.sh[3], [receivers.footprint[3]; SH_COUNT]);
        assert_eq!(stats.neighbours, receivers.texel);
        assert_eq!(stats.z_min, receivers.footprint);
        assert_eq!((bake.rays, stats.brute_rays), (7, 3));
    }

    #[test]
    fn a_hit_at_distance_near_zero_keeps_its_distance() {
        let p = Vec3::new(0.31, -0.27, 0.4);
        let d = Vec3::new(0.6, 0.0, 0.8);
        // The receiver's own ray (rel = 0) hitting at 1.5e-9.
        let v = hit_offset(p - p, d, 1.5e-9);
        assert!((v.length() - 1.5e-9).abs() < 1e-15, "{}", v.length());
        assert!((v / v.length() - d).length() < 1e-6);
        // The absolute form loses it entirely.
        assert_eq!((p + d * 1.5e-9 - p).length(), 0.0);
        // A neighbour's hit: the same point as the absolute form.
        let pj = p + Vec3::new(0.01, 0.002, 0.0);
        let v = hit_offset(pj - p, d, 0.2);
        assert!((v - (pj + d * 0.2 - p)).length() < 1e-7);
    }

    #[test]
    fn misses_of_open_cells_aim_at_the_farthest_occluded_neighbour_cell() {
        let inf = f32::INFINITY;
        let mut mid = [inf; CELL_COUNT];
        // Cell (2, 2) and (3, 3) saw occluders.
        mid[2 * 8 + 2] = 0.5;
        mid[3 * 8 + 3] = 0.8;
        let mut aim = [0.0; CELL_COUNT];
        miss_depths(&mid, &mut aim);
        // Cells with hits keep their own mid depth.
        assert_eq!(aim[2 * 8 + 2], 0.5);
        assert_eq!(aim[3 * 8 + 3], 0.8);
        // Open cells touching only (2, 2); touching both: the farther.
        assert_eq!(aim[8 + 1], 0.5);
        assert_eq!(aim[2 * 8 + 3], 0.8);
        assert_eq!(aim[4 * 8 + 4], 0.8);
        // Open cells two cells away from any occluder stay at infinity,
        // and the grid does not wrap around.
        assert_eq!(aim[0], inf);
        assert_eq!(aim[5 * 8 + 5], inf);
        assert_eq!(aim[2 * 8 + 7], inf);
        // Nothing seen anywhere: everything at infinity; a zero mid depth
        // (contact) is not a depth to aim at.
        mid = [inf; CELL_COUNT];
        mid[9] = 0.0;
        miss_depths(&mid, &mut aim);
        assert!(
            aim.iter()
                .enumerate()
                .all(|(c, &a)| a == if c == 9 { 0.0 } else { inf })
        );
    }

    #[test]
    fn spatial_radius_stiff_cases() {
        // z_max -> infinity: radius = z_min / Omega_v.
        assert!((spatial_radius(0.5, f32::INFINITY, 2.0) - 0.25).abs() < 1e-7);
        // z_min = z_max: the shear is exact, no bound on the radius.
        assert_eq!(spatial_radius(0.3, 0.3, 2.0), f32::INFINITY);
        // Contact (z_min -> 0): radius -> 0, never NaN.
        assert_eq!(spatial_radius(0.0, 1.0, 2.0), 0.0);
        assert!(spatial_radius(1e-30, 1.0, 2.0) < 1e-29);
        // Omega_v at its extremes.
        assert_eq!(spatial_radius(0.5, 1.0, f32::INFINITY), 0.0);
        assert_eq!(spatial_radius(0.5, 1.0, 0.0), f32::INFINITY);
        assert!(!spatial_radius(0.5, 1.0, 1e-30).is_nan());
        // General case matches Eq. 8 times the shading diameter.
        let (zmin, zmax, ov, d) = (0.2f32, 0.7f32, 2.0f32, 0.01f32);
        let primal_scale = (2.0 * (0.5 / d) / ov) / (1.0 / zmin - 1.0 / zmax);
        assert!((spatial_radius(zmin, zmax, ov) - d * primal_scale).abs() < 1e-5);
    }

    #[test]
    fn mid_depth_is_the_harmonic_mean() {
        assert!((mid_depth(1.0, 3.0) - 1.5).abs() < 1e-6);
        assert!((mid_depth(0.4, 0.4) - 0.4).abs() < 1e-7);
        assert!((mid_depth(1.0, f32::INFINITY) - 2.0).abs() < 1e-6);
        assert_eq!(mid_depth(0.0, 1.0), 0.0);
        assert_eq!(mid_depth(f32::INFINITY, f32::INFINITY), f32::INFINITY);
    }

    #[test]
    fn bandlimit_test_matches_the_paper() {
        // Omega_v / z_min > 0.5 / d  <=>  z_min < 2 Omega_v d.
        assert!(needs_brute_force(0.039, 2.0, 0.01));
        assert!(!needs_brute_force(0.041, 2.0, 0.01));
        assert!(needs_brute_force(0.0, 2.0, 0.01));
        assert!(needs_brute_force(f32::NAN, 2.0, 0.01));
        // Zero footprint (degenerate UVs): nothing forces brute force but contact.
        assert!(!needs_brute_force(1e-9, 2.0, 0.0));
    }

    #[test]
    fn weight_is_one_at_zero_and_vanishes_at_the_radius() {
        assert_eq!(weight(0.0, 1.0), 1.0);
        assert_eq!(weight(1.0, 1.0), 0.0);
        assert_eq!(weight(2.0, 1.0), 0.0);
        assert_eq!(weight(0.3, f32::INFINITY), 1.0);
        assert_eq!(weight(0.3, 0.0), 0.0);
        assert!(weight(0.5, 1.0) > weight(0.6, 1.0));
        for x in [0.0f32, 0.3, 0.99, 1.5] {
            assert!((weight_sq(x * x, 1.3) - weight(x, 1.3)).abs() < 1e-6);
        }
        assert_eq!(weight_sq(-1e-9, 1.0), 1.0);
    }

    #[test]
    fn reprojection_of_figure_6() {
        // Receiver at origin; a neighbour at (1,0,0) whose ray goes straight
        // up and hits at (1,0,1): effective direction toward the hit, tangent
        // offset = distance from receiver to where the ray crosses the plane
        // through the receiver perpendicular to that direction.
        let (e, x, dist) =
            reproject(Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)).unwrap();
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((e - Vec3::new(s, 0.0, s)).length() < 1e-6);
        assert!((dist - 2f32.sqrt()).abs() < 1e-6);
        // The ray (1,0,u) meets x + z = 0 at u = -1: offset |(1,0,-1)| = sqrt 2.
        assert!((x - 2f32.sqrt()).abs() < 1e-6);
        // A ray aimed at the receiver's own target from the receiver: x = 0.
        let (_, x, _) =
            reproject(Vec3::ZERO, Vec3::ZERO, Vec3::Z, Vec3::new(0.0, 0.0, 2.0)).unwrap();
        assert!(x.abs() < 1e-7);
        // Degenerate target (the receiver itself) and parallel rays.
        assert!(reproject(Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::ZERO).is_none());
        assert!(reproject(Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.0, 0.0, 1.0)).is_none());
    }

    #[test]
    fn jacobian_turns_reprojected_samples_into_the_receivers_cosine_measure() {
        // Cosine rays from a neighbour at (0.3, 0, 0) hit the plane z = 1
        // (normal +z) and are re-aimed from the receiver at the origin. With
        // the Jacobian as weight, the weight per cell must be the cosine
        // measure of the cell (1/64 each); without it, it is not.
        use crate::sample::{cell_of, cosine_hemisphere, sobol_2d};
        let (pn, h) = (Vec3::new(0.3, 0.0, 0.0), 1.0f32);
        let mut weighted = [0.0f64; CELL_COUNT];
        let mut plain = [0.0f64; CELL_COUNT];
        let (mut total_w, mut total) = (0.0f64, 0.0f64);
        for i in 0..1 << 18 {
            let d = cosine_hemisphere(sobol_2d(i, 7));
            if d.z < 1e-3 {
                continue;
            }
            let t = h / d.z;
            let target = pn + d * t;
            let dist = target.length();
            let e = target / dist;
            let j = reprojection_jacobian(e.z, d.z, e.z, d.z, dist, t);
            let c = cell_of(e);
            weighted[c] += j as f64;
            plain[c] += 1.0;
            total_w += j as f64;
            total += 1.0;
        }
        // Inner cells only: toward the horizon the clamp (MAX_JACOBIAN) and
        // the finite sample count dominate.
        let inner = |c: usize| {
            let (x, y) = ((c % 8) as i32, (c / 8) as i32);
            (2..6).contains(&x) && (2..6).contains(&y)
        };
        let (mut worst_w, mut worst_plain) = (0.0f64, 0.0f64);
        for c in (0..CELL_COUNT).filter(|&c| inner(c)) {
            let want = 1.0 / CELL_COUNT as f64;
            worst_w = worst_w.max((weighted[c] / total_w - want).abs() / want);
            worst_plain = worst_plain.max((plain[c] / total - want).abs() / want);
        }
        assert!(worst_w < 0.03, "weighted cells off by {worst_w}");
        assert!(
            worst_plain > 0.1,
            "the test must need the Jacobian: {worst_plain}"
        );
        // Same point, same normal: weight 1. Behind the receiver: 0.
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.7, 2.0, 2.0), 1.0);
        assert_eq!(reprojection_jacobian(-0.1, 0.5, 0.7, 0.7, 2.0, 2.0), 0.0);
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.0, 2.0, 2.0), 0.0);
        assert_eq!(reprojection_jacobian(0.5, 0.5, 0.7, 0.7, 0.0, 2.0), 0.0);
        assert_eq!(
            reprojection_jacobian(0.9, 0.1, 0.9, 0.1, 1.0, 9.0),
            MAX_JACOBIAN
        );
        assert_eq!(
            reprojection_jacobian(f32::NAN, 0.5, 0.7, 0.7, 2.0, 2.0),
            0.0
        );
    }

    #[test]
    fn leak_rule() {
        let (n, f) = (Vec3::Z, 0.01f32);
        let lends = |rel: Vec3, nj: Vec3| lends_rays(rel, n, n, nj, nj, f);
        // Same plane, any distance: lends.
        assert!(lends(Vec3::new(0.04, 0.0, 0.0), Vec3::Z));
        // A parallel sheet 0.3 footprints in front (a light quad under a
        // ceiling) or behind: does not.
        assert!(!lends(Vec3::new(0.02, 0.0, 0.003), Vec3::Z));
        assert!(!lends(Vec3::new(0.02, 0.0, -0.003), Vec3::Z));
        // Facing the other way, or 40 degrees off: does not.
        assert!(!lends(Vec3::new(0.02, 0.0, 0.0), -Vec3::Z));
        let tilted = Vec3::new(40f32.to_radians().sin(), 0.0, 40f32.to_radians().cos());
        assert!(!lends(Vec3::new(0.02, 0.0, 0.0), tilted));
        // A curved surface (10 degrees off) rising along the slope: lends;
        // far above the tangent plane: does not.
        let bent = Vec3::new(10f32.to_radians().sin(), 0.0, 10f32.to_radians().cos());
        assert!(lends(Vec3::new(0.04, 0.0, 0.004), bent));
        assert!(!lends(Vec3::new(0.04, 0.0, 0.03), bent));
        // The other face of a thin wall (opposite normals): does not.
        assert!(!lends_rays(Vec3::new(0.0, 0.0, -0.002), n, n, -n, -n, f));
    }

    #[test]
    fn tangent_offset_matches_reprojection() {
        // Figure 6's example: x = sqrt 2.
        let e = Vec3::new(1.0, 0.0, 1.0).normalize();
        let x2 = tangent_offset_sq(Vec3::X, Vec3::Z, e).unwrap();
        assert!((x2 - 2.0).abs() < 1e-5);
        // Against reproject for skewed rays and targets.
        let receiver = Vec3::new(0.3, -0.2, 0.1);
        for (o, d, target) in [
            (
                Vec3::new(0.5, 0.1, 0.1),
                Vec3::new(0.2, 0.3, 0.9),
                Vec3::new(0.4, 0.7, 1.3),
            ),
            (
                Vec3::new(-0.1, -0.4, 0.12),
                Vec3::new(-0.6, 0.1, 0.5),
                Vec3::new(-1.0, 0.0, 0.9),
            ),
        ] {
            let d = d.normalize();
            let (e, x, _) = reproject(receiver, o, d, target).unwrap();
            let x2 = tangent_offset_sq(o - receiver, d, e).unwrap();
            assert!((x2.sqrt() - x).abs() < 1e-5, "{x2} {x}");
        }
        // Parallel to the plane: no offset.
        assert!(tangent_offset_sq(Vec3::X, Vec3::X, Vec3::Z).is_none());
    }
}
