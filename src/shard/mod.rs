//! Shards: which pages shard I of N bakes, the partial file it writes,
//! and the checks a merge makes on a set of partials. A leaf: it knows
//! nothing of the bake job ([`crate::job::shard`] runs a shard and a
//! merge through the job).
//!
//! In: a [`Shard`] (given, or read from the scheduler's environment:
//! [`Shard::from_env`]), the pages' predicted costs, a shard's encoded
//! pages, and the partials beside an output. Out: the shard's pages
//! ([`assign`]), `OUT.shard-I-of-N` ([`partial`]), and from a set the
//! pages' images in page order, refused unless complete and of one bake
//! ([`read_set`]).
//!
//! Pages are dealt to shards by their predicted cost ([`page_cost`]),
//! largest first, each to the shard with the least so far ([`assign`]).

pub mod partial;

use crate::bits::mix64;
use crate::encode::Encoded;
use crate::error::{Error, Result};
use crate::file;
use partial::{Identity, Partial};
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
pub(crate) fn partial_path(output: &Path, shard: Shard) -> PathBuf {
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
    let mut h = 0x9E37_79B9_7F4A_7C15u64 ^ bytes.len() as u64;
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        h = mix64(h ^ u64::from_le_bytes(c.try_into().expect("8 bytes")));
    }
    let mut last = [0u8; 8];
    last[..chunks.remainder().len()].copy_from_slice(chunks.remainder());
    mix64(h ^ u64::from_le_bytes(last) ^ 0xFF)
}

/// What identifies a bake for its shards: this aobake, the input's bytes,
/// the settings' JSON (what decides the output bytes), the count of
/// shards and of pages.
pub fn identity(input_bytes: &[u8], settings_json: &[u8], count: u32, pages: u32) -> Identity {
    Identity {
        aobake: env!("CARGO_PKG_VERSION").to_string(),
        input_hash: format!("{:016x}", hash64(input_bytes)),
        settings_hash: format!("{:016x}", hash64(settings_json)),
        count,
        pages,
    }
}

/// A complete set of partials of one bake, checked ([`read_set`]).
pub struct PartialSet {
    /// Every partial, in shard order, with its path.
    pub partials: Vec<(PathBuf, Partial)>,
    /// Shards in the set.
    pub count: u32,
}

impl PartialSet {
    /// The first partial's path and header: what the set agrees on.
    pub fn reference(&self) -> (&Path, &partial::PartialHeader) {
        let (path, p) = &self.partials[0];
        (path, &p.header)
    }

    /// Every page's images, in page order.
    pub fn pages(&self) -> Vec<&Encoded> {
        let mut pages: Vec<(u32, &Encoded)> = (self.partials.iter())
            .flat_map(|(_, p)| p.pages.iter().map(|(k, e)| (*k, e)))
            .collect();
        pages.sort_by_key(|&(k, _)| k);
        pages.into_iter().map(|(_, e)| e).collect()
    }

    /// The refusal of the set's first partial, for `why`.
    pub fn refuse(&self, why: String) -> Error {
        refuse(self.reference().0, why)
    }
}

fn refuse(path: &Path, why: String) -> Error {
    Error::Merge(format!("{}: {why}", path.display()))
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

/// Reads the partials beside `output` and checks that they are one
/// complete set of one bake: each intact and under its own name, all of
/// one count, aobake, input, settings and page count, every shard and
/// every page present once.
pub fn read_set(output: &Path) -> Result<PartialSet> {
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
    let mut pages: Vec<Option<&Path>> = vec![None; page_count as usize];
    for (path, p) in &partials {
        for (page, _) in &p.pages {
            let slot = pages
                .get_mut(*page as usize)
                .ok_or_else(|| refuse(path, format!("holds page {page} of {page_count}")))?;
            if let Some(other) = slot {
                return Err(refuse(
                    path,
                    format!("holds page {page}, which {} holds too", other.display()),
                ));
            }
            *slot = Some(path);
        }
    }
    if let Some(k) = pages.iter().position(Option::is_none) {
        return Err(Error::Merge(format!(
            "no partial holds page {k} of {page_count}"
        )));
    }
    Ok(PartialSet { partials, count })
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
