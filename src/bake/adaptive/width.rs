//! The filter's width from the occluders' depth: the frequency analysis's
//! bound (occlusion from occluders at depth >= z_min is bandlimited in
//! space at Omega_h / z_min), and the depths the pre-pass needs from it.
//!
//! In: z_min, a receiver's footprint, [`AdaptiveOptions`]. Out: sigma in
//! world units and in texels, and the depths beyond which (or below
//! which) a nearer hit changes no receiver's filter.

use super::options::AdaptiveOptions;

/// Filter sigma in world units for an occluder depth bound: z_min / (2 mu
/// Omega_h); infinite for no occluder, 0 for contact or NaN.
#[inline]
pub fn filter_sigma(z_min: f32, mu: f32, omega_h: f32) -> f32 {
    let s = z_min / (2.0 * mu * omega_h);
    if s.is_nan() || s <= 0.0 { 0.0 } else { s }
}

/// Filter sigma in texels of a receiver with footprint `fp` for `z_min`:
/// [`filter_sigma`] over the footprint, at most `max_reach / 2`; 0 (not
/// filtered) below half a texel or inside geometry.
#[inline]
pub fn sigma_in_texels(z_min: f32, fp: f32, inside: bool, o: &AdaptiveOptions) -> f32 {
    let s = filter_sigma(z_min, o.mu, o.omega_h);
    // A texel size -> 0 filters as wide as allowed; a NaN one not at all.
    let t = if fp > 0.0 {
        s / fp
    } else if fp == 0.0 {
        f32::INFINITY
    } else {
        0.0
    };
    let t = t.min(o.max_reach as f32 / 2.0);
    if t.is_nan() || t < 0.5 || inside {
        0.0
    } else {
        t
    }
}

/// The occluder depth at which a receiver of footprint `fp` reaches its
/// widest filter ([`sigma_in_texels`] at `max_reach / 2`): z_min beyond it
/// changes nothing.
#[inline]
pub fn saturating_depth(fp: f32, o: &AdaptiveOptions) -> f32 {
    fp * o.max_reach as f32 * o.mu * o.omega_h
}

/// Twice the largest [`saturating_depth`] of the atlas's footprints (one
/// value for all, so z_min values cut at it compare equal); `max_distance`
/// when that is not positive and finite (no filter, or no footprint).
pub fn exact_depth(footprint: &[f32], o: &AdaptiveOptions, max_distance: f32) -> f32 {
    let fp = footprint
        .iter()
        .copied()
        .filter(|f| f.is_finite())
        .fold(0.0f32, f32::max);
    let d = 2.0 * saturating_depth(fp, o);
    if d > 0.0 && d.is_finite() {
        d.min(max_distance)
    } else {
        max_distance
    }
}

/// The two page-wide depths the pre-pass cuts its rays at, from every
/// receiver's footprint on the page (`exact_depth`, `contact_depth`).
/// A bake of part of a page (`--reuse`: only the texels an edit reaches)
/// takes them from the whole page, so its receivers trace what the whole
/// page's bake traces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Depths {
    pub exact: f32,
    pub contact: f32,
}

impl Depths {
    /// The depths of a page whose receivers have these footprints.
    pub fn of(footprint: &[f32], o: &AdaptiveOptions, max_distance: f32) -> Depths {
        Depths {
            exact: exact_depth(footprint, o, max_distance),
            contact: contact_depth(footprint, o),
        }
    }
}

/// The depth below which every receiver of the atlas is in contact
/// ([`sigma_in_texels`] 0 for its footprint, whoever's filter asks): the
/// smallest footprint's contact edge, fp mu Omega_h, less a rounding
/// margin. A z_min below it bounds nothing a nearer one would not: no
/// filter reaches such a receiver or starts from it. 0 when a footprint
/// is 0 (it filters at any depth); footprints that filter at no depth
/// (NaN, negative, infinite) do not count; infinite when none is left or
/// no filter is allowed (`max_reach` 0).
pub fn contact_depth(footprint: &[f32], o: &AdaptiveOptions) -> f32 {
    if (o.max_reach as f32) < 1.0 {
        return f32::INFINITY;
    }
    let fp = footprint
        .iter()
        .copied()
        .filter(|f| f.is_finite() && *f >= 0.0)
        .fold(f32::INFINITY, f32::min);
    fp * o.mu * o.omega_h * (1.0 - 1e-3)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigma_of_stiff_depths() {
        // z_min -> 0: no filtering; nothing hit: unbounded; NaN: 0.
        assert_eq!(filter_sigma(0.0, 0.7, 2.8), 0.0);
        assert_eq!(filter_sigma(f32::NAN, 0.7, 2.8), 0.0);
        assert_eq!(filter_sigma(f32::INFINITY, 0.7, 2.8), f32::INFINITY);
        assert!((filter_sigma(3.92, 0.7, 2.8) - 1.0).abs() < 1e-6);
        assert!(filter_sigma(1e-30, 0.7, 2.8) > 0.0);
        // In texels: capped at max_reach / 2 for far or no occluders and a
        // texel size -> 0; contact, NaN and inside receivers unfiltered.
        let o = AdaptiveOptions::default();
        let cap = o.max_reach as f32 / 2.0;
        assert_eq!(sigma_in_texels(f32::INFINITY, 0.01, false, &o), cap);
        assert_eq!(sigma_in_texels(1.0, 0.0, false, &o), cap);
        assert_eq!(sigma_in_texels(1.0, 1e-30, false, &o), cap);
        assert_eq!(sigma_in_texels(0.0, 0.01, false, &o), 0.0);
        assert_eq!(sigma_in_texels(f32::NAN, 0.01, false, &o), 0.0);
        assert_eq!(sigma_in_texels(1.0, f32::NAN, false, &o), 0.0);
        assert_eq!(sigma_in_texels(1.0, 0.01, true, &o), 0.0);
        // Half a texel is the contact threshold: z_min = 2 mu Omega_h x 0.5.
        let edge = 2.0 * o.mu * o.omega_h * 0.5;
        assert_eq!(sigma_in_texels(edge * 0.99, 1.0, false, &o), 0.0);
        assert!(sigma_in_texels(edge * 1.01, 1.0, false, &o) > 0.5);
    }

    #[test]
    fn z_min_is_exact_to_twice_the_widest_footprints_saturating_depth() {
        let o = AdaptiveOptions::default();
        // sigma_in_texels reaches max_reach / 2 at the saturating depth.
        let fp = 0.01f32;
        let z = saturating_depth(fp, &o);
        assert!((sigma_in_texels(z, fp, false, &o) - o.max_reach as f32 / 2.0).abs() < 1e-4);
        assert!(sigma_in_texels(0.9 * z, fp, false, &o) < o.max_reach as f32 / 2.0);
        // The widest finite footprint sets it; never beyond max_distance.
        let d = exact_depth(&[0.005, fp, f32::NAN, f32::INFINITY], &o, 10.0);
        assert!((d - 2.0 * z).abs() < 1e-6);
        assert_eq!(exact_depth(&[fp], &o, 0.1), 0.1);
        // Nothing to gain: no receivers, no filter, zero footprints.
        assert_eq!(exact_depth(&[], &o, 0.5), 0.5);
        assert_eq!(exact_depth(&[0.0], &o, 0.5), 0.5);
        let unfiltered = AdaptiveOptions {
            max_reach: 0,
            ..Default::default()
        };
        assert_eq!(exact_depth(&[fp], &unfiltered, 0.5), 0.5);
    }

    #[test]
    fn below_the_contact_depth_every_receiver_is_in_contact() {
        let o = AdaptiveOptions::default();
        let atlas = [
            0.003f32,
            0.0023,
            0.006,
            1e-30,
            1e30,
            f32::NAN,
            -1.0,
            f32::INFINITY,
        ];
        let c = contact_depth(&atlas, &o);
        // No receiver filters at it (nor, sigma rising with z_min, below it).
        for &fp in &atlas {
            assert_eq!(sigma_in_texels(c, fp, false, &o), 0.0, "{fp}");
        }
        // Tight: the smallest footprint filters just above it.
        let c = contact_depth(&[0.003, 0.0023, 0.006], &o);
        assert_eq!(sigma_in_texels(c, 0.0023, false, &o), 0.0);
        assert!(sigma_in_texels(1.01 * c, 0.0023, false, &o) >= 0.5);
        // A zero footprint filters at any depth: nothing is contact for sure.
        assert_eq!(contact_depth(&[0.003, 0.0], &o), 0.0);
        // Footprints that never filter, none, or no filter at all: every
        // depth is contact.
        assert_eq!(
            contact_depth(&[f32::NAN, -1.0, f32::INFINITY], &o),
            f32::INFINITY
        );
        assert_eq!(contact_depth(&[], &o), f32::INFINITY);
        let unfiltered = AdaptiveOptions {
            max_reach: 0,
            ..Default::default()
        };
        assert_eq!(contact_depth(&[0.003], &unfiltered), f32::INFINITY);
        let reach1 = AdaptiveOptions {
            max_reach: 1,
            ..Default::default()
        };
        assert!(contact_depth(&[0.003], &reach1).is_finite());
    }
}
