//! A page an edit reaches, rebaked texel by texel (`--reuse PREV`,
//! `--rebake changed`): only the receivers near the texels the edit can
//! change are baked, the lightmap stage knows only what they decide, and
//! the known texels are written over PREV's images.
//!
//! In: a [`Page`] carrying PREV's images, solve range and inside marks,
//! its dirty receivers, the edit's boxes and the settings. Out: the part's
//! [`BakePasses`] and the page's [`PageOutput`], whose images are the
//! bytes a bake of the whole page writes; or why the page must be baked
//! whole.
//!
//! Why it is exact: a receiver's value reads only receivers within
//! [`PageWide::halo`] texels once the page-wide numbers are carried
//! ([`Page::bake_part`]); the lightmap stage carries "not known" as NaN
//! ([`crate::lightmap::build`]); and [`known::missing`] checks that every
//! texel the edit can change is known. Every other texel is PREV's, and
//! PREV's bytes decode and encode back to themselves on PREV's ranges.

use super::carry;
use super::page::{BakePasses, Page, PageOutput};
use crate::bake::adaptive::PageWide;
use crate::error::Result;
use crate::job::settings::{BakeSettings, Method, RunOptions};
use crate::lightmap::seams::reach as grow;
use crate::lightmap::{Filter, dilate, known};
use crate::stage::StageTimer;

/// Texels past the halo that the first part reaches beyond the changed
/// texels, for the solve's rows around them.
const MARGIN: u32 = 16;

/// Parts tried, each grown by what the one before did not know, before
/// the page is baked whole.
const ATTEMPTS: u32 = 3;

/// The largest share of a page's receivers the parts may hold together
/// (each is baked from scratch): past it, the parts' bakes and the
/// lightmap stage's passes over the whole page cost about what baking the
/// page whole costs.
const MOST_OF_PAGE: f64 = 0.4;

/// A fit point next to a receiver lies within this many of its
/// footprints (a cell's diagonal and the conservative edge's offset).
const POINT_REACH: f32 = 2.0;

/// What [`rebake`] made of a page.
pub(crate) struct Rebaked {
    pub passes: BakePasses,
    pub out: PageOutput,
    /// The receivers baked.
    pub baked: usize,
}

/// Rebakes only the texels of `page` that the edit (`boxes`, the changed
/// nodes' world boxes) can change; `Ok(Err(why))` when the page must be
/// baked whole.
pub(crate) fn rebake(
    page: &Page,
    boxes: &[Option<[f64; 6]>],
    s: &BakeSettings,
    run: &RunOptions,
    timer: &mut StageTimer,
) -> Result<std::result::Result<Rebaked, String>> {
    let level = page.level;
    let c = &page.carry;
    let (Some(images), Some(_), Some(runs)) = (&c.images, &c.solve_range, &c.inside) else {
        return Ok(Err("PREV does not record the page's solve".into()));
    };
    if s.filter != Filter::Bilinear || s.method == Method::Sheared {
        return Ok(Err("bicubic pages and the sheared filter bake whole".into()));
    }
    if !level.cross_seams.is_empty() {
        return Ok(Err("the page has seams to other pages".into()));
    }
    let r = &page.receivers;
    let (w, h) = (r.width, r.height);
    let Some(marked) = carry::inside_texels(runs, (w * h) as usize) else {
        return Ok(Err("PREV's inside marks do not read".into()));
    };
    let prev_inside: Vec<bool> = r.texel.iter().map(|&t| marked[t as usize]).collect();
    let space = &level.geometry.space;
    let wide = carry::dirty_within(r, boxes, space, level.max_distance, POINT_REACH);
    let mut changed = vec![false; (w * h) as usize];
    for (&t, &d) in r.texel.iter().zip(&wide) {
        changed[t as usize] |= d;
    }
    let reach = PageWide::halo(&s.adaptive) + MARGIN;
    // The texels the part must know: the changed ones, then those the
    // check finds missing and those the solve says the values that may
    // change read (its reach in rows, along the charts' bands, across
    // seams and gutters), until none is missing or the page is whole.
    let mut need = changed.clone();
    let before = dilate::fill_map(w, h, &r.texel, &prev_inside);
    let mut attempt = 0;
    let mut spent = 0;
    let (part, passes, inside, built) = loop {
        attempt += 1;
        // The first part a margin past the halo; then what the solve
        // said its values read, the halo past it.
        let reach = reach - if attempt > 1 { MARGIN } else { 0 };
        let near = grow(&grow(&need, w, h, 1), w, h, reach);
        let part: Vec<u32> = (0..r.len() as u32)
            .filter(|&j| near[r.texel[j as usize] as usize])
            .collect();
        if (spent + part.len()) as f64 > MOST_OF_PAGE * r.len() as f64 {
            return Ok(Err(format!(
                "the edit's reach asks for a part of {} of the page's {} receivers, after {spent} baked",
                part.len(),
                r.len()
            )));
        }
        spent += part.len();
        let passes = page.bake_part(&part, s, run, timer)?;
        // The page's inside marks: PREV's, the part's own over them.
        let mut inside = prev_inside.clone();
        let own = passes.inside(page);
        for (k, &j) in part.iter().enumerate() {
            inside[j as usize] = match own.len() == part.len() {
                true => own[k],
                false => own.get(j as usize).copied().unwrap_or(false),
            };
        }
        // Texels whose fill changes, or shows a dirty receiver, change too.
        let after = dilate::fill_map(w, h, &r.texel, &inside);
        for (t, (&a, &b)) in before.iter().zip(&after).enumerate() {
            changed[t] |= a != b || (b != dilate::NONE && wide[b as usize]);
        }
        let built = page.lightmap_part(&part, &passes, &inside, &changed, s, timer)?;
        let missing = match &built.may_change {
            Some(may_change) => known::missing(&built.lightmap, may_change),
            None => (changed.iter().zip(&built.lightmap.ao))
                .map(|(&c, a)| c && !a.is_finite())
                .collect(),
        };
        let count = missing.iter().filter(|&&m| m).count();
        if count == 0 {
            break (part, passes, inside, built);
        }
        if attempt == ATTEMPTS {
            return Ok(Err(format!(
                "the edit's reach leaves the part ({count} texels after {ATTEMPTS} parts, the last of {} receivers)",
                part.len()
            )));
        }
        let reads = built.reads.as_deref().unwrap_or(&[]);
        for (t, (&m, &c)) in missing.iter().zip(&changed).enumerate() {
            need[t] |= m || c || reads.get(t).copied().unwrap_or(false);
        }
    };
    // PREV's texels, the known ones written over them.
    timer.restart();
    let mut lm = crate::encode::decode(images)?;
    let new = built.lightmap;
    if lm.ao.len() != new.ao.len() || lm.visibility.is_some() != new.visibility.is_some() {
        return Ok(Err("PREV's images do not match the page".into()));
    }
    for t in (0..new.ao.len()).filter(|&t| new.ao[t].is_finite()) {
        lm.ao[t] = new.ao[t];
        lm.sh[t] = new.sh[t];
        if let (Some(to), Some(from)) = (&mut lm.visibility, &new.visibility) {
            to[t] = from[t];
        }
    }
    lm.covered = new.covered;
    let mut encoded = crate::encode::encode_in(&lm, s.visibility_order, c.ranges.as_ref())?;
    encoded.scale = c.scale;
    encoded.solve_range = built.solve_range;
    encoded.inside = Some(carry::inside_runs(&r.texel, &inside));
    timer.lap("encode");
    let engine_view = page.engine_view(&encoded, s, run)?;
    let out = PageOutput {
        lightmap: lm,
        encoded,
        seams: None,
        border: None,
        engine_view,
    };
    Ok(Ok(Rebaked {
        passes,
        out,
        baked: part.len(),
    }))
}
