#!/usr/bin/env python3
"""The drift-model fit from whole-record lag statistics in the C++ core
(gyrodrift.filters.lag_drift_fit) against the numpy reference's fit, its CPU time on this
machine, and its instruction count and stack on the Cortex-M4 (QEMU, software double).

Host, for each record (AR(2) drift with q = 1 plus white noise r = r/q on 9.7, 2000 samples of
burn-in, as tests/test_lag_drift_fit.py; pushed into float statistics, as on the target, and
double ones). Prints:
  dLL max   - the largest |C++ log-likelihood - reference lag_loglike| relative to it, exact
              and Whittle's kind, at the truth and at the fit, on the double statistics;
  ref (SE)  - the largest |C++ fit - reference fit| of a1, a2, q, r, mean on the double
              statistics, in the offline fit's standard errors (gyrodrift.fit_drift_model);
  dLL fit   - the C++ fit's parameters' reference log-likelihood minus the reference fit's
              maximum (positive: the C++ fit scores higher);
  off (SE)  - the largest |C++ fit on the float statistics - offline ML fit| in offline SE;
  cpu ms    - the median process time of --repeats C++ fits on the float statistics, and the
              reference fit's (one run);
  evals     - the C++ fit's likelihood evaluations and BFGS runs (reference: evaluations).
Then, for the same records, the C++ fit of Whittle's likelihood without the first samples
from the float statistics without them at L = 12 and 8 (as the target would keep them): the
median process time of --repeats fits, its evaluations and the time an evaluation.

Cortex-M4 (cpp/cortex_m/use_lag_drift_fit.cpp, built and checked as the gate builds it, then
run on QEMU netduinoplus2 with -icount shift=0, one instruction per virtual ns): the unit's
float statistics of a simulated 60000-sample record, one fit in double, timed by SysTick on the
reference clock and calibrated by a loop of known length. For each form: the gate's (L = 32,
the first samples kept, the exact likelihood) and the statistics without the first samples
at L = 12 and L = 8 with Whittle's likelihood without them (the unit built with
-DGYRODRIFT_LAG_FIT_LAGS=L -DGYRODRIFT_LAG_FIT_NO_HEAD=1). Prints the fit's instructions, its
evaluations, the statistics' sizeof on the M4, the fit's own stack (the free stack painted
again before the fit), the unit's stack high-water mark, flash and RAM, the same record's fit
on this host where the form is bound (MCU against host: the evaluations and a1, a2 to 1e-6),
and the time one fit takes when spread over the spare instructions of 400 Hz loop steps
(budget 14000 a step; the three-gyro monitor image's median step 4619 and worst step 10488,
docs/validation/monitor-firmware.md).

    python scripts/lag_drift_fit_cost.py              # the docs run
    python scripts/lag_drift_fit_cost.py --no-m4      # host only
    python scripts/lag_drift_fit_cost.py --no-host    # Cortex-M4 only
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import gyrodrift
import numpy as np
from gyrodrift._native import core
from gyrodrift.filters import LagStatistics, lag_drift_fit, lag_drift_loglike
from gyrodrift.reference.lag_drift import lag_drift_fit as reference_fit
from gyrodrift.reference.lag_drift import lag_loglike
from scipy.signal import lfilter

ROOT = Path(__file__).resolve().parent.parent
PARAMS = ("a1", "a2", "q", "r", "mean")
# (a1, a2, r/q, samples, seed); the second is the offline fit's fold record (a maximum on
# each side of a2 = 0).
CASES = [(0.6868, -0.0213, 1.0, 60000, 1), (0.6868, -0.0213, 0.3, 60000, 9),
         (0.2297, 0.1638, 3.0, 60000, 3), (0.6868, -0.0213, 3.0, 960000, 2),
         (0.2297, 0.1638, 1.0, 960000, 1)]
STEP_BUDGET = 14000
STEP_MEDIAN = 4619
STEP_WORST = 10488
RATE_HZ = 400.0
FIT_LINE = re.compile(r"lag-drift-fit status=(?P<status>\d+) evaluations=(?P<ev>\d+) "
                      r"iterations=(?P<it>\d+) runs=(?P<runs>\d+) systick=(?P<counts>-?\d+) "
                      r"calibration=(?P<cal>-?\d+) turns=(?P<turns>\d+) a1_e6=(?P<a1>-?\d+) "
                      r"a2_e6=(?P<a2>-?\d+) lags=(?P<lags>\d+) no_head=(?P<no_head>\d) "
                      r"state_bytes=(?P<state>\d+) fit_stack=(?P<fit_stack>-?\d+)")
# (L, without the first samples): the gate's form, then the compact ones.
M4_FORMS = ((32, False), (12, True), (8, True))


def record(a1: float, a2: float, ratio: float, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x = lfilter([1.0], [1.0, -a1, -a2], rng.normal(size=n + 2000))[2000:]
    return 9.7 + x + rng.normal(0.0, math.sqrt(ratio), n)


def host(repeats: int) -> None:
    print("| samples | pair | r/q | seed | dLL max (rel) | ref (SE) | dLL fit | off (SE) "
          "| cpu ms C++ (median) | cpu ms reference | evals C++ (runs) | evals reference |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for a1, a2, ratio, n, seed in CASES:
        y = record(a1, a2, ratio, n, seed)
        st64, st32 = LagStatistics(), LagStatistics(dtype=np.float32)
        st64.push(y)
        st32.push(y)
        fit64 = lag_drift_fit(st64)
        t0 = time.process_time()
        ref = reference_fit(st64)
        t_ref = time.process_time() - t0
        times = []
        for _ in range(repeats):
            t0 = time.process_time()
            fit32 = lag_drift_fit(st32)
            times.append(time.process_time() - t0)
        offline = gyrodrift.fit_drift_model(y, rate_hz=RATE_HZ)
        se = offline.stderr
        worst = 0.0
        for p in ((a1, a2, 1.0, ratio, 9.7),
                  (fit64.a1, fit64.a2, fit64.q, fit64.r, fit64.mean)):
            for kind in ("exact", "whittle"):
                want = lag_loglike(st64, *p, kind=kind)
                worst = max(worst, abs(lag_drift_loglike(st64, *p, kind=kind) - want) / abs(want))
        z_ref = max(abs(getattr(fit64, k) - getattr(ref, k)) / se[k] for k in PARAMS)
        d_ll = lag_loglike(st64, fit64.a1, fit64.a2, fit64.q, fit64.r, fit64.mean) - ref.loglike
        z_off = max(abs(getattr(fit32, k) - getattr(offline, k)) / se[k] for k in PARAMS)
        print(f"| {n} | ({a1}, {a2}) | {ratio:g} | {seed} | {worst:.1e} | {z_ref:.4f} "
              f"| {d_ll:+.1e} | {z_off:.4f} | {1e3 * statistics.median(times):.2f} "
              f"| {1e3 * t_ref:.0f} | {fit32.evaluations} ({fit32.runs}) | {ref.evaluations} |",
              flush=True)


def host_no_head(repeats: int) -> None:
    lib = core("drift")
    print("| samples | pair | r/q | seed | L | status | cpu ms C++ (median) | evaluations (runs) "
          "| us an evaluation |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for a1, a2, ratio, n, seed in CASES:
        y = record(a1, a2, ratio, n, seed).astype(np.float32)
        for lags in (12, 8):
            bound = getattr(lib, f"LagStatisticsNoHead{lags}F32")()
            bound.push(y)
            times, out = [], None
            for _ in range(repeats):
                t0 = time.process_time()
                out = lib.lag_drift_fit(bound)
                times.append(time.process_time() - t0)
            assert out is not None
            ms = 1e3 * statistics.median(times)
            print(f"| {n} | ({a1}, {a2}) | {ratio:g} | {seed} | {lags} | {out[0].name} | {ms:.3f} "
                  f"| {int(out[9])} ({int(out[10])}) | {1e3 * ms / int(out[9]):.2f} |", flush=True)


def unit_record() -> np.ndarray:
    """The gate unit's record, as it computes it in float32 (LCG uniforms, sums of 12, the
    AR(2) recursion, the mean from the unit's first input sample, 0.51)."""
    f32 = np.float32

    def uniforms(seed: int, count: int) -> np.ndarray:
        out = np.empty(count, dtype=np.uint32)
        s = seed
        for i in range(count):
            s = (s * 1664525 + 1013904223) % 2**32
            out[i] = s >> 8
        return out.astype(np.float32) * f32(2.0**-24)

    def normals(u: np.ndarray) -> np.ndarray:
        v = np.full(u.shape[0], f32(-6.0), dtype=np.float32)
        for i in range(12):
            v = v + u[:, i]
        return v

    n, burn = 60000, 2000
    w = normals(uniforms(12345, 12 * (n + burn)).reshape(-1, 12))
    v = normals(uniforms(67890, 12 * n).reshape(-1, 12))
    a1, a2, mean = f32(0.6868), f32(0.0213), f32(0.51)
    x1 = x2 = f32(0.0)
    y = np.empty(n, dtype=np.float32)
    for k in range(n + burn):
        x = f32(f32(a1 * x1) - f32(a2 * x2)) + w[k]
        x2, x1 = x1, x
        if k >= burn:
            y[k - burn] = f32(mean + x) + v[k - burn]
    return y


def _gate() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "cortex_m_gate", ROOT / "tests" / "test_cortex_m_gate.py")
    if spec is None or spec.loader is None:
        raise SystemExit("tests/test_cortex_m_gate.py not found")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _host_fit(lags: int, no_head: bool, y: np.ndarray) -> tuple[int, int, int, int, int] | None:
    """The same record's fit on this host: (evaluations, iterations, runs, a1 x 1e6,
    a2 x 1e6), or None where the form is not bound."""
    if not no_head:
        st = LagStatistics(dtype=np.float32)
        st.push(y)
        fit = lag_drift_fit(st)
        return fit.evaluations, fit.iterations, fit.runs, int(fit.a1 * 1e6), int(fit.a2 * 1e6)
    lib = core("drift")
    cls = getattr(lib, f"LagStatisticsNoHead{lags}F32", None)
    if cls is None:
        return None
    bound = cls()
    bound.push(y)
    out = lib.lag_drift_fit(bound)
    return int(out[9]), int(out[8]), int(out[10]), int(out[1] * 1e6), int(out[2] * 1e6)


def m4() -> None:
    gate = _gate()
    y = unit_record()
    print("| L | first samples | likelihood | status | evaluations (iterations, runs) "
          "| instructions a fit | an evaluation | statistics sizeof B | fit stack B "
          "| unit stack high-water B | largest frame B | unit flash B | unit RAM B "
          "| s a fit at the median / worst step's spare | host: evaluations, a1, a2 x 1e6 |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- "
          "| --- |")
    for lags, no_head in M4_FORMS:
        work = Path(tempfile.mkdtemp(prefix="lag_fit_m4_"))
        flags = [f"-DGYRODRIFT_LAG_FIT_LAGS={lags}", f"-DGYRODRIFT_LAG_FIT_NO_HEAD={int(no_head)}"]
        unit = gate.build_unit(gate.CM_DIR / "use_lag_drift_fit.cpp", work, flags)
        if not unit.ok:
            raise SystemExit(f"the unit failed the gate: {unit.reasons}\n{unit.log}")
        elf = work / "use_lag_drift_fit.elf"
        proc = subprocess.run(
            [gate.toolchain()["qemu"], "-M", gate.QEMU_MACHINE, "-nographic", "-monitor", "none",
             "-serial", "none", "-semihosting-config", "enable=on,target=native",
             "-icount", "shift=0", "-kernel", str(elf)],
            capture_output=True, text=True, timeout=600, check=False, cwd=work)
        out = proc.stdout + proc.stderr
        m, rep = FIT_LINE.search(out), gate.REPORT_LINE.search(out)
        if m is None or rep is None or int(m["counts"]) < 0 or int(m["cal"]) <= 0:
            raise SystemExit(f"no valid measurement in the unit's output:\n{out}")
        per_count = 2 * int(m["turns"]) / int(m["cal"])
        instructions = int(m["counts"]) * per_count
        evals = int(m["ev"])
        seconds = [instructions / (STEP_BUDGET - used) / RATE_HZ
                   for used in (STEP_MEDIAN, STEP_WORST)]
        host_fit = _host_fit(lags, no_head, y)
        host_text = "-" if host_fit is None else (
            f"{host_fit[0]} ({host_fit[1]}, {host_fit[2]}), {host_fit[3]}, {host_fit[4]}")
        print(f"| {m['lags']} | {'no' if m['no_head'] == '1' else 'yes'} "
              f"| {'Whittle, no first samples' if no_head else 'exact'} | {m['status']} "
              f"| {evals} ({m['it']}, {m['runs']}) | {instructions:.3g} "
              f"| {instructions / evals:.3g} | {m['state']} | {m['fit_stack']} "
              f"| {int(rep['stack'], 16)} | {unit.max_frame_bytes} | {unit.flash_bytes} "
              f"| {unit.ram_bytes} | {seconds[0]:.0f} / {seconds[1]:.0f} "
              f"| {host_text}; M4 {m['a1']}, {m['a2']} |", flush=True)
    print(f"(SysTick at {per_count:.3f} instructions a count; spare instructions a step: "
          f"{STEP_BUDGET - STEP_MEDIAN} at the median step, {STEP_BUDGET - STEP_WORST} at the "
          f"worst, at {RATE_HZ:.0f} Hz)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="C++ fits timed per record")
    ap.add_argument("--no-m4", action="store_true", help="skip the Cortex-M4 measurement")
    ap.add_argument("--no-host", action="store_true", help="skip the host measurement")
    args = ap.parse_args()
    if not args.no_host:
        host(args.repeats)
        host_no_head(args.repeats)
    if not args.no_m4:
        m4()


if __name__ == "__main__":
    main()
