//! The `aobake` command line.

use aobake::atlas::{AtlasSize, Packing};
use aobake::gltf::write::OcclusionMode;
use aobake::report::ReportSettings;
use aobake::settings::{SeamMode, VisibilityMode};
use aobake::stage::StageTimer;
use aobake::{Method, Settings, UvSource};
use clap::{Parser, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::LazyLock;

/// The library's defaults, which the flags show and fall back to.
static DEFAULTS: LazyLock<Settings> = LazyLock::new(Settings::default);
static REPORT_DEFAULTS: LazyLock<ReportSettings> = LazyLock::new(ReportSettings::default);

/// The flag of a library setting (errors name settings by their field).
fn flag(setting: &str) -> String {
    match setting {
        "omega_v_max" => "--omega-v".into(),
        "output" => "OUTPUT".into(),
        s => format!("--{}", s.replace('_', "-")),
    }
}

/// An error as the command line says it: settings named by their flags.
fn cli_error(e: anyhow::Error) -> String {
    match e.downcast_ref::<aobake::Error>() {
        Some(aobake::Error::Option { setting, detail }) => {
            format!("invalid option: {}{detail}", flag(setting))
        }
        _ => e.to_string(),
    }
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum MethodArg {
    /// The sheared filter of Egan et al. 2011: sparse rays shared between texels, brute force where needed (`filtered` is accepted too).
    #[value(alias = "filtered")]
    Sheared,
    /// Brute-force Monte Carlo.
    Mc,
    /// Adaptive ray counts and an axis-aligned filter of the integrated values (the default).
    Adaptive,
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
enum SeamArg {
    /// Least-squares stitching of smooth seams.
    Stitch,
    /// None.
    Off,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum VisibilityArg {
    /// Primitives whose material has a normal map or a glossy lobe.
    Auto,
    /// Every baked primitive.
    All,
    /// None.
    Off,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum OcclusionArg {
    /// Keep a material's existing occlusionTexture.
    Keep,
    /// Replace it with the baked AO.
    Replace,
}

impl From<Method> for MethodArg {
    fn from(m: Method) -> Self {
        match m {
            Method::Mc => MethodArg::Mc,
            Method::Sheared => MethodArg::Sheared,
            Method::Adaptive => MethodArg::Adaptive,
        }
    }
}

impl From<Packing> for PackingArg {
    fn from(p: Packing) -> Self {
        match p {
            Packing::Fast => PackingArg::Fast,
            Packing::Shape => PackingArg::Shape,
        }
    }
}

impl From<OcclusionMode> for OcclusionArg {
    fn from(o: OcclusionMode) -> Self {
        match o {
            OcclusionMode::Keep => OcclusionArg::Keep,
            OcclusionMode::Replace => OcclusionArg::Replace,
        }
    }
}

/// Bake ambient occlusion and SH9 directional occlusion lightmaps into a glTF file.
#[derive(Parser, Debug)]
#[command(
    name = "aobake",
    version,
    about,
    after_help = "Also: aobake merge OUT.glb            writes OUT.glb from the shards of --shard I/N (see aobake merge --help).\n      aobake report IN [options]  measures AO/SH error against run time for each method (see aobake report --help).\n      aobake view [OUT.glb]            relights a bake in the browser viewer on 127.0.0.1 (see aobake view --help)."
)]
struct Cli {
    /// Input .glb or .gltf.
    input: PathBuf,
    /// Output .glb (written atomically; never the input).
    output: PathBuf,
    /// Atlas page edge in texels (the densest fit on one page).
    #[arg(long, default_value_t = aobake::settings::DEFAULT_RESOLUTION, conflicts_with = "texel_density")]
    resolution: u32,
    /// Texels per world unit instead of a fixed page size: charts are packed into as many pages as they need.
    #[arg(long)]
    texel_density: Option<f64>,
    /// With --texel-density: the largest page edge in texels (the last page may be smaller).
    #[arg(long, default_value_t = aobake::settings::DEFAULT_PAGE_SIZE)]
    page_size: u32,
    /// Rays per texel of the Monte Carlo method.
    #[arg(long, default_value_t = DEFAULTS.rays)]
    rays: u32,
    /// Filtered: sparse rays per texel shared with the neighbours.
    #[arg(long, default_value_t = DEFAULTS.filter.sparse_rays)]
    sparse_rays: u32,
    /// Filtered: neighbour gather radius in texels.
    #[arg(long, default_value_t = DEFAULTS.filter.gather_radius)]
    gather_radius: f32,
    /// Filtered: angular bandlimit Omega_v^max (larger: sharper, more brute force).
    #[arg(long, default_value_t = DEFAULTS.filter.omega_v_max)]
    omega_v: f32,
    /// Filtered: brute-force rays per hemisphere cell the filter cannot serve.
    #[arg(long, default_value_t = DEFAULTS.filter.cell_rays)]
    cell_rays: u32,
    /// Filtered: cells with less filter weight (about that many samples) are brute-forced.
    #[arg(long, default_value_t = DEFAULTS.filter.min_weight)]
    min_weight: f32,
    /// Adaptive: the quality knob, the Monte Carlo ray count whose error the bake aims at.
    #[arg(long, default_value_t = DEFAULTS.adaptive.quality)]
    quality: u32,
    /// Adaptive, expert: a fixed mean rays per texel over the atlas instead of --quality.
    #[arg(long)]
    mean_rays: Option<u32>,
    /// Filtered: write diagnostic PNG maps (brute-force fraction, z_min, neighbours, sparse AO) here.
    #[arg(long)]
    debug_dir: Option<PathBuf>,
    /// Max occluder distance in world units [default: 0.1 x scene diagonal].
    #[arg(long)]
    max_distance: Option<f64>,
    /// Baking method.
    #[arg(long, value_enum, default_value_t = MethodArg::from(DEFAULTS.method))]
    method: MethodArg,
    /// Random seed (same seed, same output, any thread count).
    #[arg(long, default_value_t = DEFAULTS.seed)]
    seed: u64,
    /// Empty texels around each chart.
    #[arg(long, default_value_t = DEFAULTS.padding)]
    padding: u32,
    /// Lightmap UVs: generate new ones, or reuse an existing set.
    #[arg(long, value_enum, default_value_t = UvArg::Generate)]
    uv: UvArg,
    /// The TEXCOORD set reused by --uv existing.
    #[arg(long, default_value_t = 1)]
    uv_set: usize,
    /// Chart packing.
    #[arg(long, value_enum, default_value_t = PackingArg::from(DEFAULTS.packing))]
    packing: PackingArg,
    /// What to do with materials that already have an occlusionTexture.
    #[arg(long, value_enum, default_value_t = OcclusionArg::from(DEFAULTS.occlusion))]
    occlusion: OcclusionArg,
    /// Also write float EXR lightmaps into this directory.
    #[arg(long)]
    exr: Option<PathBuf>,
    /// Write a JSON report (stage times, texels, rays/s) to this file.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Bake texels inside or behind single-sided geometry as they are,
    /// instead of filling them from their nearest valid texel.
    #[arg(long)]
    no_inside_fill: bool,
    /// The visibility layer (SH of the visibility itself, for normal maps and glossy lobes): auto bakes it for primitives whose material has a normalTexture, roughnessFactor <= 0.5 or a clearcoat.
    #[arg(long, value_enum, default_value_t = VisibilityArg::Auto)]
    visibility: VisibilityArg,
    /// Smooth seams (vertex normals within 10 degrees): stitch both sides by least squares, or leave them.
    #[arg(long, value_enum, default_value_t = SeamArg::Stitch)]
    seams: SeamArg,
    /// SH order of the visibility layer: 3 (16 coefficients) or 2 (9).
    #[arg(long, default_value_t = DEFAULTS.visibility_order)]
    visibility_order: u32,
    /// Bake only shard I of N's pages into OUTPUT.shard-I-of-N (then: aobake merge OUTPUT). `auto` reads a Slurm array task's index and count, `auto/N` a Kubernetes Indexed Job's JOB_COMPLETION_INDEX (or Slurm's index) with N given.
    #[arg(long)]
    shard: Option<String>,
    /// Worker threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bars and no warnings.
    #[arg(long, short)]
    quiet: bool,
}

/// Write OUTPUT from the complete set of shard partials beside it
/// (OUTPUT.shard-I-of-N, from aobake IN OUTPUT --shard I/N): byte-identical
/// to baking in one process. Refuses a missing, truncated, duplicated or
/// mismatched partial and then writes nothing.
#[derive(Parser, Debug)]
#[command(name = "aobake merge", version)]
struct MergeCli {
    /// The output .glb the shards were given.
    output: PathBuf,
    /// No summary.
    #[arg(long, short)]
    quiet: bool,
}

/// Measure what quality each second buys on a scene: bakes a high-ray Monte
/// Carlo reference, sweeps both methods over a ladder of budgets on the same
/// atlas, and writes report.json, report.md, error_vs_time.svg/.png and
/// error maps.
#[derive(Parser, Debug)]
#[command(name = "aobake report", version)]
struct ReportCli {
    /// Input .glb or .gltf.
    input: PathBuf,
    /// Directory for the report files.
    #[arg(long, default_value = "aobake-report")]
    out: PathBuf,
    /// Atlas page edge in texels.
    #[arg(long, default_value_t = REPORT_DEFAULTS.resolution)]
    resolution: u32,
    /// Rays per texel of the Monte Carlo reference.
    #[arg(long, default_value_t = REPORT_DEFAULTS.reference_rays)]
    reference_rays: u32,
    /// Runs: mc:RAYS, sheared:SPARSE_RAYS:GATHER_RADIUS[:CELL_RAYS[:OMEGA_V[:MIN_WEIGHT]]] and adaptive:MEAN_RAYS[:PRE_RAYS:MAX_RAYS], comma-separated.
    #[arg(long, default_value = aobake::report::DEFAULT_BUDGETS)]
    budgets: String,
    /// Random seed of the runs (the reference uses a different one).
    #[arg(long, default_value_t = REPORT_DEFAULTS.seed)]
    seed: u64,
    /// Max occluder distance in world units [default: 0.1 x scene diagonal].
    #[arg(long)]
    max_distance: Option<f64>,
    /// Monte Carlo rays of the 1e-4 / 1e4 scale-stability bakes (0: skip them).
    #[arg(long, default_value_t = REPORT_DEFAULTS.stability_rays)]
    stability_rays: u32,
    /// Worker threads [default: all cores].
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar and no summary.
    #[arg(long, short)]
    quiet: bool,
}

/// Open a baked file in the relighting viewer: serves the page (viewer/)
/// and the file on 127.0.0.1 and prints the address to open. Needs the
/// viewer's npm dependencies (npm ci --prefix viewer).
#[derive(Parser, Debug)]
#[command(name = "aobake view", version)]
struct ViewCli {
    /// A baked .glb to show (the page can also open files itself).
    input: Option<PathBuf>,
    /// Port on 127.0.0.1 (0: any free port).
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// The viewer's directory.
    #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/viewer"))]
    viewer_dir: PathBuf,
}

fn run_view(cli: &ViewCli) -> anyhow::Result<()> {
    let site = aobake::view::ViewSite {
        root: cli.viewer_dir.clone(),
        model: cli.input.clone(),
    };
    site.check()?;
    let listener = aobake::view::bind(cli.port)?;
    let addr = listener.local_addr()?;
    let query = if site.model.is_some() {
        "?model=/model.glb"
    } else {
        ""
    };
    println!("aobake: viewer at http://{addr}/{query} (Ctrl-C stops it)");
    use std::io::Write;
    std::io::stdout().flush()?;
    aobake::view::serve(listener, site)?;
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let result = if args.get(1).is_some_and(|a| a == "report") {
        // argv[0] of the subcommand names it in usage and errors.
        let sub = std::iter::once("aobake report".into()).chain(args[2..].iter().cloned());
        run_report(&ReportCli::parse_from(sub))
    } else if args.get(1).is_some_and(|a| a == "merge") {
        let sub = std::iter::once("aobake merge".into()).chain(args[2..].iter().cloned());
        run_merge(&MergeCli::parse_from(sub))
    } else if args.get(1).is_some_and(|a| a == "view") {
        let sub = std::iter::once("aobake view".into()).chain(args[2..].iter().cloned());
        run_view(&ViewCli::parse_from(sub))
    } else {
        run(&Cli::parse_from(&args))
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("aobake: error: {}", cli_error(e));
            ExitCode::FAILURE
        }
    }
}

fn set_threads(threads: Option<usize>) -> anyhow::Result<()> {
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()?;
    }
    Ok(())
}

fn run_merge(cli: &MergeCli) -> anyhow::Result<()> {
    let merged = aobake::shard::merge(&cli.output)?;
    if !cli.quiet {
        for w in &merged.warnings {
            eprintln!("aobake: warning: {w}");
        }
        eprintln!(
            "aobake: merged {} shards ({} page{} of {}) into {}",
            merged.shards,
            merged.pages,
            if merged.pages == 1 { "" } else { "s" },
            merged.input.display(),
            cli.output.display()
        );
    }
    Ok(())
}

fn run_report(cli: &ReportCli) -> anyhow::Result<()> {
    set_threads(cli.threads)?;
    let settings = ReportSettings {
        resolution: cli.resolution,
        reference_rays: cli.reference_rays,
        budgets: aobake::report::parse_budgets(&cli.budgets)?,
        seed: cli.seed,
        max_distance: cli.max_distance,
        stability_rays: cli.stability_rays,
        progress: !cli.quiet,
        ..ReportSettings::default()
    };
    let mut timer = StageTimer::new();
    let scene = aobake::gltf::load(&cli.input)?;
    timer.lap("load");
    let sweep = aobake::report::sweep(&scene, &cli.input.display().to_string(), timer, &settings)?;
    let report = aobake::report::write_report(&sweep, &cli.out)?;
    if !cli.quiet {
        print!("{}", aobake::report::markdown(&report));
        eprintln!(
            "aobake: report written to {} ({})",
            cli.out.display(),
            report.files.join(", ")
        );
    }
    Ok(())
}

fn run(cli: &Cli) -> anyhow::Result<()> {
    set_threads(cli.threads)?;
    let settings = Settings {
        size: match cli.texel_density {
            Some(t) => AtlasSize::TexelDensity {
                density: t,
                page_size: cli.page_size,
            },
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
            MethodArg::Sheared => Method::Sheared,
            MethodArg::Adaptive => Method::Adaptive,
        },
        rays: cli.rays,
        filter: aobake::bake::sheared::ShearedOptions {
            sparse_rays: cli.sparse_rays,
            gather_radius: cli.gather_radius,
            omega_v_max: cli.omega_v,
            cell_rays: cli.cell_rays,
            min_weight: cli.min_weight,
        },
        adaptive: aobake::bake::adaptive::AdaptiveOptions {
            quality: cli.quality,
            mean_rays: cli.mean_rays.unwrap_or(0),
            ..DEFAULTS.adaptive
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
        fill_inside: !cli.no_inside_fill,
        visibility: match cli.visibility {
            VisibilityArg::Auto => VisibilityMode::Auto,
            VisibilityArg::All => VisibilityMode::All,
            VisibilityArg::Off => VisibilityMode::Off,
        },
        visibility_order: cli.visibility_order,
        seams: match cli.seams {
            SeamArg::Stitch => SeamMode::Stitch,
            SeamArg::Off => SeamMode::Off,
        },
    };
    let report = match &cli.shard {
        Some(text) => {
            let shard = aobake::shard::Shard::parse(text, &|k| std::env::var(k).ok())?;
            let (path, report) =
                aobake::shard::run_shard(&cli.input, &cli.output, &settings, shard)?;
            if !cli.quiet {
                let mine: Vec<u32> = report
                    .pages
                    .iter()
                    .filter(|p| p.baked)
                    .map(|p| p.page)
                    .collect();
                eprintln!(
                    "aobake: shard {}/{}: pages {mine:?} of {} into {}",
                    shard.index,
                    shard.count,
                    report.pages.len(),
                    path.display()
                );
            }
            report
        }
        None => aobake::run(&cli.input, &cli.output, &settings)?,
    };
    if !cli.quiet {
        for w in &report.warnings {
            eprintln!("aobake: warning: {w}");
        }
        eprintln!(
            "aobake: baked {} texels ({} page{} of {}x{}) with {} rays in {:.2} s ({:.2} Mrays/s)",
            report.texels,
            report.pages.iter().filter(|p| p.baked).count(),
            if report.pages.iter().filter(|p| p.baked).count() == 1 {
                ""
            } else {
                "s"
            },
            report.atlas_width,
            report.atlas_height,
            report.rays_cast,
            report.total_seconds,
            report.rays_per_second / 1e6
        );
    }
    if let Some(path) = &cli.report {
        let text = serde_json::to_vec_pretty(&report)?;
        aobake::file::write_atomic(path, &text)?;
    }
    Ok(())
}
