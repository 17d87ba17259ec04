"""Every JSON the package writes is strict JSON: NaN/Inf become null (issue 13: output a
strict parser can read). Before: `gyrodrift characterize --method gmwm --json` wrote bare NaN
for taus outside the fit range, which JavaScript, jq and serde refuse."""

from __future__ import annotations

import io
import json

import numpy as np
from gyrodrift.cli.common import emit_json
from gyrodrift.json_text import json_text


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

