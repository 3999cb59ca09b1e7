"""The paper's Fig. 3 from a grid directory: f_SORL on every MO-Hopper evaluation context.

Every method's f_SORL return (Hopper's own scalar reward, the one SAC trains on), max over the
evaluation weights, against frames: mean ± standard error over seeds, SAC dashed in black. Then
which methods beat SAC at the end and by how much (paired over seeds, 95% bootstrap interval).

    morl-trl grid examples/grid/paper.toml --domains MOHopperDR-v5 --dir grids/hopper
    python examples/fsorl/hopper_figure.py grids/hopper                 # -> fsorl_MOHopperDR-v5.png
    python examples/fsorl/hopper_figure.py grids/quick --domain MOLunarLanderDR-v0

Any grid directory works (``morl-trl grid report DIR`` draws the same figure for every domain of
a grid); unfinished runs are drawn up to their last evaluation.
"""

import argparse
from pathlib import Path

from morl_trl.reporting.fsorl import grid_runs, plot_domain, sac_comparison, sorl_curves


def main(argv=None) -> Path:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grid_dir", help="a grid directory (with runs/*/eval/metrics.csv)")
    parser.add_argument("--domain", default="MOHopperDR-v5", help="training id of the domain to draw")
    parser.add_argument("--out", default=None, help="the PNG to write (default fsorl_<domain>.png)")
    args = parser.parse_args(argv)

    runs = grid_runs(args.grid_dir)
    if args.domain not in runs:
        raise SystemExit(f"no evaluated run of {args.domain} in {args.grid_dir}; domains there: {sorted(runs)}")
    png = plot_domain(args.domain, runs[args.domain], args.out or f"fsorl_{args.domain}.png")
    if png is None:
        raise SystemExit(f"the {args.domain} runs recorded no f_SORL (the env emits no original scalar reward)")
    print(f"figure: {png}")

    # f_SORL max at each run's last evaluation: {algo: {seed: {context: value}}}
    finals = {algo: {seed: {c: pts[max(pts)] for c, pts in sorl_curves(run).items()} for seed, run in by_seed.items()}
              for algo, by_seed in runs[args.domain].items()}
    for r in sac_comparison(finals):
        ci = "" if r.ci is None else f" [{r.ci[0]:.1f}, {r.ci[1]:.1f}]"
        diff = "" if r.difference is None else f"{r.difference:+.1f}{ci}"
        print(f"{r.context:32s} {r.method:16s} {r.mean:9.1f} ± {r.se:5.1f}  vs SAC {diff:24s} {r.verdict}")
    return png


if __name__ == "__main__":
    main()
