"""One stateful binding object shared by several Python threads (issue 13).

ImuProcessor, RealtimeWaveletBank, OadevStream and OadevFusedStream release the GIL while
they step their own state; before the fix concurrent calls on one object lost counter
updates (3,257 to 62,579 of 8,000,000 in the issue's runs). Each object now serialises its
calls (a lock taken after the GIL is released), so the counters must add up exactly.

Whether updates get lost depends on two threads really running at once, which a loaded
2-core machine may not give within a test's time (on this machine the sums below happened
to add up before the fix too). The deterministic check is the polling one: a reader thread
that asks for the counters while another thread is inside a call must never see a
half-done call. Before the fix it always did (the call runs without the GIL, so the reader
runs meanwhile, even on one core); with the per-object lock it waits for the call to end.
The Oadev streams only publish their counters at the end of a call, so their checks make a
second call while a long one runs (rate input: the second must continue the first's
difference chain; fused: a second pass over the same range must be refused). Both failed
before their lock on this loaded machine (one run each; the ordering makes it near-certain).
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np
from gyrodrift import _core
from gyrodrift.imu.processor import ImuChannelConfig, ImuConfig, ImuProcessor

THREADS = 4
CALLS = 6


def run_threads(work: Callable[[int], None]) -> None:
    start = threading.Barrier(THREADS)
    errors: list[BaseException] = []

    def body(k: int) -> None:
        try:
            start.wait()
            for _ in range(CALLS):
                work(k)
        except BaseException as e:  # reported below
            errors.append(e)

    threads = [threading.Thread(target=body, args=(k,)) for k in range(THREADS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors


def poll_while_running(call: Callable[[], None], read: Callable[[], int], calls: int) -> set[int]:
    """Values read() returns while another thread makes `calls` calls."""
    done = threading.Event()

    def writer() -> None:
        for _ in range(calls):
            call()
        done.set()

    t = threading.Thread(target=writer)
    seen = {read()}
    t.start()
    while not done.is_set():
        seen.add(read())
    t.join()
    seen.add(read())
    return seen


def test_reader_never_sees_half_a_processor_call() -> None:
    n = 1_000_000
    proc = ImuProcessor(ImuConfig(channels=[ImuChannelConfig() for _ in range(6)],
                                  time_tolerance_us=0))
    seq = (np.arange(n) % 65536).astype(np.uint16)
    t_us = np.arange(n, dtype=np.uint64) * 2500
    values = np.zeros((n, 6))
    seen = poll_while_running(lambda: proc.process(seq, t_us, values),
                              lambda: proc.health["samples_in"], 3)
    assert seen <= {0, n, 2 * n, 3 * n}, sorted(seen)[:5]
    assert 3 * n in seen


def test_reader_never_sees_half_a_wavelet_call() -> None:
    n = 2_000_000
    bank = _core.RealtimeWaveletBankF64(
        _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1, mode="forced", channels=1))
    x = np.full(n, np.nan)
    seen = poll_while_running(lambda: bank.filter(x), lambda: int(bank.fault_counts()[0]), 3)
    assert seen <= {0, n, 2 * n, 3 * n}, sorted(seen)[:5]
    assert 3 * n in seen


def test_shared_imu_processor_counts_every_sample() -> None:
    n = 200_000
    proc = ImuProcessor(ImuConfig(channels=[ImuChannelConfig() for _ in range(6)],
                                  time_tolerance_us=0))
    seq = (np.arange(n) % 65536).astype(np.uint16)
    t_us = np.arange(n, dtype=np.uint64) * 2500
    values = np.zeros((n, 6))
    values[::2, 0] = np.nan  # non-finite counter too
    run_threads(lambda k: proc.process(seq, t_us, values))
    h = proc.health
    total = THREADS * CALLS * n
    assert h["samples_in"] == total
    assert h["samples_accepted"] + h["duplicates"] + h["out_of_order"] == total
    # every accepted row with a NaN was counted once
    assert h["non_finite_samples"] == h["non_finite_values"]


def test_shared_realtime_wavelet_bank_counts_every_fault() -> None:
    n = 500_000
    bank = _core.RealtimeWaveletBankF64(
        _core.RealtimeWaveletConfig(wavelet="db4", window=8, level=1, mode="forced", channels=1))
    x = np.full(n, np.nan)
    run_threads(lambda k: bank.filter(x))
    assert int(bank.fault_counts()[0]) == THREADS * CALLS * n


def test_shared_oadev_stream_counts_every_term() -> None:
    n = 500_000
    acc = _core.OadevStream(1, "phase")
    y = np.zeros(n)
    run_threads(lambda k: acc.advance(y, y, y))
    assert acc.terms == THREADS * CALLS * n


def _started_then(call: Callable[[], None], started: threading.Event,
                  errors: list[BaseException]) -> threading.Thread:
    def body() -> None:
        started.set()
        try:
            call()
        except BaseException as e:  # reported by the caller
            errors.append(e)

    t = threading.Thread(target=body)
    t.start()
    return t


def test_oadev_stream_calls_during_another_call_wait_for_it() -> None:
    """Rate input carries the running difference D from call to call: a call made while
    another is running must start from where that one ends. Before the lock a short call
    made meanwhile read D before the long call wrote it back, and the long call then
    overwrote it.

    With y0 = 1, y1 = y2 = 0 every term adds 1 to D, so after N terms in any order of whole
    calls the sum of squares is 0^2 + ... + (N-1)^2 and sigma^2 = that / (2 N) (m = 1)."""
    n_long, n_short = 2_000_000, 1000
    acc = _core.OadevStream(1, "rate")
    ones_long, zeros_long = np.ones(n_long), np.zeros(n_long)
    ones_short, zeros_short = np.ones(n_short), np.zeros(n_short)
    short_calls = 0

    def short_call() -> int:
        nonlocal short_calls
        acc.advance(ones_short, zeros_short, zeros_short)
        short_calls += 1
        return 0

    poll_while_running(lambda: acc.advance(ones_long, zeros_long, zeros_long), short_call, 4)
    n = 4 * n_long + short_calls * n_short
    assert acc.terms == n
    expected = (n - 1) * n * (2 * n - 1) // 6 / (2 * n)
    assert abs(acc.sigma2() - expected) <= 1e-12 * expected, (acc.sigma2(), expected)


def test_oadev_fused_stream_second_process_of_a_range_is_refused() -> None:
    """Term ranges must be consecutive. Before the lock two threads could both process the
    range 0..N (the check ran before the first call's work ended) and the sums doubled;
    now the second one waits, sees the range already done, and is refused."""
    from gyrodrift.reference.allan import oadev_rate

    rng = np.random.default_rng(13)
    n_data = 3_000_000
    y = rng.standard_normal(n_data)
    m = np.array([1, 4], dtype=np.int64)
    st = _core.OadevFusedStream(n_data, m, 256)
    for j, mj in enumerate(int(v) for v in m):
        st.seed(j, y[:mj], y[mj:2 * mj])
    windows = [y[start:] for start, _ in st.segments()]
    n_terms0 = st.n_terms0
    started = threading.Event()
    errors: list[BaseException] = []
    t = _started_then(lambda: st.process(0, n_terms0, windows), started, errors)
    started.wait()
    try:
        st.process(0, n_terms0, windows)  # the first call is running now
    except ValueError as e:
        errors.append(e)
    t.join()
    assert len(errors) == 1 and isinstance(errors[0], ValueError), errors
    assert "consecutive" in str(errors[0])
    sigma2, terms = st.finish()
    for j, mj in enumerate(int(v) for v in m):
        sigma_ref, terms_ref = oadev_rate(y, mj)
        assert terms[j] == terms_ref
        # fused prefix sums in double around a local mean vs numpy means: ~1e-12 relative
        assert abs(sigma2[j] - sigma_ref**2) <= 1e-9 * sigma_ref**2, (j, sigma2[j], sigma_ref**2)
