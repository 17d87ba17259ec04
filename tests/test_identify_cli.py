"""`gyrodrift identify` (GMWM, Allan NNLS, slope) and the Allan fit options of
`gyrodrift allan` (--fit-range, --terms, selection, intervals, JSON `taus`), end to end."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gyrodrift
import gyrodrift.cli as cli
import numpy as np
import pytest
from cli_units import with_units


@pytest.fixture(autouse=True)
def only_these_subcommands(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(cli, "SUBCOMMAND_MODULES", ["allan", "identify"])


def run(argv: list, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(with_units(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("id") / "r.npy"
    rec = gyrodrift.simulate(n=1 << 14, rate_hz=100.0, n_deg_rt_h=0.05, k_deg_h_rt_h=400.0,
                             seed=31)
    np.save(path, rec.rate_deg_h)
    return path


def test_identify_gmwm_table_json_png(record: Path, tmp_path: Path, capsys) -> None:
    png = tmp_path / "wv.png"
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "gmwm",
                          "--model", "N+K", "--ci", "0.95", "--png", png], capsys)
    assert code == 0, err
    assert "GMWM model N+K" in out and "deg/sqrt(h)" in out and "rad/s/sqrt(Hz)" in out
    assert "deg/h/sqrt(h)" in out and "rad/s^2/sqrt(Hz)" in out and "95.00 %" in out
    assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 10_000
    code, out, _ = run(["identify", record, "--rate-hz", 100, "--identifier", "gmwm",
                        "--model", "N+K", "--ci", "0.95", "--json"], capsys)
    d = json.loads(out)
    lib = gyrodrift.identify_gmwm(np.load(record), 100.0, model="N+K")
    assert [p["name"] for p in d["gmwm"]["params"]] == ["N", "K"]
    assert d["gmwm"]["params"][0]["value"] == pytest.approx(lib.value("N"), rel=1e-12)
    n = d["gmwm"]["params"][0]
    assert n["ci_low"] < 0.05 < n["ci_high"]


def test_identify_gmwm_fit_range_selects_the_scales(record: Path, capsys) -> None:
    # Regression: --fit-range was silently ignored by --identifier gmwm (the README's real-record
    # GMWM fits scales >= 2.56 s, which the command line could not reproduce).
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "gmwm",
                          "--model", "N+K", "--fit-range", "0.1:", "--json"], capsys)
    assert code == 0, err
    got = json.loads(out)["gmwm"]
    x = np.load(record)
    lib = gyrodrift.identify_gmwm(x, 100.0, model="N+K", tau_range=(0.1, math.inf))
    whole = gyrodrift.identify_gmwm(x, 100.0, model="N+K")
    assert got["params"][1]["value"] == pytest.approx(lib.value("K"), rel=1e-12)
    assert lib.value("K") != pytest.approx(whole.value("K"), rel=1e-6)
    code, _, err = run(["identify", record, "--rate-hz", 100, "--identifier", "slope",
                        "--fit-range", "0.1:"], capsys)
    assert code == 2 and "--fit-range applies to --identifier gmwm and allan-nnls" in err


def test_identify_allan_nnls_and_slope(record: Path, capsys) -> None:
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "allan-nnls",
                          "--json"], capsys)
    assert code == 0, err
    fit = json.loads(out)["fit"]
    assert [t["name"] for t in fit["terms"]] == ["N", "K"]
    assert set(fit["dropped"]) == {"Q", "B", "R"}
    n = fit["terms"][0]
    assert n["ci_low"] < n["value"] < n["ci_high"] and n["value"] == pytest.approx(0.05,
                                                                                  rel=0.05)
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "slope"], capsys)
    assert code == 0, err
    assert "slope method" in out
    assert "deg/sqrt(h)" in out and "n/a" in out  # no -1 stretch: Q is n/a


def test_allan_fit_options_json_taus(record: Path, tmp_path: Path, capsys) -> None:
    png = tmp_path / "a.png"
    code, out, err = run(["allan", record, "--rate-hz", 100, "--json", "--png", png,
                          "--fit-range", "0.1:", "--terms", "N,B,K"], capsys)
    assert code == 0, err
    d = json.loads(out)
    taus = d["taus"]
    assert [t["tau_s"] for t in taus] == d["allan"]["tau_s"]
    assert set(taus[0]) == {"tau_s", "adev", "ci_low", "ci_high", "fit_adev", "fit_used",
                            "fit_ratio", "fit_passed"}
    assert [t["fit_used"] for t in taus] == [t["tau_s"] >= 0.1 for t in taus]
    assert d["fit"]["requested"] == ["N", "B", "K"] and "B" in d["fit"]["dropped"]
    terms = {t["name"]: t for t in d["fit"]["terms"]}
    # fitted total at each tau = the root sum of squares of the kept terms' deviations
    for t in taus:
        model = math.sqrt(terms["N"]["coeff"] / t["tau_s"] + terms["K"]["coeff"] * t["tau_s"])
        assert t["fit_adev"] == pytest.approx(model, rel=1e-9)
    assert png.read_bytes()[:4] == b"\x89PNG"
    code, text, _ = run(["allan", record, "--rate-hz", 100], capsys)
    assert code == 0 and "dropped (no gain in chi2 + 2p): Q, B, R" in text
    assert "deg/h/sqrt(h)" in text and "rad/s^2/sqrt(Hz)" in text
    code, text, _ = run(["allan", record, "--rate-hz", 100, "--no-select", "--json"], capsys)
    assert code == 0
    for bad in (["--fit-range", "5"], ["--fit-range", "3:1"], ["--terms", "N,X"],
                ["--fit-range", "1000:"]):
        code, _, err = run(["allan", record, "--rate-hz", 100, *bad], capsys)
        assert code == 2 and err.count("\n") == 1, (bad, err)


@pytest.mark.parametrize(("method", "option"), [
    ("gmwm", ["--terms", "N,K"]), ("slope", ["--terms", "N,K"]),
    ("gmwm", ["--no-select"]), ("slope", ["--no-select"]),
    ("allan-nnls", ["--model", "N+K"]), ("slope", ["--model", "N+K"]),
    ("allan-nnls", ["--max-model", "N+K+GM"]), ("allan-nnls", ["--bootstrap", "20"]),
    ("slope", ["--seed", "3"]),
])
def test_identify_refuses_options_of_another_method(record: Path, capsys, method: str,
                                                    option: list[str]) -> None:
    # Regression: --terms (and the other method-specific options) were silently ignored by
    # the methods that do not use them, so `--identifier gmwm --terms N,K` printed a fit of
    # other terms than asked for without a word.
    code, _, err = run(["identify", record, "--rate-hz", 100, "--identifier", method, *option],
                       capsys)
    assert code == 2
    assert f"{option[0]} applies to --identifier" in err and method in err


def test_identify_terms_still_select_the_allan_nnls_terms(record: Path, capsys) -> None:
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "allan-nnls",
                          "--terms", "N,B", "--json"], capsys)
    assert code == 0, err
    fit = json.loads(out)["fit"]
    assert {t["name"] for t in fit["terms"]} | set(fit["dropped"]) == {"N", "B"}


def test_identify_gm_at_its_lower_bound_becomes_white_noise(tmp_path: Path, capsys) -> None:
    # White noise fitted with a Gauss-Markov term on scales from 0.64 s: the GM's T_c goes to
    # its lower bound (0.64 / 8 s), where it is white noise over the fitted scales; GMWM
    # turns it into N, refits, and the JSON says so (this test asserted the GM and a note
    # on it, before GM terms at a bound were converted).
    path = tmp_path / "w.npy"
    x = gyrodrift.simulate(n=1 << 14, rate_hz=100.0, n_deg_rt_h=0.05, seed=5).rate_deg_h
    np.save(path, x)
    code, out, err = run(["identify", path, "--rate-hz", 100, "--identifier", "gmwm",
                          "--model", "GM", "--fit-range", "0.64:", "--json"], capsys)
    assert code == 0, err
    d = json.loads(out)
    assert d["gmwm"]["model"] == "N"
    n = next(p for p in d["gmwm"]["params"] if p["name"] == "N")
    # the refit is the white-noise model's own fit on those scales (the same iterated GMM)
    lib = gyrodrift.identify_gmwm(x, 100.0, model="N", tau_range=(0.64, math.inf))
    assert n["value"] == pytest.approx(lib.value("N"), rel=1e-9)
    assert n["value"] == pytest.approx(0.05, rel=0.1)
    assert any("lower bound" in v and "white noise" in v for v in d["gmwm"]["notes"])


def test_identify_no_note_when_every_term_is_resolved(record: Path, capsys) -> None:
    code, out, err = run(["identify", record, "--rate-hz", 100, "--identifier", "gmwm",
                          "--model", "N+K", "--json"], capsys)
    assert code == 0, err
    assert json.loads(out)["notes"] == []
