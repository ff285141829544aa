//! The choice a small page offers the engine view (`--ladder view`):
//! which pages have one, and the atlases of the other options.
//!
//! In: the rule's pick (its atlas and [`Relaxed`]), the unwrapper's
//! prepared charts. Out: where the page offers a choice
//! ([`ladder_applies`]), the same charts packed the other ways worth
//! baking ([`alternatives`]); `job/level/ladder.rs` bakes each small and
//! keeps the one whose lookups read the least error.
//!
//! Why these options: the rule relaxes a page the asked options do not
//! fit or starve (under [`super::STARVED_UTILIZATION`]), and a starved
//! page's asked options read 1.4-4.5x the relaxed error, so those are
//! not baked again. Two choices the rule cannot make:
//!
//! - Between starved and comfortable: the flight helmet at 512 fits
//!   padding 2 at 24% of the page and reads 1.34x the error of a texel
//!   of padding; the Cesium tree at 256, 1.23x. Of the rungs below it, no
//!   padding (charts blending at their edges) and no minimum width
//!   (slivers) lost to a texel of each on every such page measured, so
//!   only that one is baked.
//! - No padding: the rule passes over a padding-1 rung that fits starved,
//!   but on the helmet at 128 padding 1 with no minimum width (18% of the
//!   page, 41 texels per unit) reads 0.95x the error of no padding (68).
//!
//! (`docs/measurements/chart-count.md`.)

use super::{Relaxed, UnwrapOptions, pack_rung, relaxed_options};
use crate::error::Result;

/// How a small page's padding and minimum chart width are chosen
/// (`--ladder`): `view`, where a small page offers a choice
/// ([`ladder_applies`]), by the engine view of a small bake of each option
/// (`job/level/ladder.rs`); `rule`, by
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
/// [`LADDER_UTILIZATION`] used, or relaxed to no padding (the padding-1
/// rungs the rule passed over as starved may read less error).
pub fn ladder_applies(resolution: u32, utilization: f32, relaxed: Option<Relaxed>) -> bool {
    resolution <= LADDER_MAX_EDGE
        && match relaxed {
            None => utilization < LADDER_UTILIZATION,
            Some(r) => r.padding == 0,
        }
}

/// The options the engine view weighs against the rule's pick (packed
/// as `picked`, at `density` texels per unit) on a page where
/// [`ladder_applies`]: as asked, the first of [`relaxed_options`] (a
/// texel of padding, charts at least a texel wide); relaxed to no
/// padding, every rung with a texel of padding, starved or not. Each as
/// the rule packs its rungs (taken from `packed` where the rule packed it
/// already), where it holds the charts on one
/// `resolution` page, less those another option dominates ([`dominated`]).
pub(super) fn alternatives(
    resolution: u32,
    picked: Option<Relaxed>,
    density: f32,
    options: &UnwrapOptions,
    mut packed: Packed,
) -> Result<Vec<(uvunwrap::Atlas, Relaxed)>> {
    let rungs = relaxed_options(options.padding, options.min_chart_width);
    let tried: Vec<Relaxed> = match picked {
        None => rungs.into_iter().take(1).collect(),
        Some(_) => rungs.into_iter().filter(|r| r.padding == 1).collect(),
    };
    let mut out = Vec::new();
    for r in tried {
        let same = |(p, _): &(Relaxed, uvunwrap::Atlas)| {
            (p.padding, p.min_chart_width) == (r.padding, r.min_chart_width)
        };
        let a = match packed.passed.iter().position(same) {
            Some(k) => packed.passed.swap_remove(k).1,
            None => pack_rung(&r, resolution, options, packed.opts, packed.generate)?,
        };
        if a.page_count <= 1 {
            let starved = picked.is_none_or(|p| p.starved);
            out.push((a, Relaxed { starved, ..r }));
        }
    }
    let rung = |r: &Relaxed| (r.padding, r.min_chart_width);
    let pick = picked.map_or((options.padding, options.min_chart_width), |p| rung(&p));
    let all: Vec<((u32, f32), f32)> = std::iter::once((pick, density))
        .chain(out.iter().map(|(a, r)| (rung(r), a.texels_per_unit)))
        .collect();
    let mut k = 0;
    out.retain(|_| {
        k += 1;
        !dominated(all[k], &all)
    });
    Ok(out)
}

/// What the rule's ladder packed: the rungs it passed over (or took and
/// then replaced), which [`alternatives`] weighs without packing again,
/// and how to pack the others.
pub(super) struct Packed<'a> {
    pub passed: Vec<(Relaxed, uvunwrap::Atlas)>,
    pub opts: &'a uvunwrap::Options,
    pub generate:
        &'a dyn Fn(&uvunwrap::Options) -> std::result::Result<uvunwrap::Atlas, uvunwrap::Error>,
}

/// Whether option `o` ((padding, minimum width), texels per unit) is
/// dominated by another of `all`: one with at least its padding and
/// width and at least its density reads every texel it reads, with no
/// fewer texels between charts, so it is never worse and need not be
/// baked.
fn dominated(o: ((u32, f32), f32), all: &[((u32, f32), f32)]) -> bool {
    let ((p, w), d) = o;
    all.iter()
        .any(|&((ap, aw), ad)| ap >= p && aw >= w && ad >= d && (ap, aw) != (p, w))
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
        let none = Some(Relaxed {
            padding: 0,
            min_chart_width: 0.0,
            starved: false,
        });
        assert!(ladder_applies(128, 0.5, none));
        assert!(!ladder_applies(1024, 0.5, none));
    }

    #[test]
    fn an_option_with_no_less_padding_width_or_density_dominates() {
        let all = [
            ((2, 2.0), 180.0),
            ((1, 1.0), 309.0),
            ((1, 0.0), 309.0),
            ((0, 0.0), 308.0),
        ];
        let dominated_at = |k: usize| dominated(all[k], &all);
        assert!(!dominated_at(0) && !dominated_at(1));
        // Width 0 at the density of width 1; no padding at less.
        assert!(dominated_at(2) && dominated_at(3));
        // Denser by a texel per unit: weighed, not dominated.
        let denser = [((1, 1.0), 309.0), ((1, 0.0), 310.0)];
        assert!(!dominated(denser[1], &denser));
    }
}
