"""`gyrodrift allan --deviation NAME` and the per-tau noise-identification columns."""

from __future__ import annotations

import json
from pathlib import Path

import allantools
import gyrodrift.cli as cli
import numpy as np
import pytest
from cli_units import with_units


@pytest.fixture(autouse=True)
def only_allan(monkeypatch: pytest.MonkeyPatch) -> None:
    # the real gyrodrift.cli.main restricted to `allan`, so that another area's unfinished
    # subcommand cannot break these tests
    monkeypatch.setattr(cli, "SUBCOMMAND_MODULES", ["allan"])


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = cli.main(with_units(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("name", ["mdev", "tdev", "hdev", "ohdev", "totdev"])
def test_allan_deviation_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                              name: str) -> None:
    rng = np.random.default_rng(8)
    x = 15.0 + rng.normal(0.0, 0.3, 20_000)
    path = tmp_path / "r.npy"
    np.save(path, x)
    code, out, _ = run(["allan", path, "--rate-hz", 50, "--deviation", name, "--json"], capsys)
    assert code == 0
    res = json.loads(out)["allan"]
    assert res["deviation"] == name
    _, dev, _, ns = getattr(allantools, name)(x, rate=50.0, data_type="freq", taus="octave")
    np.testing.assert_allclose(res["adev"], dev, rtol=1e-9)
    assert res["terms"] == ns.astype(int).tolist()
    assert res["noise_id"][0] == "acf" and res["noise_id"][-1] == "slope"
    assert res["alpha"][0] == 0  # white rate noise
    code, text, _ = run(["allan", path, "--rate-hz", 50, "--deviation", name], capsys)
    assert code == 0
    lines = text.splitlines()
    h = next(k for k, line in enumerate(lines) if "noise_id" in line)
    assert name in lines[h] and "alpha" in lines[h]
    assert "IEEE 952 fit" not in text  # the Allan-variance fits run for oadev only
    rows = [line.split() for line in lines[h + 1:h + 1 + len(res["tau_s"])]]
    assert "acf" in rows[0] and "slope" in rows[-1]  # the method used, per tau


def test_allan_default_table_shows_the_noise_id(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    x = np.random.default_rng(9).normal(0.0, 1.0, 5000)
    path = tmp_path / "r.npy"
    np.save(path, x)
    code, text, _ = run(["allan", path, "--rate-hz", 10], capsys)
    assert code == 0 and "IEEE 952 fit" in text and "noise_id" in text
    code, text, _ = run(["allan", path, "--rate-hz", 10, "--noise-id", "slope"], capsys)
    lines = text.splitlines()
    h = next(k for k, line in enumerate(lines) if "noise_id" in line)
    rows = [line.split() for line in lines[h + 1:] if line[:1] == " "]
    assert rows and all("slope" in r and "acf" not in r for r in rows)
    with pytest.raises(SystemExit) as exc:
        run(["allan", path, "--rate-hz", 10, "--deviation", "bogus"], capsys)
    assert exc.value.code == 2 and "invalid choice" in capsys.readouterr().err


@pytest.mark.parametrize(("name", "words"), [("mdev", "Modified Allan"), ("tdev", "Time"),
                                             ("hdev", "Hadamard"),
                                             ("ohdev", "Overlapping Hadamard"),
                                             ("totdev", "Total")])
def test_allan_png_names_the_deviation(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                       monkeypatch: pytest.MonkeyPatch, name: str,
                                       words: str) -> None:
    # Regression: `gyrodrift allan --deviation ohdev --png` titled its plot "Overlapping
    # Allan deviation" and labelled the axis sigma(tau), whatever the deviation.
    import matplotlib.axes

    titles: list[str] = []
    labels: list[str] = []
    monkeypatch.setattr(matplotlib.axes.Axes, "set_title",
                        lambda self, t, *a, **k: titles.append(t))
    real_ylabel = matplotlib.axes.Axes.set_ylabel
    monkeypatch.setattr(matplotlib.axes.Axes, "set_ylabel",
                        lambda self, t, *a, **k: (labels.append(t), real_ylabel(self, t))[1])
    path = tmp_path / "r.npy"
    np.save(path, np.random.default_rng(3).normal(0.0, 1.0, 4096))
    code, _, err = run(["allan", path, "--rate-hz", 50, "--deviation", name, "--png",
                        tmp_path / "d.png"], capsys)
    assert code == 0, err
    assert titles == [f"{words} deviation"]
    assert labels and name in labels[-1]
