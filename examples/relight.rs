//! Relights a bake as an engine does, on the CPU: bakes a scene in memory
//! and writes its first page lit by a sky (bright above, dim below, a warm
//! low sun) through the baked SH, beside the plain AO.
//!
//!     cargo run --release --example relight -- [IN.glb] [OUT_PREFIX]
//!
//! Writes OUT_PREFIX_ao.png and OUT_PREFIX_sky.png (default prefix
//! `relit`). An engine does the same per pixel: the environment's nine SH
//! coefficients L (per colour channel) dotted with the texel's baked c
//! gives its irradiance over pi, occlusion included (`aobake::relight`;
//! the format's spec gives the formula).

use aobake::atlas::AtlasSize;
use aobake::relight::Environment;
use aobake::sh::{self, SH_COUNT};
use aobake::{BakeSettings, Method};
use glam::Vec3;

/// The SH projection of radiance `f` over the sphere (a Fibonacci lattice
/// of `n` directions: uniform, so each weighs 4 pi / n).
fn project(f: impl Fn(Vec3) -> f32, n: usize) -> [f32; SH_COUNT] {
    let mut l = [0.0f32; SH_COUNT];
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f32;
        let w = Vec3::new(r * phi.cos(), z, r * phi.sin());
        let y = sh::basis(w);
        let value = f(w);
        for k in 0..SH_COUNT {
            l[k] += value * y[k] * 4.0 * std::f32::consts::PI / n as f32;
        }
    }
    l
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let input = args
        .next()
        .unwrap_or_else(|| "assets/cornell_box.glb".into());
    let prefix = args.next().unwrap_or_else(|| "relit".into());
    let settings = BakeSettings {
        size: AtlasSize::Resolution(256),
        method: Method::Mc,
        rays: 128,
        ..BakeSettings::default()
    };
    let baked = aobake::bake_file(input.as_ref(), &settings)?;
    let lm = &baked.lightmap;
    // A sky per colour channel: the up hemisphere bright, the ground dark,
    // a sun low in +x (glTF is y-up).
    let sun = Vec3::new(0.8, 0.35, 0.2).normalize();
    let sky = |tint: f32, sun_power: f32| {
        move |w: Vec3| {
            let above = if w.y > 0.0 { tint } else { 0.15 };
            above + sun_power * w.dot(sun).max(0.0).powi(16)
        }
    };
    let channels = [sky(0.9, 6.0), sky(0.95, 4.5), sky(1.1, 2.5)].map(|f| project(f, 4096));
    let envs = channels.map(Environment::new);
    let mut ao = Vec::with_capacity(lm.ao.len());
    let mut rgb = Vec::with_capacity(lm.ao.len() * 3);
    for (a, c) in lm.ao.iter().zip(&lm.sh) {
        ao.push((a.clamp(0.0, 1.0) * 255.0).round() as u8);
        for env in &envs {
            // Irradiance over pi, tone-mapped for the picture.
            let e = env.baked_diffuse(c).max(0.0);
            rgb.push(((e / (1.0 + e)).powf(1.0 / 2.2) * 255.0).round() as u8);
        }
    }
    let (w, h) = (lm.width, lm.height);
    image::save_buffer(format!("{prefix}_ao.png"), &ao, w, h, image::ColorType::L8)?;
    image::save_buffer(
        format!("{prefix}_sky.png"),
        &rgb,
        w,
        h,
        image::ColorType::Rgb8,
    )?;
    println!("{prefix}_ao.png, {prefix}_sky.png: page 0 of {input}, {w} x {h}");
    Ok(())
}
