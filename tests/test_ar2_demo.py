"""`gyrodrift demo`: runs with no input, prints the before/after table, --json is complete."""

from __future__ import annotations

import json

import gyrodrift
import numpy as np
import pytest
from gyrodrift.cli import main
from gyrodrift.cli.demo import DEFAULT_TERMS


def _json(capsys: pytest.CaptureFixture[str], *extra: str) -> dict:
    assert main(["demo", "--json", "--duration-s", "120", *extra]) == 0
    return json.loads(capsys.readouterr().out)


def test_demo_table(capsys) -> None:
    assert main(["demo", "--duration-s", "120"]) == 0
    out = capsys.readouterr().out
    for text in ("AR(2) model (yule-walker)", "| STD (deg/h) |", "AR(2)-Kalman", "STD reduction"):
        assert text in out


def test_demo_json_numbers_are_the_filters_numbers(capsys) -> None:
    res = _json(capsys)
    assert res["record"]["samples"] == 12_000
    table = res["table"]
    assert set(table) == {"raw", "AR filter", "AR(2)-Kalman"}
    # Recompute the Kalman column independently of the CLI from the same seeded record.
    rec = gyrodrift.simulate(120.0, rate_hz=100.0, seed=2006, **DEFAULT_TERMS)
    model = gyrodrift.fit_ar2(rec.rate_deg_h)
    assert res["model"]["a1"] == model.a1 and res["model"]["a2"] == model.a2
    y = gyrodrift.kalman_filter(rec.rate_deg_h, model)[100:]
    assert table["AR(2)-Kalman"]["std_deg_h"] == pytest.approx(np.std(y), rel=1e-12)
    assert table["raw"]["std_deg_h"] == pytest.approx(np.std(rec.rate_deg_h[100:]), rel=1e-12)
    # The filter removes part of the random drift and keeps the constant drift (mean).
    assert table["AR(2)-Kalman"]["std_reduction"] > 1.2
    assert table["AR(2)-Kalman"]["mean_deg_h"] == pytest.approx(table["raw"]["mean_deg_h"],
                                                                abs=0.05)
    assert table["AR(2)-Kalman"]["n_deg_rt_h"] < table["raw"]["n_deg_rt_h"]


def test_demo_options(capsys) -> None:
    base = _json(capsys)
    f32 = _json(capsys, "--float32", "--steady-state")
    assert f32["kalman"] == {**base["kalman"], "steady_state": True, "dtype": "float32"}
    # Steady-state vs full filter differ only in the start-up transient (excluded: first 1 s);
    # float32 adds ~1e-7 relative. 1e-4 relative on the STD covers both.
    assert f32["table"]["AR(2)-Kalman"]["std_deg_h"] == pytest.approx(
        base["table"]["AR(2)-Kalman"]["std_deg_h"], rel=1e-4
    )
    custom = _json(capsys, "--kalman-r", "10", "--ar-method", "ls")
    assert custom["kalman"]["r_deg_h_sq"] == 10.0 and custom["model"]["method"] == "ls"
    # A larger r trusts the model more: more smoothing.
    assert custom["table"]["AR(2)-Kalman"]["std_deg_h"] < base["table"]["AR(2)-Kalman"]["std_deg_h"]


def test_demo_user_errors(capsys) -> None:
    assert main(["demo", "--duration-s", "-1"]) == 2
    assert "error" in capsys.readouterr().err
    assert main(["demo", "--duration-s", "5"]) == 2  # 500 samples
    assert "too short" in capsys.readouterr().err
    assert main(["demo", "--duration-s", "120", "--kalman-r", "0"]) == 2
    assert "r must be" in capsys.readouterr().err
