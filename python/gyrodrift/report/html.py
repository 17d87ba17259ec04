"""Self-contained HTML pages (jinja2; images inline as base64 PNG): the `characterize` report
of one IMU and the `fleet` summary.

Examples
--------
>>> "<table" in render_table([{"a": 1.0}])
True
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import Any

__all__ = ["characterize_html", "fleet_html", "render_table"]

_CSS = """
body { font-family: sans-serif; margin: 1.5em; color: #222; }
table { border-collapse: collapse; margin: 0.8em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.6em; text-align: right; }
th { background: #eee; } td.l, th.l { text-align: left; }
tr.bad td { background: #fdd; }
p.warn { color: #a00; } img { max-width: 100%; border: 1px solid #ddd; }
code { background: #f4f4f4; }
"""

_CHAR_TEMPLATE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>gyrodrift characterize: {{ name }}</title>
<style>{{ css }}</style></head><body>
<h1>IMU characterization: {{ name }}</h1>
<p>gyrodrift {{ version }}, method <code>{{ method }}</code>, intervals at probability
{{ "%.4g"|format(ci) }}.</p>
<h2>Input</h2>
<table id="inputs">{% for k, v in record.items() %}
<tr><th class="l">{{ k }}</th><td class="l">{{ v }}</td></tr>{% endfor %}
</table>
<h2>Noise terms per axis</h2>
<table id="terms"><tr><th class="l">channel</th><th class="l">term</th><th>value</th>
<th>interval</th><th class="l">unit (SI)</th><th>value</th><th>interval</th>
<th class="l">unit (IEEE)</th></tr>
{% for r in rows %}<tr><td class="l">{{ r.channel }}</td>
<td class="l">{{ r.term }} ({{ r.meaning }})</td>
<td>{{ "%.4g"|format(r.value) }}</td>
<td>[{{ "%.3g"|format(r.ci_low) }}, {{ "%.3g"|format(r.ci_high) }}]</td>
<td class="l">{{ r.unit }}</td><td>{{ "%.4g"|format(r.ieee_value) }}</td>
<td>[{{ "%.3g"|format(r.ieee_low) }}, {{ "%.3g"|format(r.ieee_high) }}]</td>
<td class="l">{{ r.ieee_unit }}</td></tr>
{% endfor %}</table>
{% if fit_checks %}<h2>Fit self-check</h2>
<p>Does each fitted model describe the measured curve? A point passes when the fitted value lies
inside the measured interval or within the tolerance of it as a ratio; the model holds when
every point used in the fit passes. Where it does not, the values are approximate.</p>
{% for w in kalibr_warnings %}<p class="warn"><b>WARNING:</b> {{ w }}</p>
{% endfor %}<table id="fitcheck"><tr><th class="l">channel</th><th class="l">curve</th>
<th class="l">model holds</th><th>chi2/dof</th><th>points failed / used</th>
<th>worst fitted/measured</th><th class="l">per point: x (s) ratio</th></tr>
{% for c in fit_checks %}<tr class="{{ '' if c.holds else 'bad' }}">
<td class="l">{{ c.channel }}</td><td class="l">{{ c.what }}</td>
<td class="l">{{ "yes" if c.holds else "NO" }}</td>
<td>{{ "%.3g"|format(c.statistic) if c.statistic is not none else "n/a" }}</td>
<td>{{ c.n_failed }} / {{ c.n_used }}</td>
<td>{{ "%.3g"|format(c.worst_ratio) if c.worst_ratio is not none else "n/a" }}</td>
<td class="l">{% for x, r, u, ok in c.points %}{{ "%.3g"|format(x) }}: {% if r is not none
%}{{ "%.3g"|format(r) }}{% else %}n/a{% endif %}{{ "" if ok else " (fails)" }}{{
"" if u else " (not fitted)" }}{{ "; " if not loop.last else "" }}{% endfor %}</td></tr>
{% endfor %}</table>{% endif %}
{% if kalibr_refused %}<h2>Kalibr imu.yaml</h2>
<p><b>Not written:</b> {{ kalibr_refused }}</p>{% endif %}
{% if kalibr %}<h2>Kalibr imu.yaml</h2><pre>{{ kalibr }}</pre>{% endif %}
{% if self_check %}<h2>Simulation check</h2>
<p>A record simulated with the identified terms (same length and rate, seed {{ self_check.seed }})
was identified again: {{ "every term recovered inside its interval" if self_check.all_inside
else "some terms NOT recovered inside their intervals" }}.</p>
<table id="selfcheck"><tr><th class="l">channel</th><th class="l">term</th><th>simulated</th>
<th>identified</th><th>interval</th><th class="l">inside</th></tr>
{% for r in self_check.rows %}<tr class="{{ '' if r.inside else 'bad' }}">
<td class="l">{{ r.channel }}</td>
<td class="l">{{ r.term }}</td><td>{{ "%.4g"|format(r.truth) }}</td>
<td>{{ "%.4g"|format(r.estimate) }}</td>
<td>[{{ "%.3g"|format(r.ci_low) }}, {{ "%.3g"|format(r.ci_high) }}]</td>
<td class="l">{{ r.inside }}</td></tr>
{% endfor %}</table>{% endif %}
<h2>Allan deviation</h2>
{% for title, uri in images %}<figure><img alt="{{ title }}" src="{{ uri }}">
<figcaption>{{ title }}</figcaption></figure>
{% endfor %}
</body></html>
"""

_FLEET_TEMPLATE = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>gyrodrift fleet summary</title>
<style>{{ css }}</style></head><body>
<h1>Fleet summary</h1>
<p>gyrodrift {{ version }}: {{ n_done }} units characterized, {{ n_failed }} failed,
{{ n_flagged }} outside the spec
{{ " (" + spec_name + ")" if spec_name else " (no --spec given)" }}.</p>
<h2>Distribution over units</h2>
<table id="distribution"><tr>{% for h in dist_head %}<th class="l">{{ h }}</th>{% endfor %}</tr>
{% for r in dist_rows %}<tr>{% for c in r %}<td>{{ c }}</td>{% endfor %}</tr>{% endfor %}</table>
{% for title, uri in images %}<figure><img alt="{{ title }}" src="{{ uri }}">
<figcaption>{{ title }}</figcaption></figure>
{% endfor %}
<h2>Units outside the spec</h2>
{% if flagged %}<table id="flagged"><tr><th class="l">unit</th><th class="l">parameter</th>
<th class="l">channel</th><th>value</th><th>limit</th></tr>
{% for f in flagged %}<tr class="bad"><td class="l">{{ f.unit }}</td>
<td class="l">{{ f.parameter }}</td>
<td class="l">{{ f.channel }}</td><td>{{ "%.4g"|format(f.value) }}</td><td>{{ f.limit }}</td>
</tr>{% endfor %}
</table>{% else %}<p>none</p>{% endif %}
<h2>Failed logs</h2>
{% if failed %}<table id="failed"><tr><th class="l">log</th><th class="l">reason</th></tr>
{% for f in failed %}<tr class="bad"><td class="l">{{ f.path }}</td>
<td class="l">{{ f.reason }}</td></tr>{% endfor %}
</table>{% else %}<p>none</p>{% endif %}
<h2>Units</h2>
<table id="units"><tr><th class="l">unit</th><th class="l">status</th><th class="l">report</th></tr>
{% for u in units %}<tr class="{{ 'bad' if u.status != 'done' else '' }}">
<td class="l">{{ u.name }}</td>
<td class="l">{{ u.status }}</td>
<td class="l">{% if u.link %}<a href="{{ u.link }}">{{ u.link }}</a>{% endif %}</td>
</tr>{% endfor %}
</table>
</body></html>
"""


def _env() -> Any:
    import jinja2

    return jinja2.Environment(autoescape=True, undefined=jinja2.StrictUndefined)


def characterize_html(*, name: str, version: str, method: str, ci: float,
                      record: dict[str, object], rows: Sequence[dict[str, Any]],
                      images: Sequence[tuple[str, str]], kalibr: str | None,
                      self_check: dict[str, Any] | None,
                      fit_checks: Sequence[dict[str, Any]] = (),
                      kalibr_warnings: Sequence[str] = (),
                      kalibr_refused: str | None = None) -> str:
    """The characterize report (one file: tables, inline PNG plots, inputs, version).

    ``fit_checks``: one dict per channel (channel, what, holds, statistic, n_failed, n_used,
    worst_ratio, points: (x, ratio, used, passed) tuples; None for a value not defined);
    ``kalibr_warnings``: the warning lines of the Kalibr export; ``kalibr_refused``: why no
    Kalibr file could be written.

    Examples
    --------
    >>> page = characterize_html(name="bench", version="0.1", method="allan-nnls", ci=0.6827,
    ...                          record={"source": "bench.npy"}, rows=[], images=[], kalibr=None,
    ...                          self_check=None)
    >>> page.startswith("<!DOCTYPE html>"), "bench" in page
    (True, True)
    """
    return _env().from_string(_CHAR_TEMPLATE).render(
        css=_CSS, name=name, version=version, method=method, ci=ci, record=record, rows=rows,
        images=images, kalibr=kalibr, self_check=self_check, fit_checks=list(fit_checks),
        kalibr_warnings=list(kalibr_warnings), kalibr_refused=kalibr_refused)


def fleet_html(**kw: Any) -> str:
    """The fleet summary page (see gyrodrift.workflows.fleet.write_summary for the fields).

    Examples
    --------
    >>> page = fleet_html(version="0.1", n_done=2, n_failed=0, n_flagged=0, spec_name="",
    ...                   dist_head=[], dist_rows=[], images=[], flagged=[], failed=[],
    ...                   units=[{"name": "unit1", "status": "done", "link": "units/unit1"}])
    >>> page.startswith("<!DOCTYPE html>"), "unit1" in page
    (True, True)
    """
    return _env().from_string(_FLEET_TEMPLATE).render(css=_CSS, **kw)


def render_table(rows: Sequence[dict[str, Any]]) -> str:
    """A plain HTML table of dict rows (keys as the header).

    Examples
    --------
    >>> print(render_table([{"term": "N", "value": "1e-5"}, {"term": "K<", "value": 0}]))
    <table><tr><th>term</th><th>value</th></tr><tr><td>N</td><td>1e-5</td></tr><tr><td>K&lt;...
    """
    if not rows:
        return "<table></table>"
    keys = list(rows[0])
    head = "".join(f"<th>{html.escape(str(k))}</th>" for k in keys)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(r.get(k)))}</td>" for k in keys)
                   + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"
