#!/usr/bin/env python3
"""The comparison table of docs/method-adaptive.md from `aobake report` directories.

    python3 tools/comparison.py docs/cornell-1024 docs/sponza-1024 ...

Per report: 256-ray Monte Carlo against the adaptive default (quality 256)
on the same atlas. "Equal error" is the issue's test: the default's AO RMSE,
AO 99th percentile and each SH band's RMSE all at most Monte Carlo's. The
time ratio is end to end (shared stages counted once in each). The last
column is the report's own equal-AO-RMSE time (log-log interpolation along
the adaptive curve) over Monte Carlo's.
"""
import json
import os

from toolargs import parser, path


def default_run(runs, method):
    for r in runs:
        if r["method"] == method and r["default_settings"]:
            return r
    return None


def row(path):
    rep = json.load(open(os.path.join(path, "report.json")))
    mc = next(r for r in rep["runs"] if r["label"] == "mc:256")
    ad = default_run(rep["runs"], "adaptive")
    name = os.path.basename(os.path.normpath(path))
    metrics = [("AO RMSE", lambda r: r["ao"]["rmse"]), ("p99", lambda r: r["ao"]["p99"])]
    metrics += [(f"SH L{b}", lambda r, b=b: r["sh_rmse_band"][b]) for b in range(3)]
    worse = [m for m, f in metrics if f(ad) > f(mc)]
    held = "yes" if not worse else "no (" + ", ".join(worse) + " higher)"
    # The cheapest adaptive run of the sweep that holds every metric.
    holding = [
        r
        for r in rep["runs"]
        if r["method"] == "adaptive" and all(f(r) <= f(mc) for _, f in metrics)
    ]
    cheapest = min(holding, key=lambda r: r["end_to_end_seconds"], default=None)
    every = (
        f"{cheapest['end_to_end_seconds'] / mc['end_to_end_seconds']:.2f}x ({cheapest['label']})"
        if cheapest
        else "none of the sweep"
    )
    eq = next(
        (m for m in rep["equal_error"]["methods"] if m["method"] == "adaptive"), None
    )
    eq_ratio = (
        f"{eq['seconds'] / rep['equal_error']['mc_seconds']:.2f}x"
        if eq and eq["seconds"]
        else "not reached"
    )

    def fmt(r):
        sh = " / ".join(f"{v:.4f}" for v in r["sh_rmse_band"])
        return (
            f"{r['end_to_end_seconds']:.2f} | {r['rays_per_texel']:.1f} | "
            f"{r['ao']['rmse']:.4f} | {r['ao']['p99']:.3f} | {sh}"
        )

    ratio = ad["end_to_end_seconds"] / mc["end_to_end_seconds"]
    inside = rep.get("texels_inside", 0)
    return (
        f"| {name} ({rep['texels']} texels, {inside} inside) | mc:256 | {fmt(mc)} | | | | |\n"
        f"| | {ad['label']} | {fmt(ad)} | **{ratio:.2f}x** | {held} | {every} | {eq_ratio} |"
    )


def main():
    ap = parser(__doc__)
    ap.add_argument("reports", nargs="+", type=path, help="`aobake report` output folders")
    reports = ap.parse_args().reports
    print(
        "| report | run | end-to-end s | rays/texel | AO RMSE | AO p99 | SH RMSE L0 / L1 / L2 "
        "| time vs mc:256 | equal error on every metric | cheapest run of the sweep holding every metric "
        "| equal-AO-RMSE time |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for p in reports:
        print(row(p))


if __name__ == "__main__":
    main()
