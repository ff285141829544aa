//! A bake of part of a page (`--reuse`: only the texels an edit reaches):
//! which texels of its lightmap are known, and whether they hold every
//! texel the edit can change.
//!
//! In: the lightmap [`super::build`] made with receivers not known (NaN,
//! see its doc for how NaN travels) and the texels an edit can change
//! ([`super::seams::Stitched::may_change`]). Out: the texels made NaN next to those not known
//! (`unknown_cells_to_nan`), and the texels that may change but are not
//! known ([`missing`]): none, and every texel outside the known ones
//! keeps its earlier bake's value.

use super::Lightmap;
use super::seams::{Anchor, reach};
use crate::sh::{SH_COUNT, VIS_COUNT};
use rayon::prelude::*;

/// Makes NaN (every channel) each texel that shares a bilinear cell with
/// one whose AO is NaN; returns per texel whether its value is known
/// (finite) after.
pub(crate) fn unknown_cells_to_nan(lm: &mut Lightmap) -> Vec<bool> {
    let nan: Vec<bool> = lm.ao.iter().map(|a| a.is_nan()).collect();
    let known: Vec<bool> = (reach(&nan, lm.width, lm.height, 1).iter())
        .map(|&n| !n)
        .collect();
    for (t, _) in known.iter().enumerate().filter(|&(_, &k)| !k) {
        lm.ao[t] = f32::NAN;
        lm.sh[t] = [f32::NAN; SH_COUNT];
        if let Some(v) = &mut lm.visibility {
            v[t] = [f32::NAN; VIS_COUNT];
        }
    }
    known
}

/// The texels an edit can change that `lm` does not know (NaN):
/// `may_change` marks the texels it can change (the changed ones and those
/// the solves carry a change to: [`super::seams::Stitched::may_change`]).
/// With none, the known texels written over the earlier bake's give the
/// whole page's bake.
pub fn missing(lm: &Lightmap, may_change: &[bool]) -> Vec<bool> {
    (0..lm.ao.len())
        .into_par_iter()
        .map(|t| may_change[t] && !lm.ao[t].is_finite())
        .collect()
}

/// The border fit's rows of a page of which part is known: `traced`
/// (index among the points traced, row) put back among the points in
/// their order (`uvs`, with `unknown` marking the points not traced), each
/// untraced point a row of NaN targets (`channels`) at its UV of `weight`.
/// Traced points left out (inside geometry) stay out.
pub(crate) fn with_nan_rows(
    uvs: impl Iterator<Item = [f32; 2]>,
    unknown: &[bool],
    traced: impl Iterator<Item = (usize, Anchor)>,
    channels: usize,
    weight: f32,
) -> Vec<Anchor> {
    let mut traced = traced.peekable();
    let mut out = Vec::with_capacity(unknown.len());
    let mut k = 0;
    for (uv, &u) in uvs.zip(unknown) {
        if u {
            let target = vec![f32::NAN; channels];
            out.push(Anchor { uv, target, weight });
            continue;
        }
        if let Some((_, row)) = traced.next_if(|(j, _)| *j == k) {
            out.push(row);
        }
        k += 1;
    }
    out
}
