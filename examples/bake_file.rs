//! Bakes a glTF file from Rust, as a build system would: the settings a
//! project keeps in code, one call, the report's figures.
//!
//!     cargo run --release --example bake_file -- [IN.glb] [OUT.glb]
//!
//! Defaults: the bundled Cornell box into `cornell_baked.glb`. The input is
//! never touched and the output is written atomically (a bake that fails
//! leaves nothing at OUT).

use aobake::atlas::AtlasSize;
use aobake::{BakeSettings, RunOptions};
use std::path::PathBuf;

fn main() -> Result<(), aobake::Error> {
    let mut args = std::env::args_os().skip(1).map(PathBuf::from);
    let input = args
        .next()
        .unwrap_or_else(|| "assets/cornell_box.glb".into());
    let output = args.next().unwrap_or_else(|| "cornell_baked.glb".into());
    // Everything not named here is the command line's default.
    let settings = BakeSettings {
        size: AtlasSize::Resolution(512),
        ..BakeSettings::default()
    };
    let report = aobake::bake(&input, &output, &settings, &RunOptions::QUIET)?;
    println!(
        "{} -> {}: {} x {} texels on {} page(s), {} charts, {:.1} rays per texel, {:.2} s",
        input.display(),
        output.display(),
        report.atlas_width,
        report.atlas_height,
        report.pages.len(),
        report.charts,
        report.rays_per_texel_total,
        report.total_seconds
    );
    for warning in &report.warnings {
        println!("warning: {warning}");
    }
    Ok(())
}
