//! One receiver of the sheared filter: Algorithm 1, lines 1-33, and the
//! second pass for the cells it cannot serve.
//!
//! In: a [`Pass`] (the receivers in locality order, their sparse
//! [`Samples`], the k-d tree over their positions, options) and a receiver
//! index. Out: [`Pending`] (what Algorithm 1 filtered, the cells left to
//! the second pass), whose rays [`emit_brute_force`] adds to a batch; then
//! [`finish`] with their answers: a [`ReceiverResult`], its AO and SH and
//! the counts behind [`super::ShearedStats`].

use super::geometry::{
    hit_offset, lends_rays, mid_depth, miss_depths, needs_brute_force, reproject,
    reprojection_jacobian, spatial_radius, tangent_offset_sq, weight, weight_sq,
};
use super::types::{SPARSE_STREAM, Samples, ShearedOptions};
use crate::atlas::Receivers;
use crate::bake::{BakeParams, ReceiverRays};
use crate::error::{Error, Result};
use crate::sample::{CELL_COUNT, Frame, cell_of_fast, cosine_hemisphere, in_cell, square_cell};
use crate::sh::{self, SH_COUNT};
use crate::trace::{RayBatch, Tracer};
use glam::{Vec2, Vec3};
use kiddo::{ImmutableKdTree, SquaredEuclidean};
use std::sync::LazyLock;

/// What every receiver's filtering reads.
pub(super) struct Pass<'a> {
    /// In locality order ([`super::locality_order`]).
    pub receivers: &'a Receivers,
    pub samples: &'a Samples,
    /// Over the receivers' positions.
    pub tree: ImmutableKdTree<f32, 3>,
    pub s: &'a ShearedOptions,
    pub params: &'a BakeParams,
}

impl<'a> Pass<'a> {
    /// The pass over `receivers`, with the k-d tree of their positions.
    pub(super) fn new(
        receivers: &'a Receivers,
        samples: &'a Samples,
        s: &'a ShearedOptions,
        params: &'a BakeParams,
    ) -> Result<Pass<'a>> {
        let points: Vec<[f32; 3]> = receivers.position.iter().map(|p| p.to_array()).collect();
        let tree = ImmutableKdTree::<f32, 3>::new_from_slice(&points)
            .map_err(|e| Error::Limit(format!("cannot build the receivers' k-d tree: {e}")))?;
        Ok(Pass {
            receivers,
            samples,
            tree,
            s,
            params,
        })
    }
}

/// Fewest hits in a cell for its z_max to be trusted in Eq. 8.
pub const MIN_DEPTH_HITS: u16 = 8;

/// Shading and geometric normals this close (cos 2.6 degrees) leave a
/// negligible part of the shading hemisphere below the surface.
const OPEN_NORMAL_AGREEMENT: f32 = 0.999;

/// Fewest unoccluded samples a cell without hits must receive to be trusted
/// open: a cell occluded with probability p shows no hit among N samples with
/// probability (1-p)^N, a bright bias of at most ~1/(e (N+1)) per cell.
pub const MIN_CELL_SAMPLES: u16 = 12;

/// Cell centre directions in the local frame.
static CELL_CENTRES: LazyLock<[Vec3; CELL_COUNT]> =
    LazyLock::new(|| std::array::from_fn(|c| cosine_hemisphere(in_cell(c, Vec2::splat(0.5)))));

/// Per-receiver scratch, reused across receivers of one worker.
pub(super) struct Scratch {
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
    /// The filter's sums per cell.
    sums: CellSums,
}

impl Scratch {
    pub(super) fn new() -> Scratch {
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
            sums: CellSums::new(),
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
#[derive(Clone, Copy, Default)]
pub(super) struct ReceiverResult {
    pub(super) ao: f32,
    pub(super) sh: [f32; SH_COUNT],
    pub(super) filtered: u32,
    pub(super) brute: u32,
    pub(super) contact: u32,
    pub(super) no_hit: u32,
    pub(super) open: u32,
    pub(super) brute_rays: u32,
    pub(super) z_min: f32,
    pub(super) neighbours: u32,
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

/// What Algorithm 1 leaves of a receiver for the second pass: the filtered
/// cells' share of the occlusion, the counts, and the cells it cannot serve
/// (`marked`), whose rays [`emit_brute_force`] casts and [`finish`] adds.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Pending {
    occ_ao: f32,
    occ_sh: [f32; SH_COUNT],
    filtered: u32,
    brute: u32,
    contact: u32,
    no_hit: u32,
    open: u32,
    z_min: f32,
    neighbours: u32,
    marked: u64,
}

/// Algorithm 1 for receiver `r`: the cells its neighbours' samples serve,
/// and those left to the second pass.
pub(super) fn filter_receiver(f: &Pass, r: usize, sc: &mut Scratch) -> Pending {
    let Pass {
        receivers,
        samples,
        ref tree,
        s,
        params,
        ..
    } = *f;
    let rc = Receiver::new(receivers, r);
    let Receiver {
        n, geo, footprint, ..
    } = rc;
    gather_neighbours(receivers, tree, s, &rc, sc);
    let any_occluder = depth_bounds(receivers, samples, params, &rc, sc);
    let neighbours = sc.neighbours.len() as u32;
    // Early out: the neighbourhood's rays saw no occluder (and enough of
    // them looked: at least one per cell on average).
    // The shading hemisphere must also lie above the geometric plane (within
    // 2.6 degrees), or part of it is occluded by the surface itself.
    let looked: u32 = sc.count.iter().map(|&c| c as u32).sum();
    if !any_occluder && looked >= CELL_COUNT as u32 && n.dot(geo) > OPEN_NORMAL_AGREEMENT {
        // (No occlusion: finish gives AO 1 and the open hemisphere.)
        return Pending {
            open: CELL_COUNT as u32,
            z_min: f32::INFINITY,
            neighbours,
            ..Pending::default()
        };
    }

    let (nearest, reach2) = mark_cells(s, &rc, sc);
    filter_samples(receivers, samples, params, &rc, reach2, sc);

    // Normalize, brute-force what the filter cannot serve, combine.
    let mut occ_ao = 0.0f32;
    let mut occ_sh = [0.0f32; SH_COUNT];
    let (mut filtered, mut brute, mut open) = (0u32, 0u32, 0u32);
    let (mut contact, mut no_hit) = (0u32, 0u32);
    let mut marked = 0u64;
    let inv_cells = 1.0 / CELL_COUNT as f32;
    for c in 0..CELL_COUNT {
        if !sc.brute[c] && sc.sums.w[c] >= s.min_weight {
            if sc.sums.occ[c] == 0.0 {
                open += 1;
                continue;
            }
            filtered += 1;
            let inv = inv_cells / sc.sums.w[c];
            occ_ao += sc.sums.occ[c] * inv;
            for (acc, v) in occ_sh.iter_mut().zip(sc.sums.occ_sh[c]) {
                *acc += v * inv;
            }
            continue;
        }
        // The second pass replaces whatever weight the filter gave it
        // (adding the filter's few samples to it measured worse on Sponza:
        // AO RMSE 0.0128 -> 0.0132 at 8:4): its sums start from zero.
        brute += 1;
        marked |= 1 << c;
        contact += (sc.z_min[c].is_finite()
            && needs_brute_force(sc.z_min[c], s.omega_v_max, footprint)) as u32;
        no_hit += sc.z_min[c].is_infinite() as u32;
    }
    Pending {
        occ_ao,
        occ_sh,
        filtered,
        brute,
        contact,
        no_hit,
        open,
        z_min: nearest,
        neighbours,
        marked,
    }
}

/// Per cell of a receiver's hemisphere: the weight of the samples or rays
/// summed, their occluded weight and its SH (the filter's, and the second
/// pass's over the brute-forced cells).
struct CellSums {
    w: [f32; CELL_COUNT],
    occ: [f32; CELL_COUNT],
    occ_sh: [[f32; SH_COUNT]; CELL_COUNT],
}

impl CellSums {
    fn new() -> CellSums {
        CellSums {
            w: [0.0; CELL_COUNT],
            occ: [0.0; CELL_COUNT],
            occ_sh: [[0.0; SH_COUNT]; CELL_COUNT],
        }
    }

    /// Adds weight `w` in cell `c`, occluded along `d` if `occluded`.
    #[inline]
    fn add(&mut self, c: usize, w: f32, occluded: bool, d: Vec3) {
        self.w[c] += w;
        if occluded {
            self.occ[c] += w;
            sh::accumulate(&mut self.occ_sh[c], w, d);
        }
    }
}

/// Receiver `r`'s AO and SH: the filtered cells' share in `pending`, plus
/// the second pass over its marked cells from the rays [`emit_brute_force`]
/// cast (`directions`, `occluded`, in that order).
pub(super) fn finish(
    f: &Pass,
    r: usize,
    pending: &Pending,
    directions: &[Vec3],
    occluded: &[bool],
) -> ReceiverResult {
    let n = f.receivers.normal[r];
    let Pending {
        mut occ_ao,
        mut occ_sh,
        marked,
        ..
    } = *pending;
    let inv_cells = 1.0 / CELL_COUNT as f32;
    let brute_rays = if marked != 0 {
        let (traced, cells) = brute_force_cells(f, r, marked, directions, occluded);
        for c in 0..CELL_COUNT {
            if marked & (1 << c) != 0 && cells.occ[c] > 0.0 {
                let inv = inv_cells / cells.w[c];
                occ_ao += cells.occ[c] * inv;
                for (acc, v) in occ_sh.iter_mut().zip(cells.occ_sh[c]) {
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
        filtered: pending.filtered,
        brute: pending.brute,
        contact: pending.contact,
        no_hit: pending.no_hit,
        open: pending.open,
        brute_rays,
        z_min: pending.z_min,
        neighbours: pending.neighbours,
    }
}

/// The neighbours that may lend rays (the leak rule, [`lends_rays`]) within
/// the gather radius, into `sc.neighbours`.
#[inline]
fn gather_neighbours(
    receivers: &Receivers,
    tree: &ImmutableKdTree<f32, 3>,
    s: &ShearedOptions,
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
    params: &BakeParams,
    rc: &Receiver,
    sc: &mut Scratch,
) -> bool {
    let Receiver {
        p, n, geo, frame, ..
    } = *rc;
    let k = samples.per_receiver;
    let d_max = params.max_distance;
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
fn mark_cells(s: &ShearedOptions, rc: &Receiver, sc: &mut Scratch) -> (f32, f32) {
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
    params: &BakeParams,
    rc: &Receiver,
    reach2: f32,
    sc: &mut Scratch,
) {
    let Receiver {
        p, n, geo, frame, ..
    } = *rc;
    let k = samples.per_receiver;
    let d_max = params.max_distance;
    sc.sums = CellSums::new();
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
            sc.sums
                .add(c, w, h.dist <= d_max || h.e.dot(geo) <= 0.0, h.e);
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
                // Into the receiver's own surface: occluded.
                sc.sums.add(c0, w, w > 0.0 && d.dot(geo) <= 0.0, d);
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
            sc.sums.add(c, w, e.dot(geo) <= 0.0, e);
        }
    }
}

/// The points of receiver `r`'s second pass in order: (point index, its
/// cell) for the cells set in `marked`.
///
/// The rays are the receiver's own sparse sequence continued: points
/// `0..64 m` (m = `cell_rays`) of the same Owen-scrambled Sobol sequence,
/// kept where they fall in a marked cell. Each aligned block of 64 points
/// of a (0,2)-sequence is a (0,6,2)-net, which puts exactly one point in
/// each of the 8x8 cells, so every marked cell gets exactly m points, and
/// those of the first K are the sparse rays already traced (reused, not
/// traced again). Together the points keep the sequence's stratification
/// across cells: with every cell marked this equals `--method mc` at 64 m
/// rays, where m rays drawn per cell independently erred more
/// (`docs/measurements/constants.md`, second_pass_points).
fn second_pass_points<'r>(
    rays: &'r ReceiverRays,
    cell_rays: u32,
    marked: u64,
) -> impl Iterator<Item = (u32, usize, Vec2)> + 'r {
    (0..CELL_COUNT as u32 * cell_rays.max(1)).filter_map(move |i| {
        let u = rays.point(i);
        let c = square_cell(u);
        (marked & (1 << c) != 0).then_some((i, c, u))
    })
}

/// The rays receiver `r`'s second pass traces, into `batch`: those of its
/// marked cells past the sparse ones (a direction below the geometric
/// plane blocked, to keep the order).
pub(super) fn emit_brute_force(f: &Pass, r: usize, pending: &Pending, batch: &mut RayBatch) {
    if pending.marked == 0 {
        return;
    }
    let (receivers, params) = (f.receivers, f.params);
    let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
    let k = f.samples.per_receiver;
    for (i, _, u) in second_pass_points(&rays, f.s.cell_rays, pending.marked) {
        if (i as usize) < k {
            continue;
        }
        let d = rays.direction_of(u);
        if d.dot(rays.geo_normal) > 0.0 {
            batch.push(rays.origin, d, params.max_distance);
        } else {
            batch.push_blocked(d);
        }
    }
}

/// The second pass for receiver `r`: Monte Carlo over the cells set in
/// `marked`, from the sparse samples and the traced rays
/// ([`emit_brute_force`]'s, in order). Returns the rays traced (those
/// above the geometric plane) and the cells' sums.
fn brute_force_cells(
    f: &Pass,
    r: usize,
    marked: u64,
    directions: &[Vec3],
    occluded: &[bool],
) -> (u32, CellSums) {
    let Pass {
        receivers,
        samples,
        s,
        params,
        ..
    } = *f;
    let mut cells = CellSums::new();
    // The sparse pass's sequence (stream 1).
    let rays = ReceiverRays::with_stream(receivers, r, params.seed, SPARSE_STREAM);
    let geo = rays.geo_normal;
    let k = samples.per_receiver;
    let mut traced = 0u32;
    let mut next = directions.iter().zip(occluded);
    for (i, c, _) in second_pass_points(&rays, s.cell_rays, marked) {
        let (d, occluded) = if (i as usize) < k {
            let si = r * k + i as usize;
            let t = samples.t[si];
            (samples.dir[si], t < 0.0 || t <= params.max_distance)
        } else {
            let (&d, &hit) = next
                .next()
                .expect("one traced ray per point past the sparse ones");
            traced += (d.dot(geo) > 0.0) as u32;
            (d, hit)
        };
        cells.add(c, 1.0, occluded, d);
    }
    (traced, cells)
}

/// Debugging aid: per cell of receiver `r`, the filter weight, occluded
/// weight and brute-force mark, before the second pass.
#[doc(hidden)]
pub fn cell_estimates(
    receivers: &Receivers,
    samples: &Samples,
    tracer: &Tracer,
    s: &ShearedOptions,
    params: &BakeParams,
    r: usize,
) -> Vec<(f32, f32, bool)> {
    let pass = Pass::new(receivers, samples, s, params).expect("k-d tree");
    let mut sc = Scratch::new();
    let pending = filter_receiver(&pass, r, &mut sc);
    let mut batch = RayBatch::new();
    emit_brute_force(&pass, r, &pending, &mut batch);
    let mut occluded = Vec::new();
    tracer.occluded_batch(&batch, &mut occluded);
    let (_, cells) = brute_force_cells(&pass, r, pending.marked, batch.directions(), &occluded);
    (0..CELL_COUNT)
        .map(|c| match pending.marked & (1 << c) != 0 {
            true => (cells.w[c], cells.occ[c], sc.brute[c]),
            false => (sc.sums.w[c], sc.sums.occ[c], sc.brute[c]),
        })
        .collect()
}
