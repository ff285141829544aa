//! The adaptive method's options and their ranges.
//!
//! In: the values a caller sets. Out: [`AdaptiveOptions::validate`]'s
//! verdict and the memory estimate per texel.

use super::sums::RaySums;
use crate::error::{Error, Result};

/// Options of the adaptive method. Each flag's doc comment is its
/// `--help` line; the expert constants have no flag.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct AdaptiveOptions {
    /// Closest-hit rays per receiver in the pre-pass (a power of two).
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.pre_rays))]
    pub pre_rays: u32,
    /// Adaptive: the bake's error is that of QUALITY-ray Monte Carlo (its
    /// predicted AO RMSE over the atlas)
    #[cfg_attr(feature = "cli", arg(long, value_name = "Q", default_value_t = Self::DEFAULT.quality))]
    pub quality: u32,
    /// Adaptive, expert: a fixed mean rays per texel instead of --quality
    /// (0: from --quality)
    #[cfg_attr(feature = "cli", arg(long, value_name = "N", default_value_t = Self::DEFAULT.mean_rays, hide_default_value = true))]
    pub mean_rays: u32,
    /// Most rays one receiver gets (a power of two).
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.max_rays))]
    pub max_rays: u32,
    /// Expert: the spatial bandlimit constant Omega_h (sigma = z_min / (2
    /// mu Omega_h)).
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.omega_h))]
    pub omega_h: f32,
    /// Expert: mu, how far inside the bandlimit the filter stays.
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.mu))]
    pub mu: f32,
    /// Widest filter reach in texels (2 sigma).
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.max_reach))]
    pub max_reach: u32,
    /// Receivers in contact filtered along their contact line
    /// (`bake::adaptive::line`); off: left unfiltered, as the paper
    /// leaves them.
    #[cfg_attr(feature = "cli", arg(skip = Self::DEFAULT.contact_lines))]
    #[serde(default = "contact_lines_on")]
    pub contact_lines: bool,
}

/// [`AdaptiveOptions::contact_lines`]'s default, for settings written
/// before the option.
fn contact_lines_on() -> bool {
    true
}

impl AdaptiveOptions {
    /// Every option's default.
    pub const DEFAULT: AdaptiveOptions = AdaptiveOptions {
        pre_rays: 16,
        quality: 256,
        mean_rays: 0,
        max_rays: 1024,
        omega_h: 2.8,
        mu: 0.7,
        max_reach: 4,
        contact_lines: true,
    };
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        AdaptiveOptions::DEFAULT
    }
}

/// Largest `max_rays` and `mean_rays`.
pub const MAX_ADAPTIVE_RAYS: u32 = 4096;
/// Largest `max_reach` in texels.
pub const MAX_REACH: u32 = 32;

impl AdaptiveOptions {
    /// Checks every option's range.
    pub fn validate(&self) -> Result<()> {
        let pow2 = |v: u32| v.is_power_of_two() && v <= MAX_ADAPTIVE_RAYS;
        if !pow2(self.pre_rays) {
            return Err(Error::option(
                "pre_rays",
                format!(
                    "{} must be a power of two up to {MAX_ADAPTIVE_RAYS}",
                    self.pre_rays
                ),
            ));
        }
        if !pow2(self.max_rays) || self.max_rays < self.pre_rays {
            return Err(Error::option(
                "max_rays",
                format!(
                    "{} must be a power of two in {}..={MAX_ADAPTIVE_RAYS}",
                    self.max_rays, self.pre_rays
                ),
            ));
        }
        if !(1..=MAX_ADAPTIVE_RAYS).contains(&self.quality) {
            return Err(Error::option(
                "quality",
                format!("{} is outside 1..={MAX_ADAPTIVE_RAYS}", self.quality),
            ));
        }
        if self.mean_rays != 0 && !(self.pre_rays..=self.max_rays).contains(&self.mean_rays) {
            return Err(Error::option(
                "mean_rays",
                format!(
                    "{} is outside {}..={} (pre_rays..=max_rays), or 0 for quality",
                    self.mean_rays, self.pre_rays, self.max_rays
                ),
            ));
        }
        for (name, v) in [("omega_h", self.omega_h), ("mu", self.mu)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::option(name, format!("{v} must be finite and > 0")));
            }
        }
        if self.max_reach > MAX_REACH {
            return Err(Error::option(
                "max_reach",
                format!("{} is outside 0..={MAX_REACH} texels", self.max_reach),
            ));
        }
        Ok(())
    }

    /// Bytes per atlas texel beyond what every method holds (its results,
    /// AO and SH, which the filter's column pass writes), at the larger of
    /// two peaks. The bounds: the running sums (80 B: visible and below
    /// counts, occluded and all rays' SH sums), own z_min (4 B), the
    /// pre-pass strata's crossings (2 B), the texel map (4 B) and the
    /// bounds' working arrays (spread and filter z_min, sigma, supports, sd
    /// twice, N_eff and its row sums, the allocation's terms and counts:
    /// about 64 B; the widest filter's row minima, 4 B per texel of
    /// `max_reach`). The filter's row pass: ray counts (4 B), z_min and
    /// sigma (8 B), the texel map (4 B), the filter's input (AO and SH:
    /// 40 B) and its row pass (44 B).
    pub fn bytes_per_texel(&self) -> u64 {
        let sums = std::mem::size_of::<RaySums>() as u64;
        let bounds = sums + 4 + 2 + 4 + 64 + 4 * self.max_reach as u64;
        let filter = 4 + 8 + 4 + 40 + 44;
        bounds.max(filter)
    }

    /// Bytes per receiver the bake keeps after it ends, in
    /// `AdaptiveStats`: rays, z_min, sigma and inside (which the other
    /// methods' validity stage holds instead).
    pub const KEPT_BYTES_PER_TEXEL: u64 = 13;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_checked() {
        assert!(AdaptiveOptions::default().validate().is_ok());
        for bad in [
            AdaptiveOptions {
                pre_rays: 12,
                ..Default::default()
            },
            AdaptiveOptions {
                max_rays: 8,
                ..Default::default()
            },
            AdaptiveOptions {
                mean_rays: 2048,
                ..Default::default()
            },
            AdaptiveOptions {
                mean_rays: 8,
                ..Default::default()
            },
            AdaptiveOptions {
                quality: 0,
                ..Default::default()
            },
            AdaptiveOptions {
                mu: f32::NAN,
                ..Default::default()
            },
            AdaptiveOptions {
                omega_h: 0.0,
                ..Default::default()
            },
            AdaptiveOptions {
                max_reach: 100,
                ..Default::default()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
