//! The visibility layer: the visibility itself projected on SH, without
//! the normal's cosine, so an engine can relight a normal-mapped normal or
//! a glossy lobe (the paper's split of occlusion f, precomputed, from the
//! BRDF k, evaluated per pixel).
//!
//! In: [`Receivers`], a [`Tracer`], a ray count per receiver and
//! [`BakeParams`] (and for [`shares_cap_band`] the receivers' cap sums of
//! their cosine-weighted rays, [`CapSums`]). Out: per receiver the
//! occluded share above its geometric plane (less, 16 coefficients) from
//! stratified uniform-hemisphere rays around its shading normal n
//! ([`shares`], Monte Carlo's), or from its own cosine-weighted rays in the
//! cap and uniform rays in the band at the horizon ([`shares_cap_band`],
//! the adaptive bake's and the border fit's), which the adaptive method
//! filters like its SH; [`finish`] turns a share into
//! v_i = Int V(w) H(n.w) Y_i(w) dw.
//!
//! The integrand has no cosine, so the rays are uniform in solid angle
//! (weight 2 pi / M each): the bake's cosine-weighted rays with a pi / cos
//! weight have infinite variance at the horizon. The lune of n's
//! hemisphere below the geometric plane (occluded without tracing) is
//! projected exactly ([`sh::below_plane_visibility`]) and its rays are not
//! counted, so none of their sampling error is left; the rest is the open
//! projection less the occluded rays' share, with the open projection as a
//! control variate weighted by the visible fraction, as for the SH
//! ([`sh::occluded_share`]): open and closed receivers are exact at any ray
//! count.

use super::{BakeParams, ReceiverRays};
use crate::atlas::Receivers;
use crate::sample::uniform_hemisphere;
use crate::sh::{self, VIS_COUNT};
use crate::trace::{RayBatch, Tracer, for_each_receiver};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// The receiver sequence of the visibility rays (the bake's is stream 0,
/// the sheared method's sparse pass stream 1).
pub(crate) const VISIBILITY_STREAM: u64 = 2;

/// Receivers per batch of rays (and parallel work item).
const CHUNK: usize = 64;

/// The visibility layer of every receiver, and the rays it cost.
#[derive(Clone, Debug, Default)]
pub struct Visibility {
    /// Per receiver: v_0..v_15.
    pub v: Vec<[f32; VIS_COUNT]>,
    pub rays: u64,
}

/// The angle between the shading normal n and the geometric normal, in
/// [0, pi] (0 for non-finite input).
#[inline]
fn tilt(n: Vec3, geo: Vec3) -> f32 {
    let a = n.cross(geo).length().atan2(n.dot(geo));
    if a.is_finite() { a } else { 0.0 }
}

/// Receiver `r`'s `rays` stratified uniform rays around its shading
/// normal over the zone where cos theta < `top` (1: the whole hemisphere;
/// [`CAP_COS`]: the band), from point `first` of its sequence on, those at
/// or below its geometric plane left out (they add nothing: [`share`]
/// counts the solid angle above).
fn emit_rays(
    receivers: &Receivers,
    r: usize,
    first: u32,
    rays: u32,
    top: f32,
    p: &BakeParams,
    batch: &mut RayBatch,
) {
    let geo = receivers.geo_normal[r];
    let sequence = ReceiverRays::with_stream(receivers, r, p.seed, VISIBILITY_STREAM);
    for i in first..first + rays {
        let u = sequence.point(i);
        let dir = sequence
            .frame
            .to_world(uniform_hemisphere(Vec2::new(u.x * top, u.y)))
            .normalize();
        if dir.dot(geo) > 0.0 {
            batch.push(sequence.origin, dir, p.max_distance);
        }
    }
}

/// Receiver `r`'s occluded share above its geometric plane (less), from
/// its rays above the plane ([`emit_rays`]'s) and whether each is
/// occluded.
pub fn share(
    receivers: &Receivers,
    r: usize,
    directions: &[Vec3],
    occluded_rays: &[bool],
) -> [f32; VIS_COUNT] {
    let (n, geo) = (receivers.normal[r], receivers.geo_normal[r]);
    let (above, mut visible) = (directions.len() as u32, 0u32);
    let mut occluded = [0.0f32; VIS_COUNT];
    let mut all = [0.0f32; VIS_COUNT];
    let sums = (&mut all, &mut occluded, &mut visible);
    add_rays(sums, 1.0, directions, occluded_rays);
    let open_above = open_above(n, geo);
    // Solid angle above the plane: the hemisphere's 2 pi less the lune's
    // 2 theta, shared by the rays that went there.
    let (per_ray, seen) = if above > 0 {
        let solid = 2.0 * (std::f32::consts::PI - tilt(n, geo));
        (solid / above as f32, visible as f32 / above as f32)
    } else {
        (0.0, 1.0)
    };
    sh::occluded_share(&open_above, &occluded, &all, per_ray, seen)
}

/// Adds `weight` Y_i(w) of every ray w of `directions` to `all`, and of
/// the occluded ones (`occluded_rays`) to `occluded`; counts the visible.
#[inline]
fn add_rays(
    (all, occluded, visible): (&mut [f32; VIS_COUNT], &mut [f32; VIS_COUNT], &mut u32),
    weight: f32,
    directions: &[Vec3],
    occluded_rays: &[bool],
) {
    for (&dir, &hit) in directions.iter().zip(occluded_rays) {
        let y = sh::basis16(dir);
        for (a, y) in all.iter_mut().zip(y) {
            *a += weight * y;
        }
        if hit {
            for (o, y) in occluded.iter_mut().zip(y) {
                *o += weight * y;
            }
        } else {
            *visible += 1;
        }
    }
}

/// The open hemisphere's projection around shading normal `n`, less the
/// lune below the geometric plane `geo`: what the layer's rays above the
/// plane estimate.
#[inline]
fn open_above(n: Vec3, geo: Vec3) -> [f32; VIS_COUNT] {
    let open = sh::open_visibility(n);
    let below = sh::below_plane_visibility(n, geo);
    std::array::from_fn(|i| open[i] - below[i])
}

/// Every receiver's [`share`], receiver r with `rays(r)` rays (0: open).
pub fn shares(
    receivers: &Receivers,
    tracer: &Tracer,
    rays: impl Fn(usize) -> u32 + Sync,
    p: &BakeParams,
) -> Vec<[f32; VIS_COUNT]> {
    shares_from(receivers, tracer, |r| (0, rays(r)), p)
}

/// [`shares`] from later points of the receivers' sequences: receiver r
/// with the rays `span(r)` = (first point, count).
pub fn shares_from(
    receivers: &Receivers,
    tracer: &Tracer,
    span: impl Fn(usize) -> (u32, u32) + Sync,
    p: &BakeParams,
) -> Vec<[f32; VIS_COUNT]> {
    traced_shares(
        receivers,
        tracer,
        &span,
        1.0,
        p,
        |r, directions, occluded| share(receivers, r, directions, occluded),
    )
}

/// Per receiver r, `share(r, directions, occluded)` of its rays `span(r)`
/// = (first point, count) of the layer's sequence, uniform where
/// cos theta < `top` ([`emit_rays`]).
fn traced_shares(
    receivers: &Receivers,
    tracer: &Tracer,
    span: &(impl Fn(usize) -> (u32, u32) + Sync),
    top: f32,
    p: &BakeParams,
    share: impl Fn(usize, &[Vec3], &[bool]) -> [f32; VIS_COUNT] + Sync,
) -> Vec<[f32; VIS_COUNT]> {
    let mut out = vec![[0.0f32; VIS_COUNT]; receivers.len()];
    for_each_receiver(
        tracer,
        &mut out,
        CHUNK,
        |r, _, batch| {
            let (first, rays) = span(r);
            emit_rays(receivers, r, first, rays, top, p, batch)
        },
        |r, out, directions, occluded| *out = share(r, directions, occluded),
        &|_| {},
    );
    out
}

/// v = the open hemisphere's projection, less the lune below the
/// geometric plane, plus the (filtered) occluded share above, for each
/// receiver.
pub fn finish(receivers: &Receivers, shares: Vec<[f32; VIS_COUNT]>) -> Vec<[f32; VIS_COUNT]> {
    shares
        .into_par_iter()
        .enumerate()
        .map(|(r, s)| {
            let (n, geo) = (receivers.normal[r], receivers.geo_normal[r]);
            let (open, below) = (sh::open_visibility(n), sh::below_plane_visibility(n, geo));
            std::array::from_fn(|i| open[i] - below[i] + s[i])
        })
        .collect()
}

/// The Monte Carlo layer: `rays` uniform rays per receiver, unfiltered.
pub fn bake(receivers: &Receivers, tracer: &Tracer, rays: u32, p: &BakeParams) -> Visibility {
    let s = shares(receivers, tracer, |_| rays, p);
    Visibility {
        v: finish(receivers, s),
        rays: receivers.len() as u64 * rays as u64,
    }
}

/// Where the layer takes the bake's own rays: the cap of n's hemisphere
/// with cos theta >= `CAP_COS`. There a cosine-weighted ray estimates the
/// cosine-free integrand with weight pi / cos theta, bounded by
/// pi / `CAP_COS`; towards the horizon that weight grows without bound
/// (infinite variance), so the band below the cap takes uniform rays of
/// its own ([`band_rays`]). At 0.25 the band is a quarter of the
/// hemisphere's solid angle and a cap ray's weight at most twice a
/// uniform ray's (`docs/visibility.md`, the cap from the bake's rays;
/// `docs/measurements/constants.md`, CAP_COS).
pub const CAP_COS: f32 = 0.25;

/// How many times fewer band rays a receiver gets than its cosine-weighted
/// ones, and the fewest: the band's quarter of the solid angle then sees
/// the density of uniform rays over the whole hemisphere at half the
/// cosine count, as before the cap took the bake's rays.
pub const BAND_DIVISOR: u32 = 8;
pub const MIN_BAND_RAYS: u32 = 4;

/// The band rays of a receiver with `rays` cosine-weighted ones.
#[inline]
pub const fn band_rays(rays: u32) -> u32 {
    let band = rays / BAND_DIVISOR;
    if band > MIN_BAND_RAYS {
        band
    } else {
        MIN_BAND_RAYS
    }
}

/// A receiver's cosine-weighted rays above its geometric plane, summed for
/// the layer: how many and how many visible, and over those in the cap
/// ([`CAP_COS`]) Y_i(w) / cos theta, of the visible and of the occluded.
#[derive(Clone, Copy, Debug, Default)]
pub struct CapSums {
    pub above: u32,
    pub visible: u32,
    pub open: [f32; VIS_COUNT],
    pub occluded: [f32; VIS_COUNT],
}

impl CapSums {
    /// Adds cosine-weighted ray `d` (above the geometric plane) of a
    /// receiver with shading normal `n`.
    #[inline]
    pub fn add(&mut self, n: Vec3, d: Vec3, occluded: bool) {
        self.above += 1;
        if !occluded {
            self.visible += 1;
        }
        let c = d.dot(n);
        if c >= CAP_COS {
            let (y, w) = (sh::basis16(d), 1.0 / c);
            let sum = if occluded {
                &mut self.occluded
            } else {
                &mut self.open
            };
            for (s, y) in sum.iter_mut().zip(y) {
                *s += w * y;
            }
        }
    }
}

/// Each receiver's state of `states` paired with its cap sums in `cap`
/// (none past `cap`'s end: empty without the layer), for the passes that
/// sum the cap beside their own sums.
pub fn with_caps<'a, T>(
    states: &'a mut [T],
    cap: &'a mut [CapSums],
) -> Vec<(&'a mut T, Option<&'a mut CapSums>)> {
    let caps = cap
        .iter_mut()
        .map(Some)
        .chain(std::iter::repeat_with(|| None));
    states.iter_mut().zip(caps).collect()
}

/// Receiver `r`'s occluded share above its geometric plane (less), as
/// [`share`], from two estimates: the cap's from its `cosine` cosine-weighted
/// rays' `cap` sums, the band's from its `band` uniform band rays (of
/// which `directions` and `occluded_rays` are those above the plane);
/// with the open projection above the plane as the control variate,
/// weighted by the visible fraction of all those rays.
pub fn share_cap_band(
    receivers: &Receivers,
    r: usize,
    cap: &CapSums,
    cosine: u32,
    band: u32,
    directions: &[Vec3],
    occluded_rays: &[bool],
) -> [f32; VIS_COUNT] {
    use std::f32::consts::PI;
    let (n, geo) = (receivers.normal[r], receivers.geo_normal[r]);
    let cap_per = PI / cosine.max(1) as f32;
    let band_per = 2.0 * PI * CAP_COS / band.max(1) as f32;
    let mut all: [f32; VIS_COUNT] =
        std::array::from_fn(|i| (cap.open[i] + cap.occluded[i]) * cap_per);
    let mut occluded: [f32; VIS_COUNT] = std::array::from_fn(|i| cap.occluded[i] * cap_per);
    let mut visible = cap.visible;
    let sums = (&mut all, &mut occluded, &mut visible);
    add_rays(sums, band_per, directions, occluded_rays);
    let above = cap.above + directions.len() as u32;
    let seen = if above > 0 {
        visible as f32 / above as f32
    } else {
        1.0
    };
    sh::occluded_share(&open_above(n, geo), &occluded, &all, 1.0, seen)
}

/// Every receiver's [`share_cap_band`]: receiver r with its cap sums
/// `cap[r]` over `cosine(r)` cosine-weighted rays, and the band rays
/// `band(r)` = (first point, count) of the layer's sequence.
pub fn shares_cap_band(
    receivers: &Receivers,
    tracer: &Tracer,
    cap: &[CapSums],
    cosine: impl Fn(usize) -> u32 + Sync,
    band: impl Fn(usize) -> (u32, u32) + Sync,
    p: &BakeParams,
) -> Vec<[f32; VIS_COUNT]> {
    traced_shares(
        receivers,
        tracer,
        &band,
        CAP_COS,
        p,
        |r, directions, occluded| {
            let count = band(r).1;
            share_cap_band(
                receivers,
                r,
                &cap[r],
                cosine(r),
                count,
                directions,
                occluded,
            )
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::{Frame, cosine_hemisphere};
    use glam::Vec3A;

    /// One receiver at the origin, geometric normal +z, shading normal
    /// tilted `deg` degrees towards +x.
    fn receiver(deg: f32) -> Receivers {
        let a = deg.to_radians();
        Receivers {
            width: 1,
            height: 1,
            texel: vec![0],
            position: vec![Vec3::ZERO],
            normal: vec![Vec3::new(a.sin(), 0.0, a.cos())],
            geo_normal: vec![Vec3::Z],
            footprint: vec![1e-3],
            center_inside: vec![true],
            ..Default::default()
        }
    }

    /// The receiver's `k` cosine-weighted rays' cap sums, a ray occluded
    /// where `occluded(w)`.
    fn cap_of(r: &Receivers, k: u32, occluded: impl Fn(Vec3) -> bool) -> CapSums {
        let rays = ReceiverRays::new(r, 0, 7);
        let mut cap = CapSums::default();
        for i in 0..k {
            let d = rays
                .frame
                .to_world(cosine_hemisphere(rays.point(i)))
                .normalize();
            if d.dot(r.geo_normal[0]) > 0.0 {
                cap.add(r.normal[0], d, occluded(d));
            }
        }
        cap
    }

    #[test]
    fn closed_and_open_receivers_are_exact_at_any_count() {
        // All occluded: the share is the whole open projection above the
        // plane, less; none: nothing. Both whatever the rays, tilted to
        // grazing (the lune reaching into the cap).
        for deg in [0.0, 40.0, 85.0] {
            let r = receiver(deg);
            let (n, geo) = (r.normal[0], r.geo_normal[0]);
            let open = sh::open_visibility(n);
            let below = sh::below_plane_visibility(n, geo);
            let band: Vec<Vec3> = (0..5)
                .map(|i| {
                    let u = Vec2::new(0.05 + 0.04 * i as f32, 0.13 * i as f32);
                    Frame::from_normal(n).to_world(uniform_hemisphere(u))
                })
                .filter(|d| d.dot(geo) > 0.0)
                .collect();
            // Every ray, cap and band, occluded or every ray visible.
            let all_rays = |occluded: bool| {
                let cap = cap_of(&r, 16, |_| occluded);
                share_cap_band(&r, 0, &cap, 16, 5, &band, &vec![occluded; band.len()])
            };
            let (closed, clear) = (all_rays(true), all_rays(false));
            for i in 0..VIS_COUNT {
                assert!((closed[i] + open[i] - below[i]).abs() < 1e-4, "{deg} v{i}");
                assert_eq!(clear[i], 0.0, "{deg} v{i}");
            }
        }
    }

    #[test]
    fn a_receiver_beside_a_wall_matches_quadrature_from_the_cap_and_the_band() {
        // A wall x = -0.05 occludes the directions with w.x < 0; the
        // shading normal tilted 40 degrees so the lune below the plane
        // and the cap both matter. Reference: the occluded share above
        // the plane (less) by midpoint quadrature over the sphere.
        let r = receiver(40.0);
        let (n, geo) = (r.normal[0], r.geo_normal[0]);
        let wall = [[
            Vec3A::new(-0.05, -1e3, -1e3),
            Vec3A::new(-0.05, 1e3, -1e3),
            Vec3A::new(-0.05, 0.0, 1e3),
        ]];
        let tracer = Tracer::new(&wall);
        let p = BakeParams {
            max_distance: 1e4,
            seed: 7,
        };
        let (k, band) = (4096, 512);
        let cap = [cap_of(&r, k, |d| d.x < 0.0)];
        let got = shares_cap_band(&r, &tracer, &cap, |_| k, |_| (0, band), &p)[0];
        let mut want = [0.0f64; VIS_COUNT];
        let (nz, nphi) = (800, 1600);
        let dw = 2.0 / nz as f64 * 2.0 * std::f64::consts::PI / nphi as f64;
        for a in 0..nz {
            let z = -1.0 + (a as f64 + 0.5) * 2.0 / nz as f64;
            let s = (1.0 - z * z).sqrt();
            for b in 0..nphi {
                let phi = (b as f64 + 0.5) * 2.0 * std::f64::consts::PI / nphi as f64;
                let w = Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32);
                if w.dot(n) > 0.0 && w.dot(geo) > 0.0 && w.x < 0.0 {
                    for (o, y) in want.iter_mut().zip(sh::basis16(w)) {
                        *o -= y as f64 * dw;
                    }
                }
            }
        }
        assert!(want[0] < -0.3, "{}", want[0]);
        for i in 0..VIS_COUNT {
            assert!(
                (got[i] as f64 - want[i]).abs() < 0.01,
                "v{i}: {} against {}",
                got[i],
                want[i]
            );
        }
    }
}
