//! How well a bake relights normal-mapped normals: the visibility layer
//! against the two fallbacks an engine has without it, measured against
//! brute force at sampled texels.
//!
//!     cargo run --release --example visibility_error -- SCENE.glb [RES] [METHOD] [VISIBILITY] [ORDER] [TEXELS] [REF_RAYS]
//!
//! Defaults: 1024, adaptive, all, 3, 2000 texels, 4096 reference rays.
//! The bake runs as the CLI's would; its 8-bit textures are decoded (the
//! texel's own value). At each sampled texel (not inside geometry, on a
//! primitive with the layer) a reference traces REF_RAYS stratified
//! uniform rays around the vertex normal n on a stream of its own; for 56
//! random L2 environments (6 near-directional) and tilts of 15, 30, 45 and
//! 60 degrees in a random azimuth, the truth is (1/pi) Int V H(n.w)
//! max(0, n'.w) L(w) dw over those rays, and each estimate's error is
//! (estimate - truth) / (unoccluded irradiance over pi at n'):
//!
//! - `ignore`: c.L (the normal map ignored);
//! - `open x AO`: the unoccluded irradiance at n' times the baked AO;
//! - `layer`: the anchored formula c.L + E_C(n')/pi - E_C(n)/pi from v.
//!
//! Prints mean |error|, p95 |error| and mean error (bias) per tilt, and
//! the bake's stage times.

use aobake::bits::mix64;
use aobake::job::settings::VisibilityMode;
use aobake::relight::{Environment, anchored_diffuse};
use aobake::sample::{Frame, receiver_seed, sobol_2d, uniform_hemisphere};
use aobake::sh::{self, SH_COUNT, VIS_COUNT};
use aobake::stage::StageTimer;
use aobake::trace::offset_origin;
use aobake::{BakeSettings, Method};
use glam::{Quat, Vec3};
use rayon::prelude::*;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = mix64(self.0.wrapping_add(0x9e37_79b9_7f4a_7c15));
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn direction(&mut self) -> Vec3 {
        let z = 2.0 * self.next() - 1.0;
        let phi = 2.0 * std::f32::consts::PI * self.next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// A random positive environment's L2 coefficients: a constant plus
/// clamped-cosine lobes (each projects as A_l Y_i(d)); `directional`: a
/// faint constant and one strong lobe.
fn environment(rng: &mut Rng, directional: bool) -> [f32; SH_COUNT] {
    let mut l = [0.0f32; SH_COUNT];
    let (ambient, lobes) = if directional {
        (0.05, 1)
    } else {
        (0.2 + rng.next(), 3)
    };
    l[0] = ambient * (4.0 * std::f32::consts::PI).sqrt();
    for _ in 0..lobes {
        let d = rng.direction();
        let w = if directional { 2.0 } else { rng.next() };
        let y = sh::basis(d);
        for i in 0..SH_COUNT {
            l[i] += w * sh::CLAMPED_COSINE_BAND[sh::BAND[i]] * y[i];
        }
    }
    l
}

/// Mean |error| / p95 |error| / mean error of column `k` of `rows`.
fn stat<const N: usize>(rows: &[[f32; N]], k: usize) -> String {
    let mut a: Vec<f32> = rows.iter().map(|e| e[k].abs()).collect();
    a.sort_by(f32::total_cmp);
    let mean = a.iter().sum::<f32>() / a.len() as f32;
    let p95 = a[(a.len() as f32 * 0.95) as usize];
    let bias = rows.iter().map(|e| e[k]).sum::<f32>() / rows.len() as f32;
    format!("{mean:.4} / {p95:.4} / {bias:+.4}")
}

fn decode(png: &[u8]) -> image::RgbaImage {
    image::load_from_memory(png).expect("png").to_rgba8()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = std::path::PathBuf::from(&args[0]);
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or(d.to_string());
    let res: u32 = arg(1, "1024").parse().unwrap();
    let method = match arg(2, "adaptive").as_str() {
        "mc" => Method::Mc,
        _ => Method::Adaptive,
    };
    let visibility = match arg(3, "all").as_str() {
        "auto" => VisibilityMode::Auto,
        _ => VisibilityMode::All,
    };
    let order: u32 = arg(4, "3").parse().unwrap();
    let texels: usize = arg(5, "2000").parse().unwrap();
    let ref_rays: u32 = arg(6, "4096").parse().unwrap();

    let scene = aobake::gltf::load(&path).expect("load");
    let s = BakeSettings {
        size: aobake::atlas::AtlasSize::Resolution(res),
        method,
        visibility,
        visibility_order: order,
        ..BakeSettings::default()
    };
    s.validate().expect("settings");
    let mut timer = StageTimer::new();
    let level = aobake::job::Level::new(&scene, &s, &aobake::RunOptions::QUIET, &mut timer)
        .expect("prepare");
    let p = level.page(0, &scene, &mut timer).expect("prepare");
    let passes = p
        .bake(&s, &aobake::RunOptions::QUIET, &mut timer)
        .expect("bake");
    let out = p
        .finish(&passes, &s, &aobake::RunOptions::QUIET, &mut timer)
        .expect("output");
    for st in timer.stages() {
        eprint!("{} {:.2}s, ", st.stage, st.seconds);
    }
    eprintln!();
    let enc = &out.encoded;
    let layer = enc
        .visibility
        .as_ref()
        .expect("no visibility layer was baked");
    let (ao_img, sh_img, v_img): (_, Vec<_>, Vec<_>) = (
        image::load_from_memory(&enc.occlusion_png)
            .unwrap()
            .to_luma8(),
        enc.sh_png.iter().map(|b| decode(b)).collect(),
        layer.png.iter().map(|b| decode(b)).collect(),
    );
    let rc = &p.receivers;
    let inside = passes.inside(&p);
    let w = rc.width;
    let decoded = |r: usize| {
        let t = rc.texel[r];
        let (x, y) = (t % w, t / w);
        let ao = ao_img.get_pixel(x, y)[0] as f32 / 255.0;
        let ch =
            |imgs: &[image::RgbaImage], i: usize| imgs[i / 4].get_pixel(x, y)[i % 4] as f32 / 255.0;
        let c: [f32; SH_COUNT] =
            std::array::from_fn(|i| enc.sh_scale[i] * ch(&sh_img, i) + enc.sh_offset[i]);
        let mut v = [0.0f32; VIS_COUNT];
        for (i, vi) in v.iter_mut().enumerate().take(layer.scale.len()) {
            *vi = layer.scale[i] * ch(&v_img, i) + layer.offset[i];
        }
        (ao, c, v)
    };

    // Sampled receivers (a fixed stride through a shuffled order).
    let mut rng = Rng(12345);
    // AOBAKE_TEXELS=centres: only texels whose centre lies inside a
    // triangle (what a checker that rasterizes texel centres samples);
    // =interior: only interior texels (`seams::interior`, which stitching
    // never moves).
    let pick = std::env::var("AOBAKE_TEXELS").unwrap_or_default();
    let lm = &out.lightmap;
    let mut candidates: Vec<usize> = (0..rc.len())
        .filter(|&r| inside.get(r).is_none_or(|&i| !i))
        .filter(|&r| match pick.as_str() {
            "centres" => rc.center_inside[r],
            "interior" => {
                aobake::lightmap::seams::interior(&lm.covered, lm.width, lm.height, rc.texel[r])
            }
            _ => true,
        })
        .collect();
    for i in (1..candidates.len()).rev() {
        let j = (rng.next() * (i + 1) as f32) as usize % (i + 1);
        candidates.swap(i, j);
    }
    candidates.truncate(texels);

    // Reference rays: stratified uniform directions around n, each with its
    // visibility.
    let reference: Vec<Vec<(Vec3, bool)>> = candidates
        .par_iter()
        .map(|&r| {
            let geo = rc.geo_normal[r];
            let origin = offset_origin(rc.position[r], geo, rc.footprint[r]);
            let frame = Frame::from_normal(rc.normal[r]);
            let seed = receiver_seed(0x5eed, rc.texel[r] as u64, 7);
            (0..ref_rays)
                .map(|i| {
                    let d = frame
                        .to_world(uniform_hemisphere(sobol_2d(i, seed)))
                        .normalize();
                    (
                        d,
                        p.level
                            .tracer
                            .receiver_visible(origin, geo, d, p.level.max_distance),
                    )
                })
                .collect()
        })
        .collect();

    let envs: Vec<Environment> = (0..56)
        .map(|k| Environment::new(environment(&mut rng, k < 6)))
        .collect();
    println!(
        "{} at {res}, {:?}, order {order}, {} texels, {ref_rays} reference rays, 56 environments",
        path.display(),
        method,
        candidates.len()
    );
    println!(
        "| tilt | ignore: mean / p95 / bias | open x AO: mean / p95 / bias | layer: mean / p95 / bias |"
    );
    println!("|---|---|---|---|");
    for tilt in [15.0f32, 30.0, 45.0, 60.0] {
        let rows: Vec<[f32; 3]> = candidates
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, &r)| {
                let n = rc.normal[r];
                let frame = Frame::from_normal(n);
                let mut rng = Rng(mix64(k as u64 ^ tilt.to_bits() as u64));
                let (ao, c, v) = decoded(r);
                let rays = &reference[k];
                envs.iter()
                    .map(|env| {
                        let phi = 2.0 * std::f32::consts::PI * rng.next();
                        let axis = frame.tangent * phi.cos() + frame.bitangent * phi.sin();
                        let shading =
                            Quat::from_axis_angle(axis.cross(n).normalize(), tilt.to_radians()) * n;
                        let mut truth = 0.0f64;
                        for &(d, seen) in rays {
                            if seen {
                                let l: f32 =
                                    sh::basis(d).iter().zip(&env.l).map(|(y, l)| y * l).sum();
                                truth += (shading.dot(d).max(0.0) * l) as f64;
                            }
                        }
                        let truth = (truth * 2.0 / rays.len() as f64) as f32;
                        let open = env.open_diffuse(shading);
                        let e = |est: f32| (est - truth) / open;
                        [
                            e(env.baked_diffuse(&c)),
                            e(open * ao),
                            e(anchored_diffuse(env, &c, &v, n, shading)),
                        ]
                    })
                    .collect::<Vec<_>>()
            })
            .filter(|e| e.iter().all(|x| x.is_finite()))
            .collect();
        println!(
            "| {tilt} | {} | {} | {} |",
            stat(&rows, 0),
            stat(&rows, 1),
            stat(&rows, 2)
        );
    }

    // Specular occlusion of a lobe about the tilted normal (a view along
    // n'), 30 degrees: the truth is Int V H lobe L / Int H lobe L over the
    // reference rays, lobe = max(0, R.w)^s, the Phong lobe whose zonal
    // factors relight::lobe_bands uses; error = estimate - truth.
    println!(
        "\n| roughness | AO as specular occlusion: mean / p95 / bias | layer: mean / p95 / bias |"
    );
    println!("|---|---|---|");
    for roughness in [0.6f32, 0.8] {
        let alpha = roughness * roughness;
        let s = (2.0 / (alpha * alpha) - 2.0).max(1e-3);
        let rows: Vec<[f32; 2]> = candidates
            .par_iter()
            .enumerate()
            .flat_map_iter(|(k, &r)| {
                let n = rc.normal[r];
                let frame = Frame::from_normal(n);
                let mut rng = Rng(mix64(k as u64 ^ 0x5bec));
                let (ao, _, v) = decoded(r);
                let rays = &reference[k];
                envs.iter()
                    .filter_map(|env| {
                        let phi = 2.0 * std::f32::consts::PI * rng.next();
                        let axis = frame.tangent * phi.cos() + frame.bitangent * phi.sin();
                        let reflected =
                            Quat::from_axis_angle(axis.cross(n).normalize(), 30f32.to_radians())
                                * n;
                        let (mut seen, mut all) = (0.0f64, 0.0f64);
                        for &(d, visible) in rays {
                            let lobe = reflected.dot(d).max(0.0).powf(s);
                            let l: f32 = sh::basis(d).iter().zip(&env.l).map(|(y, l)| y * l).sum();
                            let w = (lobe * l) as f64;
                            all += w;
                            if visible {
                                seen += w;
                            }
                        }
                        (all > 1e-9).then(|| {
                            let truth = (seen / all) as f32;
                            let layer = aobake::relight::specular_occlusion(
                                env, &v, n, reflected, roughness,
                            );
                            [ao - truth, layer - truth]
                        })
                    })
                    .collect::<Vec<_>>()
            })
            .filter(|e| e.iter().all(|x| x.is_finite()))
            .collect();
        println!("| {roughness} | {} | {} |", stat(&rows, 0), stat(&rows, 1));
    }
}
