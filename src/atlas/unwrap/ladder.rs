//! The choice a small page offers the engine view (`--ladder view`):
//! which pages have one, and the atlas of the other option.
//!
//! In: the rule's pick (the asked options, as packed), the unwrapper's
//! prepared charts. Out: where the page is tight but not starved
//! ([`ladder_applies`]), the same charts packed with a texel of padding
//! and charts at least a texel wide ([`alternative`]), unless it is no
//! denser; `job/level/ladder.rs` bakes both small and keeps the one whose
//! lookups read less error.
//!
//! Why only that option: the rule already relaxes a page the asked
//! options do not fit or starve (under [`super::STARVED_UTILIZATION`]),
//! and a starved page's asked options read 1.4-4.5x the relaxed error.
//! Between starved and comfortable the rule cannot tell: the flight
//! helmet at 512 fits padding 2 at 24% of the page and reads 1.34x the
//! error of a texel of padding; the Cesium tree at 256, 1.23x. Of the
//! rungs below, no padding (charts blending at their edges) and no
//! minimum width (slivers) lost to a texel of each on every tight page
//! measured (the helmet at 256 and 512, the tree at 256, the two-cylinder
//! engine at 256, the curtains at 512: `docs/measurements/chart-count.md`),
//! so they are not baked.

use super::{Relaxed, UnwrapOptions, pack_rung, relaxed_options};
use crate::error::Result;

/// How a small page's padding and minimum chart width are chosen
/// (`--ladder`): `view`, where the asked options fit a small page
/// unstarved but tight ([`ladder_applies`]), by the engine view of a small
/// bake of them and of a texel of each (`job/level/ladder.rs`); `rule`, by
/// the fixed rule alone (the asked options, relaxed only where they do not
/// fit or starve the page).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum Ladder {
    #[default]
    View,
    Rule,
}

impl Ladder {
    pub fn is_view(&self) -> bool {
        *self == Ladder::View
    }
}

/// Largest `--resolution` page whose options the engine view chooses
/// between ([`ladder_applies`]): a prop's lightmap, where two small bakes
/// cost little beside what its texels decide.
pub const LADDER_MAX_EDGE: u32 = 512;

/// Utilisation under which a small page packed as asked is tight: its
/// padding and minimum widths take most of it (module doc).
pub const LADDER_UTILIZATION: f32 = 0.35;

/// Whether a `resolution` page that the rule packed at `utilization`
/// (`relaxed`: with less than asked) offers the engine view a choice: a
/// page of at most [`LADDER_MAX_EDGE`] texels, packed as asked and under
/// [`LADDER_UTILIZATION`] used.
pub fn ladder_applies(resolution: u32, utilization: f32, relaxed: Option<Relaxed>) -> bool {
    resolution <= LADDER_MAX_EDGE && relaxed.is_none() && utilization < LADDER_UTILIZATION
}

/// The page's charts packed with a texel of padding and charts at least
/// a texel wide (the first of [`relaxed_options`], as the rule packs it),
/// where that holds them on one `resolution` page more densely than the
/// asked options' `density` (texels per unit): less padding at no more
/// density reads no texel fewer. `None` when nothing is less than asked.
pub(super) fn alternative(
    resolution: u32,
    density: f32,
    options: &UnwrapOptions,
    opts: &uvunwrap::Options,
    generate: &dyn Fn(&uvunwrap::Options) -> std::result::Result<uvunwrap::Atlas, uvunwrap::Error>,
) -> Result<Option<(uvunwrap::Atlas, Relaxed)>> {
    let Some(r) = relaxed_options(options.padding, options.min_chart_width)
        .first()
        .copied()
    else {
        return Ok(None);
    };
    let a = pack_rung(&r, resolution, options, opts, generate)?;
    let fits = a.page_count <= 1 && a.texels_per_unit > density;
    Ok(fits.then_some((a, r)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_small_page_packed_as_asked_and_tight_offers_a_choice() {
        let relaxed = Some(Relaxed {
            padding: 1,
            min_chart_width: 1.0,
            starved: true,
        });
        assert!(ladder_applies(512, 0.24, None));
        assert!(ladder_applies(128, 0.0, None));
        assert!(!ladder_applies(1024, 0.24, None));
        assert!(!ladder_applies(512, 0.35, None));
        assert!(!ladder_applies(256, 0.1, relaxed));
    }
}
