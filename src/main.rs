//! The `aobake` command line.
//!
//! Every option is derived from the library's own types: [`BakeSettings`]
//! and [`RunOptions`] (their fields' doc comments are the help lines, their
//! enums the possible values), [`ReportSettings`] for `aobake report`.
//! Every command runs through [`aobake::job`]. The README's usage blocks
//! are this program's `--help` output, checked by `tests/cli.rs`.

use aobake::job::{self, BakeSettings, Rebake, RunOptions};
use aobake::report::ReportSettings;
use aobake::shard::Shard;
use aobake::stage::StageTimer;
use clap::{Args, CommandFactory, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// Bake ambient occlusion and SH9 directional occlusion lightmaps into a
/// glTF file.
#[derive(Parser, Debug)]
#[command(
    name = "aobake",
    version,
    term_width = 80,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    override_usage = "aobake IN OUT [OPTIONS]\n       aobake <COMMAND> [ARGS]"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    bake: BakeArgs,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Bake IN into OUT (the same as `aobake IN OUT`)
    Bake(Box<BakeArgs>),
    /// Write OUT from the complete set of shard partials beside it
    /// (OUT.shard-I-of-N, from `aobake IN OUT --shard I/N`), byte-identical
    /// to a bake in one process; refuses a missing, truncated, duplicated or
    /// mismatched partial and then writes nothing
    Merge(MergeArgs),
    /// Measure AO and SH error against run time for each method on a scene:
    /// a high-ray Monte Carlo reference, the methods over a ladder of
    /// budgets on the same atlas; writes report.json, report.md,
    /// error_vs_time.svg/.png and error maps
    Report(ReportArgs),
    /// Relight a baked file in the browser viewer: serves the page (built
    /// into this program) and the file on 127.0.0.1 and prints the address
    View(ViewArgs),
}

/// `aobake IN OUT` and `aobake bake IN OUT`.
#[derive(Args, Debug)]
struct BakeArgs {
    /// Input .glb or .gltf (never written)
    #[arg(value_name = "IN", required = true)]
    input: Option<PathBuf>,
    /// Output .glb, written atomically
    #[arg(value_name = "OUT", required = true)]
    output: Option<PathBuf>,
    #[command(flatten)]
    settings: BakeSettings,
    /// Bake only shard I of N's pages into OUT.shard-I-of-N, then run
    /// `aobake merge OUT`; auto: a Slurm array task's index and count,
    /// auto/N: a Kubernetes Indexed Job's JOB_COMPLETION_INDEX
    #[arg(long, value_name = "I/N|auto|auto/N")]
    shard: Option<String>,
    /// An earlier output of aobake (only read): taken as OUT when nothing
    /// the bake reads changed since (the input's bytes, the settings, this
    /// aobake); after an edit that keeps PREV's atlas (nodes moved), the
    /// pages no ray of the edit reaches are PREV's and the others are baked
    /// on PREV's atlas; else every texel is baked and a line says why
    #[arg(long, value_name = "PREV")]
    reuse: Option<PathBuf>,
    /// With --reuse: bake again the pages an edit can change; texels: on
    /// them only the texels it can change where the page's solve allows
    /// (else the page, after a try); or all (on PREV's atlas when it is
    /// kept) [default: changed]
    #[arg(long, value_enum, value_name = "WHAT")]
    rebake: Option<Rebake>,
    #[command(flatten)]
    run: RunOptions,
    /// Write a JSON report (stage times, texels, rays, layer, seam jumps)
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Worker threads [default: all cores]
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
}

/// `aobake merge OUT`.
#[derive(Args, Debug)]
struct MergeArgs {
    /// The output .glb the shards were given
    #[arg(value_name = "OUT")]
    output: PathBuf,
    /// No summary and no warnings
    #[arg(short, long)]
    quiet: bool,
}

/// `aobake report IN`.
#[derive(Args, Debug)]
struct ReportArgs {
    /// Input .glb or .gltf
    #[arg(value_name = "IN")]
    input: PathBuf,
    /// Directory for the report files
    #[arg(long, value_name = "DIR", default_value = "aobake-report")]
    out: PathBuf,
    #[command(flatten)]
    settings: ReportSettings,
    /// Worker threads [default: all cores]
    #[arg(long, value_name = "N")]
    threads: Option<usize>,
}

/// `aobake view [OUT]`.
#[derive(Args, Debug)]
struct ViewArgs {
    /// A baked .glb to show (the page can also open files itself)
    #[arg(value_name = "OUT")]
    input: Option<PathBuf>,
    /// Port on 127.0.0.1 (0: any free port)
    #[arg(long, default_value_t = 8080)]
    port: u16,
    /// Serve the viewer from a checkout's viewer/ directory (the page's
    /// packages from the checkout's packages/) instead of the copy built in
    #[arg(long, value_name = "DIR")]
    viewer_dir: Option<PathBuf>,
    /// The engine the printed address opens (the page switches too):
    /// three.js, Babylon.js, or both side by side with one camera
    #[arg(long, value_enum, default_value_t = ViewEngine::Three)]
    engine: ViewEngine,
}

/// `aobake view --engine`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq)]
enum ViewEngine {
    Three,
    Babylon,
    Both,
}

/// The flag of a library setting, from the command line's own definition
/// (errors name settings by their field, which is the argument's id).
fn flag(setting: &str) -> String {
    let cmd = Cli::command();
    let commands = std::iter::once(&cmd).chain(cmd.get_subcommands());
    let found = commands
        .flat_map(|c| c.get_arguments())
        .find(|a| a.get_id() == setting);
    match found {
        Some(a) => match a.get_long() {
            Some(long) => format!("--{long}"),
            None => setting.to_uppercase(),
        },
        None => setting.to_string(),
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

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(),
        Err(e) => {
            // One line: clap's first, without its usage and hints.
            let text = e.render().to_string();
            let line = text.lines().next().unwrap_or_default();
            eprintln!("aobake: {} (see aobake --help)", line.trim_end_matches('.'));
            return ExitCode::from(2);
        }
    };
    let result = match cli.command {
        None => run_bake(&cli.bake),
        Some(Command::Bake(b)) => run_bake(&b),
        Some(Command::Merge(m)) => run_merge(&m),
        Some(Command::Report(r)) => run_report(&r),
        Some(Command::View(v)) => run_view(&v),
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

fn run_bake(cli: &BakeArgs) -> anyhow::Result<()> {
    set_threads(cli.threads)?;
    let (Some(input), Some(output)) = (&cli.input, &cli.output) else {
        anyhow::bail!("give IN and OUT");
    };
    let (s, run) = (&cli.settings, &cli.run);
    let quiet = !run.progress;
    if cli.rebake.is_some() && cli.reuse.is_none() {
        anyhow::bail!("--rebake needs --reuse PREV");
    }
    let prev = (cli.reuse.as_deref()).map(|p| (p, cli.rebake.unwrap_or_default()));
    let report = match &cli.shard {
        Some(text) => {
            let shard = Shard::parse(text, &|k| std::env::var(k).ok())?;
            let (path, report) = job::bake_shard(input, output, prev, s, run, shard)?;
            if !quiet {
                let mine: Vec<u32> = (report.pages.iter())
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
        None => job::bake_reusing(input, output, prev, s, run)?,
    };
    if !quiet {
        for w in &report.warnings {
            eprintln!("aobake: warning: {w}");
        }
        match &report.reuse {
            Some(r) if r.reused => {
                eprintln!(
                    "aobake: reused {}: nothing the bake reads changed, {} is its bytes ({:.2} s)",
                    r.prev,
                    output.display(),
                    report.total_seconds
                );
                return write_report(cli, &report);
            }
            Some(r) => match &r.full_bake {
                Some(why) if r.carried => eprintln!(
                    "aobake: {} of {} pages taken from {} (no ray of the edit reaches them), the others baked on its atlas, allocation and ranges ({why})",
                    r.pages_reused,
                    report.pages.len(),
                    r.prev
                ),
                Some(why) => eprintln!("aobake: full bake, {} not reused: {why}", r.prev),
                None => {}
            },
            None => {}
        }
        let pages = report.pages.iter().filter(|p| p.baked).count();
        eprintln!(
            "aobake: baked {} texels ({} page{} of {}x{}) with {} rays in {:.2} s ({:.2} Mrays/s)",
            report.texels,
            pages,
            if pages == 1 { "" } else { "s" },
            report.atlas_width,
            report.atlas_height,
            report.rays_cast,
            report.total_seconds,
            report.rays_per_second / 1e6
        );
        let b = &report.backend;
        if let (Some(gpu), Some(cpu)) = (b.rays_on_gpu, b.rays_on_cpu)
            && gpu + cpu > 0
        {
            eprintln!(
                "aobake: of the batched rays, {:.1}% traced on the GPU, {:.1}% on the CPU",
                100.0 * gpu as f64 / (gpu + cpu) as f64,
                100.0 * cpu as f64 / (gpu + cpu) as f64
            );
        }
    }
    write_report(cli, &report)
}

fn write_report(cli: &BakeArgs, report: &job::Report) -> anyhow::Result<()> {
    if let Some(path) = &cli.report {
        let text = serde_json::to_vec_pretty(report)?;
        aobake::file::write_atomic(path, &text)?;
    }
    Ok(())
}

fn run_merge(cli: &MergeArgs) -> anyhow::Result<()> {
    let merged = job::merge(&cli.output)?;
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

fn run_report(cli: &ReportArgs) -> anyhow::Result<()> {
    set_threads(cli.threads)?;
    let settings = &cli.settings;
    let mut timer = StageTimer::new();
    let scene = aobake::gltf::load(&cli.input)?;
    timer.lap("load");
    let sweep = aobake::report::sweep(&scene, &cli.input.display().to_string(), timer, settings)?;
    let report = aobake::report::write_report(&sweep, &cli.out)?;
    if settings.progress {
        print!("{}", aobake::report::markdown(&report));
        eprintln!(
            "aobake: report written to {} ({})",
            cli.out.display(),
            report.files.join(", ")
        );
    }
    Ok(())
}

fn run_view(cli: &ViewArgs) -> anyhow::Result<()> {
    let site = aobake::view::ViewSite {
        root: cli.viewer_dir.clone(),
        model: cli.input.clone(),
    };
    site.check()?;
    let listener = aobake::view::bind(cli.port)?;
    let addr = listener.local_addr()?;
    let mut query = Vec::new();
    if site.model.is_some() {
        query.push("model=/model.glb");
    }
    match cli.engine {
        ViewEngine::Three => {}
        ViewEngine::Babylon => query.push("engine=babylon"),
        ViewEngine::Both => query.push("engine=both"),
    }
    let query = if query.is_empty() {
        String::new()
    } else {
        format!("?{}", query.join("&"))
    };
    println!("aobake: viewer at http://{addr}/{query} (Ctrl-C stops it)");
    use std::io::Write;
    std::io::stdout().flush()?;
    aobake::view::serve(listener, site)?;
    Ok(())
}
