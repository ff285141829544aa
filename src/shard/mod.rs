//! Sharded bakes: shard I of N bakes its share of the pages into a
//! partial beside the output; a merge writes the output from the set,
//! byte-identical to a bake in one process.
//!
//! In: the input, the output path, the settings and a [`Shard`] (given,
//! or read from the scheduler's environment: [`Shard::from_env`]). Out:
//! `OUT.shard-I-of-N` ([`partial`]), written atomically; then [`merge`]
//! checks that the set is complete and of one bake and writes OUT.
//!
//! Pages are dealt to shards by their predicted cost ([`page_cost`]),
//! largest first, each to the shard with the least so far ([`assign`]). Every shard unwraps
//! the same atlas (the unwrap is deterministic) and bakes its pages with
//! the same per-page seeds as a bake in one process, so its encoded
//! images are the same bytes; the merge loads the input, unwraps again
//! (no ray is cast, no image re-encoded) and writes every page's images.

pub mod partial;

use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
use crate::gltf;
use crate::pipeline::{self, Report};
use crate::settings::Settings;
use crate::stage::StageTimer;
use partial::{FORMAT, Identity, Partial, PartialHeader};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Shard `index` of `count` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// Parses `I/N`; `auto` takes both from the scheduler's environment,
    /// `auto/N` only the index ([`Shard::from_env`]).
    pub fn parse(text: &str, env: &dyn Fn(&str) -> Option<String>) -> Result<Shard> {
        let bad = |why: &str| Error::option("shard", format!("{text:?}: {why}"));
        let (i, n) = text.split_once('/').unwrap_or((text, ""));
        let count = if n.is_empty() {
            None
        } else {
            Some(
                n.parse::<u32>()
                    .map_err(|_| bad("N must be a whole number"))?,
            )
        };
        let shard = if i == "auto" {
            Shard::from_env(count, env).map_err(|e| bad(&e))?
        } else {
            let index = i
                .parse::<u32>()
                .map_err(|_| bad("I must be a whole number"))?;
            Shard {
                index,
                count: count.ok_or_else(|| bad("give I/N"))?,
            }
        };
        if shard.count == 0 || shard.index >= shard.count {
            return Err(bad("needs 0 <= I < N"));
        }
        Ok(shard)
    }

    /// The shard from a scheduler's environment: a Slurm array task
    /// (`SLURM_ARRAY_TASK_ID` - `SLURM_ARRAY_TASK_MIN` of
    /// `SLURM_ARRAY_TASK_COUNT`) or a Kubernetes Indexed Job pod
    /// (`JOB_COMPLETION_INDEX`, with `count` given). `count` given wins
    /// over Slurm's.
    pub fn from_env(
        count: Option<u32>,
        env: &dyn Fn(&str) -> Option<String>,
    ) -> std::result::Result<Shard, String> {
        let num = |k: &str| -> std::result::Result<Option<u32>, String> {
            match env(k) {
                Some(v) => v
                    .trim()
                    .parse()
                    .map(Some)
                    .map_err(|_| format!("{k}={v} is not a whole number")),
                None => Ok(None),
            }
        };
        if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
            let min = num("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let count = count
                .or(num("SLURM_ARRAY_TASK_COUNT")?)
                .ok_or("SLURM_ARRAY_TASK_COUNT is not set")?;
            return Ok(Shard {
                index: id.checked_sub(min).ok_or("SLURM_ARRAY_TASK_ID < MIN")?,
                count,
            });
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX")? {
            let count = count.ok_or("a Kubernetes Indexed Job needs the count: auto/N")?;
            return Ok(Shard { index, count });
        }
        Err("neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set".into())
    }
}

/// The partial of `shard` beside `output`: `OUT.shard-I-of-N`.
pub fn partial_path(output: &Path, shard: Shard) -> PathBuf {
    let mut name = output.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".shard-{}-of-{}", shard.index, shard.count));
    output.with_file_name(name)
}

/// Weight of geometric detail in [`page_cost`].
pub const DETAIL_WEIGHT: f64 = 90.0;

/// A page's predicted bake cost, in texel units, from what is known
/// before any ray: its chart texels t and triangles n, as
/// t (1 + [`DETAIL_WEIGHT`] sqrt(n / t)). sqrt(n / t) is the inverse of a
/// triangle's edge in texels: pages of fine geometry have occluders within
/// a few texels of their receivers, where the adaptive method spends its
/// rays. Fitted on Sponza at density 28 on 8 pages of 1024, whose rays per
/// texel range from 23 to 139 (texels alone predict the shards' loads
/// 2.3 M / 2.2 M / 1.7 M texels and took 16.5 / 27.1 / 8.4 s).
pub fn page_cost(texels: f64, triangles: usize) -> f64 {
    texels + DETAIL_WEIGHT * (triangles as f64 * texels).sqrt()
}

/// Deals pages (their costs in `texels`) to `count` shards: the largest
/// first, each to the shard with the least so far (ties: the lower
/// shard). Each shard's pages ascending.
pub fn assign(texels: &[f64], count: u32) -> Vec<Vec<u32>> {
    let mut order: Vec<u32> = (0..texels.len() as u32).collect();
    order.sort_by(|&a, &b| {
        texels[b as usize]
            .total_cmp(&texels[a as usize])
            .then(a.cmp(&b))
    });
    let mut load = vec![0.0f64; count as usize];
    let mut out = vec![Vec::new(); count as usize];
    for p in order {
        let s = (0..count as usize)
            .min_by(|&a, &b| load[a].total_cmp(&load[b]).then(a.cmp(&b)))
            .expect("count > 0");
        load[s] += texels[p as usize];
        out[s].push(p);
    }
    for pages in &mut out {
        pages.sort_unstable();
    }
    out
}

/// A 64-bit hash of bytes (splitmix-style, over 8-byte words), for the
/// fingerprint: not cryptographic, only to tell files and settings apart.
pub fn hash64(bytes: &[u8]) -> u64 {
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut h = 0x9E37_79B9_7F4A_7C15u64 ^ bytes.len() as u64;
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        h = mix(h ^ u64::from_le_bytes(c.try_into().expect("8 bytes")));
    }
    let mut last = [0u8; 8];
    last[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    mix(h ^ u64::from_le_bytes(last) ^ 0xFF)
}

/// The settings as they decide the output bytes (progress bars and debug
/// outputs left out), as JSON.
fn settings_json(s: &Settings) -> serde_json::Value {
    let mut s = s.clone();
    s.progress = false;
    s.debug_dir = None;
    s.exr_dir = None;
    serde_json::to_value(&s).expect("settings serialize")
}

fn identity(input_bytes: &[u8], s: &Settings, count: u32, pages: u32) -> Identity {
    let settings = serde_json::to_vec(&settings_json(s)).expect("settings serialize");
    Identity {
        aobake: env!("CARGO_PKG_VERSION").to_string(),
        input_hash: format!("{:016x}", hash64(input_bytes)),
        settings_hash: format!("{:016x}", hash64(&settings)),
        count,
        pages,
    }
}

/// Bakes shard `shard`'s pages of `input` and writes its partial beside
/// `output` (atomically; a shard killed midway leaves none, a re-run
/// replaces it). Returns the partial's path and the shard's report.
pub fn run_shard(
    input: &Path,
    output: &Path,
    s: &Settings,
    shard: Shard,
) -> Result<(PathBuf, Report)> {
    pipeline::check_output(input, output)?;
    let mut timer = StageTimer::new();
    let (bytes, scene) = gltf::load_with_bytes(input)?;
    timer.lap("load");
    let level = pipeline::prepare_level(&scene, s, &mut timer)?;
    let costs: Vec<f64> = (level.atlas.page_areas().into_iter())
        .zip(level.atlas.page_triangles())
        .map(|(t, n)| page_cost(t, n))
        .collect();
    let mine = assign(&costs, shard.count).swap_remove(shard.index as usize);
    let done = pipeline::bake_pages(&scene, &level, &mine, s, &mut timer, &mut |_, _, _| {})?;
    let header = PartialHeader {
        format: FORMAT,
        identity: identity(&bytes, s, shard.count, level.page_count()),
        shard: shard.index,
        input: std::fs::canonicalize(input)
            .map_err(|e| Error::io(input, e))?
            .display()
            .to_string(),
        settings: settings_json(s),
        pages: Vec::new(),
    };
    let pages: Vec<(u32, &Encoded)> = done.iter().map(|d| (d.page, &d.encoded)).collect();
    let path = partial_path(output, shard);
    file::write_atomic(&path, &partial::write(header, &pages))?;
    timer.lap("save");
    let mut report = pipeline::level_report(&level, &done, s, scene.warnings.clone());
    report.input = input.display().to_string();
    report.shard = Some(shard);
    Ok((path, pipeline::finish_report(report, timer)))
}

/// What a merge did.
#[derive(Clone, Debug)]
pub struct Merged {
    pub shards: u32,
    pub pages: u32,
    pub input: PathBuf,
    pub warnings: Vec<String>,
}

/// The partials beside `output` (`OUT.shard-I-of-N`), by file name.
fn find_partials(output: &Path) -> Result<Vec<(PathBuf, Shard)>> {
    let dir = file::parent_dir(output);
    let stem = output
        .file_name()
        .ok_or_else(|| Error::option("output", format!("{} is not a file", output.display())))?
        .to_string_lossy()
        .to_string();
    let prefix = format!("{stem}.shard-");
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name().to_string_lossy().to_string();
        let Some(rest) = name.strip_prefix(&prefix) else {
            continue;
        };
        let parsed = rest
            .split_once("-of-")
            .and_then(|(i, n)| Some((i.parse().ok()?, n.parse().ok()?)));
        if let Some((index, count)) = parsed {
            out.push((dir.join(&name), Shard { index, count }));
        }
    }
    out.sort_by_key(|(_, s)| (s.count, s.index));
    Ok(out)
}

/// Checks that the partials beside `output` are one complete set of one
/// bake and writes `output` from them (atomically; on any refusal nothing
/// is written). The input is read again from the path the shards baked.
pub fn merge(output: &Path) -> Result<Merged> {
    let refuse = |path: &Path, why: String| Error::Merge(format!("{}: {why}", path.display()));
    let found = find_partials(output)?;
    let Some((first_path, first)) = found.first().cloned() else {
        return Err(Error::Merge(format!(
            "no partial beside {} (expected {}.shard-I-of-N)",
            output.display(),
            output.display()
        )));
    };
    let mut partials: Vec<(PathBuf, Partial)> = Vec::new();
    for (path, named) in &found {
        let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        let p = partial::read(&bytes).map_err(|why| refuse(path, why))?;
        if p.header.shard != named.index || p.header.identity.count != named.count {
            return Err(refuse(
                path,
                format!(
                    "holds shard {}/{} under another shard's name (a copy or a duplicate)",
                    p.header.shard, p.header.identity.count
                ),
            ));
        }
        partials.push((path.clone(), p));
    }
    let reference = &partials[0].1.header;
    for (path, p) in &partials[1..] {
        let (a, b) = (&reference.identity, &p.header.identity);
        let why = if a.count != b.count {
            Some(format!(
                "is shard {} of {}, but {} is of {}",
                p.header.shard,
                b.count,
                first_path.display(),
                a.count
            ))
        } else if a.aobake != b.aobake {
            Some(format!(
                "baked by aobake {}, {} by {}",
                b.aobake,
                first_path.display(),
                a.aobake
            ))
        } else if a.input_hash != b.input_hash || reference.input != p.header.input {
            Some(format!(
                "baked from another input ({}) than {}",
                p.header.input,
                first_path.display()
            ))
        } else if a.settings_hash != b.settings_hash {
            Some(format!(
                "baked with other settings than {}",
                first_path.display()
            ))
        } else if a.pages != b.pages {
            Some(format!(
                "has {} pages, {} has {}",
                b.pages,
                first_path.display(),
                a.pages
            ))
        } else {
            None
        };
        if let Some(why) = why {
            return Err(refuse(path, why));
        }
    }
    let count = first.count;
    if let Some(missing) = (0..count).find(|i| !partials.iter().any(|(_, p)| p.header.shard == *i))
    {
        return Err(Error::Merge(format!(
            "{} is missing: the set of {count} is incomplete",
            partial_path(
                output,
                Shard {
                    index: missing,
                    count
                }
            )
            .display()
        )));
    }
    let page_count = reference.identity.pages;
    let mut pages: Vec<Option<(&Path, &Encoded)>> = vec![None; page_count as usize];
    for (path, p) in &partials {
        for (page, e) in &p.pages {
            let slot = pages
                .get_mut(*page as usize)
                .ok_or_else(|| refuse(path, format!("holds page {page} of {page_count}")))?;
            if let Some((other, _)) = slot {
                return Err(refuse(
                    path,
                    format!("holds page {page}, which {} holds too", other.display()),
                ));
            }
            *slot = Some((path, e));
        }
    }
    if let Some(k) = pages.iter().position(Option::is_none) {
        return Err(Error::Merge(format!(
            "no partial holds page {k} of {page_count}"
        )));
    }
    // The input as the shards saw it, and the same settings.
    let input = PathBuf::from(&reference.input);
    let (bytes, scene) = gltf::load_with_bytes(&input)?;
    let settings: Settings = serde_json::from_value(reference.settings.clone())
        .map_err(|e| refuse(&first_path, format!("unreadable settings ({e})")))?;
    let expected = identity(&bytes, &settings, count, page_count);
    if expected.input_hash != reference.identity.input_hash {
        return Err(refuse(
            &first_path,
            format!("{} changed since the shards baked it", input.display()),
        ));
    }
    if expected.aobake != reference.identity.aobake {
        return Err(refuse(
            &first_path,
            format!(
                "baked by aobake {}, this is {}",
                reference.identity.aobake, expected.aobake
            ),
        ));
    }
    pipeline::check_output(&input, output)?;
    let mut timer = StageTimer::new();
    let level = pipeline::prepare_level(&scene, &settings, &mut timer)?;
    if level.page_count() != page_count {
        return Err(refuse(
            &first_path,
            format!(
                "{page_count} pages, but the input unwraps into {}",
                level.page_count()
            ),
        ));
    }
    let encoded: Vec<&Encoded> = pages.iter().map(|p| p.expect("checked").1).collect();
    let (glb, warnings) = pipeline::write(
        &scene,
        &level,
        &encoded,
        &settings,
        Some(file::parent_dir(output)),
        &mut timer,
    )?;
    file::write_atomic(output, &glb)?;
    Ok(Merged {
        shards: count,
        pages: page_count,
        input,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_are_dealt_largest_first_to_the_lightest_shard() {
        let t = [10.0, 1.0, 7.0, 4.0, 4.0, 3.0];
        let a = assign(&t, 3);
        assert_eq!(a, vec![vec![0], vec![2, 5], vec![1, 3, 4]]);
        let load: Vec<f64> = a
            .iter()
            .map(|p| p.iter().map(|&k| t[k as usize]).sum())
            .collect();
        assert_eq!(load, vec![10.0, 10.0, 9.0]);
        // More shards than pages: some get none.
        assert_eq!(assign(&[1.0], 2), vec![vec![0], vec![]]);
    }

    #[test]
    fn shards_come_from_the_argument_or_the_scheduler() {
        let none = |_: &str| None;
        assert_eq!(
            Shard::parse("2/3", &none).unwrap(),
            Shard { index: 2, count: 3 }
        );
        assert!(Shard::parse("3/3", &none).is_err());
        assert!(Shard::parse("1", &none).is_err());
        assert!(Shard::parse("auto", &none).is_err());
        let slurm = |k: &str| match k {
            "SLURM_ARRAY_TASK_ID" => Some("5".to_string()),
            "SLURM_ARRAY_TASK_MIN" => Some("4".to_string()),
            "SLURM_ARRAY_TASK_COUNT" => Some("3".to_string()),
            _ => None,
        };
        assert_eq!(
            Shard::parse("auto", &slurm).unwrap(),
            Shard { index: 1, count: 3 }
        );
        let k8s = |k: &str| (k == "JOB_COMPLETION_INDEX").then(|| "2".to_string());
        assert_eq!(
            Shard::parse("auto/4", &k8s).unwrap(),
            Shard { index: 2, count: 4 }
        );
        assert!(Shard::parse("auto", &k8s).is_err());
    }

    #[test]
    fn the_hash_tells_inputs_apart() {
        assert_ne!(hash64(b"abc"), hash64(b"abd"));
        assert_ne!(hash64(b""), hash64(&[0]));
        assert_ne!(hash64(&[0; 8]), hash64(&[0; 16]));
        assert_eq!(hash64(b"same bytes"), hash64(b"same bytes"));
    }
}
