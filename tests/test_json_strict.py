"""Every JSON the package writes is strict JSON: NaN/Inf become null (issue 13: output a
strict parser can read). Before: `gyrodrift characterize --identifier gmwm --json` wrote bare NaN
for taus outside the fit range, which JavaScript, jq and serde refuse."""

from __future__ import annotations

import io
import json

import numpy as np
from gyrodrift.cli.common import emit_json
from gyrodrift.io.json_text import json_text


def _strict_loads(text: str) -> object:
    def refuse(name: str) -> object:
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_nan_and_inf_are_written_as_null() -> None:
    payload = {"a": float("nan"), "b": [np.float32(np.inf), 1.5], "c": np.array([-np.inf, 2.0]),
               "n": np.int64(3)}
    assert _strict_loads(json_text(payload)) == {"a": None, "b": [None, 1.5], "c": [None, 2.0],
                                                  "n": 3}
    buf = io.StringIO()
    emit_json(payload, buf)
    assert _strict_loads(buf.getvalue())["a"] is None



def test_fleet_result_and_summary_files_are_strict(tmp_path, monkeypatch) -> None:
    """The fleet's result.json and summary.json (were json.dumps: bare NaN/Infinity). A GMWM
    result has no fitted Allan curve (fit_adev NaN at every tau) and an interval may be
    unbounded (inf); a stand-in identify_gmwm gives both, run serially in this process."""
    import gyrodrift
    from gyrodrift.workflows.fleet import FleetOptions, run_fleet, write_summary

    class P:
        def __init__(self, name: str, value: float, hi: float) -> None:
            self.name, self.value, self.ci_low, self.ci_high, self.unit = (
                name, value, 0.5 * value, hi, "")

    def fake(xd, rate_hz, *, ci):
        tau = np.array([0.02, 0.04, 0.08])  # a wavelet variance the model describes (the
        # fit's self-check needs one)
        return type("R", (), {"model": "N+K",
                              "params": (P("N", 0.3, 0.6), P("K", 12.0, np.inf)),
                              "tau_s": tau, "wv": 1.0 / tau, "wv_fit": 1.0 / tau,
                              "rate_hz": rate_hz, "n_samples": xd.size, "objective": 0.5,
                              "implied": lambda self: {
                                  "N": 0.3, "N_ci_low": 0.15, "N_ci_high": 0.6, "K": 12.0,
                                  "K_ci_low": 6.0, "K_ci_high": np.inf, "K_resolved": 1.0,
                                  "K_upper_limit": np.inf}})()

    import gyrodrift.stability.gmwm

    monkeypatch.setattr(gyrodrift.stability.gmwm, "identify_gmwm", fake)
    log = tmp_path / "unit0.npy"
    np.save(log, np.random.default_rng(0).standard_normal((4000, 6)) * 1e-3)
    s = run_fleet([log], tmp_path / "out", opts=FleetOptions(rate_hz=100.0, method="gmwm",
                                                             plots=False), workers=0)
    assert s["n_done"] == 1, s["failed"]
    res = _strict_loads((tmp_path / "out" / "units" / "unit0" / "result.json").read_text())
    gx = res["result"]["channels"]["gyro_x"]  # type: ignore[index]
    assert gx["taus"][0]["fit_adev"] is None
    assert gx["terms"]["K"]["ci_high"] is None
    assert res["summary"]["params"]["gyroscope_random_walk"]["gyro_x"]["ci_high"] is None  # type: ignore[index]
    # summary.json: a parameter whose value is NaN gives NaN quantiles.
    unit = {"unit": "u0", "path": "u0.npy", "status": "done",
            "params": {"gyroscope_noise_density": {
                "gyro_x": {"value": float("nan"), "ci_low": 0.0, "ci_high": 1.0,
                           "unit": "rad/s/sqrt(Hz)"}}}}
    write_summary([unit], tmp_path / "out", None)
    summ = _strict_loads((tmp_path / "out" / "summary.json").read_text())
    assert summ["distribution"]["gyroscope_noise_density"]["gyro_x"]["median"] is None  # type: ignore[index]


def test_replay_report_file_is_strict(tmp_path) -> None:
    """replay's report.json (had its own cleaner: NaN as null but Inf as the strings "inf" /
    "-inf", a number turned into text) goes through json_text like every JSON output."""
    from gyrodrift.replay.harness import ReplayResult
    from gyrodrift.report.replay import write_json

    report = {"ok": False, "comparison": {"max_abs_error": [float("inf"), 1e-6, -np.inf]},
              "latency_us": {"p50": float("nan"), "n": np.int64(0)}}
    result = ReplayResult(report, np.empty(0), np.empty(0), None)
    got = _strict_loads(write_json(result, tmp_path / "report.json").read_text())
    assert got == {"ok": False, "comparison": {"max_abs_error": [None, 1e-6, None]},
                   "latency_us": {"p50": None, "n": 0}}
