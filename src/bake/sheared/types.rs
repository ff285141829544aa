//! What goes in and out of the sheared filter: its options, the sparse
//! pass's samples, and the statistics of a filtered bake.
//!
//! In: nothing (the bottom of the folder; every other file uses these).
//! Out: [`ShearedOptions`] (validated once, by the pipeline), [`Samples`],
//! [`ShearedStats`] with its `--debug-dir` maps.

use crate::error::{Error, Result};
use crate::sample::CELL_COUNT;
use glam::Vec3;

/// The receiver sequence ([`crate::bake::ReceiverRays::with_stream`]) of
/// the sparse pass, which the second pass continues.
pub(super) const SPARSE_STREAM: u64 = 1;

/// Options of the sheared filter (paper defaults where the paper gives
/// one). The max distance and seed every method shares are in
/// `BakeParams`. Each field's doc comment is its `--help` line; the
/// measurements behind the defaults are in the comments above
/// [`ShearedOptions::DEFAULT`] and in `docs/method-sheared.md`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ShearedOptions {
    /// Sheared: sparse rays per texel, shared with the neighbours
    #[cfg_attr(feature = "cli", arg(long, value_name = "K", default_value_t = Self::DEFAULT.sparse_rays))]
    pub sparse_rays: u32,
    /// Sheared: neighbour gather radius in texel footprints
    #[cfg_attr(feature = "cli", arg(long, value_name = "R", default_value_t = Self::DEFAULT.gather_radius))]
    pub gather_radius: f32,
    /// Sheared: angular bandlimit Omega_v^max (larger: sharper, more brute
    /// force)
    #[cfg_attr(feature = "cli", arg(long = "omega-v", value_name = "W", default_value_t = Self::DEFAULT.omega_v_max))]
    pub omega_v_max: f32,
    /// Sheared: hemisphere cells with less filter weight (about that many
    /// samples) are brute-forced
    #[cfg_attr(feature = "cli", arg(long, value_name = "W", default_value_t = Self::DEFAULT.min_weight))]
    pub min_weight: f32,
    /// Sheared: brute-force rays per hemisphere cell the filter cannot serve
    #[cfg_attr(feature = "cli", arg(long, value_name = "C", default_value_t = Self::DEFAULT.cell_rays))]
    pub cell_rays: u32,
}

impl ShearedOptions {
    /// Every option's default.
    pub const DEFAULT: ShearedOptions = ShearedOptions {
        // Paper: 4-32. 4 measured best at the default radius: less time
        // than 8 for the same error (`docs/measurements/constants.md`,
        // the sheared filter's sparse rays).
        sparse_rays: 4,
        // Paper: 8-16 pixels.
        gather_radius: 4.0,
        // Paper: 2.
        omega_v_max: 2.0,
        // Paper: ~2 samples; 4 measured better
        // (`docs/measurements/constants.md`, the sheared filter's min
        // weight).
        min_weight: 4.0,
        // Paper: 1.
        cell_rays: 2,
    };
}

impl Default for ShearedOptions {
    fn default() -> Self {
        ShearedOptions::DEFAULT
    }
}

/// Largest `gather_radius` in texels: every receiver visits the
/// neighbours within it, so the filter's cost grows with its square.
pub const MAX_GATHER_RADIUS: f32 = 64.0;
/// Largest `sparse_rays` and `cell_rays`.
pub const MAX_FILTER_RAYS: u32 = 1024;

impl ShearedOptions {
    /// Checks every option's range.
    pub fn validate(&self) -> Result<()> {
        if !(1..=MAX_FILTER_RAYS).contains(&self.sparse_rays) {
            return Err(Error::option(
                "sparse_rays",
                format!("{} is outside 1..={MAX_FILTER_RAYS}", self.sparse_rays),
            ));
        }
        if !(1..=MAX_FILTER_RAYS).contains(&self.cell_rays) {
            return Err(Error::option(
                "cell_rays",
                format!("{} is outside 1..={MAX_FILTER_RAYS}", self.cell_rays),
            ));
        }
        if !(0.0..=MAX_GATHER_RADIUS).contains(&self.gather_radius) {
            return Err(Error::option(
                "gather_radius",
                format!(
                    "{} is outside 0..={MAX_GATHER_RADIUS} texels",
                    self.gather_radius
                ),
            ));
        }
        if !(self.omega_v_max > 0.0 && self.omega_v_max.is_finite()) {
            return Err(Error::option(
                "omega_v_max",
                format!("{} must be finite and > 0", self.omega_v_max),
            ));
        }
        if !(self.min_weight >= 0.0 && self.min_weight.is_finite()) {
            return Err(Error::option(
                "min_weight",
                format!("{} must be finite and >= 0", self.min_weight),
            ));
        }
        Ok(())
    }

    /// Bytes per atlas texel the filter holds beyond what every method
    /// holds: sparse samples (direction, distance, cell, hit normal: 29 B
    /// each), the k-d tree's points, per-receiver filter statistics
    /// (~40 B) and the receivers reordered for locality (44 B).
    pub fn bytes_per_texel(&self) -> u64 {
        self.sparse_rays as u64 * 29 + 12 + 40 + 44
    }
}

/// Counters and per-receiver diagnostics of a filtered bake.
#[derive(Clone, Debug, Default)]
pub struct ShearedStats {
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
    /// [`super::MIN_CELL_SAMPLES`] misses, or too little filter weight). The rest
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

impl ShearedStats {
    /// A count of cells as a fraction of all hemisphere cells (64 per
    /// receiver).
    pub fn cell_share(&self, cells: u64) -> f64 {
        cells as f64 / (self.brute_fraction.len() * CELL_COUNT).max(1) as f64
    }

    /// The `--debug-dir` maps, each in [0, 1]: `brute_force_fraction`
    /// (share of each texel's cells brute-forced, white = all; the paper's
    /// Figure 7a inset), `z_min` (nearest occluder, black = contact, white
    /// = none within `max_distance`), `neighbours` (neighbours that lent
    /// rays, white = the most of any texel) and `sparse_ao` (AO of the
    /// texel's own sparse rays).
    pub fn debug_maps(&self, max_distance: f32) -> Vec<(&'static str, Vec<f32>)> {
        let max_neighbours = self.neighbours.iter().copied().max().unwrap_or(1).max(1) as f32;
        vec![
            ("brute_force_fraction", self.brute_fraction.clone()),
            (
                "z_min",
                self.z_min
                    .iter()
                    .map(|&z| (z / max_distance).min(1.0))
                    .collect(),
            ),
            (
                "neighbours",
                self.neighbours
                    .iter()
                    .map(|&n| n as f32 / max_neighbours)
                    .collect(),
            ),
            ("sparse_ao", self.sparse_ao.clone()),
        ]
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
    /// Hit distance; `INFINITY` for a miss within [`super::sparse_t_max`];
    /// negative for a direction below the geometric horizon (it enters the
    /// receiver's own surface and says nothing about occluders).
    pub t: Vec<f32>,
    /// Unit geometric normal of the hit (either side; zero for a miss):
    /// for the solid-angle Jacobian of the reprojection.
    pub hit_normal: Vec<Vec3>,
}
