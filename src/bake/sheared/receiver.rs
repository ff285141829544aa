//! One receiver of the sheared filter: what Algorithm 1 reads, keeps and
//! returns for it.
//!
//! In: the receivers in locality order, their sparse [`Samples`], the
//! options ([`Pass`], with the k-d tree over their positions). Out: the
//! state the stages of one receiver pass along: its [`Scratch`] (per-cell
//! depth bounds, marks and the filter's [`CellSums`]), [`Pending`] (what
//! Algorithm 1 left to the second pass) and the [`ReceiverResult`]. The
//! stages are `gather` (Algorithm 1, lines 1-33) and `second_pass` (the
//! marked cells' rays and the receiver's AO and SH).

use super::types::{Samples, ShearedOptions};
use crate::atlas::Receivers;
use crate::bake::BakeParams;
use crate::error::{Error, Result};
use crate::sample::{CELL_COUNT, Frame};
use crate::sh::{self, SH_COUNT};
use glam::Vec3;
use kiddo::ImmutableKdTree;

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
pub(super) const OPEN_NORMAL_AGREEMENT: f32 = 0.999;

/// Fewest unoccluded samples a cell without hits must receive to be trusted
/// open: a cell occluded with probability p shows no hit among N samples with
/// probability (1-p)^N, a bright bias of at most ~1/(e (N+1)) per cell.
pub const MIN_CELL_SAMPLES: u16 = 12;

/// Per-receiver scratch, reused across receivers of one worker.
pub(super) struct Scratch {
    pub(super) neighbours: Vec<u32>,
    /// Neighbours' hits in this receiver's hemisphere, in neighbour order,
    /// reprojected once (line 1-14 pass) for the filter pass; `hit_start[n]`
    /// is where neighbour n's hits begin.
    pub(super) hit_cache: Vec<CachedHit>,
    pub(super) hit_start: Vec<u32>,
    pub(super) z_min: [f32; CELL_COUNT],
    pub(super) z_max: [f32; CELL_COUNT],
    pub(super) count: [u16; CELL_COUNT],
    pub(super) hits: [u16; CELL_COUNT],
    pub(super) radius: [f32; CELL_COUNT],
    pub(super) mid: [f32; CELL_COUNT],
    /// Depth at which misses of each cell are re-aimed ([`miss_depths`]).
    pub(super) aim: [f32; CELL_COUNT],
    pub(super) brute: [bool; CELL_COUNT],
    /// The filter's sums per cell.
    pub(super) sums: CellSums,
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
pub(super) struct CachedHit {
    pub(super) sample: u32,
    pub(super) cell: u8,
    pub(super) e: Vec3,
    pub(super) dist: f32,
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

/// The receiver Algorithm 1 is filtering: its position, normals, texel
/// footprint and shading frame.
#[derive(Clone, Copy)]
pub(super) struct Receiver {
    pub(super) p: Vec3,
    pub(super) n: Vec3,
    pub(super) geo: Vec3,
    pub(super) footprint: f32,
    pub(super) frame: Frame,
}

impl Receiver {
    pub(super) fn new(receivers: &Receivers, r: usize) -> Receiver {
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
    pub(super) occ_ao: f32,
    pub(super) occ_sh: [f32; SH_COUNT],
    pub(super) filtered: u32,
    pub(super) brute: u32,
    pub(super) contact: u32,
    pub(super) no_hit: u32,
    pub(super) open: u32,
    pub(super) z_min: f32,
    pub(super) neighbours: u32,
    pub(super) marked: u64,
}

/// Per cell of a receiver's hemisphere: the weight of the samples or rays
/// summed, their occluded weight and its SH (the filter's, and the second
/// pass's over the brute-forced cells).
pub(super) struct CellSums {
    pub(super) w: [f32; CELL_COUNT],
    pub(super) occ: [f32; CELL_COUNT],
    pub(super) occ_sh: [[f32; SH_COUNT]; CELL_COUNT],
}

impl CellSums {
    pub(super) fn new() -> CellSums {
        CellSums {
            w: [0.0; CELL_COUNT],
            occ: [0.0; CELL_COUNT],
            occ_sh: [[0.0; SH_COUNT]; CELL_COUNT],
        }
    }

    /// Adds weight `w` in cell `c`, occluded along `d` if `occluded`.
    #[inline]
    pub(super) fn add(&mut self, c: usize, w: f32, occluded: bool, d: Vec3) {
        self.w[c] += w;
        if occluded {
            self.occ[c] += w;
            sh::accumulate(&mut self.occ_sh[c], w, d);
        }
    }
}
