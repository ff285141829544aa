//! The `aobake` command line.

use aobake::pipeline::{self, FilterOptions, Method, Settings, UvSource};
use aobake::unwrap::{AtlasSize, Packing};
use aobake::write::OcclusionMode;
use clap::{Parser, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Clone, Copy, Debug, ValueEnum)]
enum MethodArg {
    /// Sparse rays shared between texels (Egan et al. 2011), brute force where needed.
    Filtered,
    /// Brute-force Monte Carlo.
    Mc,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum PackingArg {
    /// Rows of charts: fast, slightly less dense.
    Fast,
    /// Charts nested by shape: densest, slow with thousands of charts.
    Shape,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum UvArg {
    /// Unwrap into a new atlas and add a TEXCOORD_n.
    Generate,
    /// Reuse the lightmap UV set given by --uv-set.
    Existing,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum OcclusionArg {
    /// Keep a material's existing occlusionTexture.
    Keep,
    /// Replace it with the baked AO.
    Replace,
}

/// Bake ambient occlusion and SH9 directional occlusion lightmaps into a glTF file.
#[derive(Parser, Debug)]
#[command(name = "aobake", version, about)]
struct Cli {
    /// Input .glb or .gltf.
    input: PathBuf,
    /// Output .glb (written atomically; never the input).
    output: PathBuf,
    /// Atlas page edge in texels (the densest fit on one page).
    #[arg(long, default_value_t = 1024, conflicts_with = "texel_density")]
    resolution: u32,
    /// Texels per world unit instead of a fixed page size.
    #[arg(long)]
    texel_density: Option<f64>,
    /// Rays per texel of the Monte Carlo method.
    #[arg(long, default_value_t = 256)]
    rays: u32,
    /// Filtered: sparse rays per texel shared with the neighbours.
    #[arg(long, default_value_t = FilterOptions::default().sparse_rays)]
    sparse_rays: u32,
    /// Filtered: neighbour gather radius in texels.
    #[arg(long, default_value_t = FilterOptions::default().gather_radius)]
    gather_radius: f32,
    /// Filtered: angular bandlimit Omega_v^max (larger: sharper, more brute force).
    #[arg(long, default_value_t = FilterOptions::default().omega_v_max)]
    omega_v: f32,
    /// Filtered: brute-force rays per hemisphere cell the filter cannot serve.
    #[arg(long, default_value_t = FilterOptions::default().cell_rays)]
    cell_rays: u32,
    /// Filtered: cells with less filter weight (about that many samples) are brute-forced.
    #[arg(long, default_value_t = FilterOptions::default().min_weight)]
    min_weight: f32,
    /// Filtered: write diagnostic PNG maps (brute-force fraction, z_min, neighbours, sparse AO) here.
    #[arg(long)]
    debug_dir: Option<PathBuf>,
    /// Max occluder distance in world units [default: 0.1 x scene diagonal].
    #[arg(long)]
    max_distance: Option<f64>,
    /// Baking method.
    #[arg(long, value_enum, default_value_t = MethodArg::Mc)]
    method: MethodArg,
    /// Random seed (same seed, same output, any thread count).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Empty texels around each chart.
    #[arg(long, default_value_t = 2)]
    padding: u32,
    /// Lightmap UVs: generate new ones, or reuse an existing set.
    #[arg(long, value_enum, default_value_t = UvArg::Generate)]
    uv: UvArg,
    /// The TEXCOORD set reused by --uv existing.
    #[arg(long, default_value_t = 1)]
    uv_set: usize,
    /// Chart packing.
    #[arg(long, value_enum, default_value_t = PackingArg::Fast)]
    packing: PackingArg,
    /// What to do with materials that already have an occlusionTexture.
    #[arg(long, value_enum, default_value_t = OcclusionArg::Keep)]
    occlusion: OcclusionArg,
    /// Also write float EXR lightmaps into this directory.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Write a JSON report (stage times, texels, rays/s) to this file.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Worker threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bars and no warnings.
    #[arg(long, short)]
    quiet: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("aobake: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: &Cli) -> anyhow::Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()?;
    }
    let settings = Settings {
        size: match cli.texel_density {
            Some(t) => AtlasSize::TexelDensity(t),
            None => AtlasSize::Resolution(cli.resolution),
        },
        padding: cli.padding,
        packing: match cli.packing {
            PackingArg::Fast => Packing::Fast,
            PackingArg::Shape => Packing::Shape,
        },
        uv: match cli.uv {
            UvArg::Generate => UvSource::Generate,
            UvArg::Existing => UvSource::Existing(cli.uv_set),
        },
        method: match cli.method {
            MethodArg::Mc => Method::Mc,
            MethodArg::Filtered => Method::Filtered,
        },
        rays: cli.rays,
        filter: FilterOptions {
            sparse_rays: cli.sparse_rays,
            gather_radius: cli.gather_radius,
            omega_v_max: cli.omega_v,
            cell_rays: cli.cell_rays,
            min_weight: cli.min_weight,
        },
        debug_dir: cli.debug_dir.clone(),
        max_distance: cli.max_distance,
        seed: cli.seed,
        occlusion: match cli.occlusion {
            OcclusionArg::Keep => OcclusionMode::Keep,
            OcclusionArg::Replace => OcclusionMode::Replace,
        },
        exr_dir: cli.exr.clone(),
        progress: !cli.quiet,
    };
    let report = pipeline::run(&cli.input, &cli.output, &settings)?;
    if !cli.quiet {
        for w in &report.warnings {
            eprintln!("aobake: warning: {w}");
        }
        eprintln!(
            "aobake: baked {} texels ({}x{} atlas) with {} rays in {:.2} s ({:.2} Mrays/s)",
            report.texels,
            report.atlas_width,
            report.atlas_height,
            report.rays_cast,
            report.total_seconds,
            report.rays_per_second / 1e6
        );
    }
    if let Some(path) = &cli.report {
        let text = serde_json::to_vec_pretty(&report)?;
        aobake::write::write_atomic(path, &text)?;
    }
    Ok(())
}
