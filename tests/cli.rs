//! The command line cannot drift from the code: the README's usage blocks
//! are the program's own `--help` output, every command has one, and the
//! help texts that quote a constant of the library quote its value.

use std::process::Command;

fn aobake(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_aobake"))
        .args(args)
        .output()
        .unwrap()
}

/// The ```console blocks of the README and docs/usage.md (the
/// subcommands') that start with `$ aobake ...`: the arguments and the
/// text after the command line.
fn readme_blocks() -> Vec<(Vec<String>, String)> {
    let read = |p: &str| {
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(p)).unwrap()
    };
    let text = read("README.md") + &read("docs/usage.md");
    let mut out = Vec::new();
    for block in text.split("```console\n").skip(1) {
        let block = &block[..block.find("```").expect("a closed block")];
        let (first, rest) = block.split_once('\n').unwrap_or((block, ""));
        if let Some(cmd) = first.strip_prefix("$ aobake") {
            let args = cmd.split_whitespace().map(str::to_string).collect();
            out.push((args, rest.to_string()));
        }
    }
    out
}

#[test]
fn the_readme_usage_is_the_programs_help() {
    let blocks = readme_blocks();
    for expected in [
        vec!["--help"],
        vec!["merge", "--help"],
        vec!["report", "--help"],
        vec!["view", "--help"],
    ] {
        assert!(
            blocks.iter().any(|(a, _)| *a == expected),
            "neither the README nor docs/usage.md has a block for aobake {}",
            expected.join(" ")
        );
    }
    for (args, text) in blocks {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = aobake(&args);
        assert!(out.status.success(), "aobake {args:?}");
        let help = String::from_utf8(out.stdout).unwrap();
        assert_eq!(
            help,
            text,
            "the block for `aobake {}` differs from the program's output (python3 tools/readme-usage.py)",
            args.join(" ")
        );
    }
}

#[test]
fn bake_is_the_same_command_as_the_default() {
    let top = String::from_utf8(aobake(&["--help"]).stdout).unwrap();
    let bake = String::from_utf8(aobake(&["bake", "--help"]).stdout).unwrap();
    // The same options; only the top level prints its version.
    let options = |s: &str| {
        let s = &s[s.find("Options:").unwrap()..];
        s[..s.find("  -V, --version").unwrap_or(s.len())].to_string()
    };
    assert_eq!(options(&top), options(&bake));
}

#[test]
fn help_texts_quote_the_library_constants() {
    let help = String::from_utf8(aobake(&["--help"]).stdout).unwrap();
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let roughness = aobake::gltf::scene::GLOSSY_ROUGHNESS;
    assert!(
        flat.contains(&format!("a roughnessFactor below {roughness}")),
        "--visibility's help must say the scene's threshold {roughness}"
    );
    let degrees = aobake::lightmap::seams::SMOOTH_DEGREES;
    let faces = aobake::lightmap::seams::FLAT_DEGREES;
    assert!(flat.contains(&format!(
        "vertex normals within {degrees} degrees, faces within {faces} degrees"
    )));
    let (edge, used) = (
        aobake::atlas::unwrap::LADDER_MAX_EDGE,
        aobake::atlas::unwrap::LADDER_UTILIZATION,
    );
    assert!(
        flat.contains(&format!(
            "page of at most {edge} texels that the asked padding and chart width fill to under {}%:",
            (used * 100.0).round()
        )),
        "--ladder's help must say when the ladder runs ({edge}, {used})"
    );
    let defaults = aobake::BakeSettings::DEFAULT;
    assert!(flat.contains(&format!("--quality <Q> Adaptive: the bake's error is that of QUALITY-ray Monte Carlo (its predicted AO RMSE over the atlas) [default: {}]", defaults.adaptive.quality)));
    // Every method is listed with the name the library gives it.
    for m in [
        aobake::Method::Adaptive,
        aobake::Method::Mc,
        aobake::Method::Sheared,
    ] {
        assert!(flat.contains(m.name()), "{}", m.name());
    }
}

#[test]
fn usage_errors_are_one_line() {
    for args in [
        vec!["in.glb"],
        vec!["in.glb", "out.glb", "--method", "nope"],
        vec![
            "in.glb",
            "out.glb",
            "--resolution",
            "64",
            "--texel-density",
            "3",
        ],
        vec!["merge"],
        vec!["report", "x.glb", "--budgets", "mc:0"],
    ] {
        let out = aobake(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.starts_with("aobake: error: "), "{err}");
    }
    // The old name of the sheared method still parses.
    let out = aobake(&["in.glb", "out.glb", "--method", "filtered", "--rays", "0"]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("invalid option: --rays"), "{err}");
}
