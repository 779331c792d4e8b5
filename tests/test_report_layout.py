"""The HTML page every report is built on (:class:`~delaytrack.report.HtmlReport`): a table of
contents, folded detail, links between reports, text left and numbers right, no "NaN" where a
value does not apply."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd

from delaytrack.report import HtmlReport, frame_to_html
from delaytrack.report.robustness import display_outcomes


def test_the_table_of_contents_leads_to_every_section():
    report = HtmlReport("A report")
    for title in ("Summary", "Figures", "Detail"):
        report.heading(title)
        report.heading(f"{title}, part", level=3)
    page = report.render()
    anchors = re.findall(r'<h2 id="([^"]+)">', page)
    assert re.findall(r'<a href="#([^"]+)">', page) == anchors and len(anchors) == 3
    assert page.index('<nav class="toc">') < page.index("<h2")
    single = HtmlReport("Short")
    single.heading("Only")
    assert "<nav" not in single.render()  # one section needs no contents


def test_folded_detail_is_a_details_element_around_its_blocks():
    report = HtmlReport("A report")
    with report.folded("Grids"):
        report.table(pd.DataFrame({"k": [1.0]}))
    page = report.render()
    assert re.search(r"<details><summary>Grids</summary>\s*<div class=\"wide\"><table", page)
    assert page.index("</table>") < page.index("</details>")


def test_paths_to_other_reports_are_links_and_other_text_stays_escaped():
    report = HtmlReport("A report")
    report.paragraph("The study (../robustness/report.html) & <more>.")
    report.bullets(["see ../paper-literal/report.html"])
    page = report.render()
    assert '(<a href="../robustness/report.html">../robustness/report.html</a>)' in page
    assert '<a href="../paper-literal/report.html">' in page and "&amp; &lt;more&gt;" in page


def test_text_columns_left_numbers_right_and_headers_break_after_underscores():
    frame = pd.DataFrame(
        {
            "controller": ["AROLC", "PCON"],
            "ae_x_mm": [1.23456, np.nan],
            "draws": ["2 / 40", "—"],
            "told": ["1.5", "not told"],
        }
    )
    table = frame_to_html(frame)
    head = re.findall(r"<th( class=\"num\")?>([^<]*)", table)
    assert [bool(css) for css, _ in head] == [False, True, True, False]
    assert "ae_<wbr>x_<wbr>mm" in table
    assert '<td class="num">1.235</td>' in table and '<td class="num">—</td>' in table
    assert "NaN" not in table  # a report never shows NaN: "—" unless said otherwise
    assert "<td>AROLC</td>" in table
    assert '<td class="num">n/a</td>' in frame_to_html(frame, missing="n/a")


def test_the_robustness_maps_told_ratio_says_not_told_for_a_controller_told_nothing():
    table = pd.DataFrame(
        {
            "delay_ms": [60.0, 60.0],
            "controller": ["AROLC (paper gains)", "PCONf"],
            "scale": [math.nan, 2.0],
            "diverged": [0, 1],
            "runs": [4, 4],
            **{
                name: [1.0, 2.0]
                for name in (
                    "median_ae_mm",
                    "median_ae_ci_low_mm",
                    "median_ae_ci_high_mm",
                    "median_tv_Nm",
                    "median_tv_ci_low_Nm",
                    "median_tv_ci_high_Nm",
                )
            },
        }
    )
    shown = display_outcomes(table, ["delay_ms", "controller", "scale"])
    assert list(shown["told / true delay"]) == ["not told", "2"]
    assert "NaN" not in frame_to_html(shown)
