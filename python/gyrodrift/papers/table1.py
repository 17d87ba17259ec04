"""Reproduction of Table 1 of the 2006 paper (paper 000: Wang et al., "Comparative study on
digital filtering on the random drift of laser gyro", Chinese J. Lasers 33(11)):
Q, N, B (its eq. 8 fit) and STD of the raw record and of four filtered versions (db8 wavelet,
bior3.7 wavelet packet, AR model filter, AR(2)-Kalman), beside the published rows.

Default record (`default_record`): the paper gives no sample rate. Its raw row is matched
through these choices (see the documentation's validation page "Allan variance, noise
identification, PSD, command line, paper comparison"):

- the random part is the AR(2) drift of the paper's eq. (6) itself, y_k = -0.0340 y_{k-1}
  + 0.0252 y_{k-2} + r_k, whose low-frequency level sigma_r / (1 - a1 - a2) is set to the
  published N = 0.0012 deg/sqrt(h) (white-rate Allan line N' = 60 N (deg/h) sqrt(s));
- plus angle quantization of the published Q = 0.0035, read in the unit the paper's numbers
  actually have (``(deg/h)*s = arcsec``; see gyrodrift.stability.ieee952);
- the sample rate is then the one at which these two give the published STD = 0.0962 deg/h,
  var = gamma_AR N'^2 f_s + 2 Q^2 f_s^2, f_s = 1.737 Hz. (White rate of two-sided level N'^2
  has variance N'^2 f_s, gamma_AR = 1.019 is the AR(2)'s variance over its low-frequency
  level; a white angle error of std Q (arcsec) differenced over dt = 1/f_s is a rate of
  variance 2 Q^2 f_s^2 in (arcsec/s)^2 = (deg/h)^2.)
- B = 0.0794 deg/h is NOT put in: a flicker floor of 0.664 B = 0.053 deg/h alone has a
  variance of (B^2 / pi) ln(n) (two-sided PSD B^2/(2 pi f) over the record's band), which
  exceeds the published STD^2 for any record longer than about 100 samples, and it would
  also push the AR(2) lag-1 coefficient strongly positive. The published B and STD cannot
  both come from a stationary record with a flicker floor; we report our B honestly.
"""

from __future__ import annotations

import contextlib
import csv
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gyrodrift.errors import GyrodriftValueError
from gyrodrift.filters.ar2 import (
    KalmanFilter,
    ar_filter,
    ar_filter_pieces,
    fit_ar2,
    fit_ar2_chunks,
    kalman_filter,
)
from gyrodrift.filters.wavelet import wavelet_denoise
from gyrodrift.filters.wavelet_packet import wavelet_packet_denoise
from gyrodrift.io.json_text import json_text
from gyrodrift.io.records import is_file_backed, iter_chunks
from gyrodrift.simulation.records import simulate
from gyrodrift.stability import ieee952
from gyrodrift.stability.allan import AllanResult, oadev
from gyrodrift.stability.psd import Psd, welch_psd

__all__ = [
    "PAPER_AR2",
    "PAPER_TABLE1",
    "CompareReport",
    "CompareRow",
    "default_record",
    "default_record_rate_hz",
    "run_compare",
]

#: Table 1 of paper 000 as published: Q (printed under "(deg)", numerically arcsec),
#: N (deg/sqrt(h)), B (deg/h), STD (deg/h).
PAPER_TABLE1: dict[str, tuple[float, float, float, float]] = {
    "original": (0.0035, 0.0012, 0.0794, 0.0962),
    "db8 wavelet": (0.0069, 4.8548e-4, 0.0, 0.0201),
    "bior3.7 wavelet packet": (0.0069, 4.9396e-4, 0.0, 0.0203),
    "AR model": (8.7679e-4, 2.6560e-4, 0.0193, 0.0226),
    "AR(2)-Kalman": (4.9429e-4, 1.6080e-4, 0.0069, 0.0113),
}
#: The paper's eq. (6): AR(2) coefficients of the raw record.
PAPER_AR2 = (-0.0340, 0.0252)
DEFAULT_N_SAMPLES = 1 << 16
DEFAULT_SEED = 2006
#: A memory-mapped record longer than this (samples) is compared without holding it or a
#: filtered copy (`_run_compare_file`), in pieces of _PIECE samples.
FILE_BACKED_MIN = 1 << 20
_PIECE = 1 << 20


def _ar2_gamma(a1: float, a2: float) -> float:
    """var(y) / (sigma_r^2 / (1 - a1 - a2)^2): AR(2) variance over its low-frequency level
    (variance sigma_r^2 (1 - a2) / ((1 + a2) ((1 - a2)^2 - a1^2)), Box-Jenkins eq. 3.2.19)."""
    var_over_sr2 = (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))
    return var_over_sr2 * (1.0 - a1 - a2) ** 2


def default_record_rate_hz() -> float:
    """Sample rate at which AR(2)(N) + quantization(Q) have the published STD (docstring).

    Examples
    --------
    >>> 1.5 < default_record_rate_hz() < 2.0  # about one sample per 0.6 s
    True
    """
    _, n_pub, _, std_pub = PAPER_TABLE1["original"]
    q_as = PAPER_TABLE1["original"][0]
    n_line = 60.0 * n_pub  # (deg/h) sqrt(s)
    a = 2.0 * q_as * q_as
    b = _ar2_gamma(*PAPER_AR2) * n_line * n_line
    c = -std_pub * std_pub
    return (-b + math.sqrt(b * b - 4.0 * a * c)) / (2.0 * a)


def default_record(n: int = DEFAULT_N_SAMPLES, seed: int = DEFAULT_SEED) -> tuple[np.ndarray,
                                                                                   float]:
    """(rate_deg_h, rate_hz) of the default record (module docstring).

    Examples
    --------
    >>> x, fs = default_record(n=1024)
    >>> x.shape, fs == default_record_rate_hz()
    ((1024,), True)
    """
    rate_hz = default_record_rate_hz()
    a1, a2 = PAPER_AR2
    n_line = 60.0 * PAPER_TABLE1["original"][1]
    sigma_r = n_line * math.sqrt(rate_hz) * (1.0 - a1 - a2)  # white level N'^2 -> var N'^2 fs
    rec = simulate(n=n, rate_hz=rate_hz, q_deg=PAPER_TABLE1["original"][0] / 3600.0,
                             ar2=(a1, a2, sigma_r), seed=seed)
    return rec.rate_deg_h, rate_hz


@dataclass(frozen=True)
class CompareRow:
    """One signal of the Table-1 comparison: its Allan terms and STD (deg/h units), the published
    values, and its AllanResult and PSD.

    Examples
    --------
    >>> rep = run_compare(np.random.default_rng(0).normal(0.0, 1.0, 4096), 100.0)
    >>> row = rep.rows[0]
    >>> row.signal, round(row.n_deg_rt_h, 6), round(row.std_deg_h, 4), row.published
    ('original', 0.001614, 0.9976, (0.0035, 0.0012, 0.0794, 0.0962))
    """
    signal: str
    q_paper: float  # A_-2/sqrt(3), the paper's 'Q (deg)' column = arcsec
    n_deg_rt_h: float
    b_deg_h: float
    std_deg_h: float
    published: tuple[float, float, float, float] | None
    allan: AllanResult = field(repr=False)
    psd: Psd = field(repr=False)


@dataclass
class CompareReport:
    """The comparison: the record, the AR(2) of the raw record, one row per signal, and the files
    written.

    Examples
    --------
    >>> rep = run_compare(np.random.default_rng(0).normal(0.0, 1.0, 4096), 100.0)
    >>> rep.n_samples, rep.rate_hz, rep.files
    (4096, 100.0, {})
    >>> list(rep.as_dict())
    ['rate_hz', 'n_samples', 'source', 'ar2_measured', 'ar2_paper', 'rows', 'files']
    """
    rate_hz: float
    n_samples: int
    source: str
    ar2_measured: tuple[float, float]
    rows: list[CompareRow]
    files: dict[str, str] = field(default_factory=dict)

    def markdown(self) -> str:
        lines = [
            f"Record: {self.source}, {self.n_samples} samples at {self.rate_hz:.4g} Hz. "
            f"AR(2) of the raw record: a1 = {self.ar2_measured[0]:.4f}, "
            f"a2 = {self.ar2_measured[1]:.4f} (paper eq. 6: {PAPER_AR2[0]:.4f}, "
            f"{PAPER_AR2[1]:.4f}).",
            "",
            "Q is A_-2/sqrt(3) with sigma in deg/h and tau in s: the paper prints it under "
            "'(deg)', its unit is arcsec.",
            "",
            "| signal | source | Q (paper col., arcsec) | N (deg/sqrt(h)) | B (deg/h) | "
            "STD (deg/h) |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        for r in self.rows:
            if r.published is not None:
                q, n, b, s = r.published
                lines.append(f"| {r.signal} | paper (published) | {q:.4g} | {n:.4g} | "
                             f"{b:.4g} | {s:.4g} |")
            lines.append(f"| {r.signal} | ours (measured) | {r.q_paper:.4g} | "
                         f"{r.n_deg_rt_h:.4g} | {r.b_deg_h:.4g} | {r.std_deg_h:.4g} |")
        return "\n".join(lines) + "\n"

    def write_csv(self, path: Path) -> None:
        from gyrodrift.io.atomic import atomic_output

        with atomic_output(path) as tmp, tmp.open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["signal", "source", "q_paper_arcsec", "n_deg_rt_h", "b_deg_h",
                        "std_deg_h"])
            for r in self.rows:
                if r.published is not None:
                    w.writerow([r.signal, "paper (published)", *r.published])
                w.writerow([r.signal, "ours (measured)", r.q_paper, r.n_deg_rt_h, r.b_deg_h,
                            r.std_deg_h])

    def as_dict(self) -> dict[str, object]:
        return {
            "rate_hz": self.rate_hz, "n_samples": self.n_samples, "source": self.source,
            "ar2_measured": list(self.ar2_measured), "ar2_paper": list(PAPER_AR2),
            "rows": [{"signal": r.signal, "measured": {
                "q_paper_arcsec": r.q_paper, "n_deg_rt_h": r.n_deg_rt_h, "b_deg_h": r.b_deg_h,
                "std_deg_h": r.std_deg_h},
                "published": None if r.published is None else dict(zip(
                    ("q_paper_arcsec", "n_deg_rt_h", "b_deg_h", "std_deg_h"), r.published,
                    strict=True))} for r in self.rows],
            "files": self.files,
        }


def filters(x: np.ndarray) -> list[tuple[str, Callable[[], np.ndarray]]]:
    """The paper's four filters, each as (table label, thunk)."""
    model = fit_ar2(x, method="yule-walker")
    return [
        ("db8 wavelet", lambda: wavelet_denoise(x, wavelet="db8", level=5,
                                                          mode="soft")),
        ("bior3.7 wavelet packet", lambda: wavelet_packet_denoise(
            x, wavelet="bior3.7", level=4)),
        ("AR model", lambda: ar_filter(x, model)),
        ("AR(2)-Kalman", lambda: kalman_filter(x, model)),
    ]


def _row(label: str, y: np.ndarray, rate_hz: float, published_key: str | None,
         std: float | None = None) -> CompareRow:
    r = oadev(y, rate_hz, taus="octave", progress=False)
    fit = ieee952.paper_fit(r.tau_s, r.adev)
    return CompareRow(label, fit.q_paper, fit.n_deg_rt_h, fit.b_deg_h,
                      float(np.std(y)) if std is None else std,
                      PAPER_TABLE1.get(published_key) if published_key else None, r,
                      welch_psd(y, rate_hz))


def _std_pieces(y: np.ndarray) -> float:
    """numpy.std of a file-backed record (to rounding), in two passes over its pieces."""
    n = int(y.shape[0])
    mean = sum(float(np.sum(p)) for p in iter_chunks(y, _PIECE)) / n
    return math.sqrt(sum(float(np.sum(np.square(p - mean))) for p in iter_chunks(y, _PIECE))
                     / n)


def _file_filters(x: np.ndarray) -> tuple[Any, list[tuple[str, Callable[[], Iterator[
        np.ndarray]]]]]:
    """The AR(2) model and `filters` of a file-backed record, each filter's output in pieces
    (the same outputs: the offline denoisers from windows of the record,
    `gyrodrift.filters.wavelet_file`; the AR and Kalman filters with their state carried)."""
    from gyrodrift.filters.wavelet_file import (
        wavelet_denoise_pieces,
        wavelet_packet_denoise_pieces,
    )

    model = fit_ar2_chunks(lambda: iter_chunks(x, _PIECE), method="yule-walker")

    def kalman() -> Iterator[np.ndarray]:
        kf = KalmanFilter(model)
        return (np.asarray(kf.process(p)) for p in iter_chunks(x, _PIECE))

    return model, [
        ("db8 wavelet", lambda: wavelet_denoise_pieces(x, "db8", 5, "soft", piece=_PIECE)),
        ("bior3.7 wavelet packet", lambda: wavelet_packet_denoise_pieces(
            x, "bior3.7", 4, piece=_PIECE)),
        ("AR model", lambda: ar_filter_pieces(iter_chunks(x, _PIECE), model)),
        ("AR(2)-Kalman", kalman),
    ]


def _spool(path: Path, n: int, pieces: Iterator[np.ndarray]) -> np.ndarray:
    """The pieces written to a float64 .npy file of n samples with file writes (a written
    mapping's pages would stay resident), mapped back read-only."""
    with open(path, "wb") as fh:
        np.lib.format.write_array_header_1_0(
            fh, {"descr": np.lib.format.dtype_to_descr(np.dtype(np.float64)),
                 "fortran_order": False, "shape": (n,)})
        for p in pieces:
            np.asarray(p, dtype=np.float64).tofile(fh)
    return np.load(path, mmap_mode="r")


def _compare_file(x: np.ndarray, rate_hz: float, bar: Any) -> tuple[list[CompareRow], Any]:
    """The rows of a file-backed record without holding it or a filtered copy: each filtered
    record is written in pieces to one temporary file (disk: 8 bytes per sample) and
    analysed from it as the record is (the Allan deviation and the PSD read their input in
    pieces, the standard deviation in two passes)."""
    import tempfile

    n = int(x.shape[0])
    rows = [_row("original", x, rate_hz, "original", _std_pieces(x))]
    bar.update(1)
    model, runs = _file_filters(x)
    with tempfile.TemporaryDirectory(prefix="gyrodrift-compare.") as d:
        for label, run in runs:
            y = _spool(Path(d) / "filtered.npy", n, run())
            rows.append(_row(label, y, rate_hz, label, _std_pieces(y)))
            del y
            bar.update(1)
    return rows, model


def run_compare(x: np.ndarray | None = None, rate_hz: float | None = None, *,
                out_dir: str | Path | None = None, source: str = "",
                progress: bool = False) -> CompareReport:
    """Filter the record (default: default_record()) with the paper's four filters and
    measure Q, N, B, STD of each; write table (md, csv, json) and PNG overlays to out_dir.
    progress: tqdm bar on stderr over the five signals (the default run takes a few s).

    Examples
    --------
    >>> rep = run_compare(np.random.default_rng(0).normal(0.0, 1.0, 4096), 100.0)
    >>> [row.signal for row in rep.rows]
    ['original', 'db8 wavelet', 'bior3.7 wavelet packet', 'AR model', 'AR(2)-Kalman']
    >>> all(row.std_deg_h < rep.rows[0].std_deg_h for row in rep.rows[1:])  # each filter helps
    True
    """
    from tqdm import tqdm

    from gyrodrift.report import plots  # matplotlib only when plotting

    if x is None:
        x, rate_hz = default_record()
        source = source or (f"default simulated record (AR(2) {PAPER_AR2}, N, Q of the paper; "
                            f"seed {DEFAULT_SEED})")
    if rate_hz is None:
        raise GyrodriftValueError("rate_hz is required with an input record")
    on_file = (is_file_backed(x) and np.asarray(x).dtype == np.float64
               and x.shape[0] > FILE_BACKED_MIN)
    if not on_file:
        x = np.ascontiguousarray(x, dtype=np.float64)
    with tqdm(total=6, desc="compare", unit="step",
              disable=not progress, leave=False) as bar:
        if on_file:
            rows, model = _compare_file(x, rate_hz, bar)
        else:
            model = fit_ar2(x, method="yule-walker")
            rows = [_row("original", x, rate_hz, "original")]
            bar.update(1)
            for label, run in filters(x):
                rows.append(_row(label, np.asarray(run(), dtype=np.float64), rate_hz, label))
                bar.update(1)
        report = _finish_report(rows, x, rate_hz, model, source, out_dir, plots)
        bar.update(1)
    return report


def _finish_report(rows: list[CompareRow], x: np.ndarray, rate_hz: float, model: Any,
                   source: str, out_dir: str | Path | None, plots: Any) -> CompareReport:
    report = CompareReport(float(rate_hz), int(x.shape[0]), source or "input record",
                           (float(model.a1), float(model.a2)), rows)
    if out_dir is not None:
        _write_report(report, rows, Path(out_dir), plots)
    return report


def _write_report(report: CompareReport, rows: list[CompareRow], out: Path, plots: Any) -> None:
    """The five report files, all or none: each is written to a temporary file next to it
    and renamed only when every one has been written (gyrodrift.io.atomic.atomic_output); on any
    failure or Ctrl-C the temporary files go, and so does the directory if this made it."""
    from gyrodrift.io.atomic import atomic_output

    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    report.files = {"markdown": str(out / "compare.md"), "csv": str(out / "compare.csv"),
                    "allan_png": str(out / "compare_allan.png"),
                    "psd_png": str(out / "compare_psd.png"),
                    "json": str(out / "compare.json")}
    try:
        with contextlib.ExitStack() as stack:
            tmp = {k: stack.enter_context(atomic_output(v)) for k, v in report.files.items()}
            tmp["markdown"].write_text("# Paper 000 Table 1: published vs measured\n\n"
                                       + report.markdown())
            report.write_csv(tmp["csv"])
            plots.plot_allan([(r.signal, r.allan) for r in rows], tmp["allan_png"],
                             title="Allan deviation before/after filtering")
            plots.plot_psd([(r.signal, r.psd) for r in rows], tmp["psd_png"],
                           title="Welch PSD before/after filtering")
            tmp["json"].write_text(json_text(report.as_dict()))
    except BaseException:
        report.files = {}
        if made:
            with contextlib.suppress(OSError):
                out.rmdir()
        raise
