"""Overlapping Allan deviation (C++ kernel via gyrodrift.stability.allan) against allantools, the
numpy
reference from the definition, and the chunked (memory-mapped) path; EDF and chi-squared
intervals against allantools.edf_simple / confidence_interval."""

from __future__ import annotations

import allantools
import numpy as np
import pytest
from gyrodrift.reference import oadev_phase, oadev_rate
from gyrodrift.stability import allan, edf, noise_type

# allantools forms the phase with a float64 cumulative sum (mean removed first), whose
# rounding is ~ N * eps relative on the phase; for 2e4..1e5 samples that stays far below
# 1e-9 on the deviation, so 1e-9 relative is the brief's bar and a real check.
ORACLE_RTOL = 1e-9
# Reference vs kernel: both take the long-double / pairwise route on 2e4 samples, agreement
# is at rounding level (~1e-14); 1e-12 leaves room for numpy's summation order.
REF_RTOL = 1e-12


def gyro_like(rng: np.random.Generator, n: int) -> np.ndarray:
    """White rate + random walk + large constant (Earth rate-like offset), deg/h."""
    return 15.0 + rng.normal(0.0, 0.05, n) + np.cumsum(rng.normal(0.0, 2e-4, n))


def test_rate_octave_equals_allantools(rng: np.random.Generator) -> None:
    y = gyro_like(rng, 100_000)
    res = allan.oadev(y, 100.0, taus="octave")
    taus, dev, _, ns = allantools.oadev(y, rate=100.0, data_type="freq", taus="octave")
    np.testing.assert_array_equal(res.tau_s, taus)
    np.testing.assert_array_equal(res.terms, ns)
    np.testing.assert_allclose(res.adev, dev, rtol=ORACLE_RTOL, atol=0)


def test_rate_decade_and_explicit_taus_equal_allantools(rng: np.random.Generator) -> None:
    y = gyro_like(rng, 30_000)
    res = allan.oadev(y, 10.0, taus="decade", per_decade=7)
    _, dev, _, ns = allantools.oadev(y, rate=10.0, data_type="freq", taus=res.tau_s)
    np.testing.assert_array_equal(res.terms, ns)
    np.testing.assert_allclose(res.adev, dev, rtol=ORACLE_RTOL, atol=0)
    explicit = np.array([0.1, 0.3, 2.0, 55.5, 1000.0])
    res2 = allan.oadev(y, 10.0, taus=explicit)
    _, dev2, _, _ = allantools.oadev(y, rate=10.0, data_type="freq", taus=explicit)
    np.testing.assert_allclose(res2.adev, dev2, rtol=ORACLE_RTOL, atol=0)


def test_phase_input_equals_allantools(rng: np.random.Generator) -> None:
    # Cumulative angle in arcsec of a 100 Hz rate record (angle = integral of rate).
    x = np.cumsum(rng.normal(0.0, 0.3, 50_001)) / 100.0
    res = allan.oadev(x, 100.0, kind="phase", taus="octave")
    taus, dev, _, ns = allantools.oadev(x, rate=100.0, data_type="phase", taus="octave")
    np.testing.assert_array_equal(res.tau_s, taus)
    np.testing.assert_array_equal(res.terms, ns)
    np.testing.assert_allclose(res.adev, dev, rtol=ORACLE_RTOL, atol=0)


def test_kernel_equals_definition_reference(rng: np.random.Generator) -> None:
    y = gyro_like(rng, 20_000)
    res = allan.oadev(y, 1.0, taus="decade", per_decade=5)
    for m, dev, terms in zip(res.m, res.adev, res.terms, strict=True):
        ref, n_ref = oadev_rate(y, int(m))
        assert terms == n_ref
        assert dev == pytest.approx(ref, rel=REF_RTOL)
    x = np.concatenate([[0.0], np.cumsum(y)]) / 4.0  # phase at 4 Hz
    resp = allan.oadev(x, 4.0, kind="phase", taus=[0.25, 1.0, 64.0])
    for m, dev in zip(resp.m, resp.adev, strict=True):
        # the phase route itself loses ~ |x| eps / |d2x| ~ 1e-11 here (x up to 4e4)
        assert dev == pytest.approx(oadev_phase(x, int(m), 0.25)[0], rel=1e-9)


def test_float32_input_matches_float64_of_same_values(rng: np.random.Generator) -> None:
    y32 = (rng.normal(0.0, 1.0, 10_000)).astype(np.float32)
    a = allan.oadev(y32, 1.0)
    b = allan.oadev(y32.astype(np.float64), 1.0)
    # Same values, same long double sums: only the order of reading differs (none).
    np.testing.assert_allclose(a.adev, b.adev, rtol=1e-15)


def test_memmap_chunked_equals_in_memory(tmp_path, rng: np.random.Generator) -> None:
    y = gyro_like(rng, 200_003)
    path = tmp_path / "rec.npy"
    np.save(path, y)
    mm = np.load(path, mmap_mode="r")
    assert isinstance(mm, np.memmap)
    whole = allan.oadev(y, 100.0, taus="decade", per_decade=4)
    for chunk in (1, 997, 1 << 16, allan.DEFAULT_CHUNK_SAMPLES):
        if chunk == 1:
            # every sample its own chunk: only for the short taus (slow otherwise)
            part = allan.oadev(y[:3000], 100.0, taus=[0.01, 0.05, 1.0], chunk_samples=1)
            ref = allan.oadev(y[:3000], 100.0, taus=[0.01, 0.05, 1.0])
            # chunking only regroups long-double additions: ~1e-18 relative
            np.testing.assert_allclose(part.adev, ref.adev, rtol=1e-14)
            continue
        chunked = allan.oadev(mm, 100.0, taus="decade", per_decade=4, chunk_samples=chunk)
        np.testing.assert_array_equal(chunked.terms, whole.terms)
        if chunk == allan.DEFAULT_CHUNK_SAMPLES:
            # same fused block size as in memory: bit-identical
            np.testing.assert_array_equal(chunked.adev, whole.adev)
        else:
            # small chunks use 4096-sample blocks: only the block-local rounding differs
            # (~B eps relative on each local prefix sum), 1e-13
            np.testing.assert_allclose(chunked.adev, whole.adev, rtol=1e-13)
    # phase input on the chunked path
    np.save(tmp_path / "ph.npy", np.cumsum(y[:50_000]) / 100.0)
    mp = np.load(tmp_path / "ph.npy", mmap_mode="r")
    a = allan.oadev(mp, 100.0, kind="phase", chunk_samples=4096)
    b = allan.oadev(np.asarray(mp), 100.0, kind="phase")
    np.testing.assert_allclose(a.adev, b.adev, rtol=1e-14)


def test_memmap_with_nan_is_an_error(tmp_path, rng: np.random.Generator) -> None:
    y = rng.normal(size=5000)
    y[1234] = np.nan
    np.save(tmp_path / "bad.npy", y)
    with pytest.raises(ValueError, match="non-finite"):
        allan.oadev(np.load(tmp_path / "bad.npy", mmap_mode="r"), 1.0, chunk_samples=1000)


@pytest.mark.parametrize("alpha", [2, 1, 0, -1, -2])
def test_edf_simple_equals_allantools(alpha: int) -> None:
    n_phase = 10_001
    for m in (1, 2, 7, 100, 1000, 4999):
        if alpha == -1 and m == 1:
            continue  # allantools drops the square of SP 1065 Table 5 here (next test)
        assert edf.edf_simple(n_phase, m, alpha)[()] == pytest.approx(
            allantools.edf_simple(n_phase, m, alpha), rel=1e-13)


def test_edf_simple_flicker_fm_at_m1_is_of_order_n() -> None:
    """Regression: the flicker-FM edf at m = 1 was 2 (N-2) / (2.3 N - 4.9) ~ 0.87 for any N
    (as in allantools), so a 1.8e5-sample record got a 1-sigma interval [0.7, 5] x adev
    once the lag-1 ACF (the new default) read flicker FM at the first tau. SP 1065 Table 5
    has 2 (N-2)^2 / (2.3 N - 4.9); Greenhall's exact algorithm gives 0.895 N."""
    from gyrodrift.stability.edf import edf_greenhall

    for n_phase in (1001, 184_719):
        simple = float(edf.edf_simple(n_phase, 1, -1))
        exact = edf_greenhall(-1, 2, 1, n_phase, overlapping=True, modified=False)
        assert simple == pytest.approx(2 * (n_phase - 2) ** 2 / (2.3 * n_phase - 4.9))
        assert simple == pytest.approx(exact, rel=0.05)


def test_confidence_interval_equals_allantools(rng: np.random.Generator) -> None:
    y = rng.normal(0.0, 1.0, 20_000)
    res = allan.oadev(y, 1.0, alpha=0, ci=0.9)
    for dev, dof, lo, hi in zip(res.adev, res.edf, res.ci_low, res.ci_high, strict=True):
        lo_ref, hi_ref = allantools.confidence_interval(dev, dof, ci=0.9)
        assert lo == pytest.approx(lo_ref, rel=1e-12)
        assert hi == pytest.approx(hi_ref, rel=1e-12)
        assert lo < dev < hi


def test_ci_coverage_on_white_noise() -> None:
    # 1-sigma intervals must cover the true white-noise deviation sigma/sqrt(m) in about
    # 68 % of records; 200 records give a binomial std of 3.3 %, so [0.55, 0.81] is > 3.9 sd.
    true_sigma = 1.0
    hits = total = 0
    for seed in range(200):
        y = np.random.default_rng(seed).normal(0.0, true_sigma, 2000)
        res = allan.oadev(y, 1.0, taus=[4.0, 64.0], alpha=0)
        truth = true_sigma / np.sqrt(res.m)
        hits += int(np.count_nonzero((res.ci_low <= truth) & (truth <= res.ci_high)))
        total += res.m.size
    assert 0.55 <= hits / total <= 0.81


def test_noise_alpha_from_slope_on_pure_terms() -> None:
    tau = np.logspace(0, 3, 13)
    assert set(noise_type.noise_alpha_from_slope(tau, 1.0 / tau)) == {2}
    assert set(noise_type.noise_alpha_from_slope(tau, tau**-0.5)) == {0}
    assert set(noise_type.noise_alpha_from_slope(tau, np.ones_like(tau))) == {-1}
    assert set(noise_type.noise_alpha_from_slope(tau, tau**0.5)) == {-2}


def test_bad_input_errors(rng: np.random.Generator) -> None:
    y = rng.normal(size=100)
    with pytest.raises(ValueError, match="too short for tau"):
        allan.oadev(y, 1.0, taus=[60.0])
    with pytest.raises(ValueError, match="too short"):
        allan.oadev(y[:2], 1.0)
    with pytest.raises(ValueError, match="1-D"):
        allan.oadev(np.zeros((10, 2)), 1.0)
    with pytest.raises(ValueError, match="rate_hz"):
        allan.oadev(y, 0.0)
    bad = y.copy()
    bad[[3, 50]] = [np.nan, np.inf]
    with pytest.raises(ValueError, match="2 NaN/Inf"):
        allan.oadev(bad, 1.0)
    with pytest.raises(TypeError):
        allan.oadev(np.array(["a", "b", "c", "d"]), 1.0)
    with pytest.raises(ValueError, match="constant"):
        allan.oadev(np.full(1000, 15.0), 1.0)


def test_zero_deviation_at_some_taus() -> None:
    # Period-4 pattern: averages over m = 4k samples are all equal, so sigma(4k) = 0 exactly
    # while the other taus are positive; the result and its CIs stay finite.
    y = np.tile([1.0, -1.0, 2.0, -2.0], 500)
    res = allan.oadev(y, 1.0, taus="octave")
    zero = res.m % 4 == 0
    assert np.all(res.adev[zero] < 1e-12) and np.all(res.adev[~zero] > 0.1)
    assert np.all(np.isfinite(res.ci_low)) and np.all(np.isfinite(res.ci_high))
    assert set(np.unique(res.alpha)) <= {-2, -1, 0, 1, 2}


def test_progress_bar_on_request(rng: np.random.Generator, capsys) -> None:
    y = rng.normal(size=50_000)
    allan.oadev(y, 1.0, progress=True)
    assert "Allan" in capsys.readouterr().err
    allan.oadev(y, 1.0, progress="auto")  # small work: no bar
    assert "Allan" not in capsys.readouterr().err


def test_fused_kernel_equals_per_tau_kernel_on_drifting_record(rng) -> None:
    from gyrodrift import _core

    # rate random walk dominating at long taus + a 1e3 deg/h offset: the fused path's local
    # prefix sums must not lose the short-tau differences (measured ~1e-14, bound 1e-12).
    n = 300_001
    y = 1e3 + rng.normal(0.0, 1.0, n) + np.cumsum(rng.normal(0.0, 0.05, n))
    for grid in ("octave", "decade"):
        m = allan.averaging_factors(n, grid, per_decade=20)
        a, ta = _core.oadev_sigma2(y, m, _core.OadevOptions(kind="rate", method="fused"))
        b, tb = _core.oadev_sigma2(y, m, _core.OadevOptions(method="per_tau"))
        np.testing.assert_array_equal(ta, tb)
        np.testing.assert_allclose(a, b, rtol=1e-12)
    with pytest.raises(ValueError, match="strictly increasing"):
        _core.oadev_sigma2(y, np.array([4, 2], dtype=np.int64))
    with pytest.raises(TypeError):
        _core.oadev_sigma2(y.astype(">f8"), np.array([1], dtype=np.int64))  # noconvert


def test_in_memory_path_allocates_little(rng) -> None:
    import tracemalloc

    from gyrodrift.stability import noise_type

    y = rng.normal(size=2_000_000)
    for alpha, extra in (("slope", 0), (None, 6 * 8 * noise_type.MAX_ACF_POINTS)):
        tracemalloc.start()
        base = tracemalloc.get_traced_memory()[0]
        allan.oadev(y, 1.0, progress=False, alpha=alpha)
        peak = tracemalloc.get_traced_memory()[1] - base
        tracemalloc.stop()
        # outputs and tau arrays only: far below the 16 MB input (the C++ workspace is
        # ~0.3 MB and not traced; the bound here is on numpy temporaries); the default
        # lag-1 ACF noise ID adds a few arrays of at most MAX_ACF_POINTS averages per tau,
        # whatever the record length
        assert peak < 0.02 * y.nbytes + extra, alpha


def test_memmap_path_memory_is_bounded(tmp_path, rng) -> None:
    import tracemalloc

    # 4e6 samples (32 MB) read in 2**17-sample chunks: the documented bound is about
    # 4 * chunk * 8 bytes = 4 MiB (windows + seed chunks), whatever the record length.
    n, chunk = 4_000_000, 1 << 17
    np.save(tmp_path / "big.npy", rng.normal(size=n))
    mm = np.load(tmp_path / "big.npy", mmap_mode="r")
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    res = allan.oadev(mm, 100.0, chunk_samples=chunk)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    assert peak < 5 * chunk * 8
    assert res.adev.size == allan.averaging_factors(n, "octave").size


def test_real_laser_gyro_record_equals_allantools(tmp_path) -> None:
    """The shared ring-laser record (integer pulse counts, 0.1 arcsec each, 100 Hz): loaded
    as per-sample angle increments through gyrodrift.io.records, Allan deviation equals allantools,
    and the vertical gyro sees the Earth rate (15.041 deg/h * sin(34.246 deg) = 8.46 deg/h;
    the vehicle stood with its engine running, so 0.3 deg/h covers bias and disturbance)."""
    from conftest import SHARED_DATA, skip_unless_ci
    from gyrodrift.io import records

    path = SHARED_DATA / "lasergyro.imu"
    if not path.exists():
        skip_unless_ci(f"{path} not present (shared real-data record)")
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("%")]
    counts = np.array([ln.split() for ln in lines[3:]], dtype=np.float64)
    # 3 header lines, then the counts (184,718 rows; the data README's 184,719 counts one
    # header line as data)
    assert counts.shape == (184_718, 6)
    np.save(tmp_path / "gz.npy", counts[:, 2] * 0.1)  # arcsec per 10 ms sample
    rec = records.load_record(tmp_path / "gz.npy", rate_hz=100.0, units="arcsec")
    z_deg_h = np.asarray(rec.rate_deg_h)
    assert np.mean(z_deg_h) == pytest.approx(15.041 * np.sin(np.radians(34.246048)), abs=0.3)
    res = allan.oadev(z_deg_h, 100.0, taus="decade", per_decade=8)
    _, dev, _, _ = allantools.oadev(z_deg_h, rate=100.0, data_type="freq", taus=res.tau_s)
    np.testing.assert_allclose(res.adev, dev, rtol=ORACLE_RTOL)


def test_lag1_noise_id_equals_allantools_and_finds_the_types() -> None:
    # Pure power-law rate noises from the simulator (8192 samples: allantools' lag1_acf is a
    # Python loop) and the known alpha of each (S_y ~ f^alpha): quantization = white phase
    # (+2), ARW = white rate (0), RRW = random-walk rate (-2).
    import gyrodrift

    cases = {
        2: gyrodrift.simulate(n=8192, rate_hz=1.0, q_deg=1e-3, seed=1).rate_deg_h,
        0: gyrodrift.simulate(n=8192, rate_hz=1.0, n_deg_rt_h=0.01, seed=2).rate_deg_h,
        -2: gyrodrift.simulate(n=8192, rate_hz=1.0, k_deg_h_rt_h=1.0, seed=3).rate_deg_h,
    }
    for expected, y in cases.items():
        for m in (1, 4, 16, 64):
            ours = allan.lag1_noise_id(y, m)
            ref = allantools.autocorr_noise_id(y, m, data_type="freq")[0]
            assert ours == ref, (expected, m)
            if m <= 16:  # >= 512 averages: r1 sd <= 0.05; at m = 64 (128 averages) the
                # white-PM estimate can round to 3 in both implementations
                assert ours == expected, (expected, m)
    assert allan.lag1_noise_id(cases[0], 300) is None  # 27 averages < 30
    res = allan.oadev(cases[-2], 1.0, alpha="acf")
    assert res.alpha[0] == -2 and np.all(res.alpha >= -2)
    assert list(res.noise_id[:3]) == ["acf"] * 3
    with pytest.raises(ValueError, match="acf"):
        allan.oadev(cases[0], 1.0, alpha="bogus")


def test_fused_result_does_not_depend_on_thread_count(rng) -> None:
    from gyrodrift import _core

    # Workers take whole factor groups whose cut depends only on (n, m, block), so any
    # thread count must give the same bits; and the groups must still equal the per-tau
    # kernel (long double, no blocks) to the fused path's documented 1e-12.
    n = 300_001
    y = 1e3 + rng.normal(0.0, 1.0, n) + np.cumsum(rng.normal(0.0, 0.05, n))
    m = allan.averaging_factors(n, "octave")
    groups = _core.oadev_fused_groups(n, m, 4096)
    assert len(groups) == 2 and groups[0][0] == 0 and groups[-1][1] == m.size
    one, t1 = _core.oadev_sigma2(y, m, _core.OadevOptions(block=4096, threads=1))
    for threads in (2, 3):
        many, tn = _core.oadev_sigma2(y, m, _core.OadevOptions(block=4096, threads=threads))
        np.testing.assert_array_equal(many, one)
        np.testing.assert_array_equal(tn, t1)
    ref, _ = _core.oadev_sigma2(y, m, _core.OadevOptions(method="per_tau"))
    np.testing.assert_allclose(one, ref, rtol=1e-12)
    np.testing.assert_array_equal(allan.oadev(y, 1.0, threads=1).adev,
                                  allan.oadev(y, 1.0, threads=2).adev)
    with pytest.raises(ValueError, match="threads"):
        allan.oadev(y, 1.0, threads=0)
