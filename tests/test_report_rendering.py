"""Every HTML report as a browser shows it (headless Chromium, when installed) in a window of
1280 px with every folded part opened: the page is no wider than the window, no table scrolls
sideways inside its box, every image loads, the table of contents leads to every section,
numbers are right-aligned and text left-aligned."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from delaytrack.cli import main

BROWSER = next(
    (
        shutil.which(name)
        for name in ("chromium", "chromium-browser", "google-chrome")
        if shutil.which(name)
    ),
    None,
)
pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(BROWSER is None, reason="no headless Chromium installed"),
]
EXAMPLES = Path(__file__).parents[1] / "examples"
WIDTH = 1280

# Written into the page after it loads; the browser's DOM dump then carries the answer.
_PROBE = """<script>window.addEventListener('load', () => {
  document.querySelectorAll('details').forEach(d => { d.open = true; });
  const images = Array.from(document.images);
  const wide = Array.from(document.body.querySelectorAll('*')).filter(e => {
    const r = e.getBoundingClientRect();
    return r.right > window.innerWidth + 1 && !e.closest('.wide');
  }).map(e => e.tagName + ': ' + (e.textContent || '').slice(0, 60));
  const scrolling = Array.from(document.querySelectorAll('.wide'))
    .filter(e => e.scrollWidth > e.clientWidth + 1)
    .map(e => (e.textContent || '').slice(0, 60));
  const cells = Array.from(document.querySelectorAll('table.data td'));
  const align = cells.filter(c => getComputedStyle(c).textAlign
    !== (c.classList.contains('num') ? 'right' : 'left')).length;
  const sections = Array.from(document.querySelectorAll('h2')).map(h => h.id);
  const contents = Array.from(document.querySelectorAll('nav.toc a'))
    .map(a => a.getAttribute('href').slice(1));
  document.body.setAttribute('data-probe', JSON.stringify({
    page: document.documentElement.scrollWidth, window: window.innerWidth,
    images: images.length, broken: images.filter(i => !(i.complete && i.naturalWidth > 0)).length,
    wide: wide, scrolling: scrolling, cells: cells.length, misaligned: align,
    numbers: cells.filter(c => c.classList.contains('num')).length,
    sections: sections, contents: contents}));
});</script>"""


def rendered(report: Path, tmp_path: Path) -> dict:
    """The probe's findings for ``report`` rendered at :data:`WIDTH` px."""
    page = tmp_path / f"probe-{report.parent.name}.html"
    page.write_text(report.read_text().replace("</body>", _PROBE + "</body>"))
    dom = subprocess.run(
        [
            BROWSER,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            f"--window-size={WIDTH},1000",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout
    start = dom.index("data-probe=") + len("data-probe=") + 1
    quote = dom[start - 1]
    text = dom[start : dom.index(quote, start)].replace("&quot;", '"').replace("&amp;", "&")
    return json.loads(text)


@pytest.fixture(scope="module")
def reports(tmp_path_factory, reproduced):
    # The paper job, its literal sibling and the robustness study: the reproduce run of
    # tests/conftest.py (with contact physics and the dt check), which test_paper.py reads too.
    paper, code, _printed = reproduced
    assert code == 0
    out = tmp_path_factory.mktemp("reports")
    quiet = ["--quiet"]
    assert (
        main(["reproduce", "--job", "two-link", "--out", str(out), "--duration", "1", *quiet]) == 0
    )
    assert (
        main(["reproduce", "--job", "margins", "--out", str(out), "--duration", "6", *quiet]) == 0
    )
    sweep = out / "sweep"
    assert main(["sweep", str(EXAMPLES / "sweep_small.toml"), "--out", str(sweep), *quiet]) == 0
    # The trade-off's page, on the small linear plant of tests/test_tradeoff.py: its table has
    # a column for every margin and count, the widest the package writes.
    from delaytrack.scenario import Scenario
    from test_tradeoff import PLANT

    plant = out / "light_mass.toml"
    Scenario.from_dict(PLANT).to_toml(plant)
    tradeoff = ["tradeoff", str(plant), "--omega", "0.7", "1.4", "2", "--upper", "2"]
    assert main([*tradeoff, "--out", str(out / "tradeoff"), *quiet]) == 0
    return {
        "paper": paper / "paper" / "report.html",
        "paper-literal": paper / "paper-literal" / "report.html",
        "robustness": paper / "robustness" / "report.html",
        "two-link": out / "two-link" / "report.html",
        "margins": out / "margins" / "report.html",
        "sweep": sweep / "report.html",
        "tradeoff": out / "tradeoff" / "report.html",
    }


@pytest.fixture(scope="module")
def probes(reports, tmp_path_factory):
    """Each report's probe findings, one headless Chromium run per report for every test."""
    folder = tmp_path_factory.mktemp("probes")
    return {name: rendered(path, folder) for name, path in reports.items()}


#: Every report the fixture writes.
REPORTS = ["paper", "paper-literal", "robustness", "two-link", "margins", "sweep", "tradeoff"]


@pytest.mark.parametrize("name", REPORTS)
def test_report_fits_the_window_and_every_image_loads(probes, name):
    probe = probes[name]
    assert probe["images"] > 0 and probe["broken"] == 0, probe
    assert probe["page"] <= probe["window"], probe
    assert probe["wide"] == [], probe
    assert probe["scrolling"] == [], probe  # no table scrolls sideways in its box


@pytest.mark.parametrize("name", REPORTS)
def test_report_tables_say_what_a_missing_value_is_not_nan(reports, name):
    # A run that left the path, a margin not searched: said in the caption, shown "—".
    assert ">NaN</td>" not in reports[name].read_text()


@pytest.mark.parametrize("name", REPORTS)
def test_report_is_laid_out_for_the_device_s_width(reports, name):
    # Without it a phone lays the page out 980 px wide and shrinks it: 16 px text shown at 6 px.
    page = reports[name].read_text()
    assert '<meta name="viewport" content="width=device-width, initial-scale=1"/>' in page


@pytest.mark.parametrize("name", REPORTS)
def test_report_ends_with_the_papers_reference(reports, name):
    page = reports[name].read_text()
    footer = page[page.rindex("<footer>") : page.rindex("</footer>")]
    assert "S. Roy and I. N. Kar" in footer and "Unknown Input Delay" in footer


@pytest.mark.parametrize("name", REPORTS)
def test_report_is_navigable_and_aligned(probes, name):
    probe = probes[name]
    if len(probe["sections"]) > 1:  # a table of contents leads to every section
        assert probe["contents"] == probe["sections"], probe
    # Numbers right-aligned, text left-aligned.
    assert probe["numbers"] > 0 and probe["misaligned"] == 0, probe


def test_paper_report_puts_summary_and_figures_first_and_folds_the_grids(reports):
    page = reports["paper"].read_text()

    def section(title: str) -> int:
        return re.search(f'<h2 id="[^"]+">{title}', page).start()

    summary, figures, tuning = section("Summary"), section("Figures"), section("Tuning")
    assert summary < figures < page.index("<figure>") < section("Claims check") < tuning
    grids = page[tuning:]
    assert grids.index("<details>") < grids.index("the five best grid points")
    assert '<a href="../robustness/report.html">' in page  # the link to the study is clickable


def test_robustness_map_table_says_not_told_instead_of_nan(reports):
    page = reports["robustness"].read_text()
    start = page.index(">Robustness map (table)</h2>")
    table = page[start : page.index("</table>", start)]
    assert "not told" in table and "NaN" not in table
