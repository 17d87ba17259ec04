"""`gyrodrift align`: SINS alignment on a rocking base (paper 004).

Monte Carlo study (default): for each scenario, --runs seeded records of --duration-s at 400 Hz,
1 min inertial-frame coarse alignment then 15-state zero-velocity Kalman fine alignment, with
and without the real-time wavelet prefilter (db4, level 5, N = 256, forced; accelerometers
delayed 8 samples to match). Writes table.md / table.csv (beside the published figures and
the theory rows) and heading_<scenario>.png / level_<scenario>.png into --out-dir.
--mechanism: the prefilter mechanism study (which modelled effects make it help).
--real PATH: heading consistency across segments of a PSINS IMU log (e.g. lasergyro.imu).
"""

from __future__ import annotations

import argparse
import csv
import shutil
import time
from pathlib import Path
from typing import TYPE_CHECKING

from gyrodrift.cli import CliError
from gyrodrift.cli.common import (
    add_json_arg,
    add_progress_arg,
    check_out_dir,
    emit_json,
    progress_enabled,
)
from gyrodrift.defaults import DEFAULT_SAMPLE_RATE_HZ
from gyrodrift.io.atomic import atomic_output

__all__ = ["register", "run"]

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``align`` subcommand.

    Examples
    --------
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> args = p.parse_args(["align", "--scenario", "static", "--runs", "4"])
    >>> args.scenario, args.runs, args.duration_s, args.rate_hz, args.progress
    ('static', 4, 1800.0, 400.0, 'auto')
    """
    p = subparsers.add_parser(
        "align", help="SINS alignment Monte Carlo study, mechanism study, real-data consistency",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="all",
                   help="static, ship_mild, ship_moderate, vehicle_engine or all (default all)")
    p.add_argument("--runs", type=int, default=30,
                   help="Monte Carlo runs per scenario (default 30)")
    p.add_argument("--duration-s", type=float, default=1800.0,
                   help="record length, s (default 1800 = 30 min)")
    p.add_argument("--rate-hz", type=float, default=DEFAULT_SAMPLE_RATE_HZ,
                   help=f"IMU sample rate, Hz (default {DEFAULT_SAMPLE_RATE_HZ:g})")
    p.add_argument("--coarse-s", type=float, default=60.0, help="coarse alignment, s (default 60)")
    p.add_argument("--states", type=int, choices=(12, 15), default=15,
                   help="KF states (default 15)")
    p.add_argument("--kf-noise", choices=("spec", "samples"), default="spec",
                   help="KF process noise from the IMU spec or from the raw per-sample scatter")
    p.add_argument("--gyro-lsb-arcsec", type=float, default=0.0,
                   help="gyro pulse quantization, arcsec (0 = off)")
    p.add_argument("--dither-arcsec", type=float, default=0.0,
                   help="dither residue amplitude, arcsec (0 = off)")
    p.add_argument("--seed", type=int, default=2014, help="Monte Carlo seed (default 2014)")
    p.add_argument("--mechanism", action="store_true", help="run the mechanism study instead")
    p.add_argument("--real", metavar="PATH", help="real-data mode on a PSINS IMU log")
    p.add_argument("--segment-s", type=float, default=300.0,
                   help="real-data segment length, s (300 = 5 min)")
    p.add_argument("--out-dir", default="align_study",
                   help="output directory for the tables and plots (align_study)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_json_arg(p)
    add_progress_arg(p)
    p.set_defaults(func=run)


def _write(rows: list[dict[str, object]], out: Path, stem: str, title: str) -> str:
    from gyrodrift.papers.alignment_study import markdown_table

    md = f"### {title}\n\n" + markdown_table(rows) + "\n"
    with atomic_output(out / f"{stem}.md") as tmp:
        tmp.write_text(md)
    with atomic_output(out / f"{stem}.csv") as tmp, tmp.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    return md


def _plots(out: Path, name: str, results: dict, th: dict[str, float]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from gyrodrift.units import ARCSEC

    fig, ax = plt.subplots(figsize=(8, 4.5))
    for pre, color in ((False, "tab:red"), (True, "tab:blue")):
        if pre not in results:
            continue
        r = results[pre]
        t = r.t_fine_s / 60.0
        m = r.psi.mean(axis=0) / ARCSEC
        s = r.psi.std(axis=0, ddof=1) / ARCSEC if r.psi.shape[0] > 1 else 0 * m
        ax.plot(t, m, color=color, label=f"{r.label}: mean")
        ax.fill_between(t, m - s, m + s, color=color, alpha=0.2, label=f"{r.label}: ±1σ")
    ax.axhline(th["psi_ss_rad"] / ARCSEC, color="k", ls="--", label="steady-state theory")
    ax.set_ylim(th["psi_ss_rad"] / ARCSEC - 600, th["psi_ss_rad"] / ARCSEC + 600)
    ax.set_ylabel("heading error (arcsec)")
    _save_fine_time_plot(fig, ax, out / f"heading_{name}.png",
                         f"{name}: heading error, {results[next(iter(results))].psi.shape[0]} runs")
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for pre, ls in ((False, "-"), (True, "--")):
        if pre not in results:
            continue
        r = results[pre]
        for i, lab in enumerate(("phi_E", "phi_N")):
            ax.plot(r.t_fine_s / 60.0, r.level[:, :, i].mean(axis=0) / ARCSEC, ls=ls,
                    label=f"{lab} {r.label}")
    ax.axhline(th["phi_e_ss_rad"] / ARCSEC, color="k", ls=":", label="theory -nab_N/g")
    ax.axhline(th["phi_n_ss_rad"] / ARCSEC, color="gray", ls=":", label="theory nab_E/g")
    ax.set_ylim(-300, 300)
    ax.set_ylabel("level error, mean over runs (arcsec)")
    _save_fine_time_plot(fig, ax, out / f"level_{name}.png", f"{name}: level errors")


def _save_fine_time_plot(fig: Figure, ax: Axes, path: Path, title: str) -> None:
    """Common finish of the study plots (x axis: fine alignment time): label, title, legend,
    grid, save at 110 dpi, close."""
    import matplotlib.pyplot as plt

    ax.set_xlabel("fine alignment time (min)")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=110)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    """Run ``gyrodrift align``; returns the exit code. The output directory is checked first
    and, when this run creates it, removed again if the run fails (no empty directory).

    Examples
    --------
    >>> import os, tempfile
    >>> p = argparse.ArgumentParser(prog="gyrodrift"); register(p.add_subparsers())
    >>> with tempfile.TemporaryDirectory() as d:  # a study takes minutes; a bad option, at once
    ...     run(p.parse_args(["align", "--runs", "1", "--out-dir", os.path.join(d, "out")]))
    Traceback (most recent call last):
    ...
    gyrodrift.cli.CliError: --runs must be >= 2 (a 1-sigma needs two runs)
    """
    out = check_out_dir(args.out_dir)
    assert out is not None
    top = out  # the outermost directory this run creates (None: it exists already)
    while not top.parent.exists():
        top = top.parent
    created = None if out.exists() else top
    out.mkdir(parents=True, exist_ok=True)
    try:
        return _run(args, out)
    except BaseException:
        if created is not None:
            shutil.rmtree(created, ignore_errors=True)
        raise


def _run(args: argparse.Namespace, out: Path) -> int:
    from gyrodrift.nav.trajectory import SCENARIOS
    from gyrodrift.papers.alignment_study import (
        MECHANISMS,
        PUBLISHED_RAW_ROW,
        PUBLISHED_ROW,
        StudyConfig,
        run_study,
        summary_rows,
    )
    from gyrodrift.papers.imu_errors import ImuErrors

    if args.real:
        return _run_real(args, out)
    if args.runs < 2:
        raise CliError("--runs must be >= 2 (a 1-sigma needs two runs)")
    if not args.duration_s > 0 or not args.rate_hz > 0:
        raise CliError("--duration-s and --rate-hz must be > 0")
    show = progress_enabled(args)
    t0 = time.perf_counter()
    rows: list[dict[str, object]] = []
    if args.mechanism:
        for label, (scen, errors, kf_noise) in MECHANISMS.items():
            st = StudyConfig(scenario=scen, runs=args.runs, duration_s=args.duration_s,
                             rate_hz=args.rate_hz, coarse_s=args.coarse_s,
                             n_states=args.states, errors=errors, kf_noise=kf_noise,
                             seed=args.seed)
            res, th = run_study(st, progress=show)
            for r in summary_rows(scen, res, th):
                rows.append({"effect": label, **r})
        md = _write(rows, out, "mechanism", "Prefilter mechanism study")
    else:
        names = SCENARIOS if args.scenario == "all" else (args.scenario,)
        for name in names:
            if name not in SCENARIOS:
                raise CliError(f"unknown scenario {name!r}; choose from {', '.join(SCENARIOS)} "
                               "or all")
            errors = ImuErrors(gyro_lsb_arcsec=args.gyro_lsb_arcsec,
                               dither_residue_arcsec=args.dither_arcsec)
            st = StudyConfig(scenario=name, runs=args.runs, duration_s=args.duration_s,
                             rate_hz=args.rate_hz, coarse_s=args.coarse_s, n_states=args.states,
                             errors=errors, kf_noise=args.kf_noise, seed=args.seed)
            try:
                res, th = run_study(st, progress=show)
            except ValueError as exc:
                raise CliError(str(exc)) from None
            rows += summary_rows(name, res, th)
            if not args.no_plots:
                _plots(out, name, res, th)
        rows += [PUBLISHED_ROW, PUBLISHED_RAW_ROW]
        md = _write(rows, out, "table", "Alignment Monte Carlo (angles arcsec, times min)")
    wall_s = time.perf_counter() - t0
    if args.json:
        emit_json({"rows": rows, "out_dir": str(out), "wall_time_s": wall_s})
        return 0
    print(md)
    print(f"wall time {wall_s:.1f} s; outputs in {out}/")
    return 0


def _run_real(args: argparse.Namespace, out: Path) -> int:
    from gyrodrift.io.psins import read_psins_imu
    from gyrodrift.papers.alignment_realdata import align_segments, consistency_rows

    try:
        rec = read_psins_imu(args.real)
    except (OSError, ValueError) as exc:
        raise CliError(str(exc)) from None
    rows = []
    for kf_noise in ("spec", "samples"):
        try:
            segs = align_segments(rec, args.segment_s, args.coarse_s, kf_noise=kf_noise)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        rows += [{"kf_noise": kf_noise, **r} for r in consistency_rows(segs)]
    md = _write(rows, out, "real", f"Real data {Path(args.real).name}: heading consistency "
                f"across {args.segment_s:g}-s segments (no truth)")
    if args.json:
        emit_json({"rows": rows, "out_dir": str(out),
                   "segments": [{"start_s": s.start_s, "heading_deg": dict(s.heading_deg)}
                                for s in segs]})
        return 0
    print(md)
    print("segment headings (deg): " + "; ".join(
        f"{s.start_s / 60:.0f} min: " + ", ".join(f"{k} {v:.4f}" for k, v in s.heading_deg.items())
        for s in segs))
    return 0
