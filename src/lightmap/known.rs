//! A bake of part of a page (`--reuse`: only the texels an edit reaches):
//! which texels of its lightmap are known, and whether they hold every
//! texel the edit can change.
//!
//! In: the lightmap [`super::build`] made with receivers not known (NaN,
//! see its doc for how NaN travels), the solve's components
//! ([`super::seams::Stitched::components`]) and the texels whose inputs an
//! edit changed. Out: the texels made NaN next to those not known
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

/// The texels an edit can change that `lm` does not know (NaN): `changed`
/// marks the texels whose inputs the edit changes (their values before
/// the solve, the fit points and edge rows in their cells). A texel's
/// value after the stitch depends on its value, on the first solve's
/// component it is in, on whether it is solved again (the first solve's
/// values within two texels) and on the second solve's component. So an
/// edit can change: S1, the first solve's components with a texel within
/// one of a changed one (a row reads its cell's four taps); W, the texels
/// within two of S1 and the changed ones; S2, the second solve's
/// components with a texel within one of W. Returns per texel whether it
/// is in W or S2 and NaN: with none, the known texels written over the
/// earlier bake's give the whole page's bake.
pub fn missing(
    lm: &Lightmap,
    components: &[(Vec<u32>, Vec<u32>); 2],
    changed: &[bool],
) -> Vec<bool> {
    let n = lm.ao.len();
    let grow = |mask: &[bool], by: u32| reach(mask, lm.width, lm.height, by);
    // The components with a texel in `near`, and every texel of them.
    let touched = |(texels, component): &(Vec<u32>, Vec<u32>), near: &[bool]| {
        let count = component.iter().map(|&c| c as usize + 1).max().unwrap_or(0);
        let mut hit = vec![false; count];
        for (&t, &c) in texels.iter().zip(component) {
            hit[c as usize] |= near[t as usize];
        }
        let mut out = vec![false; n];
        for (&t, &c) in texels.iter().zip(component) {
            out[t as usize] = hit[c as usize];
        }
        out
    };
    let s1 = touched(&components[0], &grow(changed, 1));
    let either: Vec<bool> = s1.iter().zip(changed).map(|(&a, &b)| a || b).collect();
    let within = grow(&either, 2);
    let s2 = touched(&components[1], &grow(&within, 1));
    (0..n)
        .into_par_iter()
        .map(|t| (within[t] || s2[t]) && !lm.ao[t].is_finite())
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
