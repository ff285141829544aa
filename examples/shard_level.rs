//! Shards a level's bake, as a farm does: the level is unwrapped into
//! several pages, each of N shards bakes its share of them into a partial
//! file beside the output, and a merge writes the file. The result is the
//! same bytes as one process's bake (checked here).
//!
//!     cargo run --release --example shard_level -- [IN.glb] [OUT.glb] [N]
//!
//! Defaults: the bundled courtyard at 8 texels per unit on pages of 256,
//! 3 shards. On a cluster each `bake_shard` is its own job (any order, any
//! machine sharing the folder) and the merge a job that depends on them:
//! `aobake IN OUT --shard I/N` and `aobake merge OUT`
//! (`examples/slurm/`, `examples/kubernetes/`).

use aobake::atlas::AtlasSize;
use aobake::job::shard::{bake_shard, merge};
use aobake::shard::Shard;
use aobake::{BakeSettings, RunOptions};
use std::path::PathBuf;

fn main() -> Result<(), aobake::Error> {
    let mut args = std::env::args().skip(1);
    let input = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "assets/generated/courtyard.glb".into()),
    );
    let output = PathBuf::from(args.next().unwrap_or_else(|| "courtyard_baked.glb".into()));
    let count: u32 = args.next().map_or(3, |n| n.parse().expect("N: a count"));
    let settings = BakeSettings {
        size: AtlasSize::TexelDensity {
            density: 8.0,
            page_size: 256,
        },
        ..BakeSettings::default()
    };
    let run = RunOptions::QUIET;
    for index in 0..count {
        let (partial, report) = bake_shard(
            &input,
            &output,
            None,
            &settings,
            &run,
            Shard { index, count },
        )?;
        let mine: Vec<u32> = (report.pages.iter())
            .filter(|p| p.baked)
            .map(|p| p.page)
            .collect();
        println!(
            "shard {index}/{count}: pages {mine:?} of {} -> {}",
            report.pages.len(),
            partial.display()
        );
    }
    let merged = merge(&output)?;
    println!(
        "merged {} shards, {} pages -> {}",
        merged.shards,
        merged.pages,
        output.display()
    );
    // One process, for comparison: the same bytes.
    let single = output.with_extension("single.glb");
    aobake::bake(&input, &single, &settings, &run)?;
    let same = std::fs::read(&single).ok() == std::fs::read(&output).ok();
    println!("one process's bake is the same bytes: {same}");
    std::fs::remove_file(&single).ok();
    Ok(())
}
