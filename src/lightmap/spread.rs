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
pub fn spread(receivers: &Receivers, bake: &Bake, fill: &[u32]) -> Result<Lightmap> {
    let layer = bake.visibility.as_ref().map(|l| &l.v);
    if let Some(r) = (0..receivers.len()).find(|&r| {
        !bake.ao[r].is_finite()
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
    let mut covered = vec![false; fill.len()];
    for &t in &receivers.texel {
        covered[t as usize] = true;
    }
    let pick = |t: &u32| (*t != NONE).then_some(*t as usize);
    Ok(Lightmap {
        width: receivers.width,
        height: receivers.height,
        ao: fill
            .par_iter()
            .map(|t| pick(t).map_or(1.0, |r| bake.ao[r]))
            .collect(),
        sh: fill
            .par_iter()
            .map(|t| pick(t).map_or([0.0; SH_COUNT], |r| bake.sh[r]))
            .collect(),
        covered,
        // A gutter texel far from any receiver: the open hemisphere of +z
        // would be as arbitrary; zero, as for the SH.
        visibility: layer.map(|v| {
            fill.par_iter()
                .map(|t| pick(t).map_or([0.0; VIS_COUNT], |r| v[r]))
                .collect()
        }),
    })
}
