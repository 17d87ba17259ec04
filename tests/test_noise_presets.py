"""The default noise identification (the IEEE 952 Allan fit, gyrodrift.stability.allan_fit)
on the realistic, misspecified presets: a small fixed-seed Monte Carlo with accuracy and
coverage thresholds (scripts/noise_id_presets_mc.py runs the full one,
docs/validation/noise-identification.md), the regression "flat B with every tau marked used"
and the default on the shared laser-gyro record."""

from __future__ import annotations

import sys
from pathlib import Path

import gyrodrift
import numpy as np
import pytest
from gyrodrift.simulation import PRESETS, simulate_preset
from gyrodrift.stability import DEFAULT_IDENTIFIER
from gyrodrift.stability.allan import oadev
from gyrodrift.stability.allan_fit import fit_allan

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
import noise_id_presets_mc as mc

#: records per preset and length factor of the small Monte Carlo (about 40 s of CPU in all)
RECORDS = 6
LENGTH = {"tactical-mems": 0.4, "consumer-mems": 0.5, "navigation-fog": 0.25}


@pytest.fixture(scope="module")
def small_mc() -> dict[str, tuple[mc.Tally, object]]:
    out = {}
    for name in PRESETS:
        n = round(PRESETS[name].default_n_samples * LENGTH[name])
        out[name] = mc.tally(name, n, range(RECORDS), 0.95)
    return out


def test_default_identifier_is_the_allan_fit() -> None:
    assert DEFAULT_IDENTIFIER == "allan-nnls"


@pytest.mark.xdist_group("noise_presets_mc")
@pytest.mark.parametrize("name", list(PRESETS))
def test_accuracy_on_presets(small_mc, name: str) -> None:
    res, truth = small_mc[name]
    # N within 10 % on every record (the spread of N is about 1 %, full Monte Carlo).
    assert np.all(np.abs(np.asarray(res.n_ratio) - 1.0) <= 0.10), res.n_ratio
    # Fitted B within 20 % as a median; the median of 6 records scatters by about 0.08
    # (the per-record 5-95 % range is about 0.65-1.5 on the shortest preset, full run), so the
    # bound is the target plus about 1.25 of those: [0.7, 1.3]. B kept on at least half the
    # records.
    kept = [b for b in res.b_ratio if b > 0]
    assert len(kept) >= RECORDS // 2
    assert 0.7 <= float(np.median(kept)) <= 1.3, kept
    # K: the upper limit holds on every record where K is not identified; where K is
    # reported as identified, it is within 30 % (the rule asks for that at 90 %).
    assert all(res.k_limit_holds)
    assert all(abs(k - 1.0) <= 0.3 for k in res.k_ratio), res.k_ratio
    # the read-off tracks the true curve's minimum (median within 15 %)
    assert 0.85 <= float(np.median(res.ro_ratio)) <= 1.15
    assert truth.b_min_deg_h > truth.b_deg_h  # type: ignore[attr-defined]


def test_identified_k_is_within_30_percent() -> None:
    # Regression: K was reported as identified when its 95 % interval spanned at most a
    # factor 3; that picked the records whose K came out high (a larger K line carries more
    # of the model, so its relative interval is narrower): on these tactical-mems records
    # of the default length (2.8 h) it reported K = 1.48x and 1.51x the generating K
    # (seeds 6 and 16) as identified. A 2.8 h record measures this K to about +-35 % (sd of
    # log K over records): it must now be given as an upper limit that holds, or, where
    # identified, within 30 %.
    p = PRESETS["tactical-mems"]
    for seed in (6, 16):
        rec = simulate_preset(p, p.default_n_samples, seed)
        r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False, ci=0.95, threads=1)
        fit = fit_allan(r.tau_s, r.adev, r.edf, n_samples=r.n_samples, rate_hz=r.rate_hz)
        k_true = rec.truth.k_deg_h_rt_h
        if "K" in fit.upper_limits:
            assert fit.upper_limits["K"] >= k_true, (seed, fit.upper_limits)
            assert "K" not in fit.names or not fit.term("K").identified
            assert any("K not identified" in line for line in fit.notes())
        else:
            assert abs(fit.value("K") / k_true - 1.0) <= 0.3, (seed, fit.value("K"))


@pytest.mark.xdist_group("noise_presets_mc")
def test_coverage_on_presets(small_mc) -> None:
    # 95 % intervals pooled over the 3 x 6 records: binomial sd at p = 0.95, n = 18 is 5.1
    # points, so >= 80 % (2.9 sd below 95 %; P(at most 14 of 18) = 1.1 %) rarely fails when
    # the intervals are right, and a systematic under-coverage fails (N intervals without the
    # model-discrepancy weight covered 30-55 % on filtered MEMS records during development;
    # the fitted B's intervals without the model set covered 67-76 % of the tactical-mems
    # records whose selected model drops K). Every record whose fit keeps B counts for B.
    n_cover = [c for r, _ in small_mc.values() for c in r.n_cover]
    ro_cover = [c for r, _ in small_mc.values() for c in r.ro_cover]
    b_cover = [c for r, _ in small_mc.values()
               for c, x in zip(r.b_cover, r.b_ratio, strict=True) if x > 0]
    assert len(b_cover) >= 12
    assert np.mean(n_cover) >= 0.80, n_cover
    assert np.mean(ro_cover) >= 0.80, ro_cover
    assert np.mean(b_cover) >= 0.80, b_cover


@pytest.mark.xdist_group("noise_presets_mc")
def test_intervals_not_inflated_on_presets(small_mc) -> None:
    # Over-coverage: the standardised errors z = log(estimate / truth) / se_log of N and of
    # the fitted B (se_log = log(high / value) / 1.96, scripts/noise_id_presets_mc.py)
    # pooled over the records. For honest intervals mean z^2 is about 1 (somewhat less here:
    # the intervals use Student's t and cover the models near the selected one); these
    # seeds give 0.47 for N and 1.2 for B. Intervals made 2x wider than these (a way to
    # reach any coverage) give about 0.12 for N: mean z^2 >= 0.2 for N and for B.
    for name in ("N", "B"):
        z2 = [v for r, _ in small_mc.values() for v in r.z2[name]]
        assert len(z2) >= 12
        assert float(np.mean(z2)) >= 0.2, (name, z2)


def test_no_unflagged_misfit() -> None:
    # the self-check travels with every fit: a used tau that fails it makes the fit approximate
    for name in PRESETS:
        n = round(PRESETS[name].default_n_samples * LENGTH[name])
        rec = simulate_preset(name, n, 0)
        r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False, ci=0.95)
        fit = fit_allan(r.tau_s, r.adev, r.edf)
        assert fit.check.used.tolist() == fit.fit_used.tolist()
        if np.any(fit.fit_used & ~fit.check.passed):
            assert fit.approximate and fit.check.warnings


def test_flat_b_with_all_taus_used_is_flagged() -> None:
    # Regression: on a MEMS record with an output filter, fitting every tau (what the default
    # did) cannot follow the filter's bend at the shortest taus; that fit must be flagged, and
    # the default (automatic range) must leave those taus out and keep B near the truth
    # (the old default gave B = 65x the generating B here, N dropped, nothing flagged).
    rec = simulate_preset("tactical-mems", 400_000, seed=5)
    r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False, ci=0.95)
    forced = fit_allan(r.tau_s, r.adev, r.edf, fit_range=(0.0, np.inf))
    assert forced.fit_used.all() or forced.fit_used[r.adev > 0].all()
    assert not forced.check.holds
    assert forced.approximate
    assert any("does not hold" in w for w in forced.check.warnings)
    default = fit_allan(r.tau_s, r.adev, r.edf)
    assert not default.fit_used[0] and default.range_source == "automatic"
    assert "shortest left out" in default.range_note
    assert default.check.holds
    assert abs(default.value("N") / rec.truth.n_deg_rt_h - 1.0) <= 0.1
    # one record: the fitted B's 5-95 % range over records of this length is about 0.9-1.4
    # of the generating B (small Monte Carlo), so [0.6, 1.6] bounds it; the old fit gave 65.
    assert "B" in default.names
    assert 0.6 <= default.value("B") / rec.truth.b_deg_h <= 1.6
    # the read-off is printed beside the fitted B
    notes = "\n".join(default.notes())
    assert "datasheet read-off B" in notes and "fitted B" in notes


def test_default_on_shared_laser_gyro_record(lasergyro_path: Path) -> None:
    # The default (automatic range) on the real ring-laser record in a vehicle: angle random
    # walk in the ranges GMWM and the hand-ranged Allan fits give per axis (x 0.36-0.44 with
    # GMWM's GM folded in, y 0.56-0.82, z 0.051-0.070 deg/sqrt(h): scripts/gmwm_real_record.py)
    # widened by 25 %, no B above the curve's minimum, and the fit says which taus it used.
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "scripts"))
    import gmwm_real_record as real

    axes = real.load_axes(lasergyro_path)
    expect = {"x": (0.27, 0.55), "y": (0.42, 1.03), "z": (0.038, 0.088)}
    for ax, (lo, hi) in expect.items():
        r = gyrodrift.oadev(axes[ax], 100.0, taus="octave", ci=0.95, alpha="acf")
        fit = fit_allan(r.tau_s, r.adev, r.edf)
        assert lo <= fit.value("N") <= hi, (ax, fit.value("N"))
        assert fit.value("B") <= fit.b_readoff
        assert int(fit.fit_used.sum()) >= 5 and "chosen automatically" in fit.range_note
        t = fit.term("N")
        assert t.ci_low < t.value < t.ci_high


def test_characterize_uses_the_same_default_fit() -> None:
    # One default for allan, identify and characterize: characterize's N (rad/s/sqrt(Hz), on
    # the record in rad/s) is the identify fit's N (deg/sqrt(h), on deg/h) converted. The
    # log-scale fit is invariant to the unit up to the optimizer's tolerance: 1e-6 relative.
    import math

    from gyrodrift.workflows.characterize import characterize_channel

    rec = simulate_preset("consumer-mems", 100_000, seed=2)
    r = oadev(rec.gyro_deg_h, rec.rate_hz, progress=False)
    fit = fit_allan(r.tau_s, r.adev, r.edf)
    ch = characterize_channel(np.deg2rad(rec.gyro_deg_h / 3600.0), rec.rate_hz, "gyro_x")
    n_si = fit.value("N") * math.pi / 180.0 / 60.0
    assert ch.terms["N"].value == pytest.approx(n_si, rel=1e-6)
    assert ch.extra["fit_range"] == fit.range_note
    assert ch.extra["approximate"] == fit.approximate
