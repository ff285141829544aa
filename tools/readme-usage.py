#!/usr/bin/env python3
"""Rewrites the usage blocks of README.md and docs/usage.md (```console
blocks starting with `$ aobake ...`) from the program's own output, which
tests/cli.rs checks.

    cargo build && python3 tools/readme-usage.py [target/debug/aobake]
"""
import re
import subprocess
from pathlib import Path

from toolargs import parser, path

ap = parser(__doc__)
ap.add_argument("binary", nargs="?", default="target/debug/aobake", type=path,
                help="the aobake to run (default: target/debug/aobake)")
binary = ap.parse_args().binary
root = Path(__file__).resolve().parent.parent


def block(match):
    args = match.group(1).split()
    out = subprocess.run([binary, *args], capture_output=True, text=True, check=True).stdout
    return f"```console\n$ aobake {' '.join(args)}\n{out}```"


for page in [root / "README.md", root / "docs" / "usage.md"]:
    text = re.sub(r"```console\n\$ aobake ([^\n]*)\n.*?```", block, page.read_text(), flags=re.S)
    page.write_text(text)
