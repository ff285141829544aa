//! Spread: per-receiver results over every texel of the page.
//!
//! In: a page's [`Receivers`], their [`Bake`] and the fill map
//! ([`super::dilate::fill_map`]: the receiver each texel shows). Out: the
//! float [`Lightmap`] (AO, the 9 SH coefficients and the visibility layer
//! at every texel, and which texels are covered).

use super::Lightmap;
use super::dilate::NONE;
use crate::atlas::Receivers;
use crate::bake::Bake;
use crate::error::{Error, Result};
use crate::sh::{SH_COUNT, VIS_COUNT};
use rayon::prelude::*;

/// Spreads receiver results over the image through the dilation map.
/// Fails if any value is NaN or infinite (it must never reach a texture).
/// `known`: per receiver, whether its result was baked (a bake of part of
/// a page): a texel that shows a receiver not known is NaN in every
/// channel, which the later stages carry as "not known" ([`super::build`]).
pub fn spread(
    receivers: &Receivers,
    bake: &Bake,
    fill: &[u32],
    known: Option<&[bool]>,
) -> Result<Lightmap> {
    let layer = bake.visibility.as_ref().map(|l| &l.v);
    let known = |r: usize| known.is_none_or(|k| k[r]);
    if let Some(r) = (0..receivers.len()).find(|&r| {
        known(r) && !bake.ao[r].is_finite()
            || !bake.sh[r].iter().all(|c| c.is_finite())
            || layer.is_some_and(|v| !v[r].iter().all(|c| c.is_finite()))
    }) {
        let t = receivers.texel[r];
        return Err(Error::Encode(format!(
            "non-finite result at texel ({}, {})",
            t % receivers.width,
            t / receivers.width
        )));
    }
    let nan = f32::NAN;
    Ok(Lightmap {
        width: receivers.width,
        height: receivers.height,
        ao: shown(fill, 1.0, |r| if known(r) { bake.ao[r] } else { nan }),
        sh: shown(fill, [0.0; SH_COUNT], |r| match known(r) {
            true => bake.sh[r],
            false => [nan; SH_COUNT],
        }),
        covered: covered(receivers),
        // A gutter texel far from any receiver: the open hemisphere of +z
        // would be as arbitrary; zero, as for the SH.
        visibility: layer.map(|v| {
            shown(fill, [0.0; VIS_COUNT], |r| match known(r) {
                true => v[r],
                false => [nan; VIS_COUNT],
            })
        }),
    })
}

/// Per texel of the page, whether a receiver lies in it.
pub(crate) fn covered(receivers: &Receivers) -> Vec<bool> {
    let mut covered = vec![false; (receivers.width * receivers.height) as usize];
    for &t in &receivers.texel {
        covered[t as usize] = true;
    }
    covered
}

/// Per texel, `value` of the receiver it shows in `fill`
/// ([`super::dilate::fill_map`]), `gutter` where it shows none.
pub(crate) fn shown<T: Copy + Send + Sync>(
    fill: &[u32],
    gutter: T,
    value: impl Fn(usize) -> T + Sync,
) -> Vec<T> {
    fill.par_iter()
        .map(|&r| if r == NONE { gutter } else { value(r as usize) })
        .collect()
}
