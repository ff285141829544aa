//! Engine view: the bake judged where an engine reads it.
//!
//! An engine never reads a texel centre: every fragment reads the
//! lightmap bilinearly at its own UV. This module measures that.
//!
//! In: a page's triangles ([`crate::atlas::rasterize::surface_triangles`]),
//! which texel centres lie inside a triangle (the receivers'
//! `center_inside`), the images an engine reads (decoded from the 8-bit
//! textures: [`crate::encode::decode`]) and a reference at surface points.
//! Out: [`EngineView`]: AO and SH RMSE over points spread uniformly by
//! world area, by texel class of the points' four bilinear taps:
//!
//! - *interior*: all four taps' centres lie inside a triangle;
//! - *border*: at least one does not (slivers included);
//! - *sliver*: none does (a chart thinner than a texel there).
//!
//! The reference (`reference`) is the contract's: AO and c_i at the point
//! with n = its interpolated normal, by Monte Carlo (and v_i where the
//! visibility layer is baked); points inside geometry (the contract's rule,
//! [`crate::bake::validity`]) are left out, as no camera sees them.
//!
//! Where a point's primitive carries the visibility layer, the *relight
//! error* is what an engine's normal-mapped diffuse makes of the lookups:
//! |E(n') from the looked-up c and v - E(n') from the reference's| / the
//! unoccluded E(n'), the anchored diffuse of [`crate::relight`] at a normal
//! n' tilted `RELIGHT_TILT_DEGREES` from n (azimuth per point) under
//! `RELIGHT_ENVIRONMENTS` fixed L2 environments, averaged.

use crate::atlas::Receivers;
use crate::atlas::rasterize::SurfaceTri;
use crate::bake::{BakeParams, mc, validity, visibility};
use crate::bits::{mix64, unit};
use crate::sh::{SH_COUNT, VIS_COUNT};
use crate::trace::Tracer;
use serde::Serialize;

pub(crate) mod relight;

use relight::{environments, relight_error};

use super::Lightmap;
use super::filter::Filter;
use super::filter::bilinear_taps as taps;

/// Surface points of a page, uniform by world area: each a receiver (for
/// the reference) with its lightmap UV.
#[derive(Clone, Debug, Default)]
pub struct SurfacePoints {
    /// Position, normals and footprint of each point (`texel` holds the
    /// point's index, which seeds its rays).
    pub receivers: Receivers,
    /// Lightmap UV of each point, in [0, 1] of the page.
    pub uv: Vec<[f32; 2]>,
    /// Receiver mesh of each point.
    pub mesh: Vec<u32>,
}

/// The reference at surface points (`reference`).
#[derive(Clone, Debug, Default)]
pub struct PointReference {
    pub ao: Vec<f32>,
    pub sh: Vec<[f32; SH_COUNT]>,
    /// v_0..v_15 at each point, when asked for.
    pub visibility: Option<Vec<[f32; VIS_COUNT]>>,
    /// Points inside geometry (left out).
    pub inside: Vec<bool>,
    /// Rays per point.
    pub rays: u32,
}

/// `count` points on `tris` (a page's triangles, of a `width` x `height`
/// page), uniform by area: point k at the stratified area quantile (k + u)
/// / count, uniform in its triangle. Deterministic for `seed`.
pub fn surface_points(
    tris: &[SurfaceTri],
    width: u32,
    height: u32,
    count: usize,
    seed: u64,
) -> SurfacePoints {
    let mut cumulative = Vec::with_capacity(tris.len());
    let mut total = 0.0f64;
    for t in tris {
        total += t.area() as f64;
        cumulative.push(total);
    }
    let mut out = SurfacePoints {
        receivers: Receivers {
            width,
            height,
            ..Default::default()
        },
        uv: Vec::with_capacity(count),
        mesh: Vec::with_capacity(count),
    };
    if total.is_nan() || total <= 0.0 || count == 0 {
        return out;
    }
    let r = &mut out.receivers;
    for k in 0..count {
        let key = seed ^ (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let q = (k as f64 + unit(key) as f64) / count as f64 * total;
        let i = cumulative.partition_point(|&c| c <= q).min(tris.len() - 1);
        let t = &tris[i];
        // Uniform in the triangle: the square-root map.
        let (s, v) = (unit(key ^ 1).sqrt(), unit(key ^ 2));
        let b = [1.0 - s, s * (1.0 - v), s * v];
        let uv = t.uv[0] * b[0] + t.uv[1] * b[1] + t.uv[2] * b[2];
        r.push_surface_point(k as u32, t, b, true);
        out.mesh.push(t.mesh);
        out.uv
            .push([uv.x / width as f32, uv.y / height as f32].map(|c| c.clamp(0.0, 1.0)));
    }
    out
}

/// The contract's AO and SH at every point by Monte Carlo with `rays`
/// cosine rays (and, with `layer`, v_i with `rays` uniform rays), and which
/// points are inside geometry.
pub fn reference(
    points: &SurfacePoints,
    tracer: &Tracer,
    max_distance: f32,
    rays: u32,
    seed: u64,
    layer: bool,
) -> PointReference {
    let params = BakeParams { max_distance, seed };
    let bake = mc::bake(&points.receivers, tracer, rays, &params, &|_| {});
    let visibility = layer.then(|| visibility::bake(&points.receivers, tracer, rays, &params).v);
    PointReference {
        ao: bake.ao,
        sh: bake.sh,
        visibility,
        inside: validity::inside_geometry(&points.receivers, tracer, max_distance, seed),
        rays,
    }
}

/// The class of a lookup at `uv` by its four taps: how many of their
/// centres lie inside a triangle (`center_inside` per texel).
pub fn class_of(uv: [f32; 2], width: u32, height: u32, center_inside: &[bool]) -> TexelClass {
    let inside = taps(uv, width, height)
        .iter()
        .filter(|&&(t, _)| center_inside[t as usize])
        .count();
    match inside {
        4 => TexelClass::Interior,
        0 => TexelClass::Sliver,
        _ => TexelClass::Border,
    }
}

/// A point's class by its four bilinear taps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexelClass {
    Interior,
    /// Some but not all taps' centres inside a triangle.
    Border,
    /// No tap's centre inside a triangle.
    Sliver,
}

/// The lookup through `filter` of every channel at `uv` (glTF
/// conventions, clamp to edge): AO and the 9 SH coefficients.
pub fn lookup(lm: &Lightmap, uv: [f32; 2], filter: Filter) -> (f32, [f32; SH_COUNT]) {
    let (w, h) = (lm.width, lm.height);
    let ao = filter.lookup1(&lm.ao, w, h, uv);
    (ao, filter.lookup(&lm.sh, w, h, uv))
}

/// The error of one class of points.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct ClassError {
    /// Points compared (inside-geometry points left out).
    pub points: usize,
    /// Their share of all compared points (of the surface's area).
    pub area_share: f64,
    pub ao_rmse: f64,
    /// RMSE over the 9 SH coefficients.
    pub sh_rmse: f64,
    /// Share of all points' squared AO error.
    pub ao_error_share: f64,
    /// Share of the class's points with |AO error| > 0.05.
    pub ao_over_005: f64,
    /// Points whose primitive carries the visibility layer.
    pub layer_points: usize,
    /// Their mean relight error (see the module doc).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub relight_error: Option<f64>,
}

/// The engine-view error of a bake by texel class.
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct EngineView {
    pub all: ClassError,
    pub interior: ClassError,
    /// Border points, slivers included.
    pub border: ClassError,
    pub sliver: ClassError,
    /// Points left out: inside geometry.
    pub inside: usize,
    /// Reference rays per point.
    pub reference_rays: u32,
}

/// Running sums of one class.
#[derive(Clone, Copy, Default)]
struct Sums {
    n: usize,
    ao2: f64,
    sh2: f64,
    over: usize,
    layer: usize,
    relight: f64,
}

impl Sums {
    fn add(&mut self, ao_err: f64, sh2: f64, relight: Option<f64>) {
        self.n += 1;
        self.ao2 += ao_err * ao_err;
        self.sh2 += sh2;
        self.over += (ao_err.abs() > 0.05) as usize;
        if let Some(r) = relight {
            self.layer += 1;
            self.relight += r;
        }
    }

    fn error(&self, all: &Sums) -> ClassError {
        let n = self.n.max(1) as f64;
        ClassError {
            points: self.n,
            area_share: self.n as f64 / all.n.max(1) as f64,
            ao_rmse: (self.ao2 / n).sqrt(),
            sh_rmse: (self.sh2 / (n * SH_COUNT as f64)).sqrt(),
            ao_error_share: if all.ao2 > 0.0 {
                self.ao2 / all.ao2
            } else {
                0.0
            },
            ao_over_005: self.over as f64 / n,
            layer_points: self.layer,
            relight_error: (self.layer > 0).then(|| self.relight / self.layer as f64),
        }
    }
}

/// Compares the lookups of `lm` (the images as an engine reads them) at
/// `points` with their `reference`, leaving out the points inside
/// geometry; `center_inside` classifies them ([`Receivers::centers_inside`]). The
/// relight error is measured at points of the meshes `layer_meshes` marks
/// when both `lm` and the reference carry the layer; `layer_count`: the
/// coefficients the textures hold (9 or 16), the reference cut alike.
pub fn measure(
    points: &SurfacePoints,
    lm: &Lightmap,
    filter: Filter,
    reference: &PointReference,
    center_inside: &[bool],
    layer_meshes: &[bool],
    layer_count: usize,
) -> EngineView {
    let (mut all, mut interior, mut border, mut sliver) = Default::default();
    let mut left_out = 0;
    let envs = environments();
    let layer = lm
        .visibility
        .as_deref()
        .zip(reference.visibility.as_deref());
    for (k, &uv) in points.uv.iter().enumerate() {
        if reference.inside.get(k).copied().unwrap_or(false) {
            left_out += 1;
            continue;
        }
        let (ao, sh) = lookup(lm, uv, filter);
        let ao_err = (ao - reference.ao[k]) as f64;
        let sh2: f64 = (sh.iter().zip(&reference.sh[k]))
            .map(|(a, b)| ((a - b) as f64).powi(2))
            .sum();
        let has_layer = (points.mesh.get(k))
            .is_some_and(|&m| layer_meshes.get(m as usize).copied().unwrap_or(false));
        let relight = match layer {
            Some((v, rv)) if has_layer => {
                let got = filter.lookup(v, lm.width, lm.height, uv);
                let mut want = rv[k];
                want[layer_count.min(VIS_COUNT)..].fill(0.0);
                let n = points.receivers.normal[k];
                let key = mix64(k as u64 ^ 0x7117);
                Some(relight_error(
                    &envs,
                    n,
                    key,
                    &sh,
                    &got,
                    &reference.sh[k],
                    &want,
                ))
            }
            _ => None,
        };
        let add = |s: &mut Sums| s.add(ao_err, sh2, relight);
        add(&mut all);
        match class_of(uv, lm.width, lm.height, center_inside) {
            TexelClass::Interior => add(&mut interior),
            TexelClass::Border => add(&mut border),
            TexelClass::Sliver => {
                add(&mut border);
                add(&mut sliver);
            }
        }
    }
    let all: Sums = all;
    EngineView {
        all: all.error(&all),
        interior: interior.error(&all),
        border: border.error(&all),
        sliver: sliver.error(&all),
        inside: left_out,
        reference_rays: reference.rays,
    }
}

/// Merges pages' figures: each class's sums recombined from its points and
/// RMSE (the shares from the merged counts).
pub fn merge(views: &[EngineView]) -> Option<EngineView> {
    let first = views.first()?;
    let combine = |pick: fn(&EngineView) -> &ClassError| -> Sums {
        let mut s = Sums::default();
        for v in views {
            let c = pick(v);
            s.n += c.points;
            s.ao2 += c.ao_rmse * c.ao_rmse * c.points as f64;
            s.sh2 += c.sh_rmse * c.sh_rmse * (c.points * SH_COUNT) as f64;
            s.over += (c.ao_over_005 * c.points as f64).round() as usize;
            s.layer += c.layer_points;
            s.relight += c.relight_error.unwrap_or(0.0) * c.layer_points as f64;
        }
        s
    };
    let all = combine(|v| &v.all);
    Some(EngineView {
        all: all.error(&all),
        interior: combine(|v| &v.interior).error(&all),
        border: combine(|v| &v.border).error(&all),
        sliver: combine(|v| &v.sliver).error(&all),
        inside: views.iter().map(|v| v.inside).sum(),
        reference_rays: first.reference_rays,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec2, Vec3};

    fn texel_uv(uv: [f32; 2], width: u32, height: u32) -> Vec2 {
        Vec2::new(uv[0] * width as f32, uv[1] * height as f32)
    }

    fn square(n: u32) -> Vec<SurfaceTri> {
        // A unit square on z = 0 covering an n x n page, two triangles.
        let s = n as f32;
        let tri = |a: [f32; 2], b: [f32; 2], c: [f32; 2]| SurfaceTri {
            mesh: 0,
            uv: [a, b, c].map(|p| Vec2::new(p[0] * s, p[1] * s)),
            pos: [a, b, c].map(|p| Vec3::new(p[0], p[1], 0.0)),
            nrm: None,
            geo: Vec3::Z,
            footprint: 1.0 / s,
        };
        vec![
            tri([0.0, 0.0], [1.0, 0.0], [1.0, 1.0]),
            tri([0.0, 0.0], [1.0, 1.0], [0.0, 1.0]),
        ]
    }

    #[test]
    fn points_are_uniform_by_area_and_carry_their_uv() {
        let tris = square(8);
        let p = surface_points(&tris, 8, 8, 4000, 3);
        assert_eq!(p.uv.len(), 4000);
        // Each quadrant of the square gets a quarter of the points.
        let mut q = [0usize; 4];
        for (uv, pos) in p.uv.iter().zip(&p.receivers.position) {
            assert!((uv[0] - pos.x).abs() < 1e-5 && (uv[1] - pos.y).abs() < 1e-5);
            q[(uv[0] >= 0.5) as usize + 2 * (uv[1] >= 0.5) as usize] += 1;
        }
        for c in q {
            assert!((c as f64 - 1000.0).abs() < 60.0, "{q:?}");
        }
    }

    #[test]
    fn a_bilinear_function_is_read_back_exactly_and_classes_follow_the_taps() {
        // AO = a linear function of the texel centre: bilinear lookups
        // inside the centres' hull reproduce it exactly.
        let (w, h) = (8u32, 8u32);
        let f = |x: f32, y: f32| 0.1 + 0.05 * x + 0.03 * y;
        let mut lm = Lightmap {
            width: w,
            height: h,
            ao: vec![0.0; 64],
            sh: vec![[0.0; SH_COUNT]; 64],
            covered: vec![true; 64],
            visibility: None,
        };
        for y in 0..h {
            for x in 0..w {
                lm.ao[(y * w + x) as usize] = f(x as f32 + 0.5, y as f32 + 0.5);
            }
        }
        let tris = square(8);
        let p = surface_points(&tris, w, h, 500, 1);
        let refs: Vec<f32> = (p.uv.iter())
            .map(|uv| {
                let t = texel_uv(*uv, w, h);
                f(t.x.clamp(0.5, 7.5), t.y.clamp(0.5, 7.5))
            })
            .collect();
        let reference = |inside: Vec<bool>| PointReference {
            ao: refs.clone(),
            sh: vec![[0.0; SH_COUNT]; refs.len()],
            visibility: None,
            inside,
            rays: 1,
        };
        let all_out = reference(Vec::new());
        // Every centre inside: every point interior, error zero.
        let centers = vec![true; 64];
        let v = measure(&p, &lm, Filter::Bilinear, &all_out, &centers, &[], 0);
        assert_eq!(v.interior.points, 500);
        assert!(v.all.ao_rmse < 1e-6, "{}", v.all.ao_rmse);
        // Column 3's centres outside: points whose taps reach it are
        // border, and none is a sliver.
        let mut centers = vec![true; 64];
        for y in 0..8 {
            centers[y * 8 + 3] = false;
        }
        let v = measure(&p, &lm, Filter::Bilinear, &all_out, &centers, &[], 0);
        let near = (p.uv.iter())
            .filter(|uv| (2.5..4.5).contains(&(uv[0] * 8.0)))
            .count();
        assert_eq!(v.border.points, near);
        assert_eq!(v.sliver.points, 0);
        assert_eq!(v.interior.points + v.border.points, 500);
        // No centre inside: all slivers (and border).
        let v = measure(&p, &lm, Filter::Bilinear, &all_out, &[false; 64], &[], 0);
        assert_eq!((v.sliver.points, v.border.points), (500, 500));
        // Inside points are left out.
        let inside: Vec<bool> = (0..500).map(|k| k % 5 == 0).collect();
        let v = measure(
            &p,
            &lm,
            Filter::Bilinear,
            &reference(inside),
            &centers,
            &[],
            0,
        );
        assert_eq!((v.all.points, v.inside), (400, 100));
    }

    #[test]
    fn merged_pages_equal_one_measure() {
        let a = EngineView {
            all: ClassError {
                points: 10,
                ao_rmse: 0.1,
                sh_rmse: 0.2,
                ..Default::default()
            },
            ..Default::default()
        };
        let b = EngineView {
            all: ClassError {
                points: 30,
                ao_rmse: 0.2,
                sh_rmse: 0.1,
                ..Default::default()
            },
            ..Default::default()
        };
        let m = merge(&[a, b]).unwrap();
        assert_eq!(m.all.points, 40);
        let want = ((10.0 * 0.01 + 30.0 * 0.04) / 40.0f64).sqrt();
        assert!((m.all.ao_rmse - want).abs() < 1e-12);
    }
}
