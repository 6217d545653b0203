"""The files of a report, shared by the controller, study and comparison reports.

A report is ``data`` (every number behind every figure), figures drawn from it and sections
``(title, paragraphs, tables, figure names)`` (a table is ``(caption, rows)``, the first row the
header). This module writes them: ``data.json`` (keys sorted, no NaN: byte-identical for the
same data), a self-contained ``report.html`` (figures embedded as base64 PNG) and the blocks of
``report.pdf`` (:func:`~drivetrain_ctrl.reporting.figures.write_report_pdf` draws them).
"""

from __future__ import annotations

import base64
import html
import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

__all__ = [
    "Section",
    "data_json_text",
    "html_page",
    "pdf_blocks",
    "png_base64",
    "write_data_json",
]

#: one section: title, paragraphs, tables ``(caption, rows)``, names of its figures
Section = tuple[str, list[str], list[tuple[str, list[list[str]]]], list[str]]

_STYLE = (
    "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
    "table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #999;"
    "padding:2px 6px;font-size:0.9em;text-align:left}img{max-width:100%}</style>"
)


def data_json_text(data: Mapping[str, Any]) -> str:
    """The text of ``data.json``: keys sorted, indent 1, NaN refused (the same data gives the
    same bytes)."""
    return json.dumps(data, sort_keys=True, indent=1, allow_nan=False) + "\n"


def write_data_json(data: Mapping[str, Any], path: Path) -> Path:
    """Write ``data`` as JSON to ``path`` (:func:`data_json_text`)."""
    path.write_text(data_json_text(data), encoding="utf-8")
    return path


def png_base64(fig: Any, dpi: int = 90) -> str:
    """Figure ``fig`` as a base64-encoded PNG (for an ``<img src="data:...">``)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def html_page(
    title: str,
    heading: str,
    sections: Sequence[Section],
    figs: Mapping[str, Any],
    *,
    style: str | None = None,
    sortable: bool = False,
    script: str = "",
) -> str:
    """A self-contained HTML page: ``heading``, then each section's paragraphs, tables and
    figures (embedded PNGs; a section may name a figure ``figs`` lacks: left out).

    ``style``: a ``<style>`` element instead of the default one; ``sortable``: every table gets
    ``class="sortable"``, its header row a ``<thead>`` and its rows a ``<tbody>`` and the page a
    viewport line (for ``script``, e.g. one sorting the rows on a click on a heading);
    ``script``: appended to the body as it is (a ``<script>`` element)."""
    e = html.escape
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        *(['<meta name="viewport" content="width=device-width, initial-scale=1">'] * sortable),
        f"<title>{e(title)}</title>",
        _STYLE if style is None else style,
        "</head><body>",
        f"<h1>{e(heading)}</h1>",
    ]
    for stitle, paras, tables, fnames in sections:
        parts.append(f"<h2>{e(stitle)}</h2>")
        parts += [f"<p>{e(p)}</p>" for p in paras]
        for cap, rows in tables:
            head = "<tr>" + "".join(f"<th>{e(c)}</th>" for c in rows[0]) + "</tr>"
            body = ["<tr>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>" for r in rows[1:]]
            if sortable:
                parts.append(f'<table class="sortable"><caption>{e(cap)}</caption>')
                parts += [f"<thead>{head}</thead><tbody>", *body, "</tbody>"]
            else:
                parts += [f"<table><caption>{e(cap)}</caption>", head, *body]
            parts.append("</table>")
        for f in fnames:
            if f in figs:
                parts.append(
                    f'<img alt="{e(f)}" src="data:image/png;base64,{png_base64(figs[f])}">'
                )
    if script:
        parts.append(script)
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def pdf_blocks(
    heading: str, sections: Sequence[Section], figs: Mapping[str, Any]
) -> list[tuple[Any, ...]]:
    """The PDF's content in reading order: ``heading``, each section's text, tables and then its
    figures (each figure once, where first named); figures no section names come last."""
    blocks: list[tuple[Any, ...]] = [("h1", heading)]
    placed: list[str] = []
    for title, paras, tables, fnames in sections:
        blocks.append(("h2", title))
        blocks += [("p", p) for p in paras]
        for cap, rows in tables:
            blocks.append(("table", cap, rows))
        for f in fnames:
            if f in figs and f not in placed:
                blocks.append(("figure", figs[f]))
                placed.append(f)
    rest = [f for f in figs if f not in placed]
    if rest:
        blocks.append(("h2", "Other figures"))
        blocks += [("figure", figs[f]) for f in rest]
    return blocks
