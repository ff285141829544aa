//! The command line's flags of the two settings enums whose variants
//! carry values, written out rather than derived: `--resolution` or
//! `--texel-density` with `--page-size` ([`AtlasSize`]); `--uv` with
//! `--uv-set` ([`UvSource`]). Built with the `cli` feature only.
//!
//! In: clap's matches. Out: the library's values.

use super::{AtlasSize, DEFAULT_PAGE_SIZE, DEFAULT_RESOLUTION, UvSource};
use clap::{Arg, ArgMatches, Args, Command, FromArgMatches};

fn matched<T: Clone + Send + Sync + 'static>(m: &ArgMatches, id: &str) -> Option<T> {
    m.try_get_one::<T>(id).ok().flatten().cloned()
}

impl Args for AtlasSize {
    fn augment_args(cmd: Command) -> Command {
        cmd.arg(
            Arg::new("resolution")
                .long("resolution")
                .value_name("N")
                .value_parser(clap::value_parser!(u32))
                .default_value(DEFAULT_RESOLUTION.to_string())
                .conflicts_with("texel_density")
                .help("Atlas page edge in texels, the densest fit on one page"),
        )
        .arg(
            Arg::new("texel_density")
                .long("texel-density")
                .value_name("T")
                .value_parser(clap::value_parser!(f64))
                .help("Texels per world unit instead, on as many pages as the charts need"),
        )
        .arg(
            Arg::new("page_size")
                .long("page-size")
                .value_name("E")
                .value_parser(clap::value_parser!(u32))
                .default_value(DEFAULT_PAGE_SIZE.to_string())
                .help("With --texel-density: the largest page edge in texels (the last page may be smaller)"),
        )
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for AtlasSize {
    fn from_arg_matches(m: &ArgMatches) -> std::result::Result<Self, clap::Error> {
        Ok(match matched::<f64>(m, "texel_density") {
            Some(density) => AtlasSize::TexelDensity {
                density,
                page_size: matched(m, "page_size").unwrap_or(DEFAULT_PAGE_SIZE),
            },
            None => AtlasSize::Resolution(matched(m, "resolution").unwrap_or(DEFAULT_RESOLUTION)),
        })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> std::result::Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl Args for UvSource {
    fn augment_args(cmd: Command) -> Command {
        cmd.arg(
            Arg::new("uv")
                .long("uv")
                .value_name("SOURCE")
                .value_parser(["generate", "existing"])
                .default_value("generate")
                .help("Lightmap UVs: generate a new atlas (a new TEXCOORD_n), or reuse the set --uv-set"),
        )
        .arg(
            Arg::new("uv_set")
                .long("uv-set")
                .value_name("N")
                .value_parser(clap::value_parser!(usize))
                .default_value("1")
                .help("The TEXCOORD set that --uv existing reuses"),
        )
    }

    fn augment_args_for_update(cmd: Command) -> Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for UvSource {
    fn from_arg_matches(m: &ArgMatches) -> std::result::Result<Self, clap::Error> {
        Ok(match matched::<String>(m, "uv").as_deref() {
            Some("existing") => UvSource::Existing(matched(m, "uv_set").unwrap_or(1)),
            _ => UvSource::Generate,
        })
    }

    fn update_from_arg_matches(&mut self, m: &ArgMatches) -> std::result::Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::*;

    #[test]
    fn the_flags_parse_into_the_library_settings() {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            s: BakeSettings,
            #[command(flatten)]
            run: RunOptions,
        }
        use clap::Parser;
        let parse = |args: &[&str]| {
            Cli::try_parse_from(std::iter::once("aobake").chain(args.iter().copied()))
        };
        let none = parse(&[]).unwrap();
        assert_eq!(none.s, BakeSettings::DEFAULT);
        assert_eq!(none.run, RunOptions::default());
        let some = parse(&[
            "--texel-density",
            "28",
            "--page-size",
            "1024",
            "--uv",
            "existing",
            "--uv-set",
            "2",
            "--method",
            "filtered",
            "--no-inside-fill",
            "--omega-v",
            "3",
            "--mean-rays",
            "64",
            "-q",
        ])
        .unwrap();
        assert_eq!(
            some.s.size,
            AtlasSize::TexelDensity {
                density: 28.0,
                page_size: 1024
            }
        );
        assert_eq!(some.s.uv, UvSource::Existing(2));
        assert_eq!(some.s.method, Method::Sheared);
        assert!(!some.s.fill_inside);
        assert_eq!(some.s.sheared.omega_v_max, 3.0);
        assert_eq!(some.s.adaptive.mean_rays, 64);
        assert_eq!(some.s.adaptive.pre_rays, AdaptiveOptions::DEFAULT.pre_rays);
        assert!(!some.run.progress);
        assert!(parse(&["--resolution", "64", "--texel-density", "3"]).is_err());
    }
}
